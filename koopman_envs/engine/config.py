"""``EngineConfig``: the env keywords resolved and validated into the definition of an environment
(task, map, slip, team, limits): each keyword's own check from its row of
:data:`~koopman_envs.engine.keywords.ENV_KEYWORDS`, then the rules that involve several keywords.

And what a batch of a config costs, bounded before it is allocated: every env keyword is bounded
on its own (:data:`~koopman_envs.params.LIMITS`), but a batch multiplies them.
:func:`engine_array_bytes` estimates from above the bytes of the arrays a
:class:`~koopman_envs.engine.engine.NavigationEngine` of a config holds and builds in a step, from
the settings alone, and :func:`check_engine_memory` refuses a batch over ``LIMITS.engine_bytes``
naming what to reduce. The engine runs the check first thing in its constructor."""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice
from koopman_envs.engine.keywords import env_keywords, unknown_keywords
from koopman_envs.layout import ObservationLayout
from koopman_envs.params import LIMITS, PARAMS, RANDOM_SLIP, slip_lambdas
from koopman_envs.settings.moving_obstacles import MoverConfig
from koopman_envs.settings.uncertainty import (
    UNCERTAINTY_PRESETS,
    CommConfig,
    LidarConfig,
    PoseNoise,
    parse_setting,
)
from koopman_envs.sim.maps.generator_config import RandomMapConfig
from koopman_envs.sim.maps.map_spec import MapSpec, load_map
from koopman_envs.sim.movers.motion import DRAW_SIZE
from koopman_envs.sim.perception import BLOCK_NUMBERS
from koopman_envs.sim.physics.model import world_bytes
from koopman_envs.sim.physics.surfaces import SurfaceSetting, floor_surface
from koopman_envs.sim.slip.schedule import SlipSchedule, is_schedule
from koopman_envs.suites.suite import SUITE_PREFIX, Suite, load_suite, parse_suite_map
from koopman_envs.tasks.base import TASKS, TaskSpec

__all__ = ["EngineConfig", "check_engine_memory", "engine_array_bytes"]


def _random_map_formation(config: RandomMapConfig, formation: str) -> RandomMapConfig:
    """``random_map`` with the ``formation`` keyword's shape; a different shape set in both is an error."""
    default = RandomMapConfig.formation
    if config.formation not in (default, formation):
        raise ValueError(
            f"formation={formation!r} and random_map's formation={config.formation!r} differ: "
            "give the shape once (the formation keyword or the random_map field)"
        )
    return dataclasses.replace(config, formation=formation)


def _uncertainty(kw: dict[str, Any]) -> dict[str, Any]:
    """The uncertainty fields of :class:`EngineConfig` from the checked keywords ``kw``: the
    ``uncertainty`` preset's settings, each replaced (or, for a dict, updated field by field) by
    the keyword given beside it."""
    preset = UNCERTAINTY_PRESETS[kw["uncertainty"]]
    lidar = None
    if kw["sensing"] == "lidar":
        lidar = parse_setting("lidar", kw["lidar"], LidarConfig, preset.lidar)
    elif kw["lidar"] is not None:
        raise ValueError(f"lidar={kw['lidar']!r} is given with sensing='state'; add sensing='lidar'")
    delay = kw["actuation_delay"]
    return {
        "uncertainty": kw["uncertainty"],
        "pose_noise": parse_setting("pose_noise", kw["pose_noise"], PoseNoise, preset.pose_noise),
        "lidar": lidar,
        "comm": parse_setting("comm", kw["comm"], CommConfig, preset.comm),
        "actuation_delay": preset.actuation_delay if delay is None else delay,
    }


def _episode_limit(kw: dict[str, Any], front: str | None) -> int | None:
    """The episode limit from the checked keywords ``kw``: ``max_episode_steps`` or its other
    name ``max_cycles`` (two different values are an error); without either, the vector and
    PettingZoo fronts' default (they truncate by themselves), else None."""
    max_episode_steps: int | None = kw["max_episode_steps"]
    max_cycles: int | None = kw.get("max_cycles")
    if max_cycles is not None:
        if max_episode_steps is not None and max_episode_steps != max_cycles:
            raise ValueError(
                f"max_cycles={max_cycles!r} and max_episode_steps={max_episode_steps!r} differ: "
                "they are two names of the one episode limit (max_cycles as in PettingZoo's MPE); "
                "give one of them, or the same value to both"
            )
        max_episode_steps = max_cycles
    if max_episode_steps is None and front in ("vector", "parallel"):
        max_episode_steps = PARAMS.max_episode_steps  # these fronts truncate by themselves
    return max_episode_steps


