"""The training terms the learned policies add to the env's per-robot reward, for every RL adapter
(the SB3 vector env, :mod:`baselines.sb3.vec_env`; the TorchRL env BenchMARL trains on,
:mod:`baselines.marl.torchrl_env`): one place, so that a policy trained through either library
meets the same reward.

- **Precision potential** (``precision_shaping``, potential-based, so it changes no optimal
  policy): ``w (log(d_prev + eps) - log(d + eps))`` per robot, the log-distance potential that
  rewards the last centimetres, which the env's linear progress term barely does.
- **Mover proximity** (``mover_shaping``): ``w max(0, 1 - clearance / MOVER_SHAPING_BAND)`` per
  robot and step within :data:`MOVER_SHAPING_BAND` of its nearest mover.
- **Collision credit** (``collision_penalty``): on the step a collision ends an episode, the
  robots that touched something pay ``collision_penalty`` more, and the env's team collision
  penalty is refunded to the others (a crash of a team-mate only cuts their episode short).

All terms read the step's end state: for an episode that ended in the step (the vector env's
``SameStep`` mode has already reset it), its final info.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_number

__all__ = ["MOVER_SHAPING_BAND", "PRECISION_EPS", "RewardShaping"]

#: [m]: the log-distance potential's floor, half the default goal tolerance
PRECISION_EPS = 0.05
#: clearance to a mover below which ``mover_shaping`` charges a robot [m] (ours: about 1.5 s of a
#: mover at 0.3 m/s, the time a unicycle needs to turn away and accelerate)
MOVER_SHAPING_BAND = 0.5


class RewardShaping:
    """The training terms of a batch of K environments of N robots (module docstring).

    Parameters
    ----------
    collision_penalty, precision_shaping, mover_shaping : float
        Weights (>= 0; 0 switches a term off).
    team_collision : float
        The env's own team collision penalty (refunded to bystanders).
    mover_reach : ndarray, shape (N,), optional
        Centre distance at contact of each robot with a mover (None: no movers).
    """

    def __init__(
        self,
        collision_penalty: float = 0.0,
        precision_shaping: float = 0.0,
        mover_shaping: float = 0.0,
        team_collision: float = 0.0,
        mover_reach: NDArray[np.float64] | None = None,
    ) -> None:
        self.collision_penalty = check_number("collision_penalty", collision_penalty, at_least=0)
        self.precision_shaping = check_number("precision_shaping", precision_shaping, at_least=0)
        self.mover_shaping = check_number("mover_shaping", mover_shaping, at_least=0)
        self.team_collision = float(team_collision)
        self.mover_reach = None if mover_reach is None else np.asarray(mover_reach, dtype=np.float64)
        self._potential: NDArray[np.float64] | None = None

    def _precision_potential(self, distances: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.precision_shaping * np.log(distances + PRECISION_EPS)

    def reset(self, info: dict[str, Any]) -> None:
        """Start from a reset's info (its ``distances``, (K, N))."""
        self._potential = self._precision_potential(info["distances"])

    def _end_state(self, info: dict[str, Any], key: str) -> NDArray[Any]:
        """``info[key]`` (K, ...) with the ended episodes' rows from their final info."""
        value = np.asarray(info[key])
        if "final_info" in info:
            ended = np.asarray(info["_final_info"]).reshape((-1,) + (1,) * (value.ndim - 1))
            value = np.where(ended, info["final_info"][key], value)
        return value

    def mover_cost(self, info: dict[str, Any]) -> NDArray[np.float64]:
        """(K, N) proximity cost of the step's end state."""
        assert self.mover_reach is not None  # only asked for with movers
        poses, movers = self._end_state(info, "poses"), self._end_state(info, "movers")
        gap = poses[:, :, None, :2] - movers[:, None, :, :2]  # (K, N, M, 2)
        clearance = np.sqrt((gap**2).sum(-1)).min(-1) - self.mover_reach
        return self.mover_shaping * np.clip(1.0 - clearance / MOVER_SHAPING_BAND, 0.0, None)

    def __call__(
        self, rewards: NDArray[np.float64], info: dict[str, Any]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None, NDArray[np.bool_] | None]:
        """The shaped (K, N) rewards of a step; where a collision ended an episode, which
        environments crashed (K,) and the engine's per-robot collision flags (K, N) (both None
        when no episode crashed in the step)."""
        if self.precision_shaping:
            assert self._potential is not None, "call reset() first"
            end_potential = self._precision_potential(self._end_state(info, "distances"))
            rewards = rewards + (self._potential - end_potential)
            self._potential = self._precision_potential(info["distances"])  # the new episodes'
        if self.mover_shaping and self.mover_reach is not None:
            rewards = rewards - self.mover_cost(info)
        if "final_info" not in info:
            return rewards, None, None
        final_info = info["final_info"]
        crashed = np.asarray(info["_final_info"]) & np.asarray(final_info["collision"])
        if not crashed.any():
            return rewards, None, None
        involved = np.asarray(final_info["robot_collision"])
        rewards = np.array(rewards, copy=True)
        # the env's team penalty, undone for the robots that touched nothing
        rewards[crashed] += np.where(involved[crashed], -self.collision_penalty, self.team_collision)
        return rewards, crashed, involved
