"""The batched navigation engine under every front.

It owns K environments of N robots: their poses, maps, targets, slip generators and episode
counters, and advances all of them in compiled batch loops (numba). The Gymnasium env is this
engine with K = 1, the vector env is the engine with K = num_envs, and the PettingZoo env reads per-agent
blocks of the same observation features. Because all fronts run this one code path,
sub-environment i of a batch seeded with s + i reproduces a lone environment seeded s + i.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from koopman_envs.params import PARAMS, slip_lambdas
from koopman_envs.scenario import Scenario
from koopman_envs.sim.collision import CollisionKind, collision_flags
from koopman_envs.sim.dynamics import advance_teams, wrap_angle
from koopman_envs.sim.maps import (
    BUILTIN_MAPS,
    MapSpec,
    RandomMapConfig,
    formation_offsets,
    generate_random_map,
    load_map,
)
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.sim.geometry import TeamGeometry
from koopman_envs.sim.slip import RANDOM_SLIP, SlipSampler, draw_random_lambdas
from koopman_envs.sim.slip_schedule import DRIFT_SLIP, SlipClock, SlipSchedule, is_schedule
from koopman_envs.sim.zones import ZoneTable
from koopman_envs.tasks.base import TASKS, TaskSpec
from koopman_envs.tasks.observation import FeatureBuilder
from koopman_envs.tasks.reward import score_step

__all__ = [
    "ENV_KEYWORDS",
    "EngineConfig",
    "EnvKeyword",
    "FRONTS",
    "NavigationEngine",
    "DRIFT_SLIP",
    "RANDOM_SLIP",
    "RESET_OPTIONS",
    "ResetOptions",
    "StepResult",
    "env_keywords",
    "keyword_table",
    "parse_reset_options",
    "takes_env_keywords",
]

#: ``start_noise``: draws of a whole team's start perturbation before a reset gives up (ours).
START_NOISE_ATTEMPTS = 100



def _random_map_config(value: RandomMapConfig | dict | None) -> RandomMapConfig:
    """``random_map`` keyword: a :class:`RandomMapConfig`, a dict of its fields, or None."""
    if value is None or isinstance(value, RandomMapConfig):
        return value or RandomMapConfig()
    if isinstance(value, dict):
        allowed = [f.name for f in dataclasses.fields(RandomMapConfig)]
        unknown = sorted(set(value) - set(allowed))
        if unknown:
            raise ValueError(f"random_map has unknown fields {unknown}; allowed: {allowed}")
        return RandomMapConfig(**value)
    raise ValueError(f"random_map={value!r} must be a RandomMapConfig, a dict of its fields or None")


def _random_map_formation(config: RandomMapConfig, formation: str) -> RandomMapConfig:
    """``random_map`` with the ``formation`` keyword's shape; a different shape set in both is an error."""
    default = RandomMapConfig.formation
    if config.formation not in (default, formation):
        raise ValueError(
            f"formation={formation!r} and random_map's formation={config.formation!r} differ: "
            "give the shape once (the formation keyword or the random_map field)"
        )
    return dataclasses.replace(config, formation=formation)


def _check_positive(name: str, value: Any, integer: bool = False) -> None:
    ok = isinstance(value, (int, np.integer)) if integer else isinstance(value, (int, float, np.number))
    if not ok or isinstance(value, bool) or not np.isfinite(value) or value <= 0:
        kind = "an integer >= 1" if integer else "a finite number > 0"
        raise ValueError(f"{name}={value!r} must be {kind}")


def _check_non_negative(name: str, value: Any) -> None:
    # np.floating rather than np.number: a complex scalar is a number but has no order
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or value < 0:
        raise ValueError(f"{name}={value!r} must be a finite number >= 0")


#: the fronts, by the names :class:`EnvKeyword` uses
FRONTS = ("gym", "vector", "parallel")


@dataclass(frozen=True)
class EnvKeyword:
    """One keyword argument of the environments: a row of :data:`ENV_KEYWORDS`.

    Attributes
    ----------
    name : str
        The keyword.
    default : Any
        Its value when not given.
    annotation : str
        Its type, as the fronts' signatures and docs show it.
    doc : str
        One line for the docs of every front (the Gymnasium env docstring's Arguments table,
        the PettingZoo modules' ``make`` call, the keyword list of docs/environments.md).
    fronts : tuple of str
        The fronts that take it (:data:`FRONTS`).
    """

    name: str
    default: Any
    annotation: str
    doc: str
    fronts: tuple[str, ...] = FRONTS


