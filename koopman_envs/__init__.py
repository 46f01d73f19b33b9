"""KoopNav environments: multi-robot navigation with stochastic wheel slip.

Importing the package registers the Gymnasium ids ``KoopNav-TargetReaching-v0`` and
``KoopNav-Formation-v0`` (each with a native ``vector_entry_point``). Without the import,
``gym.make("koopman_envs:KoopNav-Formation-v0")`` imports it for you. The PettingZoo versions
are the modules :mod:`koopman_envs.target_reaching_v0` and :mod:`koopman_envs.formation_v0`,
reachable as attributes of the package (``koopman_envs.formation_v0.parallel_env()`` after
``import koopman_envs``), imported on first use so that the Gymnasium import stays light.

The package is the face of the environments (docs/layout.md): what controllers, baselines, the
evaluator and users need of the folders (``sim/``, ``tasks/``, ``suites/``, ``engine/``,
``rendering/``, ``fronts/``, ``episodes/``, all internal) is exported here, the fronts, the episode
runners and the renderer imported on first use like the PettingZoo modules. The other public modules are the root's:
``params``, ``checks``, ``files``, ``deprecation``, ``scenario``, ``observed``, ``layout`` and the
two PettingZoo modules, and the face of the settings' folder, :mod:`koopman_envs.settings`
(uncertainty, moving obstacles, reset options; tests/test_architecture.py::PUBLIC_MODULES).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from gymnasium.envs.registration import register, registry

from koopman_envs.deprecation import register_moved_paths
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.keywords import ENV_KEYWORDS, env_keyword, keyword_argument
from koopman_envs.engine.plant import BudgetExceeded, CalibrationPlant, make_plant
from koopman_envs.layout import (
    FAR,
    MessageEntry,
    MoverEntry,
    ObservationLayout,
    ObstacleEntry,
    PartOffsets,
    TeamEntry,
)
from koopman_envs.observed import Observed
from koopman_envs.params import PARAMS, SLIP_SETTINGS, PaperParams, slip_lambdas
from koopman_envs.scenario import Scenario
from koopman_envs.sim.dynamics import rk4_pose, rk4_step, wrap_angle, wrap_scalar
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.sim.maps.generator import generate_random_map
from koopman_envs.sim.maps.map_spec import BUILTIN_MAPS, MAP_NAMES, MapSpec, load_map
from koopman_envs.sim.rollout import rollout
from koopman_envs.sim.slip.zones import SlipZone
from koopman_envs.suites import (
    FAMILIES,
    SPLITS,
    SUITES,
    TIERS,
    Suite,
    SuiteLayout,
    check_split_allowed,
    load_suite,
)
from koopman_envs.suites.suite import SUITE_PREFIX, parse_suite_map
from koopman_envs.tasks.base import ENV_IDS, TASKS, TaskSpec, env_id_for_map, task_for_env

if TYPE_CHECKING:  # pragma: no cover - typing only: these are read on first use (_LAZY)
    from koopman_envs.episodes.batch import run_episodes_in_batch
    from koopman_envs.episodes.single import (
        ComputeCharge,
        EpisodeResult,
        path_ratio,
        run_episode,
        smallest_clearance,
    )
    from koopman_envs.fronts.dict_observation import DictObservation
    from koopman_envs.fronts.gym_env import KoopNavEnv
    from koopman_envs.fronts.vector_env import KoopNavVectorEnv
    from koopman_envs.rendering.renderer import Renderer, save_episode
    from koopman_envs.sim.collision import CollisionKind
    from koopman_envs.sim.lidar import beam_angles
    from koopman_envs.sim.movers.tracking import cv_model, cv_predict, cv_update
    from koopman_envs.sim.nearest import nearest_by_clearance, nearest_order
    from koopman_envs.tasks.observation import observation_from_beliefs

__version__ = "0.1.0"

#: the previous release's module paths that docs/ named as public (docs/layout.md's public root
#: modules, the API page docs/api/koopman_envs.md, docs/uncertainty.md, the demo's command in
#: docs/getting_started.md) and that moved by concept (issue 61: did-you-mean into the checks, the
#: settings into settings/, the renderer out of fronts/ into rendering/, the episode runner and the
#: demo into episodes/), kept one release with a DeprecationWarning by koopman_envs.deprecation's
#: import hook (no file at the old path; CHANGELOG.md, Deprecated)
MOVED_PATHS = {
    "koopman_envs.suggest": "koopman_envs.checks",
    "koopman_envs.movers": "koopman_envs.settings.moving_obstacles",
    "koopman_envs.uncertainty": "koopman_envs.settings.uncertainty",
    "koopman_envs.reset_options": "koopman_envs.settings.reset_options",
    "koopman_envs.fronts.episode": "koopman_envs.episodes.single",
    "koopman_envs.fronts.rendering": "koopman_envs.rendering.renderer",
    "koopman_envs.fronts.demo": "koopman_envs.episodes.demo",
}
register_moved_paths(MOVED_PATHS, commands=("koopman_envs.fronts.demo",))

# front classes per task; ids, labels and maps come from the one task table (tasks/base.py)
_FRONTS = {
    "target_reaching": ("TargetReachingEnv", "make_target_reaching_vec"),
    "formation": ("FormationEnv", "make_formation_vec"),
}

for _task, (_cls, _vec) in _FRONTS.items():
    if TASKS[_task].env_id not in registry:
        register(
            id=TASKS[_task].env_id,
            entry_point=f"koopman_envs.fronts.gym_env:{_cls}",
            vector_entry_point=f"koopman_envs.fronts.vector_env:{_vec}",
            max_episode_steps=PARAMS.max_episode_steps,
        )

#: the PettingZoo modules, imported when first read as attributes of the package
_PETTINGZOO_MODULES = ("formation_v0", "target_reaching_v0")

#: names exported from modules that ``import koopman_envs`` does not load (the fronts, the
#: episode runners, the renderer, the kernels only perception and the policies use): name ->
#: its module, imported when the name is first read
_LAZY = {
    "KoopNavEnv": "koopman_envs.fronts.gym_env",
    "KoopNavVectorEnv": "koopman_envs.fronts.vector_env",
    "DictObservation": "koopman_envs.fronts.dict_observation",
    "run_episode": "koopman_envs.episodes.single",
    "EpisodeResult": "koopman_envs.episodes.single",
    "ComputeCharge": "koopman_envs.episodes.single",
    "smallest_clearance": "koopman_envs.episodes.single",
    "path_ratio": "koopman_envs.episodes.single",
    "run_episodes_in_batch": "koopman_envs.episodes.batch",
    "Renderer": "koopman_envs.rendering.renderer",
    "save_episode": "koopman_envs.rendering.renderer",
    "CollisionKind": "koopman_envs.sim.collision",
    "beam_angles": "koopman_envs.sim.lidar",
    "cv_model": "koopman_envs.sim.movers.tracking",
    "cv_predict": "koopman_envs.sim.movers.tracking",
    "cv_update": "koopman_envs.sim.movers.tracking",
    "nearest_by_clearance": "koopman_envs.sim.nearest",
    "nearest_order": "koopman_envs.sim.nearest",
    "observation_from_beliefs": "koopman_envs.tasks.observation",
}


def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, and ``koopman_envs.formation_v0`` and
    ``koopman_envs.target_reaching_v0`` without importing them by name first (PettingZoo's
    ``from pettingzoo.butterfly import ...`` convention), each imported when first read."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    if name in _PETTINGZOO_MODULES:
        return importlib.import_module(f"koopman_envs.{name}")
    raise AttributeError(f"module 'koopman_envs' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY, *_PETTINGZOO_MODULES})


__all__ = [
    "beam_angles",
    "BudgetExceeded",
    "BUILTIN_MAPS",
    "CalibrationPlant",
    "check_split_allowed",
    "CollisionKind",
    "ComputeCharge",
    "cv_model",
    "cv_predict",
    "cv_update",
    "DictObservation",
    "EngineConfig",
    "env_id_for_map",
    "ENV_IDS",
    "ENV_KEYWORDS",
    "env_keyword",
    "EpisodeResult",
    "FAMILIES",
    "FAR",
    "FORMATION_SHAPES",
    "generate_random_map",
    "KoopNavEnv",
    "KoopNavVectorEnv",
    "keyword_argument",
    "load_map",
    "load_suite",
    "make_plant",
    "MAP_NAMES",
    "MapSpec",
    "MessageEntry",
    "MoverEntry",
    "nearest_by_clearance",
    "nearest_order",
    "observation_from_beliefs",
    "ObservationLayout",
    "Observed",
    "ObstacleEntry",
    "PaperParams",
    "PARAMS",
    "PartOffsets",
    "Renderer",
    "rk4_pose",
    "rk4_step",
    "rollout",
    "run_episode",
    "run_episodes_in_batch",
    "save_episode",
    "Scenario",
    "slip_lambdas",
    "SLIP_SETTINGS",
    "SlipZone",
    "smallest_clearance",
    "path_ratio",
    "SPLITS",
    "Suite",
    "SUITE_PREFIX",
    "parse_suite_map",
    "SuiteLayout",
    "SUITES",
    "task_for_env",
    "TASKS",
    "TaskSpec",
    "TeamEntry",
    "TIERS",
    "wrap_angle",
    "wrap_scalar",
]
