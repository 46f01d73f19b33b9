"""The env keywords: declared once (:data:`ENV_KEYWORDS`), each row with its default, type,
documentation and check; the fronts' signatures, ``TypeError`` for unknown keywords and argument
tables are generated from the table."""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import inspect
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from koopman_envs.checks import check_choice, check_int, check_number, closest, did_you_mean
from koopman_envs.params import INSTALL_HINT, LIMITS, PARAMS, PLANTS, SLIP_NAMES, SLIP_SURFACES, SURFACES
from koopman_envs.settings.moving_obstacles import MOVER_BEHAVIOURS, parse_movers
from koopman_envs.settings.uncertainty import SENSING_MODES, UNCERTAINTY_PRESETS
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.sim.maps.generator import RandomMapConfig
from koopman_envs.sim.maps.map_spec import BUILTIN_MAPS
from koopman_envs.tasks.base import TASKS

__all__ = [
    "ENV_KEYWORDS",
    "EnvKeyword",
    "FRONTS",
    "env_keyword",
    "env_keywords",
    "keyword_argument",
    "keyword_table",
    "takes_env_keywords",
    "unknown_keywords",
]


def _random_map_config(name: str, value: RandomMapConfig | dict[str, Any] | None) -> RandomMapConfig:
    """``random_map`` keyword: a :class:`RandomMapConfig`, a dict of its fields, or None."""
    if value is None or isinstance(value, RandomMapConfig):
        return value or RandomMapConfig()
    if isinstance(value, dict):
        allowed = [f.name for f in dataclasses.fields(RandomMapConfig)]
        # in the dict's order, not sorted: keys of mixed types do not sort
        unknown = [key for key in value if key not in allowed]
        if unknown:
            hint = did_you_mean(unknown[0], allowed)
            raise ValueError(f"{name} has unknown fields {unknown}{hint}; allowed: {allowed}")
        try:
            return RandomMapConfig(**value)
        except ValueError as exc:  # the field's own message, said to come from this keyword
            raise ValueError(f"{name}: {exc}") from None
    raise ValueError(f"{name}={value!r} must be a RandomMapConfig, a dict of its fields or None")


def _formation(name: str, value: Any) -> str | None:
    if value is None:
        return None
    return str(check_choice(name, value, FORMATION_SHAPES, " or None (the map's own layout)"))


def _choice(allowed: Sequence[str]) -> Callable[[str, Any], str]:
    """A check that ``value`` is one of ``allowed`` (with did-you-mean)."""

    def check(name: str, value: Any) -> str:
        return str(check_choice(name, value, allowed))

    return check


def _plant(name: str, value: Any) -> str:
    """``plant``: one of :data:`~koopman_envs.params.PLANTS`; ``"mujoco"`` only with MuJoCo installed."""
    plant = _choice(PLANTS)(name, value)
    if plant == "mujoco" and importlib.util.find_spec("mujoco") is None:
        raise ModuleNotFoundError(
            f"{name}={plant!r} needs the mujoco package, which is not installed: {INSTALL_HINT}"
        )
    return plant


def _optional_delay(name: str, value: Any) -> int | None:
    if value is None:
        return None
    return check_int(name, value, 0, maximum=LIMITS.actuation_delay, note="control periods")


