"""Learned baselines for the KoopNav environments: stable-baselines3 and multi-agent policies.

One folder per family and one for what both read (docs/layout.md):

- :mod:`baselines.sb3` (extra ``[rl]``): PPO on the native vector env.
  ``python -m baselines.sb3.train --env KoopNav-Formation-v0 --policy set --out runs/formation``
  trains one set-encoder policy shared by every robot (:mod:`baselines.sb3.set_encoder`) on the
  random-layout curriculum of :mod:`baselines.curriculum` (teams of 2 to 12); ``--policy mlp``
  (the default) trains the first, 3-robot MLP. ``python -m baselines.sb3.select`` keeps the best
  checkpoint on held-out random layouts. The ``rl-ppo*`` controllers play the shipped policies:
  ``rl-ppo-set`` (``baselines/policies/set/``, any team size) and ``rl-ppo``
  (``baselines/policies/``).
- :mod:`baselines.marl` (extras ``[benchmarl]``, ``[torchrl]``): both tasks as BenchMARL tasks on
  a batched TorchRL env, ``python -m baselines.marl.benchmarl_train``, and the ``mappo`` /
  ``ippo`` controllers (numpy alone).
- :mod:`baselines.features`: what a policy reads beside the env's block, its set observation,
  and under lidar the perceived obstacles and movers (numpy only).
- at the root, what both families share: the training terms (:mod:`baselines.shaping`), the
  curriculum (:mod:`baselines.curriculum`), training on a benchmark suite
  (:mod:`baselines.suite_training`) and the policy-file loader (:mod:`baselines.safe_load`).

The package is the face others import from: the controllers, the envs and encoder the trainers
use and the loader's names are exported here (``from baselines import RLSetPolicyController,
KoopNavTask``), each imported when first read, so that ``import baselines`` loads neither torch
nor stable-baselines3. The controllers are registered through the ``koopnav.controllers`` entry
point (``rl-ppo``, ``rl-ppo-set``, ``rl-ppo-set-realistic``, ``rl-ppo-set-movers``, ``ippo``).
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover - typing only: these are read on first use (_LAZY)
    from baselines.features.robot_features import robot_features
    from baselines.features.set_features import SetFeatureConfig, set_features
    from baselines.marl.benchmarl_task import KoopNavTask
    from baselines.marl.marl_policy import IppoController, MappoController
    from baselines.marl.torchrl_env import KoopNavMultiAgentEnv
    from baselines.safe_load import PolicyLoadError, UnsafePolicyFile, load_model
    from baselines.sb3.actor import compile_actor
    from baselines.sb3.policy import (
        SHIPPED,
        RLPolicyController,
        RLSetMoversPolicyController,
        RLSetPolicyController,
        RLSetRealisticPolicyController,
        load_policy,
    )
    from baselines.sb3.set_encoder import SetEncoder
    from baselines.sb3.vec_env import KoopNavSB3VecEnv, MixtureVecEnv

#: the exported names -> the module each lives in (imported when the name is first read)
_LAZY = {
    "RLPolicyController": "baselines.sb3.policy",
    "RLSetPolicyController": "baselines.sb3.policy",
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
    "KoopNavTask": "baselines.marl.benchmarl_task",
    "KoopNavMultiAgentEnv": "baselines.marl.torchrl_env",
    "SetFeatureConfig": "baselines.features.set_features",
    "set_features": "baselines.features.set_features",
    "robot_features": "baselines.features.robot_features",
    "PolicyLoadError": "baselines.safe_load",
    "UnsafePolicyFile": "baselines.safe_load",
    "load_model": "baselines.safe_load",
}

#: the release that removes the deprecated module paths (the stubs at the package root)
REMOVAL = "0.2.0"


def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, each imported when first read."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'baselines' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


def _moved_module(old: str, new: str) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` (PEP 562) of the deprecated stub module ``old``: every
    name is read from ``new``. Called from the stub's body, so importing ``old`` warns once (a
    ``DeprecationWarning`` at the importing line, naming ``new`` and the removal release); a plain
    stub module rather than an import hook, as stable-baselines3 keeps its moved paths."""
    warnings.warn(
        f"{old} is deprecated and will be removed in KoopNav {REMOVAL}; import from {new} "
        "(or from the package, baselines)",
        DeprecationWarning,
        stacklevel=3,
    )

    def __getattr__(attribute: str) -> Any:
        if attribute.startswith("__"):
            raise AttributeError(attribute)
        return getattr(importlib.import_module(new), attribute)

    def __dir__() -> list[str]:
        module = importlib.import_module(new)
        return sorted(getattr(module, "__all__", None) or (n for n in vars(module) if not n.startswith("_")))

    return __getattr__, __dir__


def _run_moved_command(old: str, new: str) -> None:
    """``python -m old`` of a deprecated command: warn (at the stub, which is ``__main__``, so the
    default filters show it) and run ``python -m new`` with the same arguments and exit code."""
    warnings.warn(
        f"python -m {old} is deprecated and will be removed in KoopNav {REMOVAL}; run python -m {new}",
        DeprecationWarning,
        stacklevel=2,
    )
    raise SystemExit(importlib.import_module(new).main())


__all__ = [
    "compile_actor",
    "IppoController",
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
    "RLSetRealisticPolicyController",
    "robot_features",
    "set_features",
    "SetEncoder",
    "SetFeatureConfig",
    "SHIPPED",
    "UnsafePolicyFile",
]