def _resolve_map(spec: TaskSpec, kw: dict[str, Any]) -> tuple[MapSpec | None, RandomMapConfig, Suite | None]:
    """The fixed map (None for ``map="random"`` and for a suite), the random-map settings and the
    suite split (``map="suite:<name>/<split>"``), from the checked keywords ``kw`` of task
    ``spec``: the team (``n_robots``, ``robot_radius``) and the ``formation`` shape must fit the
    map, checked now rather than at a reset hours into training."""
    n_robots, robot_radius, formation = kw["n_robots"], kw["robot_radius"], kw["formation"]
    random_map: RandomMapConfig = kw["random_map"]
    map_arg = spec.default_map if kw["map"] is None else kw["map"]
    if isinstance(map_arg, str) and map_arg == "random":
        if formation is not None:
            random_map = _random_map_formation(random_map, formation)
        # a team whose shape cannot be placed fails here, not at a reset hours into training
        random_map.shape_for(n_robots, float(np.max(robot_radius)))
        return None, random_map, None
    if isinstance(map_arg, str) and map_arg.startswith(SUITE_PREFIX):
        return None, random_map, _resolve_suite(spec, map_arg, n_robots, robot_radius, formation)
    map_spec = load_map(map_arg)
    try:
        map_spec.validate(n_robots, robot_radius)
    except ValueError as exc:  # a map that holds the default team may not hold this one
        raise ValueError(f"{exc} (n_robots={n_robots}, robot_radius={robot_radius:g})") from None
    if formation is not None:
        if not spec.formation:
            raise ValueError(
                f"formation={formation!r} applies to formation maps ({TASKS['formation'].env_id}) or to "
                f"map='random'; map {map_spec.name!r} of {spec.label} keeps its own targets"
            )
        map_spec = map_spec.with_formation(formation, n_robots, PARAMS.formation_spacing, robot_radius)
    return map_spec, random_map, None


def _resolve_suite(
    spec: TaskSpec, map_arg: str, n_robots: int, robot_radius: float, formation: str | None
) -> Suite:
    """The suite split of ``map="suite:<name>/<split>"`` for task ``spec``, its every layout
    checked for the team; a suite's layouts are its own, so ``formation`` is refused."""
    name, split = parse_suite_map(map_arg)
    suite = load_suite(name, spec.name, split)
    if formation is not None:
        raise ValueError(
            f"formation={formation!r} does not apply to map={map_arg!r}: a suite's layouts keep their own "
            "targets (a benchmark episode is the stored one); allowed: formation=None"
        )
    _check_suite_team(suite, n_robots, float(robot_radius))
    return suite


@functools.lru_cache(maxsize=64)
def _check_suite_team(suite: Suite, n_robots: int, robot_radius: float) -> None:
    """Every layout of ``suite`` holds the team (checked once per suite and team: a vector env
    of a 500-layout split would spend 0.2 s on it per construction)."""
    for layout in suite.layouts:
        try:
            layout.spec.validate(n_robots, robot_radius)
        except ValueError as exc:
            raise ValueError(
                f"{suite.map_name} ({suite.label}), layout {layout.index}: {exc} "
                f"(n_robots={n_robots}, robot_radius={robot_radius:g})"
            ) from None


def _resolve_slip(slip: Any, n_robots: int) -> tuple[NDArray[np.float64], SlipSchedule | None, str]:
    """The per-robot base slip means (NaN when drawn per reset), the schedule (None for a level
    that is constant through an episode) and the label of the checked ``slip`` setting."""
    schedule = None
    if isinstance(slip, str) and slip == RANDOM_SLIP:
        lambdas = np.full(n_robots, np.nan)  # drawn per reset
    elif is_schedule(slip):
        schedule = SlipSchedule.parse(slip, n_robots)
        lambdas = np.full(n_robots, np.nan) if schedule.drift else schedule.levels[0].copy()
    else:
        lambdas = slip_lambdas(slip, n_robots)
    label = slip if isinstance(slip, str) else ("schedule" if schedule is not None else "custom")
    return lambdas, schedule, label


