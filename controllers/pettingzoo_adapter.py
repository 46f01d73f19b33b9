"""Drive a PettingZoo KoopNav env with any (centralized) controller."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.base import Controller

__all__ = ["ParallelAdapter"]


class ParallelAdapter:
    """Turns per-agent observations and infos into the controller's joint view and back.

    >>> ctrl = controllers.make("nominal-nmpc")
    >>> calibrate_controller(ctrl, "KoopNav-Formation-v0")  # its tuned margins need it, as in the evaluator
    >>> adapter = ParallelAdapter(ctrl)
    >>> observations, infos = env.reset(seed=0)       # env = formation_v0.parallel_env()
    >>> adapter.reset(env)
    >>> observations, rewards, terms, truncs, infos = env.step(adapter.act(observations, infos))
    """

    def __init__(self, controller: Controller) -> None:
        self.controller = controller
        self._agents: list[str] = []

    def reset(self, env: Any, *, seed: int | None = None) -> None:
        """Hand the env's scenario to the controller (call after ``env.reset``)."""
        self._agents = list(env.possible_agents)
        self.controller.reset(env.scenario, seed=seed)

    def act(self, observations: dict[str, NDArray], infos: dict[str, dict[str, Any]]) -> dict[str, NDArray]:
        """One (v, omega) per live agent, computed jointly."""
        live = [a for a in self._agents if a in observations]
        if not live:
            return {}
        joint_obs = np.concatenate([np.asarray(observations[a], dtype=np.float64) for a in live])
        joint = np.asarray(self.controller.act(joint_obs, infos[live[0]]), dtype=np.float64).reshape(-1, 2)
        return {a: joint[self._agents.index(a)].astype(np.float32) for a in live}
