"""Batched resets (issue 47): the vector env resets the environments that end in the same step
together (``NavigationEngine.reset_envs``, ``MoverField.reset_envs``, ``place_movers_batch``);
every environment must draw and start exactly as it would alone."""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.settings import ResetOptions
from koopman_envs.sim.movers.placement import PlacementError, place_movers, place_movers_batch

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"

SETTINGS = {
    "fixed map": (TR, {}),
    "random layouts, random slip": (FO, {"map": "random", "slip": "random"}),
    "drift and start noise": (TR, {"slip": "drift", "start_noise": 0.1}),
    "harsh faults on random layouts": (TR, {"uncertainty": "harsh", "map": "random"}),
    "tracked constant movers": (TR, {"movers": {"count": 6}}),
    "waypoint walkers on random layouts": (
        FO,
        {"movers": {"count": 5, "behaviour": "waypoints"}, "map": "random"},
    ),
    "lidar among movers": (TR, {"sensing": "lidar", "movers": {"count": 4}}),
    "slip zones": (TR, {"map": "map5"}),
}
#: what an episode's start writes, and what the first steps read
ENGINE_ARRAYS = ("state", "target", "offset", "starts", "nominal_starts", "obstacles", "distances")


def _engine(env_id: str, kwargs: dict, num_envs: int):
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    ).unwrapped.engine


def _arrays(engine) -> dict[str, np.ndarray]:
    out = {name: getattr(engine, name).copy() for name in ENGINE_ARRAYS}
    out["lambdas"] = engine.slip.lambdas.copy()
    if engine.movers is not None:
        for name in ("_states", "goal", "arena", "leg_speed", "pool", "cursor"):
            out["movers." + name] = getattr(engine.movers, name).copy()
    return out


#: the setting that runs by default; the others run with -m slow (issue 61: seconds each, most of
#: them compiling their own kernels in a process the warm-up did not reach)
DEFAULT_SETTING = "fixed map"


@pytest.mark.parametrize(
    "setting",
    [pytest.param(s, marks=[] if s == DEFAULT_SETTING else [pytest.mark.slow]) for s in SETTINGS],
)
def test_a_batched_reset_equals_resetting_one_environment_at_a_time(setting: str) -> None:
    env_id, kwargs = SETTINGS[setting]
    batched, single = _engine(env_id, kwargs, 5), _engine(env_id, kwargs, 5)
    rows = [4, 0, 2]  # not in order, and not every environment
    seeds = {0: 7, 2: 8, 4: 9}
    for repeat in range(3):  # later episodes too: the children carry over between episodes
        if repeat == 0:
            rngs = {i: np.random.default_rng(seeds[i]) for i in rows}
            twins = {i: copy.deepcopy(rng) for i, rng in rngs.items()}
        batched.reset_envs(rows, [rngs[i] for i in rows])
        for i in rows:
            single.reset_env(i, twins[i])
        a, b = _arrays(batched), _arrays(single)
        for name in a:
            assert np.array_equal(a[name], b[name], equal_nan=True), (setting, repeat, name)
        for i in rows:  # the generators are left in the same state
            assert rngs[i].bit_generator.state == twins[i].bit_generator.state
    commands = np.random.default_rng(1).uniform(-0.3, 0.3, (40, 5, batched.config.n_robots, 2))
    for i in (1, 3):  # the environments outside the batch start too, the same in both
        batched.reset_env(i, np.random.default_rng(i))
        single.reset_env(i, np.random.default_rng(i))
    for step in range(40):
        ra, rb = batched.step(commands[step]), single.step(commands[step])
        assert np.array_equal(ra.features, rb.features, equal_nan=True), (setting, step)
        assert np.array_equal(ra.robot_reward, rb.robot_reward)