@dataclass(frozen=True)
class EngineConfig:
    """Everything that defines an environment, resolved and validated.

    Build it with :meth:`EngineConfig.create`, which accepts the env keywords
    (:data:`~koopman_envs.engine.keywords.ENV_KEYWORDS`).
    """

    task: TaskSpec
    map_spec: MapSpec | None  # None means a layout drawn per reset: random, or from ``suite``
    random_map: RandomMapConfig
    #: per-robot base slip means; NaN when drawn per reset ("random", "drift")
    lambdas: NDArray[np.float64]
    slip_label: str
    n_robots: int
    goal_tolerance: float
    robot_radius: NDArray[np.float64]
    n_obstacle_obs: int
    max_episode_steps: int | None
    #: radius [m] of the start-position disc and bound [rad] of the heading turn drawn per reset
    start_noise: float = 0.0
    #: base levels that change within an episode ("drift" or a list schedule), else None
    slip_schedule: SlipSchedule | None = None
    #: the formation shape asked for (``formation`` keyword), None for the map's own layout
    formation: str | None = None
    #: the ``uncertainty`` preset the settings below start from
    uncertainty: str = "nominal"
    #: localization error of every robot's own pose estimate
    pose_noise: PoseNoise = PoseNoise()
    #: the lidar of ``sensing="lidar"``, None for ``sensing="state"``
    lidar: LidarConfig | None = None
    #: the team's radio
    comm: CommConfig = CommConfig()
    #: control periods between a command and its action
    actuation_delay: int = 0
    #: the moving obstacles
    movers: MoverConfig = MoverConfig()
    #: the suite split a layout is taken from at every reset (``map="suite:<name>/<split>"``), else None
    suite: Suite | None = None
    #: what the robots are (:data:`~koopman_envs.params.PLANTS`)
    plant: str = "kinematic"
    #: the physics plant's floor (a surface name or a friction), None on the kinematic plant
    floor: SurfaceSetting | None = None

    @property
    def lidar_datasheet(self) -> dict[str, Any]:
        """The lidar fields of the scenario (its fov, range, noise and map mode; none under
        state sensing, which leaves the scenario's defaults)."""
        lidar = self.lidar
        if lidar is None:
            return {}
        return {
            "lidar_fov": lidar.fov,
            "lidar_range": lidar.range,
            "lidar_noise": lidar.noise,
            "map_known": lidar.map_known,
        }

    @property
    def perceives(self) -> bool:
        """True when robots observe anything but the exact state at once (then
        :class:`~koopman_envs.sim.perception.Perception` runs)."""
        return (
            self.pose_noise.active
            or not self.comm.perfect
            or self.lidar is not None
            or self.actuation_delay > 0
        )

    @property
    def observation_layout(self) -> ObservationLayout:
        """One robot's observation block by name (:mod:`koopman_envs.layout`): the movers
        are listed only under state sensing (with lidar the beams hit them)."""
        return ObservationLayout.for_settings(
            self.n_robots,
            self.n_obstacle_obs,
            self.task.formation,
            0 if self.lidar is None else self.lidar.beams,
            not self.comm.perfect,
            self.movers.observed if self.movers.active else 0,
        )

    @classmethod
    def create(cls, task: str, *, front: str | None = None, **keywords: Any) -> EngineConfig:
        """Validate the env keywords into a config; a keyword not given takes its default.

        Parameters
        ----------
        task : str
            ``"target_reaching"`` or ``"formation"``.
        front : str, optional
            The front that forwards the keywords (:data:`FRONTS`): which keywords it takes, and
            the vector and PettingZoo fronts' default time limit (they truncate by themselves).
            None (the calibration plant, tests): every keyword, no default limit.
        **keywords
            The env keywords of :data:`~koopman_envs.engine.keywords.ENV_KEYWORDS` (documented there and in the env docstrings).
            ``max_cycles`` is another name of ``max_episode_steps``, the one of PettingZoo's MPE
            environments; giving both with different values is a ``ValueError``.

        Raises
        ------
        TypeError
            An unknown keyword (named, with the allowed ones).
        ValueError
            A bad value (named, with what is allowed).
        """
        rows = env_keywords(front)
        error = unknown_keywords(keywords, [k.name for k in rows], f"the {front or 'KoopNav'} env")
        if error is not None:
            raise error
        check_choice("task", task, sorted(TASKS))
        spec = TASKS[task]
        # each keyword's own check (its row), then the rules between keywords
        kw = {k.name: k.resolve(keywords.get(k.name, k.default)) for k in rows}
        n_robots, robot_radius, formation = kw["n_robots"], kw["robot_radius"], kw["formation"]
        # the preset's slip; a slip given beside the preset wins
        slip = kw["slip"] if "slip" in keywords else UNCERTAINTY_PRESETS[kw["uncertainty"]].slip
        max_episode_steps = _episode_limit(kw, front)
        map_spec, random_map, suite = _resolve_map(spec, kw)
        floor = None
        if kw["plant"] == "mujoco":  # slip is the floor's surface: no drawn slip on top of physics
            floor = floor_surface(slip)
            lambdas, schedule, label = np.zeros(n_robots), None, str(slip)
        else:
            lambdas, schedule, label = _resolve_slip(slip, n_robots)
        return cls(
            task=spec,
            map_spec=map_spec,
            random_map=random_map,
            lambdas=lambdas,
            slip_label=label,
            n_robots=n_robots,
            goal_tolerance=kw["goal_tolerance"],
            robot_radius=np.full(n_robots, robot_radius),
            n_obstacle_obs=kw["n_obstacle_obs"],
            max_episode_steps=max_episode_steps,
            start_noise=kw["start_noise"],
            slip_schedule=schedule,
            formation=formation,
            movers=kw["movers"],
            suite=suite,
            plant=kw["plant"],
            floor=floor,
            **_uncertainty(kw),
        )

    @property
    def random_slip(self) -> bool:
        """True when every episode draws its own constant slip level (``slip="random"``)."""
        return self.slip_schedule is None and bool(np.isnan(self.lambdas).any())

    @property
    def n_slip_zones(self) -> int:
        """Slip zones per environment (fixed for a config; suite layouts have none)."""
        if self.suite is not None:
            return 0
        return self.random_map.n_slip_zones if self.map_spec is None else len(self.map_spec.slip_zones)

    @property
    def map_name(self) -> str:
        """Name of the fixed map, ``"random"``, or the suite split's ``"suite:<name>/<split>"``."""
        if self.suite is not None:
            return self.suite.map_name
        return "random" if self.map_spec is None else self.map_spec.name

    @property
    def n_obstacles(self) -> int:
        """Obstacles per environment (fixed for a config: every layout of a suite has as many)."""
        if self.suite is not None:
            return self.suite.n_obstacles
        return self.random_map.n_obstacles if self.map_spec is None else self.map_spec.obstacles.shape[0]


