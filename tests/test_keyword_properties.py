"""Property test (Hypothesis) over the env keyword table, issue 41: for every keyword of
:data:`koopman_envs.engine.keywords.ENV_KEYWORDS`, a random value either builds an env that resets and
steps (finite observations and rewards), or raises ``ValueError`` / ``TypeError`` whose message
names the keyword; never another exception, and never more than :data:`MEMORY_LIMIT` bytes of
traced allocations (tracemalloc's peak: numpy reports its arrays to it, so an allocation of a size
the user typed shows even when the operating system would hand out the pages lazily).

The values: about half plausible (the allowed names, numbers in and just past their ranges, the
settings' dicts with up to four of their own fields, as Python numbers or NumPy scalars), so
that many examples build an env and reach reset and step; the rest anything: integers (small,
huge, negative, past 64 bits), floats (NaN, infinities, denormal, huge), NumPy scalars of every
width, strings (random, the allowed names and their other cases), None, booleans, lists, and
dicts with random keys, nested. Keywords that need a context get it half of the time
(``random_map`` with ``map="random"``, ``lidar`` with ``sensing="lidar"``, ...), and the task is
drawn (target reaching or formation).

Size: :data:`EXAMPLES` examples per keyword: 40 by default, 18 keywords, 720 examples (a few
seconds); ``KOOPNAV_PROPERTY_EXAMPLES=1000`` runs more (passed when this was written, as did
three runs of 500 per keyword without derandomizing). Derandomized (the same examples every run:
a failure reproduces) and without Hypothesis's example database (nothing written to the
checkout). No time is asserted (``deadline=None``): the test holds on a busy machine.

Found and fixed with it (tests/test_env_limits.py holds each): a ``RuntimeError`` from
``start_noise`` too large for the map and from an impossible ``random_map``; numpy's "high - low
< 0" for a ``random_map.border`` or ``robot_radius`` that leaves no room; an ``OverflowError`` for
``start_noise=9e307``; infinite observations for ``pose_noise=5e307``; a ``ZeroDivisionError`` for
a denormal ``lidar.fov``; NaN obstacles for a denormal ``random_map.travel``; NaN movers for a
huge ``movers.radius``; a message without the keyword for a ``robot_radius`` the map cannot
hold.
"""

from __future__ import annotations

import importlib.util
import math
import os
import string
import tracemalloc
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.engine.keywords import ENV_KEYWORDS
from koopman_envs.fronts.gym_env import FormationEnv, TargetReachingEnv
from koopman_envs.fronts.parallel_env import KoopNavParallelEnv
from koopman_envs.params import LIMITS, SLIP_NAMES
from koopman_envs.settings import MOVER_BEHAVIOURS, SENSING_MODES, UNCERTAINTY_PRESETS
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.sim.maps.map_spec import MAP_NAMES

#: examples per keyword
EXAMPLES = int(os.environ.get("KOOPNAV_PROPERTY_EXAMPLES", "40"))
#: the largest traced allocation peak of one example (build, reset, three steps) [bytes]
MEMORY_LIMIT = 500 * 2**20
#: periods stepped after the reset
STEPS = 3

SETTINGS = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# ---------------------------------------------------------------------------- values
NAMES = sorted(
    {
        *MAP_NAMES,
        *SLIP_NAMES,
        *FORMATION_SHAPES,
        *UNCERTAINTY_PRESETS,
        *SENSING_MODES,
        *MOVER_BEHAVIOURS,
        "auto",
    }
)
integers = st.one_of(
    st.integers(-3, 12),
    st.sampled_from([0, 1, -1, 2**31, 2**63, -(2**63), 10**9, 10**30, LIMITS.robots, LIMITS.movers + 1]),
    st.integers(),
)
floats = st.one_of(
    st.floats(-2.0, 8.0),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, math.inf, -math.inf, math.nan, 0.5, 2 * math.pi]),
    st.floats(allow_nan=True, allow_infinity=True),
)
numpy_scalars = st.one_of(
    st.integers(-(2**63), 2**63 - 1).map(np.int64),
    st.integers(-128, 127).map(np.int8),
    st.integers(0, 2**16 - 1).map(np.uint16),
    st.floats(width=32, allow_nan=True, allow_infinity=True).map(np.float32),
    st.floats(width=16, allow_nan=True, allow_infinity=True).map(np.float16),
    st.floats(allow_nan=True, allow_infinity=True).map(np.float64),
    st.booleans().map(np.bool_),
)
texts = st.one_of(
    st.sampled_from(NAMES),
    st.sampled_from(NAMES).map(str.upper),
    st.text(alphabet=string.ascii_letters + string.digits + "._-/ ", max_size=12),
    st.text(max_size=6),
)
scalars = st.one_of(integers, floats, numpy_scalars, texts, st.none(), st.booleans())
leaves = st.one_of(scalars, st.lists(st.one_of(integers, floats, numpy_scalars), max_size=4).map(tuple))
anything = st.recursive(
    leaves,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.one_of(texts, integers), inner, max_size=3)
    ),
    max_leaves=8,
)