def test_the_crowd_is_reset_in_a_batch_as_alone() -> None:
    pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    kwargs = {"movers": {"count": 5, "behaviour": "crowd", "aware": True}, "map": "random"}
    batched, single = _engine(TR, kwargs, 3), _engine(TR, kwargs, 3)
    batched.reset_envs([0, 1, 2], [np.random.default_rng(s) for s in (3, 4, 5)])
    for i, s in enumerate((3, 4, 5)):
        single.reset_env(i, np.random.default_rng(s))
    commands = np.random.default_rng(2).uniform(-0.3, 0.3, (30, 3, 3, 2))
    for step in range(30):
        assert np.array_equal(batched.step(commands[step]).features, single.step(commands[step]).features)
        assert np.array_equal(batched.movers._states, single.movers._states)


def test_a_rejected_option_leaves_every_environment_of_the_batch_as_it_was() -> None:
    engine = _engine(TR, {}, 3)
    engine.reset_envs([0, 1, 2], [np.random.default_rng(s) for s in range(3)])
    before = _arrays(engine)
    inside_an_obstacle = engine.maps[0].obstacles[0, :2]
    bad = engine.maps[0].starts[:3].copy()
    bad[1, :2] = inside_an_obstacle
    options = [None, ResetOptions(start_poses=bad), None]
    with pytest.raises(ValueError, match="start_poses"):
        engine.reset_envs([0, 1, 2], [np.random.default_rng(s) for s in range(3)], options)
    after = _arrays(engine)
    for name in before:
        assert np.array_equal(before[name], after[name]), name


def test_placing_a_batch_of_environments_equals_placing_each_alone() -> None:
    """Including an environment that needs more than its first block of candidates."""
    arenas = np.array([[-3.0, 3.0, -3.0, 3.0], [-1.3, 1.3, -1.3, 1.3], [-5.0, 5.0, -4.0, 4.0]])
    obstacles = np.array([[[0.0, 0.0, 0.5]], [[0.2, 0.0, 0.2]], [[2.0, 1.0, 1.0]]])
    starts = np.array([[[-2.0, -2.0, 0.0]], [[-1.0, -1.0, 0.0]], [[-3.0, 0.0, 0.0]]])
    targets = -starts
    count, radius, clearance = 8, 0.25, 0.3
    rngs = [np.random.default_rng(s) for s in (10, 11, 12)]
    twins = [copy.deepcopy(rng) for rng in rngs]
    placed = place_movers_batch(rngs, count, radius, arenas, obstacles, starts, targets, clearance)
    for b in range(3):
        alone = place_movers(
            twins[b], count, radius, arenas[b], obstacles[b], (starts[b], targets[b]), clearance
        )
        assert np.array_equal(placed[b], alone)
        assert rngs[b].bit_generator.state == twins[b].bit_generator.state
    # the tight arena drew more than its first block: the batch's continuation was exercised
    probe = np.random.default_rng(11)
    probe.random((4 * count + 16, 2))
    assert probe.bit_generator.state != twins[1].bit_generator.state


def test_a_batch_that_cannot_place_its_movers_names_the_environment_s_arena() -> None:
    arenas = np.array([[-3.0, 3.0, -3.0, 3.0], [-1.0, 1.0, -1.0, 1.0]])
    obstacles = np.zeros((2, 0, 3))
    starts = np.zeros((2, 1, 3))
    rngs = [np.random.default_rng(s) for s in (1, 2)]
    with pytest.raises(PlacementError, match=r"arena \[-1.0, 1.0, -1.0, 1.0\]") as caught:
        place_movers_batch(rngs, 30, 0.3, arenas, obstacles, starts + 2.5, starts + 2.5, 0.1)
    assert caught.value.row == 1 and isinstance(caught.value, ValueError)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--batch", "0"], "--batch=0 must be >= 1"),
        (["--envs", "4", "--batch", "5"], "--batch=5 must be <= --envs=4"),
    ],
)
def test_the_reset_bench_refuses_bad_sizes_by_name(args: list[str], message: str) -> None:
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "bench" / "batched_resets.py"
    run = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and message in run.stderr, run.stderr