def engine_array_bytes(config: EngineConfig, num_envs: int) -> int:
    """An estimate from above of the bytes of the arrays a
    :class:`~koopman_envs.engine.engine.NavigationEngine` of
    ``num_envs`` environments of ``config`` holds and builds in a step, computed before any is
    allocated: every keyword is bounded on its own (:data:`~koopman_envs.params.LIMITS`), but
    their product over a batch is bounded here (``LIMITS.engine_bytes``).

    Each term is an array (or a step's copies of it) of the engine's parts, in 8-byte numbers
    unless said; the exact allocations are those parts' constructors.

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    num_envs : int
        Batch size K.

    Returns
    -------
    int
        Bytes [B], at least what the engine allocates.
    """
    n, m, k = config.n_robots, config.n_obstacles, int(num_envs)
    comm, movers, layout = config.comm, config.movers, config.observation_layout
    beams, width = layout.beams, layout.size
    words = (
        40 * n  # poses, targets, starts, offsets, distances and the step's copies of them
        + 3 * 128 * n  # the slip draws' block (SlipSampler: 128 periods)
        + n * (n + m)
        + 3 * m  # radius sums, obstacle discs
        + n * n  # the builder's message ages
        + 4 * n * width  # the features, their clipped copy, the observation and the info's
        + 6 * config.n_slip_zones * (n + 1)  # zone table
    )
    if config.perceives:
        numbers = 6 * n + n * (n - 1) + 2 * n * beams  # per period at most (Perception.__init__)
        block = int(np.clip(BLOCK_NUMBERS // max(1, numbers), 8, 256))
        words += (
            8 * n * n  # known poses, message ages, their info copies
            + 4 * n * beams  # readings, the exact scan, the info's copy
            + 5 * n * (comm.latency + 1)  # the radio's sent poses and positions
            + 2 * n * max(config.actuation_delay, 1)  # the command queue
            + block * numbers  # single-precision normals and uniforms: two halves of one block
        )
    if movers.active:
        c = movers.count
        words += max(4096, 8 * c * DRAW_SIZE) + 16 * c + 6 * n  # the uniforms' pool, states, goals, hits
    if config.plant == "mujoco":
        words += world_bytes(n, m) // 8  # every environment's MuJoCo model copy, data and arena
    return 8 * k * words


def check_engine_memory(config: EngineConfig, num_envs: int) -> None:
    """Refuse a batch whose arrays would exceed ``LIMITS.engine_bytes`` (before allocating).

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    num_envs : int
        Batch size K.

    Raises
    ------
    ValueError
        :func:`engine_array_bytes` is over the limit: naming the batch, the sizes that drive it,
        the estimate and the limit, and what to reduce.
    """
    need = engine_array_bytes(config, num_envs)
    if need > LIMITS.engine_bytes:
        per_env = need / num_envs / 2**20
        raise ValueError(
            f"num_envs={num_envs} environments of n_robots={config.n_robots} (lidar.beams="
            f"{0 if config.lidar is None else config.lidar.beams}, comm.latency={config.comm.latency}, "
            f"movers.count={config.movers.count}) need about {need / 2**30:.1f} GiB of arrays "
            f"({per_env:.1f} MiB each); the limit is {LIMITS.engine_bytes / 2**30:g} GiB "
            "(koopman_envs.params.LIMITS): use fewer environments, robots or lidar beams"
        )