def numpy_too(values: st.SearchStrategy[Any]) -> st.SearchStrategy[Any]:
    """``values`` as drawn, or as NumPy scalars (the integers as int64, the floats as float32)."""

    def as_numpy(value: Any) -> Any:
        return (
            np.int64(value) if isinstance(value, int) and not isinstance(value, bool) else np.float32(value)
        )

    return st.one_of(values, values.map(as_numpy))


def ints(low: int, high: int, bound: int | None = None) -> st.SearchStrategy[Any]:
    """Plausible integers, now and then up to past the bound (``bound`` + 50)."""
    wide = st.integers(low, high if bound is None else bound + 50)
    return numpy_too(st.one_of(st.integers(low, high), wide))


def reals(low: float, high: float) -> st.SearchStrategy[Any]:
    return numpy_too(st.floats(low, high))


def pair(low: float, high: float) -> st.SearchStrategy[Any]:
    """(low, high) pairs, mostly in order."""
    ordered = st.tuples(st.floats(low, high), st.floats(low, high)).map(lambda p: (min(p), max(p)))
    return st.one_of(numpy_too(ordered.map(lambda p: p[0])).flatmap(lambda a: st.just((a, a))), ordered, ordered,
                     st.tuples(reals(low, high), reals(low, high)))  # fmt: skip


def keyword_values(plausible: st.SearchStrategy[Any]) -> st.SearchStrategy[Any]:
    """Half plausible values (which mostly build an env, so that reset and step run), half
    anything."""
    return st.one_of(plausible, plausible, scalars, anything)


def setting(
    fields: dict[str, st.SearchStrategy[Any]], number: st.SearchStrategy[Any] | None = None
) -> st.SearchStrategy[Any]:
    """Dicts of up to four of a setting's fields, each mostly plausible, and now and then a
    stranger key; ``number``: the setting also takes one number."""

    def dicts(names: list[str]) -> st.SearchStrategy[dict[str, Any]]:
        return st.fixed_dictionaries(
            {name: st.one_of(fields[name], fields[name], fields[name], scalars) for name in names}
        )

    field_dicts = st.lists(st.sampled_from(sorted(fields)), unique=True, max_size=4).flatmap(dicts)
    strangers = st.dictionaries(
        st.one_of(st.sampled_from(sorted(fields)), texts, integers), anything, max_size=3
    )
    options = [field_dicts, field_dicts, field_dicts, strangers] + ([number] if number is not None else [])
    return st.one_of(*options, scalars, anything)


L = LIMITS
MOVER_FIELDS = {
    "count": ints(0, 8, L.movers),
    "radius": reals(0.02, 1.0),
    "speed": reals(0.0, L.mover_speed + 0.5),
    "behaviour": st.sampled_from(MOVER_BEHAVIOURS),
    "aware": st.one_of(st.booleans(), st.booleans().map(np.bool_)),
    "observed": ints(0, 6, L.movers),
    "pause": reals(0.0, 5.0),
}
RANDOM_MAP_FIELDS = {
    "n_obstacles": ints(0, 8, L.random_obstacles),
    "travel": pair(0.5, 9.0),
    "obstacle_radius": pair(0.05, 1.5),
    "obstacle_along": pair(0.0, 1.0),
    "spacing": reals(0.3, 2.0),
    "formation": st.sampled_from(["auto", *FORMATION_SHAPES]),
    "clearance": reals(0.0, 1.0),
    "gap": reals(0.0, 1.5),
    "border": reals(0.0, 4.0),
    "max_attempts": ints(1, 300, None),
    "swap_targets": reals(0.0, 1.0),
    "n_slip_zones": ints(0, 4, L.slip_zones),
    "slip_zone_radius": pair(0.05, 3.0),
    "slip_zone_lambda": pair(0.0, L.slip_lambda + 1),
    "slip_zone_mode": st.sampled_from(["replace", "add", "ADD"]),
}
SLIP_LEVELS = st.one_of(
    st.sampled_from(sorted(SLIP_NAMES)),
    reals(0.0, 0.5),
    st.lists(reals(0.0, L.slip_lambda + 1), min_size=1, max_size=4),
)
SCHEDULES = st.lists(
    st.tuples(st.one_of(st.just(0.0), reals(0.0, 20.0)), SLIP_LEVELS), min_size=1, max_size=3
)

#: MuJoCo installed (the [physics] extra): plant="mujoco" is a value to try
HAS_MUJOCO = importlib.util.find_spec("mujoco") is not None