def _optional_steps(name: str, value: Any) -> int | None:
    # bounded: the vector and PettingZoo fronts hand it to a compiled kernel as a 64-bit integer
    return None if value is None else check_int(name, value, 1, maximum=LIMITS.episode_steps)


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
    check : callable, optional
        Its own validation: ``check(name, value)`` returns the value in normal form.
    """

    name: str
    default: Any
    annotation: str
    doc: str
    fronts: tuple[str, ...] = FRONTS
    # ``check(name, value)`` -> the value in normal form, or ``ValueError`` naming it; None for
    # the keywords checked together with others (``map``, ``slip``: they depend on ``n_robots``)
    check: Callable[[str, Any], Any] | None = None

    def resolve(self, value: Any) -> Any:
        """``value`` checked and in normal form (``ValueError`` naming the keyword otherwise)."""
        return value if self.check is None else self.check(self.name, value)


#: The env keywords: the one place where they are declared and defaulted. Every front forwards
#: its keywords to :meth:`EngineConfig.create`, which validates them; the fronts' signatures and
#: argument tables are generated from this table (:func:`takes_env_keywords`,
#: :func:`keyword_table`), and tests/test_keyword_spec.py holds the fronts and docs/environments.md to it.
ENV_KEYWORDS: tuple[EnvKeyword, ...] = (
    EnvKeyword(
        "map",
        None,
        "str | os.PathLike | MapSpec | None",
        f'"{BUILTIN_MAPS[0]}".."{BUILTIN_MAPS[-1]}", "random" (a new seeded layout per reset), '
        '"suite:<name>/<split>" (a benchmark split, one of its layouts per reset: docs/benchmark.md), a '
        "JSON map file or a MapSpec; None: the task's first map",
    ),
    EnvKeyword(
        "slip",
        "nominal",
        "str | Sequence[Any]",
        f"{', '.join(map(json.dumps, SLIP_NAMES))}, one lambda >= 0 per robot, or (time [s], lambdas) pairs",
    ),
    EnvKeyword(
        "plant",
        PLANTS[0],
        "str",
        f"what the robots are, one of {list(PLANTS)}: the paper's kinematic unicycle with drawn slip, or "
        "TurtleBot3-class robots in MuJoCo (extra [physics]; slip then names a floor surface: "
        + ", ".join(f"{k}: {v} {SURFACES[v]}" for k, v in SLIP_SURFACES.items())
        + ", a surface name or a friction in (0, 2]; docs/physics.md)",
        check=_plant,
    ),
    EnvKeyword(
        "n_robots",
        PARAMS.n_robots,
        "int",
        f"team size N, 1 to {LIMITS.robots}: at most the map's starts (a smaller team takes the first N), "
        'any N that fits with map="random"',
        check=lambda name, v: check_int(name, v, 1, maximum=LIMITS.robots),
    ),
    EnvKeyword(
        "goal_tolerance",
        PARAMS.goal_tolerance,
        "float",
        "success tolerance [m]",
        check=lambda name, v: check_number(name, v, above=0),
    ),
    EnvKeyword(
        "robot_radius",
        PARAMS.robot_radius,
        "float",
        "disc radius of every robot [m]",
        check=lambda name, v: check_number(name, v, above=0),
    ),
    EnvKeyword(
        "n_obstacle_obs",
        4,
        "int",
        f"nearest obstacles listed in each robot's block, 0 to {LIMITS.obstacle_obs}",
        check=lambda name, v: check_int(name, v, 0, maximum=LIMITS.obstacle_obs),
    ),
    EnvKeyword(
        "random_map",
        None,
        "RandomMapConfig | dict | None",
        'generator settings for map="random" (a RandomMapConfig or a dict of its fields; '
        f"n_obstacles and n_slip_zones at most {LIMITS.random_obstacles}, max_attempts at most "
        f"{LIMITS.map_attempts:_})",
        check=_random_map_config,
    ),
    EnvKeyword(
        "start_noise",
        0.0,
        "float",
        f"per-reset start jitter: disc radius [m] and heading bound [rad], at most {LIMITS.start_noise:g}",
        check=lambda name, v: check_number(name, v, at_least=0, at_most=LIMITS.start_noise),
    ),
    EnvKeyword(
        "formation",
        None,
        "str | None",
        f"formation shape of the team, one of {list(FORMATION_SHAPES)} (spacing "
        f"{PARAMS.formation_spacing:g} m): follower targets on formation maps, starts and targets "
        'with map="random"; None: the map\'s own',
        check=_formation,
    ),
    EnvKeyword(
        "max_episode_steps",
        None,
        "int | None",
        f"time limit in control periods, 1 to {LIMITS.episode_steps:_}; None: {PARAMS.max_episode_steps} "
        "(the Gymnasium env leaves it to gym.make's TimeLimit)",
        check=_optional_steps,
    ),
    EnvKeyword(
        "uncertainty",
        "nominal",
        "str",
        f"named runtime-uncertainty preset, one of {list(UNCERTAINTY_PRESETS)}: slip, pose_noise, comm, "
        "actuation_delay (and lidar noise) together (docs/uncertainty.md); keywords given beside it win",
        check=_choice(tuple(UNCERTAINTY_PRESETS)),
    ),
    EnvKeyword(
        "pose_noise",
        None,
        "float | dict | PoseNoise | None",
        "each robot's localization error: dict(xy [m], heading [rad], drift_xy [m/sqrt(s)], "
        f"drift_heading [rad/sqrt(s)]), each at most {LIMITS.pose_noise:g} (a number: the xy std); None: "
        "the preset's (none)",
    ),
    EnvKeyword(
        "sensing",
        "state",
        "str",
        f"how robots see obstacles, one of {list(SENSING_MODES)}: the known map, or lidar beams only",
        check=_choice(SENSING_MODES),
    ),
    EnvKeyword(
        "lidar",
        None,
        "dict | LidarConfig | None",
        f'with sensing="lidar": dict(beams (at most {LIMITS.lidar_beams}), fov [rad], range [m] (at most '
        f"{LIMITS.lidar_range:g}), noise [m], dropout); None: 32 beams, 360 deg, 5 m, the preset's noise",
    ),
    EnvKeyword(
        "comm",
        None,
        "dict | CommConfig | None",
        f"what robots hear of team-mates: dict(latency [periods, 0 to {LIMITS.latency}], drop [0-1], "
        "range [m]); None: the preset's (instant and lossless)",
    ),
    EnvKeyword(
        "actuation_delay",
        None,
        "int | None",
        f"periods between a command and its action, 0 to {LIMITS.actuation_delay}; None: the preset's (0)",
        check=_optional_delay,
    ),
    EnvKeyword(
        "movers",
        None,
        "int | dict | MoverConfig | None",
        f"moving obstacles: dict(count (at most {LIMITS.movers}), radius [m], speed [m/s] (at most "
        f"{LIMITS.mover_speed:g} m/s), behaviour, aware, observed, pause [s]), behaviour one of "
        f"{list(MOVER_BEHAVIOURS)} (docs/movers.md); a number: that many constant movers; None: none",
        check=parse_movers,
    ),
    EnvKeyword(
        "max_cycles",
        None,
        "int | None",
        f"PettingZoo MPE's name of max_episode_steps (1 to {LIMITS.episode_steps:_})",
        fronts=("parallel",),
        check=_optional_steps,
    ),
)


def env_keywords(front: str | None = None) -> tuple[EnvKeyword, ...]:
    """The rows of :data:`ENV_KEYWORDS` that ``front`` takes (None: every row)."""
    if front is not None:
        check_choice("front", front, FRONTS, " or None")
    return tuple(k for k in ENV_KEYWORDS if front is None or front in k.fronts)


def env_keyword(name: str) -> EnvKeyword:
    """The row of :data:`ENV_KEYWORDS` named ``name`` (``ValueError`` naming the allowed ones)."""
    for row in ENV_KEYWORDS:
        if row.name == name:
            return row
    names = [k.name for k in ENV_KEYWORDS]
    raise ValueError(f"{name!r} is not an env keyword{did_you_mean(name, names)}; allowed: {names}")


def keyword_argument(name: str) -> dict[str, Any]:
    """``argparse`` settings of a command-line option that sets env keyword ``name``: its default,
    its one-line doc as the help, and a ``type`` that is the keyword's own check, so that a command
    line takes the values the envs take and refuses the others with the env's message (one check
    per keyword, never a second parser's ``choices``).

    Returns
    -------
    dict
        ``default``, ``help`` and ``type`` for ``parser.add_argument("--<name>", **settings)``.
    """
    import argparse  # the command lines' module, not the envs'

    row = env_keyword(name)

    def parse(text: str) -> Any:
        try:
            return row.resolve(text)
        except (ValueError, ModuleNotFoundError) as exc:  # argparse names the option before it
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = name  # argparse's "invalid <name> value" when a check raises something else
    help_text = f"env keyword {name}: {row.doc}".replace("%", "%%")  # argparse formats help with %
    return {"default": row.default, "help": help_text, "type": parse}


def unknown_keywords(given: Any, allowed: Sequence[str], owner: str) -> TypeError | None:
    """A TypeError naming the keywords of ``given`` outside ``allowed`` (and close matches), or None."""
    unknown = [name for name in given if name not in allowed]
    if not unknown:
        return None
    hints = [f"{match!r} for {name!r}" for name in unknown if (match := closest(name, allowed)) is not None]
    hint = f" (did you mean {', '.join(hints)}?)" if hints else ""
    # Python's own phrase first: wrappers such as TorchRL's GymEnv retry without a keyword (e.g.
    # frameskip) when the error reads "unexpected keyword argument '<name>'"
    return TypeError(
        f"{owner} got an unexpected keyword argument {unknown[0]!r}; unknown keyword arguments "
        f"{unknown}{hint}; allowed: {list(allowed)}"
    )


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
            own
            + [
                inspect.Parameter(k.name, keyword_only, default=k.default, annotation=k.annotation)
                for k in rows
            ]
        )

        @functools.wraps(init)
        def wrapper(self: Any, *args: Any, **kwargs: Any) -> None:
            error = unknown_keywords(kwargs, names[1:], type(self).__name__)
            if error is not None:
                raise error
            init(self, *args, **kwargs)

        wrapper.__signature__ = signature  # type: ignore[attr-defined]
        return wrapper

    return decorate


def keyword_table(
    front: str, extra: Sequence[tuple[str, str, str, str]] = (), task: str | None = None
) -> str:
    """The env keywords of ``front`` as a Markdown table (Parameter, Type, Default, Description).

    ``extra`` rows (name, type, default, description) of the front's own parameters come first;
    with a ``task``, the default of ``map`` shown is that task's default map.
    """
    shown = {"map": TASKS[task].default_map} if task is not None else {}
    rows = list(extra) + [
        (k.name, k.annotation, repr(shown.get(k.name, k.default)), k.doc) for k in env_keywords(front)
    ]
    lines = ["| Parameter | Type | Default | Description |", "|---|---|---|---|"]
    lines += [
        f"| {name} | {kind.replace('|', 'or')} | {default} | {doc} |" for name, kind, default, doc in rows
    ]
    return "\n".join(lines)
