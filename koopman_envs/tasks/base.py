"""The two navigation tasks: the one table of task name, env id, label, maps and reward terms."""

from __future__ import annotations

from dataclasses import dataclass

from koopman_envs.checks import choice_message

__all__ = ["ENV_IDS", "RewardWeights", "TASKS", "TaskSpec", "env_id_for_map", "task_for_env"]


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
    """A task: its name, registered env id, label, maps and whether formation terms apply.

    Attributes
    ----------
    name : str
        Task name used by the engine (``"target_reaching"``, ``"formation"``).
    env_id : str
        Registered Gymnasium id.
    label : str
        Human-readable name for reports.
    paper_maps : tuple of str
        The paper's maps of this task (SPEC section 5); the first is the default map. The paper
        protocols evaluate exactly these.
    formation : bool
        Whether formation terms (offsets, formation error) apply.
    reward : RewardWeights
        Weights of the shaped reward.
    extra_maps : tuple of str
        Further shipped maps of this task that are not the paper's (ours: with slip zones, or
        for six robots).
    """

    name: str
    env_id: str
    label: str
    paper_maps: tuple[str, ...]
    formation: bool
    reward: RewardWeights = RewardWeights()
    extra_maps: tuple[str, ...] = ()

    @property
    def maps(self) -> tuple[str, ...]:
        """Every shipped map of this task: the paper's, then the extra ones."""
        return self.paper_maps + self.extra_maps

    @property
    def default_map(self) -> str:
        """The map an env of this task uses when none is given."""
        return self.paper_maps[0]


TASKS: dict[str, TaskSpec] = {
    "target_reaching": TaskSpec(
        "target_reaching",
        "KoopNav-TargetReaching-v0",
        "target reaching",
        ("map1", "map2"),
        formation=False,
        extra_maps=("map5", "map7"),
    ),
    "formation": TaskSpec(
        "formation",
        "KoopNav-Formation-v0",
        "formation",
        ("map3", "map4"),
        formation=True,
        extra_maps=("map6", "map8"),
    ),
}

#: Registered env ids, in task order.
ENV_IDS: tuple[str, ...] = tuple(spec.env_id for spec in TASKS.values())


def task_for_env(env_id: str) -> TaskSpec:
    """The task of a registered env id (``ValueError`` naming the known ids otherwise)."""
    for spec in TASKS.values():
        if spec.env_id == env_id:
            return spec
    raise ValueError(choice_message("env id", env_id, ENV_IDS, sep=" "))


def env_id_for_map(map_name: str, default: str = ENV_IDS[0]) -> str:
    """The env id whose shipped maps include ``map_name`` (``default`` for any other map)."""
    for spec in TASKS.values():
        if map_name in spec.maps:
            return spec.env_id
    return default
