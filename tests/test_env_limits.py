"""Issue 41, item 4: every size a user sets through the env keywords has an upper bound
(:data:`koopman_envs.params.LIMITS`), stated in the keyword table and refused with a
``ValueError`` naming the keyword, the value and the allowed range before anything of that size
is allocated. Before the bounds, ``comm.latency=10**9`` and ``actuation_delay=10**9`` died in a
numpy ``MemoryError`` and ``lidar.beams=10**7`` was accepted (18.7 s per step)."""

from __future__ import annotations

import json
import re
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import formation_v0
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.engine.keywords import ENV_KEYWORDS
from koopman_envs.fronts.gym_env import TargetReachingEnv
from koopman_envs.params import LIMITS, MAX_EPISODES_PER_CELL, MAX_ROBOTS
from koopman_envs.sim.maps.generator import RandomMapConfig

ENV = "KoopNav-TargetReaching-v0"
#: a refusal allocates nothing of the refused size: far below any of the sizes refused here
REFUSAL_PEAK_BYTES = 32 * 2**20

L = LIMITS
#: (keywords, the start of the message): each one past its bound, refused naming it and the range
TOO_LARGE: list[tuple[dict[str, Any], str]] = [
    ({"comm": {"latency": 10**9}}, rf"comm.latency=1000000000 must be an integer >= 0 and <= {L.latency}"),
    ({"comm": {"latency": L.latency + 1}}, rf"comm.latency={L.latency + 1} must be an integer >= 0 and <= {L.latency}"),
    ({"actuation_delay": 10**9}, rf"actuation_delay=1000000000 must be an integer >= 0 and <= {L.actuation_delay}"),
    ({"actuation_delay": L.actuation_delay + 1}, rf"actuation_delay={L.actuation_delay + 1} must be"),
    ({"sensing": "lidar", "lidar": {"beams": 10**7}}, rf"lidar.beams=10000000 must be an integer >= 1 and <= {L.lidar_beams}"),
    ({"sensing": "lidar", "lidar": {"range": 1e300}}, rf"lidar.range=1e\+300 must be a finite number > 0 <= {L.lidar_range}"),
    ({"movers": 10**9}, rf"movers=1000000000 must be an integer >= 0 and <= {L.movers}"),
    ({"movers": {"count": 10**6}}, rf"movers.count=1000000 must be an integer >= 0 and <= {L.movers}"),
    ({"movers": {"count": 2, "observed": 10**6}}, rf"movers.observed=1000000 must be an integer >= 0 and <= {L.movers}"),
    ({"movers": {"count": 2, "speed": 100.0}}, rf"movers.speed=100.0 must be a finite number >= 0 <= {L.mover_speed}"),
    ({"movers": {"count": 2, "pause": 1e300, "behaviour": "waypoints"}}, rf"movers.pause=1e\+300 must be a finite number >= 0 <= {L.mover_pause}"),
    ({"n_robots": 10**9}, rf"n_robots=1000000000 must be an integer >= 1 and <= {L.robots}"),
    ({"n_robots": 10**6, "map": "random"}, rf"n_robots=1000000 must be an integer >= 1 and <= {L.robots}"),
    ({"n_obstacle_obs": 10**9}, rf"n_obstacle_obs=1000000000 must be an integer >= 0 and <= {L.obstacle_obs}"),
    ({"max_episode_steps": 10**30}, rf"max_episode_steps={10**30} must be an integer >= 1 and <= {L.episode_steps}"),
    ({"map": "random", "random_map": {"n_obstacles": 10**9}}, rf"n_obstacles=1000000000 must be an integer >= 0 and <= {L.random_obstacles}"),
    ({"map": "random", "random_map": {"n_slip_zones": 10**9}}, rf"n_slip_zones=1000000000 must be an integer >= 0 and <= {L.slip_zones}"),
    ({"map": "random", "random_map": {"max_attempts": 10**12}}, rf"max_attempts=1000000000000 must be an integer >= 1 and <= {L.map_attempts}"),
    ({"pose_noise": 5e307}, rf"pose_noise=5e\+307 must be a finite number >= 0 <= {L.pose_noise}"),
    ({"pose_noise": {"drift_xy": 1e300}}, rf"pose_noise.drift_xy=1e\+300 must be a finite number >= 0 <= {L.pose_noise}"),
    ({"start_noise": 9e307}, rf"start_noise=9e\+307 must be a finite number >= 0 <= {L.start_noise}"),
    ({"slip": [0.0, 1e300, 0.1]}, rf"slip=\[0.0, 1e\+300, 0.1\] contains a lambda above {L.slip_lambda:g}"),
    ({"map": "random", "random_map": {"n_slip_zones": 1, "slip_zone_lambda": (0.1, 1e300)}}, rf"slip_zone_lambda=\(0.1, 1e\+300\) must be .*<= {L.slip_lambda:g}"),
]  # fmt: skip