#: each keyword's values
VALUES: dict[str, st.SearchStrategy[Any]] = {
    "map": keyword_values(st.one_of(st.sampled_from(MAP_NAMES), st.sampled_from(["", ".", "/", "x.json", "/no/m.json"]))),
    "slip": keyword_values(st.one_of(SLIP_LEVELS, SCHEDULES)),
    "n_robots": keyword_values(ints(1, 6, L.robots)),
    "goal_tolerance": keyword_values(reals(0.0, 2.0)),
    "robot_radius": keyword_values(reals(0.0, 1.0)),
    "n_obstacle_obs": keyword_values(ints(0, 10, L.obstacle_obs)),
    "random_map": setting(RANDOM_MAP_FIELDS),
    "start_noise": keyword_values(reals(0.0, 3.0)),
    "formation": keyword_values(st.sampled_from([None, *FORMATION_SHAPES, "Wedge"])),
    "max_episode_steps": keyword_values(st.one_of(st.none(), ints(1, 50, L.episode_steps))),
    "max_cycles": keyword_values(st.one_of(st.none(), ints(1, 50, L.episode_steps))),
    "uncertainty": keyword_values(st.sampled_from([*UNCERTAINTY_PRESETS, "HARSH"])),
    "pose_noise": setting({f: reals(0.0, 0.5) for f in ("xy", "heading", "drift_xy", "drift_heading")}, reals(0.0, 0.5)),
    "sensing": keyword_values(st.sampled_from([*SENSING_MODES, "LIDAR"])),
    "lidar": setting({
        "beams": ints(1, 64, L.lidar_beams), "fov": reals(0.0, 7.0), "range": reals(0.0, L.lidar_range + 10),
        "noise": reals(0.0, 1.0), "dropout": reals(0.0, 1.2),
    }),
    "comm": setting({
        "latency": ints(0, 5, L.latency), "drop": reals(0.0, 1.2),
        "range": st.one_of(reals(0.0, 50.0), st.sampled_from([math.inf, np.float32(np.inf)])),
    }),
    "actuation_delay": keyword_values(st.one_of(st.none(), ints(0, 5, L.actuation_delay))),
    "movers": setting(MOVER_FIELDS, ints(0, 6, L.movers)),
    # "mujoco" only where the [physics] extra is installed (without it: ModuleNotFoundError, by design)
    "plant": keyword_values(st.sampled_from(["kinematic", "Kinematic", "physics", *(["mujoco"] if HAS_MUJOCO else [])])),
}  # fmt: skip


#: keywords given beside the one under test, half of the time, so that it takes effect
CONTEXT: dict[str, dict[str, Any]] = {
    "random_map": {"map": "random"},
    "lidar": {"sensing": "lidar"},
    "formation": {"map": "random"},
    "n_robots": {"map": "random"},
    "movers": {"map": "random"},
    "max_cycles": {},
}


def _build(name: str, value: Any, context: dict[str, Any], formation: bool) -> Any:
    kwargs = {**context, name: value}
    if name == "max_cycles":
        return KoopNavParallelEnv("formation" if formation else "target_reaching", **kwargs)
    return (FormationEnv if formation else TargetReachingEnv)(**kwargs)


def _run(env: Any) -> None:
    """Reset and step: every observation and reward finite."""
    if isinstance(env, KoopNavParallelEnv):
        observations, _ = env.reset(seed=0)
        for _ in range(STEPS):
            if not env.agents:
                break
            actions = {agent: np.full(2, 0.1) for agent in env.agents}
            observations, rewards, *_ = env.step(actions)
            assert all(np.isfinite(r) for r in rewards.values())
        assert all(np.isfinite(o).all() for o in observations.values())
        return
    observation, _ = env.reset(seed=0)
    assert np.isfinite(observation).all()
    for _ in range(STEPS):
        observation, reward, terminated, truncated, _ = env.step(np.full(env.action_space.shape, 0.1))
        assert np.isfinite(observation).all() and np.isfinite(reward)
        if terminated or truncated:
            break


def check_keyword(name: str, value: Any, context: dict[str, Any], formation: bool) -> None:
    """The property of one example (module docstring)."""
    tracemalloc.start()
    try:
        try:
            _run(_build(name, value, context, formation))
            event("a working env")
        except (ValueError, TypeError) as exc:
            assert name in str(exc), f"{name}={value!r}: {type(exc).__name__} without the keyword: {exc}"
            event(f"refused: {type(exc).__name__}")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < MEMORY_LIMIT, f"{name}={value!r}: {peak / 2**20:.0f} MiB traced"


@pytest.mark.parametrize("name", [row.name for row in ENV_KEYWORDS])
def test_any_value_of_a_keyword_builds_a_working_env_or_is_refused_by_name(name: str) -> None:
    values = VALUES[name]
    context = st.sampled_from([{}, CONTEXT.get(name, {})])

    @SETTINGS
    @given(value=values, context=context, formation=st.booleans())
    def check(value: Any, context: dict[str, Any], formation: bool) -> None:
        check_keyword(name, value, context, formation)

    check()


def test_every_keyword_is_covered() -> None:
    """Every keyword of the table has its values here (a new keyword needs its own)."""
    assert set(VALUES) == {row.name for row in ENV_KEYWORDS}
    assert len(ENV_KEYWORDS) == 19
