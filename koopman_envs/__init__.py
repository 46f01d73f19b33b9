"""KoopNav environments: multi-robot navigation with stochastic wheel slip.

Importing the package registers the Gymnasium ids ``KoopNav-TargetReaching-v0`` and
``KoopNav-Formation-v0`` (each with a native ``vector_entry_point``). Without the import,
``gym.make("koopman_envs:KoopNav-Formation-v0")`` imports it for you. The PettingZoo versions
are the modules :mod:`koopman_envs.target_reaching_v0` and :mod:`koopman_envs.formation_v0`,
reachable as attributes of the package (``koopman_envs.formation_v0.parallel_env()`` after
``import koopman_envs``), imported on first use so that the Gymnasium import stays light.
"""

from __future__ import annotations

import importlib
from typing import Any

from gymnasium.envs.registration import register, registry

from koopman_envs.builder.keywords import ENV_KEYWORDS
from koopman_envs.builder.plant import BudgetExceeded, CalibrationPlant, make_plant
from koopman_envs.layout import MessageEntry, MoverEntry, ObstacleEntry, TeamEntry
from koopman_envs.observed import Observed
from koopman_envs.params import PARAMS, SLIP_SETTINGS, PaperParams, slip_lambdas
from koopman_envs.scenario import Scenario
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.sim.maps import BUILTIN_MAPS, MAP_NAMES, MapSpec, load_map
from koopman_envs.sim.random_maps import generate_random_map
from koopman_envs.sim.zones import SlipZone
from koopman_envs.suites import SPLITS, SUITES, Suite, check_split_allowed, load_suite
from koopman_envs.tasks.base import ENV_IDS, TASKS, TaskSpec, task_for_env

__version__ = "0.1.0"

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


def __getattr__(name: str) -> Any:
    """``koopman_envs.formation_v0`` and ``koopman_envs.target_reaching_v0`` without importing
    them by name first (PettingZoo's ``from pettingzoo.butterfly import ...`` convention)."""
    if name in _PETTINGZOO_MODULES:
        return importlib.import_module(f"koopman_envs.{name}")
    raise AttributeError(f"module 'koopman_envs' has no attribute {name!r}")


__all__ = [
    "BUILTIN_MAPS",
    "BudgetExceeded",
    "CalibrationPlant",
    "ENV_IDS",
    "ENV_KEYWORDS",
    "FORMATION_SHAPES",
    "MAP_NAMES",
    "MapSpec",
    "MessageEntry",
    "MoverEntry",
    "ObstacleEntry",
    "Observed",
    "PARAMS",
    "PaperParams",
    "SLIP_SETTINGS",
    "Scenario",
    "SlipZone",
    "SPLITS",
    "SUITES",
    "Suite",
    "TASKS",
    "TaskSpec",
    "TeamEntry",
    "check_split_allowed",
    "generate_random_map",
    "load_map",
    "load_suite",
    "make_plant",
    "slip_lambdas",
    "task_for_env",
]