def _peak_of(make: Callable[[], Any]) -> int:
    """The largest traced allocation total while ``make`` runs (numpy reports to tracemalloc)."""
    tracemalloc.start()
    try:
        make()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


@pytest.mark.parametrize("kwargs, message", TOO_LARGE, ids=[re.sub(r"\W", "", m[:24]) for _, m in TOO_LARGE])
def test_a_size_past_its_bound_is_refused_naming_it_before_any_allocation(
    kwargs: dict[str, Any], message: str
) -> None:
    def make() -> None:
        with pytest.raises(ValueError, match=message):
            TargetReachingEnv(**kwargs)

    assert _peak_of(make) < REFUSAL_PEAK_BYTES


@pytest.mark.parametrize(
    "make",
    [
        lambda: gym.make_vec(ENV, num_envs=2, max_episode_steps=10**30),
        lambda: formation_v0.parallel_env(max_cycles=10**30),
        lambda: formation_v0.parallel_env(max_episode_steps=L.episode_steps + 1),
    ],
    ids=["vector", "parallel max_cycles", "parallel max_episode_steps"],
)
def test_the_episode_limit_is_bounded_on_the_fronts_that_truncate(make: Callable[[], Any]) -> None:
    """The vector and PettingZoo fronts hand the limit to a compiled kernel (a 64-bit integer):
    10**30 was an OverflowError there."""
    with pytest.raises(
        ValueError,
        match=rf"(max_episode_steps|max_cycles)=\d+ must be an integer >= 1 and <= {L.episode_steps}",
    ):
        make()


def test_num_envs_is_bounded() -> None:
    def make() -> None:
        with pytest.raises(
            ValueError, match=rf"num_envs=1000000000 must be an integer >= 1 and <= {L.num_envs}"
        ):
            gym.make_vec(ENV, num_envs=10**9)

    assert _peak_of(make) < REFUSAL_PEAK_BYTES


def test_a_batch_whose_arrays_exceed_the_memory_bound_is_refused_before_allocating() -> None:
    """Each keyword within its bound, but their product over a large batch: the engine estimates
    its arrays from the settings first (hundreds of GiB here) and refuses, naming what to reduce."""

    def make() -> None:
        with pytest.raises(
            ValueError,
            match=r"num_envs=16384 environments .* need about \d+(\.\d)? GiB of arrays .*; the limit is 4 GiB",
        ):
            gym.make_vec(
                ENV, num_envs=L.num_envs, map="random", n_robots=64, sensing="lidar", lidar={"beams": 4096}
            )

    assert _peak_of(make) < REFUSAL_PEAK_BYTES


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"comm": {"latency": 7, "drop": 0.1}, "actuation_delay": 3, "pose_noise": 0.05},
        {"sensing": "lidar", "lidar": {"beams": 256, "noise": 0.01, "dropout": 0.1}},
        {"movers": {"count": 12, "behaviour": "waypoints"}, "map": "random", "n_robots": 8},
    ],
    ids=["default", "radio", "lidar", "movers"],
)
def test_the_memory_estimate_covers_what_the_engine_allocates(kwargs: dict[str, Any]) -> None:
    """The estimate the bound is checked on is not below what the engine allocates (nor absurdly above)."""
    from koopman_envs.engine.engine import engine_array_bytes

    config = EngineConfig.create("target_reaching", **kwargs)
    estimate = engine_array_bytes(config, 64)
    actual = _peak_of(lambda: NavigationEngine(config, num_envs=64))
    assert actual <= estimate <= 8 * actual + 2**20


def test_the_values_at_the_bounds_work() -> None:
    env = TargetReachingEnv(
        comm={"latency": L.latency},
        actuation_delay=L.actuation_delay,
        sensing="lidar",
        lidar={"beams": L.lidar_beams, "range": L.lidar_range},
        n_obstacle_obs=L.obstacle_obs,
        max_episode_steps=L.episode_steps,
        movers={"count": 2, "speed": L.mover_speed, "pause": L.mover_pause, "behaviour": "waypoints", "observed": L.movers},
    )  # fmt: skip
    observation, _ = env.reset(seed=0)
    for _ in range(3):
        observation, *_ = env.step(np.zeros(6))
    assert np.isfinite(observation).all()
    config = RandomMapConfig(
        n_obstacles=L.random_obstacles, n_slip_zones=L.slip_zones, max_attempts=L.map_attempts
    )
    assert config.n_obstacles == L.random_obstacles
    assert (
        EngineConfig.create(
            "formation", map="random", n_robots=L.robots, random_map={"spacing": 0.5}
        ).n_robots
        == L.robots
    )


