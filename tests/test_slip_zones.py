"""Slip zones: the slip they cause inside and outside, the overlap rule, the unchanged generator
stream, map files, random maps with zones, the shipped maps 5 and 6, and rendering."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.episodes.demo import naive_command
from koopman_envs.params import PARAMS
from koopman_envs.sim.maps.generator import RandomMapConfig, generate_random_map
from koopman_envs.sim.maps.map_spec import MapSpec, load_map
from koopman_envs.sim.slip.zones import SlipZone, ZoneTable
from koopman_envs.tasks.base import task_for_env

TR = "KoopNav-TargetReaching-v0"
FO = "KoopNav-Formation-v0"
SPIN = np.array([0.0, np.pi / 4] * 3)  # turn in place: the robots stay where they are


def parked(slip_zones=()) -> MapSpec:
    """Robot 0 inside a replace circle, robot 1 outside every zone, robot 2 inside an add rect."""
    poses = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [-3.0, 0.0, 0.0]]
    targets = [[0.0, 2.0, 0.0], [3.0, 2.0, 0.0], [-3.0, 2.0, 0.0]]
    return MapSpec("parked", obstacles=[], starts=poses, targets=targets, slip_zones=slip_zones)


ZONES = [
    {"circle": [0.0, 0.0, 1.0], "lambda": 0.4},
    {"rect": [-4.0, -1.0, -2.0, 1.0], "lambda": [0.3, 0.3, 0.3], "mode": "add"},
]


def turn_slip(env: gym.Env, steps: int) -> np.ndarray:
    """Realized turn slip gamma of every robot and period, (steps, N), from the heading increments
    of robots turning in place at omega_max (theta' = omega (1 + gamma), exact in RK4)."""
    _, info = env.reset(seed=0)
    gammas = []
    for _ in range(steps):
        before = info["poses"][:, 2]
        _, _, _, _, info = env.step(SPIN)
        turned = (info["poses"][:, 2] - before + np.pi) % (2 * np.pi) - np.pi
        gammas.append(turned / (PARAMS.omega_max * PARAMS.dt) - 1.0)
    return np.array(gammas)


def test_realized_slip_follows_the_zones_inside_and_not_outside() -> None:
    """Sample means of the realized turn slip against lambda: 0.4 in the replace zone, the base
    level 0.1 outside, base 0.2 + 0.3 in the add zone (4000 periods: standard error < 1.2%)."""
    env = gym.make(TR, map=parked(ZONES), slip=[0.0, 0.1, 0.2], max_episode_steps=10_000)
    gamma = turn_slip(env, 4000)
    expected = np.array([0.4, 0.1, 0.5])
    np.testing.assert_allclose(env.unwrapped.lambdas, expected)
    np.testing.assert_allclose(gamma.mean(axis=0), expected, rtol=0.06)
    assert (gamma > -1e-9).all()  # one-sided slip


def test_a_zone_scales_the_same_draws() -> None:
    """Inside a replace zone of lambda 0.4 a robot moves bit for bit as with slip 0.4; a robot
    outside every zone as on the map without zones; and the generator ends in the same state."""
    zoned = gym.make(TR, map=parked(ZONES), slip=[0.0, 0.1, 0.2])
    plain = gym.make(TR, map=parked(), slip=[0.4, 0.1, 0.5])
    bare = gym.make(TR, map=parked(), slip=[0.0, 0.1, 0.2])
    for env in (zoned, plain, bare):
        env.reset(seed=3)
    commands = np.random.default_rng(1).uniform(-1, 1, (30, 6)) * 0.1  # small: nobody leaves its zone
    for command in commands:
        a, b, c = (env.step(command)[4]["poses"] for env in (zoned, plain, bare))
        np.testing.assert_array_equal(a, b)  # every robot: its zone's lambda is plain's setting
        np.testing.assert_array_equal(a[1], c[1])  # robot 1 is outside every zone
    states = [env.unwrapped.np_random.bit_generator.state for env in (zoned, plain, bare)]
    assert states[0] == states[1] == states[2]


def test_overlapping_zones_last_replace_wins_and_adds_sum() -> None:
    zones = [
        SlipZone("circle", (0.0, 0.0, 2.0), 0.1),
        SlipZone("rect", (-1.0, -1.0, 1.0, 1.0), (0.3, 0.4), "add"),
        SlipZone("circle", (0.5, 0.0, 1.0), 0.2),
        SlipZone("rect", (-3.0, -3.0, 3.0, 3.0), 0.05, "add"),
    ]
    table = ZoneTable(1, len(zones), 2)
    table.set_env(0, zones)
    base = np.array([[0.7, 0.8]])

    def means(x: float, y: float) -> np.ndarray:
        state = np.array([[[x, x], [y, y], [0.0, 0.0]]])
        return table.slip_means(state, base, np.empty((1, 2)))[0]

    np.testing.assert_allclose(means(1.0, 0.0), [0.2 + 0.3 + 0.05, 0.2 + 0.4 + 0.05])  # in all four
    np.testing.assert_allclose(means(-0.8, 0.0), [0.1 + 0.3 + 0.05, 0.1 + 0.4 + 0.05])  # not in the third
    np.testing.assert_allclose(means(0.0, 1.5), [0.1 + 0.05, 0.1 + 0.05])  # first and last
    np.testing.assert_allclose(means(2.5, 2.5), [0.7 + 0.05, 0.8 + 0.05])  # base + the large add
    np.testing.assert_array_equal(means(5.0, 5.0), base[0])  # outside: the base, exactly
    assert zones[0].contains(2.0, 0.0) and zones[1].contains(1.0, -1.0)  # boundaries are inside


def test_zone_mean_is_taken_where_the_period_starts() -> None:
    """A robot driving out of a zone slips with the zone's lambda in the period it leaves it, and
    with its base level from the next period on."""
    zones = [{"circle": [0, 0, 1.0], "lambda": 0.4}]
    starts, targets = [[0.96, 0.0, 0.0]], [[4.0, 0.0, 0.0]]
    zoned = gym.make(TR, map=MapSpec("exit", [], starts, targets, slip_zones=zones), n_robots=1)
    inside = gym.make(TR, map=MapSpec("exit", [], starts, targets), n_robots=1, slip=[0.4])
    outside = gym.make(TR, map=MapSpec("exit", [], starts, targets), n_robots=1, slip=[0.0])
    for env in (zoned, inside, outside):
        env.reset(seed=0)
    assert zoned.unwrapped.lambdas[0] == 0.4
    command = np.array([0.6, 0.1])
    first = [env.step(command)[4]["poses"] for env in (zoned, inside, outside)]
    assert first[0][0, 0] > 1.0  # started inside, ended outside
    np.testing.assert_array_equal(first[0], first[1])
    assert zoned.unwrapped.lambdas[0] == 0.0
    inside.unwrapped.engine.poses = outside.unwrapped.engine.poses = zoned.unwrapped.engine.poses
    second = [env.step(command)[4]["poses"] for env in (zoned, inside, outside)]
    np.testing.assert_array_equal(second[0], second[2])
    assert not np.array_equal(second[0], second[1])


def test_map_file_with_zones_round_trips(tmp_path) -> None:
    path = tmp_path / "zoned.json"
    load_map("map5").save(path)
    data = json.loads(path.read_text())
    assert data["slip_zones"] == [{"rect": [-0.7, -2.2, 0.8, 2.2], "lambda": 0.4, "mode": "replace"}]
    loaded = load_map(str(path))
    assert [z.to_dict() for z in loaded.slip_zones] == data["slip_zones"]
    zones = [{"circle": [1, 0, 0.5], "lambda": [0.1, 0.2], "mode": "add"}]
    starts, targets = [[0, 0, 0], [0, 1, 0]], [[3, 0, 0], [3, 1, 0]]
    spec = MapSpec.from_dict({"obstacles": [], "starts": starts, "targets": targets, "slip_zones": zones})
    assert spec.slip_zones[0].lam == (0.1, 0.2) and spec.slip_zones[0].per_robot
    np.testing.assert_array_equal(spec.slip_zones[0].lambdas_for(1), [0.1])


# ------------------------------------------------------------------ random maps
def test_random_maps_with_zones_keep_the_layout_and_are_reproducible() -> None:
    """Zone draws come after the layout's: the same seed gives the same obstacles, starts and
    targets with and without zones, and the same zones again."""
    config = RandomMapConfig(n_slip_zones=2)
    for seed in range(30):
        plain = generate_random_map(np.random.default_rng(seed), 3)
        zoned = generate_random_map(np.random.default_rng(seed), 3, config)
        again = generate_random_map(np.random.default_rng(seed), 3, config)
        assert plain.slip_zones == () and len(zoned.slip_zones) == 2
        for key in ("obstacles", "starts", "targets"):
            np.testing.assert_array_equal(getattr(zoned, key), getattr(plain, key))
        assert [z.to_dict() for z in zoned.slip_zones] == [z.to_dict() for z in again.slip_zones]
        for zone in zoned.slip_zones:
            assert zone.shape == "circle" and zone.mode == "replace"
            assert config.slip_zone_radius[0] <= zone.bounds[2] <= config.slip_zone_radius[1]
            assert config.slip_zone_lambda[0] <= zone.lam <= config.slip_zone_lambda[1]
        # centred in the corridor, between 25% and 75% of the way from the starts to the targets
        a, b = zoned.starts[:, :2].mean(axis=0), zoned.targets[:, :2].mean(axis=0)
        along = [(np.array(z.bounds[:2]) - a) @ (b - a) / ((b - a) @ (b - a)) for z in zoned.slip_zones]
        assert all(0.25 - 1e-9 <= t <= 0.75 + 1e-9 for t in along)


def test_random_map_zones_reach_the_env_and_change_per_reset() -> None:
    env = gym.make(FO, map="random", random_map={"n_slip_zones": 3, "slip_zone_mode": "add"})
    env.reset(seed=5)
    first = env.unwrapped.engine.maps[0].slip_zones
    env.reset()
    second = env.unwrapped.engine.maps[0].slip_zones
    assert len(first) == len(second) == 3 and first[0].to_dict() != second[0].to_dict()
    assert all(z.mode == "add" for z in first)


# ------------------------------------------------------------------ shipped maps 5 and 6
def _drive(spec: MapSpec, env_id: str, routes: list[list[tuple[float, float]]]) -> tuple[dict, np.ndarray]:
    """Every robot follows its waypoints with the demo's naive rule; returns the last info and
    whether each robot ever stood where a slip zone raises its mean (base level nominal)."""
    env = gym.make(env_id, map=spec, n_robots=spec.max_robots, max_episode_steps=600)
    _, info = env.reset(seed=0)
    reached = [0] * len(routes)
    slipped = np.zeros(len(routes), dtype=bool)
    for _ in range(600):
        goals = np.zeros((len(routes), 3))
        for i, route in enumerate(routes):
            if reached[i] < len(route) - 1 and np.hypot(*(info["poses"][i, :2] - route[reached[i]])) < 0.3:
                reached[i] += 1
            goals[i, :2] = route[reached[i]]
        slipped |= env.unwrapped.lambdas > 0
        _, _, terminated, truncated, info = env.step(naive_command(info["poses"], goals).reshape(-1))
        if terminated or truncated:
            break
    return info, slipped


DETOURS = {  # per robot: waypoints around the zone (then the target), found by hand
    "map5": [[(-1.0, -2.8), (1.1, -2.8)], [(-1.0, 2.8), (1.1, 2.8), (2.6, 1.9)], [(-1.0, 2.8), (1.1, 2.8)]],
    "map6": [
        [(-3.0, 3.3), (-1.0, 3.3), (1.0, 3.0)],
        [(-3.8, 3.3), (-1.0, 3.3), (1.0, 3.0)],
        [(-3.8, -2.1), (-1.0, -2.2), (0.6, -2.3), (1.9, -1.2)],
    ],
}


@pytest.mark.parametrize("name, env_id", [("map5", TR), ("map6", FO)])
def test_the_zone_lies_across_the_straight_routes_and_a_detour_exists(name: str, env_id: str) -> None:
    spec = load_map(name)
    assert len(spec.slip_zones) == 1 and 0.3 <= spec.slip_zones[0].lam <= 0.5
    assert spec.slip_zones[0].mode == "replace"
    assert name in task_for_env(env_id).extra_maps and name not in task_for_env(env_id).paper_maps
    zone = spec.slip_zones[0]
    for start, target in zip(spec.starts[:, :2], spec.targets[:, :2]):  # every straight segment crosses it
        assert any(zone.contains(*(start + t * (target - start))) for t in np.linspace(0, 1, 200))
    # driven straight (obstacles taken away), every robot passes through the zone
    open_field = MapSpec(name, [], spec.starts, spec.targets, slip_zones=spec.slip_zones)
    info, slipped = _drive(open_field, env_id, [[tuple(t)] for t in spec.targets[:, :2]])
    assert info["is_success"] and slipped.all()
    # around the zone, every robot reaches its target on the real map without touching anything
    for i, waypoints in enumerate(DETOURS[name]):
        alone = MapSpec(
            name, spec.obstacles, spec.starts[i : i + 1], spec.targets[i : i + 1], slip_zones=spec.slip_zones
        )
        info, slipped = _drive(alone, env_id, [[*waypoints, tuple(spec.targets[i, :2])]])
        assert info["is_success"] and not info["collision"] and not slipped.any(), (name, i)


def test_map6_has_the_paper_formation_offsets() -> None:
    np.testing.assert_allclose(load_map("map6").formation_offsets, load_map("map3").formation_offsets)


# ------------------------------------------------------------------ rendering
def test_zones_are_shaded_beneath_the_obstacles_and_blitting_matches_a_full_redraw() -> None:
    from koopman_envs.rendering.renderer import Renderer, frame_title

    env = gym.make(TR, map="map5", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    spec = load_map("map5")
    without = MapSpec("map5", spec.obstacles, spec.starts, spec.targets)
    plain = gym.make(TR, map=without, render_mode="rgb_array")
    plain.reset(seed=0)
    difference = np.abs(frame.astype(int) - plain.render().astype(int)).sum(axis=-1) > 30
    assert difference.mean() > 0.02  # the band is drawn (the view also grows to show it)
    base = env.unwrapped
    for step in range(3):
        args = (base.scenario, np.asarray(base._trail), frame_title(base.config), step * 0.1)
        fast = Renderer().draw(*args, slip_zones=base.engine.maps[0].slip_zones)
        full = Renderer(blit=False).draw(*args, slip_zones=base.engine.maps[0].slip_zones)
        assert np.abs(fast.astype(int) - full.astype(int)).mean() < 0.1
        env.step(np.array([0.6, 0.0] * 3))