#: The env keywords: the one place where they are declared and defaulted. Every front forwards
#: its keywords to :meth:`EngineConfig.create`, which validates them; the fronts' signatures and
#: argument tables are generated from this table (:func:`takes_env_keywords`,
#: :func:`keyword_table`), and tests/test_keyword_spec.py holds the fronts and docs/environments.md to it.
ENV_KEYWORDS: tuple[EnvKeyword, ...] = (
    EnvKeyword("map", None, "str | os.PathLike | MapSpec | None",
               f'"{BUILTIN_MAPS[0]}".."{BUILTIN_MAPS[-1]}", "random" (a new seeded layout per reset), a JSON '
               "map file or a MapSpec; None: the task's first map"),
    EnvKeyword("slip", "nominal", "str | Sequence[Any]",
               '"nominal", "low", "high", "random", "drift", one lambda >= 0 per robot, or '
               "(time [s], lambdas) pairs"),
    EnvKeyword("n_robots", PARAMS.n_robots, "int",
               "team size N: at most the map's starts (a smaller team takes the first N), any N "
               'with map="random"'),
    EnvKeyword("goal_tolerance", PARAMS.goal_tolerance, "float", "success tolerance [m]"),
    EnvKeyword("robot_radius", PARAMS.robot_radius, "float", "disc radius of every robot [m]"),
    EnvKeyword("n_obstacle_obs", 4, "int", "nearest obstacles listed in each robot's block"),
    EnvKeyword("random_map", None, "RandomMapConfig | dict | None",
               'generator settings for map="random" (a RandomMapConfig or a dict of its fields)'),
    EnvKeyword("start_noise", 0.0, "float", "per-reset start jitter: disc radius [m] and heading bound [rad]"),
    EnvKeyword("formation", None, "str | None",
               f"formation shape of the team, one of {list(FORMATION_SHAPES)} (spacing "
               f"{PARAMS.formation_spacing:g} m): follower targets on formation maps, starts and targets "
               'with map="random"; None: the map\'s own'),
    EnvKeyword("max_episode_steps", None, "int | None",
               f"time limit in control periods; None: {PARAMS.max_episode_steps} (the Gymnasium env leaves "
               "it to gym.make's TimeLimit)"),
    EnvKeyword("max_cycles", None, "int | None", "PettingZoo MPE's name of max_episode_steps",
               fronts=("parallel",)),
)  # fmt: skip

def env_keywords(front: str | None = None) -> tuple[EnvKeyword, ...]:
    """The rows of :data:`ENV_KEYWORDS` that ``front`` takes (None: every row)."""
    if front is not None and front not in FRONTS:
        raise ValueError(f"front={front!r} is not one of {list(FRONTS)} or None")
    return tuple(k for k in ENV_KEYWORDS if front is None or front in k.fronts)


def _unknown_keywords(given: Any, allowed: Sequence[str], owner: str) -> TypeError | None:
    """A TypeError naming the keywords of ``given`` outside ``allowed`` (and close matches), or None."""
    unknown = [name for name in given if name not in allowed]
    if not unknown:
        return None
    hints = [f"{close[0]!r} for {name!r}" for name in unknown if (close := difflib.get_close_matches(name, allowed, 1))]
    hint = f" (did you mean {', '.join(hints)}?)" if hints else ""
    # Python's own phrase first: wrappers such as TorchRL's GymEnv retry without a keyword (e.g.
    # frameskip) when the error reads "unexpected keyword argument '<name>'"
    return TypeError(f"{owner} got an unexpected keyword argument {unknown[0]!r}; unknown keyword arguments "
                     f"{unknown}{hint}; allowed: {list(allowed)}")  # fmt: skip


