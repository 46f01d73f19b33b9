"""``mappo`` (and ``ippo``): multi-agent PPO policies trained with BenchMARL, played as controllers.

Each policy was trained by ``python -m baselines.marl.benchmarl_train`` (BenchMARL's MAPPO on the
task's batched vector env, :mod:`baselines.marl.torchrl_env`; the command, seed, frames, wall time
and evaluation curve are in its ``metadata.json``) and exported as numpy arrays
(``policy.npz``: the shared actor MLP's layers and the action bounds, read without pickle). The
controller runs that actor on every robot's own observation block, deterministically, as
BenchMARL's deterministic exploration does: ``Tanh`` MLP, the first half of its output is the
location of a ``TanhNormal``, and the action is ``low + (high - low) (tanh(loc) + 1) / 2``
(checked against BenchMARL's own policy in tests/test_marl_policy.py). A policy trained with
``--features`` reads its block with :func:`baselines.features.robot_features.robot_features` appended, as
in training. numpy only: neither torch nor BenchMARL is needed to play it.

The actor takes the block of the team size it was trained with (3 robots, the env's default
obstacle slots, ``sensing="state"``); message ages (a ``comm`` setting) and listed movers are
dropped before it, as for the PPO policies. Other team sizes and lidar are refused by name.
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from baselines.features.robot_features import FEATURE_SETS, feature_count, robot_features
from baselines.safe_load import PolicyLoadError, load_npz, read_json
from controllers.base import BaseController
from koopman_envs import Observed
from koopman_envs.checks import choice_message
from koopman_envs.scenario import Scenario

__all__ = ["IppoController", "MappoController", "actor_command"]

SHIPPED = Path(__file__).resolve().parents[1] / "policies"
#: the parts of a block a policy trained without them does not read
_DROPPED = ("messages", "movers")


def actor_command(arrays: dict[str, NDArray[Any]], blocks: NDArray[np.float64]) -> NDArray[np.float64]:
    """(..., 2) deterministic actions of the exported actor ``arrays`` for observation blocks
    (..., F): standardized as in training when the export holds ``obs_mean``/``obs_std``, Tanh
    between the linear layers, then the TanhNormal head's deterministic action."""
    x = np.asarray(blocks, dtype=np.float32)
    if "obs_mean" in arrays:
        x = (x - arrays["obs_mean"]) / arrays["obs_std"]
    layers = sum(1 for key in arrays if key.startswith("weight_"))
    for i in range(layers):
        x = x @ arrays[f"weight_{i}"].T + arrays[f"bias_{i}"]
        if i < layers - 1:
            x = np.tanh(x)
    loc = x[..., : x.shape[-1] // 2]
    low, high = arrays["low"], arrays["high"]
    return (low + (high - low) * (np.tanh(loc) + 1.0) / 2.0).astype(np.float64)


class MappoController(BaseController):
    """Plays the shipped BenchMARL MAPPO policy of the task (``baselines/policies/mappo/<task>``).

    Parameters
    ----------
    policy_root : path, optional
        Directory holding one sub-directory per task with ``policy.npz`` and ``metadata.json``
        (default: the shipped policies).
    """

    name = "mappo"
    #: the folder under ``baselines/policies`` of the shipped policies
    shipped = "mappo"
    #: the policy reads its observation block (the listed obstacles), not a perception's output
    perceives = False

    def __init__(self, policy_root: str | os.PathLike[str] | None = None) -> None:
        super().__init__()
        self.policy_root = Path(policy_root) if policy_root else SHIPPED / self.shipped
        if not self.policy_root.is_dir():
            raise ValueError(
                f"{self.name}: no trained policies in {self.policy_root}; train one with "
                f"`python -m baselines.marl.benchmarl_train --algorithm {self.shipped} "
                "--task target_reaching --out DIR`"
            )
        self._loaded: dict[str, tuple[dict[str, NDArray[Any]], dict[str, Any]]] = {}

    @classmethod
    def weight_files(cls, options: Mapping[str, Any], task: str) -> list[Path]:
        """The files a controller of this class built with ``options`` loads for ``task``, found
        without building it: a run's header records their digest (:mod:`evaluation.run.weights`)."""
        directory = Path(options.get("policy_root") or SHIPPED / cls.shipped) / task
        return [directory / "policy.npz", directory / "metadata.json"]

    def _load(self, task: str) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        if task not in self._loaded:
            directory = self.policy_root / task
            if not (directory / "policy.npz").is_file():
                raise ValueError(f"{self.name}: no policy for task {task!r} in {directory}")
            metadata = read_json(directory / "metadata.json")
            keys = tuple(metadata.get("arrays", ()))
            if not keys:
                raise PolicyLoadError(f"{directory / 'metadata.json'} names no arrays")
            self._loaded[task] = (load_npz(directory / "policy.npz", keys), metadata)
        return self._loaded[task]

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        if scenario.lidar_beams:
            raise ValueError(
                f"{self.name} reads the listed obstacles of sensing='state'; this env has sensing='lidar' "
                f"({scenario.lidar_beams} beams)"
            )
        self._arrays, self.metadata = self._load(scenario.task)
        trained = int(self.metadata["n_robots"])
        if scenario.n_robots != trained:
            raise ValueError(
                f"{self.name}'s {scenario.task} policy takes teams of {trained} robots (an MLP over one "
                f"robot's block, which lists every team-mate), not n_robots={scenario.n_robots}; "
                "rl-ppo-set runs any team size"
            )
        layout = scenario.observation_layout
        if layout is None:
            raise ValueError(
                f"{self.name}: the scenario has no observation layout (an env front's scenario does)"
            )
        self._block = layout.size
        self._keep = np.concatenate(
            [
                np.arange(layout[name].start, layout[name].stop)
                for name, _ in layout.parts
                if name not in _DROPPED
            ]
        )
        self._features = self.metadata.get("features")
        if self._features is not None and self._features not in FEATURE_SETS:
            raise PolicyLoadError(
                choice_message(
                    f"{self.name}'s {scenario.task} metadata: features", self._features, FEATURE_SETS
                )
            )
        expected = int(self.metadata["observation_size"])
        read = (
            self._keep.size
            if self._features is None
            else feature_count(self._keep.size, trained, self._features)
        )
        if read != expected:
            raise ValueError(
                f"{self.name}'s {scenario.task} policy reads blocks of {expected} entries; this env gives "
                f"{read} (without message ages and movers, with its features): it runs with the env settings it was "
                "trained on (n_obstacle_obs, sensing='state')"
            )

    def _act(self, observation: NDArray[np.float64], observed: Observed) -> NDArray[np.float64]:
        start = time.perf_counter()
        assert self.scenario is not None  # act() checked it
        blocks = np.asarray(observation, dtype=np.float64).reshape(self.scenario.n_robots, self._block)
        read = blocks[:, self._keep]
        if self._features is not None:  # what it was trained to read beside its block
            read = robot_features(read, self._features)
        command = actor_command(self._arrays, read)
        self._stats.solve_times.append(time.perf_counter() - start)
        return command.reshape(-1)


class IppoController(MappoController):
    """Plays the shipped BenchMARL IPPO policy (``baselines/policies/ippo/<task>``): per task, the
    training seed chosen on koopnav-bench-v1's validation layouts among the seeds trained on its
    train layouts (docs/rl.md, "What ships as ippo")."""

    name = "ippo"
    shipped = "ippo"


class IppoV0Controller(IppoController):
    """``ippo-v0``: the random-layout IPPO policies ippo shipped before its seeds.

    The policies trained on random layouts that ``ippo`` shipped before its training seeds
    chosen on validation (``baselines/policies/ippo_v0``), kept for comparison as
    ``rl-ppo-set-v0`` keeps rl-ppo-set's; run only when named. The ``ippo`` rows of results
    published before the seeds shipped are this policy."""

    name = "ippo-v0"
    shipped = "ippo_v0"