def test_the_bounds_are_stated_in_the_keyword_table_and_the_docs() -> None:
    """Each bounded keyword's row (which generates the env docstrings) and docs/environments.md
    give the bound."""
    docs = {row.name: row.doc for row in ENV_KEYWORDS}
    stated = {
        "n_robots": L.robots,
        "n_obstacle_obs": L.obstacle_obs,
        "max_episode_steps": L.episode_steps,
        "max_cycles": L.episode_steps,
        "actuation_delay": L.actuation_delay,
        "comm": L.latency,
        "lidar": L.lidar_beams,
        "movers": L.movers,
        "random_map": L.random_obstacles,
    }
    for name, bound in stated.items():
        assert f"{bound:g}" in docs[name] or f"{bound:_}" in docs[name], (name, docs[name])
    assert f"{L.mover_speed:g} m/s" in docs["movers"] and f"{L.lidar_range:g}" in docs["lidar"]
    page = (Path(__file__).parents[1] / "docs" / "environments.md").read_text()
    assert "koopman_envs.params.LIMITS" in page
    for bound in (L.robots, L.latency, L.lidar_beams, L.movers, L.engine_bytes // 2**30):
        assert str(bound) in page


def test_the_evaluator_constants() -> None:
    assert MAX_EPISODES_PER_CELL == L.episodes_per_cell == 10_000
    assert MAX_ROBOTS == L.robots


def test_a_slip_zone_of_a_map_file_is_bounded(tmp_path: Path) -> None:
    path = tmp_path / "zoned.json"
    spec = {
        "obstacles": [],
        "starts": [[0, 0, 0], [0, 1, 0], [0, 2, 0]],
        "targets": [[4, 0, 0], [4, 1, 0], [4, 2, 0]],
        "slip_zones": [{"circle": [1, 1, 0.5], "lambda": 1e300}],
    }
    path.write_text(json.dumps(spec))
    with pytest.raises(
        ValueError, match=rf"lambda=1e\+300 must be a finite number >= 0 <= {L.slip_lambda:g}"
    ):
        TargetReachingEnv(map=str(path))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"sensing": "lidar", "lidar": {"fov": 5e-324, "beams": 64}}, r"lidar.fov=5e-324 is narrower than 0.001 rad"),
        ({"map": "random", "random_map": {"travel": (5e-324, 5e-324)}}, r"random_map: travel=\(5e-324, 5e-324\) must have low >= 0.01"),
        ({"movers": {"count": 3, "radius": 1e6}}, r"movers: a mover of radius 1000000.0 m \(movers.radius\) does not fit the arena"),
        ({"map": "random", "random_map": {"border": 1e6}}, r"random_map border=1e\+06 m and robot_radius=0.2 m leave no room"),
        ({"map": "random", "robot_radius": 1e6}, r"random_map border=1 m and robot_radius=1e\+06 m leave no room"),
        ({"map": "random", "random_map": {"obstacle_radius": (1e3, 1e3), "max_attempts": 50}}, r"random_map: no valid random map in max_attempts=50"),
        ({"start_noise": 20.0}, r"start_noise=20.0: no valid start poses on map 'map1'"),
    ],
)  # fmt: skip
def test_extreme_values_found_by_the_property_test_are_refused_by_name(
    kwargs: dict[str, Any], message: str
) -> None:
    """tests/test_keyword_properties.py found these: a ZeroDivisionError in the beam caster, NaN
    obstacles, NaN mover positions (a NaN candidate passed every clearance test), numpy's "high -
    low < 0", a RuntimeError from the random maps and from the start draws; each is a
    ``ValueError`` naming the keyword now (at reset for the last ones: they depend on the draws)."""
    with pytest.raises(ValueError, match=message):
        env = TargetReachingEnv(**kwargs)
        env.reset(seed=0)
        env.step(np.zeros(6))


def test_a_map_file_is_checked_before_it_is_read_whole(tmp_path: Path) -> None:
    """``map="/dev/zero"`` read forever (json.load of an endless file); a huge file was read whole."""
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:  # sparse: no disk used
        fh.truncate(L.map_file_bytes + 1)
    latin = tmp_path / "latin.json"
    latin.write_bytes(b'{"obstacles": [], "name": "\xe9"}')
    cases = [
        ("/dev/zero", r"map file '/dev/zero' cannot be read: it is a character device, not a regular file"),
        (str(tmp_path), r"it is a directory, not a regular file"),
        (
            str(big),
            rf"map file .*big.json' cannot be read: it is {L.map_file_bytes + 1} bytes .*; at most "
            rf"{L.map_file_bytes} bytes .* are allowed",
        ),
        (
            str(latin),
            r"map file .*latin.json' is not UTF-8 text \(byte 27 is b'\\xe9'\); expected a JSON map",
        ),
    ]
    for path, message in cases:

        def make(path: str = path, message: str = message) -> None:
            with pytest.raises(ValueError, match=message):
                TargetReachingEnv(map=path)

        assert _peak_of(make) < REFUSAL_PEAK_BYTES