def takes_env_keywords(front: str) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Decorate a front's ``__init__(self, <own parameters>, **keywords)``.

    The decorated ``__init__`` shows the signature of its own parameters plus, keyword-only
    with the table's defaults, the env keywords ``front`` takes (so ``help()`` and
    ``inspect.signature`` list them), and raises ``TypeError`` naming any other keyword and the
    allowed ones before the front runs. The keywords go on to :meth:`EngineConfig.create`.
    """
    rows = env_keywords(front)

    def decorate(init: Callable[..., None]) -> Callable[..., None]:
        own = [p for p in inspect.signature(init).parameters.values() if p.kind is not p.VAR_KEYWORD]
        names = [p.name for p in own if p.kind is not p.VAR_POSITIONAL] + [k.name for k in rows]
        keyword_only = inspect.Parameter.KEYWORD_ONLY
        signature = inspect.Signature(
            own + [inspect.Parameter(k.name, keyword_only, default=k.default, annotation=k.annotation) for k in rows]
        )

        @functools.wraps(init)
        def wrapper(self: Any, *args: Any, **kwargs: Any) -> None:
            error = _unknown_keywords(kwargs, names[1:], type(self).__name__)
            if error is not None:
                raise error
            init(self, *args, **kwargs)

        wrapper.__signature__ = signature  # type: ignore[attr-defined]
        return wrapper

    return decorate


def keyword_table(front: str, extra: Sequence[tuple[str, str, str, str]] = (), task: str | None = None) -> str:
    """The env keywords of ``front`` as a Markdown table (Parameter, Type, Default, Description).

    ``extra`` rows (name, type, default, description) of the front's own parameters come first;
    with a ``task``, the default of ``map`` shown is that task's default map.
    """
    shown = {"map": TASKS[task].default_map} if task is not None else {}
    rows = list(extra) + [(k.name, k.annotation, repr(shown.get(k.name, k.default)), k.doc) for k in env_keywords(front)]
    lines = ["| Parameter | Type | Default | Description |", "|---|---|---|---|"]
    lines += [f"| {name} | {kind.replace('|', 'or')} | {default} | {doc} |" for name, kind, default, doc in rows]
    return "\n".join(lines)


@dataclass(frozen=True)
class EngineConfig:
    """Everything that defines an environment, resolved and validated.

    Build it with :meth:`EngineConfig.create`, which accepts the env keywords
    (:data:`ENV_KEYWORDS`).
    """

    task: TaskSpec
    map_spec: MapSpec | None  # None means a random map per reset
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
            The env keywords of :data:`ENV_KEYWORDS` (documented there and in the env docstrings).
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
        error = _unknown_keywords(keywords, [k.name for k in rows], f"the {front or 'KoopNav'} env")
        if error is not None:
            raise error
        kw = {k.name: keywords.get(k.name, k.default) for k in rows}
        n_robots, robot_radius, slip = kw["n_robots"], kw["robot_radius"], kw["slip"]
        max_episode_steps, max_cycles = kw["max_episode_steps"], kw.get("max_cycles")
        random_map = _random_map_config(kw["random_map"])
        if task not in TASKS:
            raise ValueError(f"task={task!r} is not one of {sorted(TASKS)}")
        spec = TASKS[task]
        _check_positive("n_robots", n_robots, integer=True)
        _check_positive("goal_tolerance", kw["goal_tolerance"])
        _check_positive("robot_radius", robot_radius)
        n_obstacle_obs = kw["n_obstacle_obs"]
        if isinstance(n_obstacle_obs, bool) or not isinstance(n_obstacle_obs, (int, np.integer)) or n_obstacle_obs < 0:
            raise ValueError(f"n_obstacle_obs={n_obstacle_obs!r} must be an integer >= 0")
        if max_cycles is not None:
            _check_positive("max_cycles", max_cycles, integer=True)
            if max_episode_steps is not None and max_episode_steps != max_cycles:
                raise ValueError(
                    f"max_cycles={max_cycles!r} and max_episode_steps={max_episode_steps!r} differ: "
                    "they are two names of the one episode limit (max_cycles as in PettingZoo's MPE); "
                    "give one of them, or the same value to both"
                )
            max_episode_steps = max_cycles
        if max_episode_steps is not None:
            _check_positive("max_episode_steps", max_episode_steps, integer=True)
        elif front in ("vector", "parallel"):
            max_episode_steps = PARAMS.max_episode_steps  # these fronts truncate by themselves
        _check_non_negative("start_noise", kw["start_noise"])
        formation = kw["formation"]
        if formation is not None and (not isinstance(formation, str) or formation not in FORMATION_SHAPES):
            raise ValueError(
                f"formation={formation!r} is not one of {list(FORMATION_SHAPES)} or None (the map's own layout)"
            )
        map_arg = spec.default_map if kw["map"] is None else kw["map"]
        if isinstance(map_arg, str) and map_arg == "random":
            map_spec = None
            if formation is not None:
                random_map = _random_map_formation(random_map, formation)
        else:
            map_spec = load_map(map_arg)
            map_spec.validate(int(n_robots), float(robot_radius))
            if formation is not None:
                if not spec.formation:
                    raise ValueError(
                        f"formation={formation!r} applies to formation maps ({TASKS['formation'].env_id}) or to "
                        f"map='random'; map {map_spec.name!r} of {spec.label} keeps its own targets"
                    )
                map_spec = map_spec.with_formation(formation, int(n_robots), PARAMS.formation_spacing, float(robot_radius))
        schedule = None
        if isinstance(slip, str) and slip == RANDOM_SLIP:
            lambdas = np.full(int(n_robots), np.nan)  # drawn per reset
        elif is_schedule(slip):
            schedule = SlipSchedule.parse(slip, int(n_robots))
            lambdas = np.full(int(n_robots), np.nan) if schedule.drift else schedule.levels[0].copy()
        else:
            lambdas = slip_lambdas(slip, int(n_robots))
        label = slip if isinstance(slip, str) else ("schedule" if schedule is not None else "custom")
        return cls(
            task=spec,
            map_spec=map_spec,
            random_map=random_map,
            lambdas=lambdas,
            slip_label=label,
            n_robots=int(n_robots),
            goal_tolerance=float(kw["goal_tolerance"]),
            robot_radius=np.full(int(n_robots), float(robot_radius)),
            n_obstacle_obs=int(n_obstacle_obs),
            max_episode_steps=None if max_episode_steps is None else int(max_episode_steps),
            start_noise=float(kw["start_noise"]),
            slip_schedule=schedule,
            formation=formation,
        )

    @property
    def random_slip(self) -> bool:
        """True when every episode draws its own constant slip level (``slip="random"``)."""
        return self.slip_schedule is None and bool(np.isnan(self.lambdas).any())

    @property
    def n_slip_zones(self) -> int:
        """Slip zones per environment (fixed for a config)."""
        return self.random_map.n_slip_zones if self.map_spec is None else len(self.map_spec.slip_zones)

    @property
    def map_name(self) -> str:
        """Name of the fixed map, or ``"random"``."""
        return "random" if self.map_spec is None else self.map_spec.name

    @property
    def n_obstacles(self) -> int:
        """Obstacles per environment (fixed for a config)."""
        return self.random_map.n_obstacles if self.map_spec is None else self.map_spec.obstacles.shape[0]


#: the keys of ``reset(options=...)``, on every front (docs/reset_options.md)
RESET_OPTIONS = ("start_poses", "targets")


@dataclass(frozen=True)
class ResetOptions:
    """Per-episode replacements of one environment's map data (None: the map's).

    Attributes
    ----------
    start_poses : ndarray, shape (N, 3), optional
        Start pose (x [m], y [m], heading [rad]) of every robot, used as given (no
        ``start_noise``).
    targets : ndarray, shape (N, 3), optional
        Target pose of every robot; for formation, the formation offsets are these targets
        relative to robot 0's.
    """

    start_poses: NDArray[np.float64] | None = None
    targets: NDArray[np.float64] | None = None


def parse_reset_options(
    options: dict[str, Any] | None,
    n_robots: int,
    num_envs: int | None = None,
    ignored: Sequence[str] = (),
) -> list[ResetOptions]:
    """Check the ``options`` of a ``reset`` and split them per environment.

    The one check of every front's reset options. Keys (see docs/reset_options.md):

    ``start_poses``
        (N, 3) array of x [m], y [m], heading [rad] per robot that replaces the map's starts
        for this episode (``start_noise`` is not applied to it).
    ``targets``
        (N, 3) array of target poses that replaces the map's targets for this episode.

    A value of None means the map's. Here only the keys, shapes and finiteness are checked; the
    engine checks the placement (inside the workspace, clear of obstacles and of each other)
    against the episode's map, which with ``map="random"`` is drawn by the reset itself.

    Parameters
    ----------
    options : dict or None
        What the user passed to ``reset``.
    n_robots : int
        Team size N.
    num_envs : int, optional
        None for a single environment; K for the vector env, where an (N, 3) array applies to
        every sub-environment and a (K, N, 3) array gives sub-environment i its row i.
    ignored : sequence of str
        Keys to accept without effect (the PettingZoo fronts: the probe of ``pettingzoo.test``).

    Returns
    -------
    list of ResetOptions
        One per environment (one for a single environment).

    Raises
    ------
    ValueError
        ``options`` is not a dict, has an unknown key (the message lists the allowed ones), or a
        value of the wrong shape or with NaN/inf entries.
    """
    count = 1 if num_envs is None else int(num_envs)
    if options is None:
        return [ResetOptions()] * count
    if not isinstance(options, dict):
        raise ValueError(f"options={options!r} must be a dict or None; allowed keys: {list(RESET_OPTIONS)}")
    unknown = [key for key in options if key not in RESET_OPTIONS and key not in ignored]
    if unknown:
        raise ValueError(
            f"reset options {unknown} are not supported; allowed keys: {list(RESET_OPTIONS)} "
            "(see docs/reset_options.md)"
        )
    shapes = [(n_robots, 3)] if num_envs is None else [(n_robots, 3), (count, n_robots, 3)]
    per_env: dict[str, list[NDArray[np.float64] | None]] = {}
    for key in RESET_OPTIONS:
        value = options.get(key)
        if value is None:
            per_env[key] = [None] * count
            continue
        try:
            arr = np.array(value, dtype=np.float64)  # a copy: later changes by the caller do not leak in
        except (TypeError, ValueError) as exc:
            raise ValueError(f"options[{key!r}]={value!r} is not an array of numbers") from exc
        if arr.shape not in shapes:
            allowed = " or ".join(str(shape) for shape in shapes)
            raise ValueError(
                f"options[{key!r}] has shape {arr.shape}; allowed: {allowed}, rows of (x [m], y [m], heading [rad])"
            )
        if not np.isfinite(arr).all():
            bad = np.argwhere(~np.isfinite(arr))[0].tolist()
            raise ValueError(
                f"options[{key!r}] has a non-finite entry at index {bad} ({arr[tuple(bad)]}); allowed: finite numbers"
            )
        arr.setflags(write=False)
        per_env[key] = [arr if arr.ndim == 2 else arr[i] for i in range(count)]
    return [ResetOptions(**{key: per_env[key][i] for key in RESET_OPTIONS}) for i in range(count)]


@dataclass
class StepResult:
    """Arrays produced by one batched step (K environments, N robots, F features)."""

    features: NDArray[np.float64]  # (K, N, F)
    robot_reward: NDArray[np.float64]  # (K, N)
    team_reward: NDArray[np.float64]  # (K,)
    terminated: NDArray[np.bool_]  # (K,)
    truncated: NDArray[np.bool_]  # (K,)


class NavigationEngine:
    """K navigation environments advanced together.

    The state is kept channel-first, ``state[k] = [x; y; theta]`` of shape (3, N);
    :attr:`poses` gives the familiar (K, N, 3) view. A step is four compiled passes over the
    batch: physics (:func:`~koopman_envs.sim.dynamics.advance_teams`), collision flags,
    observation features, and rewards with episode ends (:mod:`koopman_envs.tasks.reward`).
    Maps with slip zones add a fifth before the physics
    (:func:`~koopman_envs.sim.zones.zone_slip_means`: every robot's slip mean where it stands),
    and a slip schedule updates the base levels after the step
    (:class:`~koopman_envs.sim.slip_schedule.SlipClock`); without them neither runs.

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    num_envs : int
        Batch size K.
    """

    def __init__(self, config: EngineConfig, num_envs: int = 1) -> None:
        self.config = config
        self.num_envs = int(num_envs)
        k, n, m = self.num_envs, config.n_robots, config.n_obstacles
        self.state = np.zeros((k, 3, n))
        self.target = np.zeros((k, 3, n))
        self.offset = np.zeros((k, 2, n))
        #: start poses of the current episodes, (K, N, 3): the map's, perturbed by ``start_noise``
        self.starts = np.zeros((k, n, 3))
        self.obstacles = np.zeros((k, m, 3))
        self.maps: list[MapSpec | None] = [None] * k
        self.distances = np.zeros((k, n))
        self.settled = np.zeros(k, dtype=np.int64)
        self.elapsed = np.zeros(k, dtype=np.int64)
        self.collision = np.zeros(k, dtype=np.int64)
        self.success = np.zeros(k, dtype=bool)
        self.slip = SlipSampler(k, n)
        #: slip zones of every environment, None on maps without zones (then no zone pass runs)
        self.zones = ZoneTable(k, config.n_slip_zones, n) if config.n_slip_zones else None
        self._means = np.zeros((k, n))  # the zone pass's output
        #: scheduled base levels, None for a slip level that is constant through an episode
        self.slip_clock = None if config.slip_schedule is None else SlipClock(config.slip_schedule, k, n)
        self.geometry = TeamGeometry(k, config.robot_radius, m)
        self.builder = FeatureBuilder(k, n, m, config.n_obstacle_obs, config.task.formation)
        self.feature_size = self.builder.shape[-1]
        self.feature_low, self.feature_high = self.builder.low, self.builder.high
        self.command_low = np.array([-PARAMS.v_max, -PARAMS.omega_max])
        self.command_high = np.array([PARAMS.v_max, PARAMS.omega_max])
        # effort weight per command channel: (1 / v_max^2, 1 / omega_max^2)
        self._effort_scale = 1.0 / self.command_high**2
        self._workspace = np.asarray(PARAMS.workspace, dtype=np.float64)
        self._all_active = np.ones(k, dtype=bool)
        self._no_formation = np.zeros((k, n))
        self._settle_steps = PARAMS.settle_steps
        if config.map_spec is not None:
            for index in range(k):
                self._set_map(index, config.map_spec)

    # ----------------------------------------------------------------- spaces
    def robot_spaces(self) -> tuple[spaces.Box, spaces.Box]:
        """(action, observation) spaces of one robot: (v, omega) and its feature block."""
        action = spaces.Box(self.command_low.astype(np.float32), self.command_high.astype(np.float32), dtype=np.float32)
        observation = spaces.Box(
            self.feature_low.astype(np.float32), self.feature_high.astype(np.float32), dtype=np.float32
        )
        return action, observation

    def team_spaces(self) -> tuple[spaces.Box, spaces.Box]:
        """(action, observation) spaces of the whole team of one environment (flat, robot 0 first)."""
        n = self.config.n_robots
        action, observation = self.robot_spaces()
        return (
            spaces.Box(np.tile(action.low, n), np.tile(action.high, n), dtype=np.float32),
            spaces.Box(np.tile(observation.low, n), np.tile(observation.high, n), dtype=np.float32),
        )

    # ------------------------------------------------------------------ views
    @property
    def poses(self) -> NDArray[np.float64]:
        """Poses of every robot, shape (K, N, 3) (a view of :attr:`state`)."""
        return self.state.transpose(0, 2, 1)

    @poses.setter
    def poses(self, value: NDArray) -> None:
        self.state = np.ascontiguousarray(np.asarray(value, dtype=np.float64).transpose(0, 2, 1))

    @property
    def targets(self) -> NDArray[np.float64]:
        """Target poses, shape (K, N, 3) (a view)."""
        return self.target.transpose(0, 2, 1)

    @property
    def offsets(self) -> NDArray[np.float64]:
        """Formation offsets, shape (K, N, 2) (a view)."""
        return self.offset.transpose(0, 2, 1)

    # ------------------------------------------------------------------ reset
    def _set_map(self, index: int, spec: MapSpec) -> None:
        n = self.config.n_robots
        self.maps[index] = spec
        self.obstacles[index] = spec.obstacles
        self.geometry.set_obstacles(index, spec.obstacles)
        self.target[index] = spec.targets[:n].T
        self.offset[index] = formation_offsets(spec.targets[:n]).T
        self.starts[index] = spec.starts[:n]
        if self.zones is not None:
            self.zones.set_env(index, spec.slip_zones)

    def reset_env(self, index: int, rng: np.random.Generator, options: ResetOptions | None = None) -> None:
        """Start a new episode in environment ``index``, drawing only from ``rng``.

        ``options`` (from :func:`parse_reset_options`) replace the map's start poses and/or
        targets for this episode; they are checked against the episode's map (a new one per
        reset with ``map="random"``) before anything changes.

        Raises
        ------
        ValueError
            A start pose or target of ``options`` that is outside the workspace, overlaps an
            obstacle or another robot's (the environment keeps its previous episode).
        """
        cfg = self.config
        n = cfg.n_robots
        options = options or ResetOptions()
        spec = self.maps[index]
        if cfg.map_spec is None:
            spec = generate_random_map(rng, n, cfg.random_map, float(cfg.robot_radius[0]))
        targets = spec.targets[:n] if options.targets is None else options.targets
        if options.targets is not None:
            self._check_placement(spec, targets, "targets")
        if options.start_poses is not None:
            self._check_placement(spec, options.start_poses, "start_poses")
            starts = options.start_poses
        elif cfg.start_noise > 0:
            # the noise is drawn after the map and before the slip level, and only when asked
            # for, so that start_noise=0 consumes nothing and replays earlier rollouts bit for bit
            starts = self._perturbed_starts(spec, rng)
        else:
            starts = spec.starts[:n]
        if spec is not self.maps[index]:
            self._set_map(index, spec)
        self.target[index] = targets.T
        self.offset[index] = formation_offsets(targets).T
        self.starts[index] = starts
        self.state[index] = starts.T
        self.settled[index] = 0
        self.elapsed[index] = 0
        self.collision[index] = 0
        self.success[index] = False
        dx = self.target[index, 0] - self.state[index, 0]
        dy = self.target[index, 1] - self.state[index, 1]
        self.distances[index] = np.sqrt(dx * dx + dy * dy)  # the formula of FeatureBuilder
        if self.slip_clock is not None:
            # the last draws of a reset (drift only), so that every other setting draws as before
            lambdas = self.slip_clock.reset_env(index, rng)
        else:
            lambdas = draw_random_lambdas(rng, n) if cfg.random_slip else cfg.lambdas
        self.slip.reset_env(index, rng, lambdas)

    def _check_placement(self, spec: MapSpec, poses: NDArray, key: str) -> None:
        """Raise ValueError naming ``options[key]`` if the team cannot stand at ``poses`` on ``spec``."""
        radius = float(self.config.robot_radius[0])
        label = "start" if key == "start_poses" else "target"
        problem = spec.pose_problem(poses, radius, PARAMS.workspace, label)
        if problem is not None:
            raise ValueError(
                f"options[{key!r}]: {problem} (map {spec.name!r}); allowed: (x, y, heading) rows whose "
                f"robot discs of radius {radius} lie inside the workspace {PARAMS.workspace}, clear of "
                "every obstacle and of each other"
            )

    def _perturbed_starts(self, spec: MapSpec, rng: np.random.Generator) -> NDArray[np.float64]:
        """The map's starts, each displaced uniformly in a disc of radius ``start_noise`` [m] and
        turned uniformly within +-``start_noise`` [rad], redrawn for the whole team until the
        placement passes :meth:`MapSpec.pose_problem` (the check every map passes).

        Raises
        ------
        RuntimeError
            No valid draw in :data:`START_NOISE_ATTEMPTS` attempts.
        """
        cfg = self.config
        n, noise = cfg.n_robots, cfg.start_noise
        base = spec.starts[:n]
        radius = float(cfg.robot_radius[0])
        for _ in range(START_NOISE_ATTEMPTS):
            # sqrt of a uniform radius fraction makes the displacement uniform over the disc's area
            distance = noise * np.sqrt(rng.uniform(size=n))
            bearing = rng.uniform(-np.pi, np.pi, size=n)
            turn = rng.uniform(-noise, noise, size=n)
            starts = np.column_stack(
                [
                    base[:, 0] + distance * np.cos(bearing),
                    base[:, 1] + distance * np.sin(bearing),
                    wrap_angle(base[:, 2] + turn),
                ]
            )
            problem = spec.pose_problem(starts, radius, PARAMS.workspace, "start")
            if problem is None:
                return starts
        raise RuntimeError(
            f"start_noise={noise!r}: no valid start poses on map {spec.name!r} in "
            f"{START_NOISE_ATTEMPTS} draws of the whole team (last: {problem}); use a smaller start_noise"
        )

    def features(self) -> NDArray[np.float64]:
        """Observation blocks of every robot, shape (K, N, F)."""
        features, _ = self.builder.build(
            self.state, self.target, self.geometry, self.offset if self.config.task.formation else None
        )
        return features

    # ------------------------------------------------------------------- step
    def validate_commands(self, commands: Any) -> NDArray[np.float64]:
        """Check a batch of joint commands and return it as float64 (K, N, 2).

        Raises
        ------
        ValueError
            Wrong shape, or NaN/inf entries.
        """
        k, n = self.num_envs, self.config.n_robots
        arr = np.asarray(commands, dtype=np.float64)
        if arr.shape != (k, n, 2):
            if arr.size == k * n * 2 and arr.shape in ((k, 2 * n), (2 * n,), (n, 2)):
                arr = arr.reshape(k, n, 2)
            else:
                allowed = f"({2 * n},) or ({n}, 2)" if k == 1 else f"({k}, {2 * n}) or ({k}, {n}, 2)"
                raise ValueError(
                    f"action has shape {arr.shape}; expected {allowed}: (v [m/s], omega [rad/s]) "
                    "per robot"
                )
        if not np.isfinite(arr).all():
            bad = np.argwhere(~np.isfinite(arr))[0].tolist()
            raise ValueError(
                f"action contains a non-finite value at index {bad} ({arr[tuple(bad)]}); "
                "allowed: finite (v, omega), saturated to the actuation limits"
            )
        return arr

    def step(self, commands: NDArray[np.float64], active: NDArray[np.bool_] | None = None) -> StepResult:
        """Advance every (active) environment by one control period.

        Parameters
        ----------
        commands : ndarray, shape (K, N, 2)
            Validated commands (v [m/s], omega [rad/s]); saturated here to the limits.
        active : ndarray of bool, shape (K,), optional
            Environments to advance; the others keep their state and consume no randomness.

        Returns
        -------
        StepResult
        """
        cfg = self.config
        slip = self.slip
        slip.prepare(active)
        stepping = self._all_active if active is None else active
        new = np.empty_like(self.state)
        effort = np.empty(self.distances.shape)
        # one branch per step: maps without zones scale the draws by the base levels directly
        means = slip.lambdas
        if self.zones is not None:
            means = self.zones.slip_means(self.state, slip.lambdas, self._means)
        advance_teams(
            self.state, commands, slip.unit, slip.cursor, means, stepping,
            self.command_low, self.command_high, self._effort_scale, PARAMS.dt, new, effort,
        )  # fmt: skip
        self.state = new
        geometry = self.geometry
        collision = np.empty(self.num_envs, dtype=np.int64)
        collision_flags(
            new, geometry.obstacle_x, geometry.obstacle_y, geometry.radius_sum, self._workspace, collision
        )
        features, distances = self.builder.build(
            new, self.target, geometry, self.offset if cfg.task.formation else None
        )
        k, n = distances.shape
        robot_reward, team_reward = np.empty((k, n)), np.empty(k)
        success, terminated, truncated = np.empty(k, bool), np.empty(k, bool), np.empty(k, bool)
        score_step(
            cfg.task.reward, cfg.task.formation, cfg.goal_tolerance, self._settle_steps,
            cfg.max_episode_steps,
            self.distances, distances, effort, self._formation_error(), collision, stepping, self.settled,
            self.elapsed,
            robot_reward, team_reward, success, terminated, truncated,
        )  # fmt: skip
        self.distances = distances
        self.collision = collision
        self.success = success
        if self.slip_clock is not None:
            self.slip_clock.advance(self.elapsed, active, slip.rngs, slip.lambdas)
        return StepResult(features, robot_reward, team_reward, terminated, truncated)

    def slip_means(self) -> NDArray[np.float64]:
        """Slip mean lambda of every robot for the period that starts now, shape (K, N).

        The base level (the slip setting, this episode's draw, or the schedule's level at the
        current time) with the slip zones that contain the robot's centre applied: exactly the
        scale the next :meth:`step` gives the robot's Exponential draws. Ground truth, for tests
        and analysis; controllers must not read it.
        """
        if self.zones is None:
            return self.slip.lambdas.copy()
        return self.zones.slip_means(self.state, self.slip.lambdas, np.empty_like(self.slip.lambdas))

    # ------------------------------------------------------------------- info
    def scenario(self, index: int = 0) -> Scenario:
        """The scenario a model-based controller may use for environment ``index``."""
        cfg = self.config
        spec = self.maps[index]
        if spec is None:
            raise RuntimeError("call reset() before reading the scenario")
        n = cfg.n_robots
        return Scenario(
            task=cfg.task.name,
            map_name=spec.name,
            n_robots=n,
            obstacles=self.obstacles[index].copy(),
            robot_radius=cfg.robot_radius.copy(),
            starts=self.starts[index].copy(),
            targets=self.target[index].T.copy(),
            formation_offsets=self.offset[index].T.copy(),
            leader=0,
            v_max=PARAMS.v_max,
            omega_max=PARAMS.omega_max,
            workspace=PARAMS.workspace,
            dt=PARAMS.dt,
            goal_tolerance=cfg.goal_tolerance,
            settle_steps=self._settle_steps,
        )

    def _formation_error(self) -> NDArray[np.float64]:
        """What the reward charges: the slot errors for formation, a placeholder otherwise."""
        return self.formation_errors() if self.config.task.formation else self._no_formation

    def formation_errors(self) -> NDArray[np.float64]:
        """Distance of every robot from its formation slot relative to the leader [m], (K, N)
        (the leader's is 0), from the engine's state, not from the clipped observation."""
        ex = self.state[:, 0] - self.state[:, 0, :1] - self.offset[:, 0]
        ey = self.state[:, 1] - self.state[:, 1, :1] - self.offset[:, 1]
        return np.hypot(ex, ey)

    def robot_collisions(self) -> NDArray[np.bool_]:
        """Which robots are in collision, (K, N): overlapping an obstacle or another robot, or with
        the centre outside the workspace (the per-robot view of the collision flags)."""
        out = np.zeros(self.distances.shape, dtype=bool)
        hit = np.flatnonzero(self.collision)
        if hit.size:  # only the environments that collided: this runs on every vector step
            x, y = self.state[hit, 0], self.state[hit, 1]
            touching = (self.geometry.clearances(x, y, rows=hit) < 0.0).any(axis=-1)
            x_min, x_max, y_min, y_max = PARAMS.workspace
            out[hit] = touching | (x < x_min) | (x > x_max) | (y < y_min) | (y > y_max)
        return out

    def batch_info(self) -> dict[str, Any]:
        """The true structured state of every environment, one array per key (copies).

        Keys: ``poses`` (K, N, 3), ``targets`` (K, N, 3), ``distances`` (K, N), ``collision``
        (K,) bool, ``collision_code`` (K,) int (bit flags of
        :class:`~koopman_envs.sim.collision.CollisionKind`: 1 obstacle, 2 robot, 4 workspace;
        ``CollisionKind.describe(code)`` names them, e.g. ``"robot+workspace"``; every value of
        an info is a number or an array, which RL libraries stack into tensors),
        ``robot_collision`` (K, N) bool (which robots collided), ``is_success`` (K,),
        ``settled_steps`` (K,), and ``formation_error`` (K, N) for formation.
        :meth:`info` is row ``index`` of this, so every front reports the same keys.
        """
        info = {
            "poses": self.poses.copy(),
            "targets": self.targets.copy(),
            "distances": self.distances.copy(),
            "collision": self.collision != 0,
            "collision_code": self.collision.astype(np.int64),
            "robot_collision": self.robot_collisions(),
            "is_success": self.success.copy(),
            "settled_steps": self.settled.copy(),
        }
        if self.config.task.formation:
            info["formation_error"] = self.formation_errors()
        return info

    def info(self, index: int = 0) -> dict[str, Any]:
        """The true structured state of environment ``index`` (copies; see :meth:`batch_info`)."""
        collision = int(self.collision[index])
        info = {
            "poses": self.state[index].T.copy(),
            "targets": self.target[index].T.copy(),
            "distances": self.distances[index].copy(),
            "collision": collision != 0,
            "collision_code": collision,
            "robot_collision": (self.robot_collisions()[index] if collision
                                else np.zeros(self.config.n_robots, dtype=bool)),  # fmt: skip
            "is_success": bool(self.success[index]),
            "settled_steps": int(self.settled[index]),
        }
        if self.config.task.formation:
            info["formation_error"] = self.formation_errors()[index]
        return info
