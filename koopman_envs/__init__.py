"""KoopNav environments: multi-robot navigation with stochastic wheel slip.

Importing the package registers the Gymnasium ids ``KoopNav-TargetReaching-v0`` and
``KoopNav-Formation-v0`` (each with a native ``vector_entry_point``). Without the import,
``gym.make("koopman_envs:KoopNav-Formation-v0")`` imports it for you. The PettingZoo versions
are the modules :mod:`koopman_envs.target_reaching_v0` and :mod:`koopman_envs.formation_v0`.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from koopman_envs.params import PARAMS, SLIP_SETTINGS, PaperParams, slip_lambdas
from koopman_envs.scenario import Scenario
from koopman_envs.sim.maps import BUILTIN_MAPS, MAP_NAMES, MapSpec, generate_random_map, load_map

__version__ = "0.1.0"

ENV_IDS = ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0")

_REGISTRATIONS = {
    "KoopNav-TargetReaching-v0": ("TargetReachingEnv", "make_target_reaching_vec"),
    "KoopNav-Formation-v0": ("FormationEnv", "make_formation_vec"),
}

for _env_id, (_cls, _vec) in _REGISTRATIONS.items():
    if _env_id not in registry:
        register(
            id=_env_id,
            entry_point=f"koopman_envs.fronts.gym_env:{_cls}",
            vector_entry_point=f"koopman_envs.fronts.vector_env:{_vec}",
            max_episode_steps=PARAMS.max_episode_steps,
        )

__all__ = [
    "BUILTIN_MAPS",
    "ENV_IDS",
    "MAP_NAMES",
    "MapSpec",
    "PARAMS",
    "PaperParams",
    "SLIP_SETTINGS",
    "Scenario",
    "generate_random_map",
    "load_map",
    "slip_lambdas",
]
