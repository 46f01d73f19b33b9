"""The two navigation tasks: which targets, which reward terms, which default map."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RewardWeights", "TaskSpec", "TASKS"]


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the shaped reward (all ours).

    Per robot i and step: ``progress * (d_i,prev - d_i) - effort * ((v_i/v_max)^2 +
    (omega_i/omega_max)^2) - formation * ||e_i|| + settle * [d_i <= goal_tolerance]`` where d is
    the distance to the target [m] and e_i the follower's formation error [m] (formation task
    only); the settle term rewards staying on target, which progress alone does not. Team terms, added once to the
    centralized reward and to every agent's reward: ``- collision`` on the step a collision ends
    the episode, ``+ success`` on the step success ends it.
    """

    progress: float = 10.0
    effort: float = 0.01
    formation: float = 0.1
    settle: float = 0.2
    collision: float = 10.0
    success: float = 10.0


@dataclass(frozen=True)
class TaskSpec:
    """A task: its name, default map and whether formation terms apply."""

    name: str
    default_map: str
    formation: bool
    reward: RewardWeights = RewardWeights()


TASKS: dict[str, TaskSpec] = {
    "target_reaching": TaskSpec("target_reaching", default_map="map1", formation=False),
    "formation": TaskSpec("formation", default_map="map3", formation=True),
}
