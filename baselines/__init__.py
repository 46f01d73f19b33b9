"""Learned baselines for the KoopNav environments: stable-baselines3 and multi-agent policies.

One folder per family and one for what both read (docs/layout.md):

- :mod:`baselines.sb3` (extra ``[rl]``): PPO on the native vector env.
  ``python -m baselines.sb3.train --env KoopNav-Formation-v0 --policy set --out runs/formation``
  trains one set-encoder policy shared by every robot (:mod:`baselines.sb3.set_encoder`) on the
  random-layout curriculum of :mod:`baselines.curriculum` (teams of 2 to 12); ``--policy mlp``
  (the default) trains the first, 3-robot MLP. ``python -m baselines.sb3.select`` keeps the best
  checkpoint on held-out random layouts. The ``rl-ppo*`` controllers play the shipped policies:
  ``rl-ppo-set`` (``baselines/policies/set/``, any team size: the training seed chosen on
  validation), ``rl-ppo-set-v0`` (``baselines/policies/set_v0/``, the curriculum-trained policies
  shipped before, kept for comparison) and ``rl-ppo`` (``baselines/policies/``).
- :mod:`baselines.marl` (extras ``[benchmarl]``, ``[torchrl]``): both tasks as BenchMARL tasks on
  a batched TorchRL env, ``python -m baselines.marl.benchmarl_train``, and the ``mappo`` /
  ``ippo`` / ``ippo-v0`` controllers (numpy alone; ``ippo-v0``, ``baselines/policies/ippo_v0/``,
  the random-layout policies ``ippo`` shipped before its seeds chosen on validation).
- :mod:`baselines.features`: what a policy reads beside the env's block, its set observation,
  and under lidar the perceived obstacles and movers (numpy only).
- at the root, what both families share: the training terms (:mod:`baselines.shaping`), the
  curriculum (:mod:`baselines.curriculum`), training on a benchmark suite
  (:mod:`baselines.suite_training`) and the policy-file loader (:mod:`baselines.safe_load`).

The package is the face others import from: the controllers, the envs and encoder the trainers
use and the loader's names are exported here (``from baselines import RLSetPolicyController,
KoopNavTask``), each imported when first read, so that ``import baselines`` loads neither torch
nor stable-baselines3. The controllers are registered through the ``koopnav.controllers`` entry
point (``rl-ppo``, ``rl-ppo-set``, ``rl-ppo-set-v0``, ``rl-ppo-set-realistic``,
``rl-ppo-set-physics``, ``rl-ppo-set-movers``, ``ippo``, ``ippo-v0``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from koopman_envs.deprecation import register_moved_paths

if TYPE_CHECKING:  # pragma: no cover - typing only: these are read on first use (_LAZY)
    from baselines.features.robot_features import robot_features
    from baselines.features.set_features import SetFeatureConfig, set_features
    from baselines.marl.benchmarl_task import KoopNavTask
    from baselines.marl.marl_policy import IppoController, IppoV0Controller, MappoController
    from baselines.marl.torchrl_env import KoopNavMultiAgentEnv
    from baselines.safe_load import PolicyLoadError, UnsafePolicyFile, load_model
    from baselines.sb3.actor import compile_actor
    from baselines.sb3.policy import (
        SHIPPED,
        RLPolicyController,
        RLSetMoversPolicyController,
        RLSetPhysicsPolicyController,
        RLSetPolicyController,
        RLSetRealisticPolicyController,
        RLSetV0PolicyController,
        load_policy,
    )
    from baselines.sb3.set_encoder import SetEncoder
    from baselines.sb3.vec_env import KoopNavSB3VecEnv, MixtureVecEnv

#: the previous release's module paths named in docs/api/baselines.md, docs/rl.md, the installed
#: controllers' entry points or as commands, kept one release with a DeprecationWarning by
#: koopman_envs.deprecation's import hook (no file at the old path; CHANGELOG.md, Deprecated)
MOVED_PATHS = {
    "baselines.policy": "baselines.sb3.policy",
    "baselines.set_encoder": "baselines.sb3.set_encoder",
    "baselines.train": "baselines.sb3.train",
    "baselines.select": "baselines.sb3.select",
    "baselines.set_features": "baselines.features.set_features",
    "baselines.benchmarl_task": "baselines.marl.benchmarl_task",
    "baselines.benchmarl_train": "baselines.marl.benchmarl_train",
    "baselines.marl_policy": "baselines.marl.marl_policy",
}
register_moved_paths(
    MOVED_PATHS, commands=("baselines.train", "baselines.select", "baselines.benchmarl_train")
)

#: the exported names -> the module each lives in (imported when the name is first read)
_LAZY = {
    "RLPolicyController": "baselines.sb3.policy",
    "RLSetPolicyController": "baselines.sb3.policy",
    "RLSetV0PolicyController": "baselines.sb3.policy",
    "RLSetPhysicsPolicyController": "baselines.sb3.policy",
    "RLSetRealisticPolicyController": "baselines.sb3.policy",
    "RLSetMoversPolicyController": "baselines.sb3.policy",
    "load_policy": "baselines.sb3.policy",
    "SHIPPED": "baselines.sb3.policy",
    "compile_actor": "baselines.sb3.actor",
    "SetEncoder": "baselines.sb3.set_encoder",
    "KoopNavSB3VecEnv": "baselines.sb3.vec_env",
    "MixtureVecEnv": "baselines.sb3.vec_env",
    "MappoController": "baselines.marl.marl_policy",
    "IppoController": "baselines.marl.marl_policy",
    "IppoV0Controller": "baselines.marl.marl_policy",
    "KoopNavTask": "baselines.marl.benchmarl_task",
    "KoopNavMultiAgentEnv": "baselines.marl.torchrl_env",
    "SetFeatureConfig": "baselines.features.set_features",
    "set_features": "baselines.features.set_features",
    "robot_features": "baselines.features.robot_features",
    "PolicyLoadError": "baselines.safe_load",
    "UnsafePolicyFile": "baselines.safe_load",
    "load_model": "baselines.safe_load",
}


def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, each imported when first read."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'baselines' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "compile_actor",
    "IppoController",
    "IppoV0Controller",
    "KoopNavMultiAgentEnv",
    "KoopNavSB3VecEnv",
    "KoopNavTask",
    "load_model",
    "load_policy",
    "MappoController",
    "MixtureVecEnv",
    "PolicyLoadError",
    "RLPolicyController",
    "RLSetMoversPolicyController",
    "RLSetPolicyController",
    "RLSetPhysicsPolicyController",
    "RLSetRealisticPolicyController",
    "RLSetV0PolicyController",
    "robot_features",
    "set_features",
    "SetEncoder",
    "SetFeatureConfig",
    "SHIPPED",
    "UnsafePolicyFile",
]
