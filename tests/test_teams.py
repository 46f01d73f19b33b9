"""Teams of many robots on the env side: formation shapes through every front, random layouts of
6-16 robots, the team size a map holds, and the six-robot maps map7 / map8."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

import koopman_envs
from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.params import PARAMS
from koopman_envs.sim.formations import FORMATION_SHAPES, formation_offsets_for
from koopman_envs.sim.maps.generator import RandomMapConfig, generate_random_map
from koopman_envs.sim.maps.map_spec import load_map

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
SPACING = PARAMS.formation_spacing


def shape_offsets(poses: np.ndarray, shape: str) -> tuple[np.ndarray, np.ndarray]:
    """(positions relative to robot 0, the shape's offsets for robot 0's heading)."""
    expected = formation_offsets_for(shape, len(poses), SPACING, float(poses[0, 2]))
    return poses[:, :2] - poses[0, :2], expected


# ------------------------------------------------------------------ shapes through the env
@pytest.mark.parametrize("shape", FORMATION_SHAPES)
@pytest.mark.parametrize("n", [1, 2, 3, 6, 10])
def test_a_shape_sets_the_targets_and_starts_of_random_maps(shape: str, n: int) -> None:
    env = gym.make(FO, map="random", n_robots=n, formation=shape)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        relative, expected = shape_offsets(info["targets"], shape)
        np.testing.assert_allclose(relative, expected, atol=1e-9)
        np.testing.assert_array_equal(info["targets"][:, 2], info["targets"][0, 2])  # one heading
        scenario = env.unwrapped.scenario
        np.testing.assert_allclose(scenario.formation_offsets, expected, atol=1e-9)
        # the team starts in the same shape, travelling along the targets' heading
        np.testing.assert_allclose(scenario.starts[:, :2] - scenario.starts[0, :2], expected, atol=1e-9)


def test_target_reaching_random_maps_take_the_shape_too() -> None:
    env = gym.make(TR, map="random", n_robots=6, formation="line")
    _, info = env.reset(seed=5)
    relative, expected = shape_offsets(info["targets"], "line")
    np.testing.assert_allclose(relative, expected, atol=1e-9)


@pytest.mark.parametrize("shape", ["line", "column", "circle", "grid"])
def test_a_shape_on_a_formation_map_keeps_the_leader_target_and_the_starts(shape: str) -> None:
    spec = load_map("map3")
    env = gym.make(FO, map="map3", formation=shape)
    _, info = env.reset(seed=0)
    np.testing.assert_array_equal(info["targets"][0], spec.targets[0])
    relative, expected = shape_offsets(info["targets"], shape)
    np.testing.assert_allclose(relative, expected, atol=1e-12)
    np.testing.assert_array_equal(info["poses"], spec.starts)
    # map8 holds six robots: a shape of 6 around its leader's target
    env = gym.make(FO, map="map8", n_robots=6, formation="circle")
    _, info = env.reset(seed=0)
    relative, expected = shape_offsets(info["targets"], "circle")
    np.testing.assert_allclose(relative, expected, atol=1e-12)


@pytest.mark.parametrize(
    "env_id, map_name", [(FO, "map3"), (FO, "map4"), (FO, "map6"), (TR, "map1"), (FO, "random")]
)
def test_no_formation_keeps_every_map_and_seed_as_before(env_id: str, map_name: str) -> None:
    """formation=None is the default: the maps' own targets (the paper's offsets), and on random
    maps the wedge, drawn exactly as RandomMapConfig() draws it."""
    plain, default = gym.make(env_id, map=map_name), gym.make(env_id, map=map_name, formation=None)
    for seed in (0, 1):
        a, b = plain.reset(seed=seed)[1], default.reset(seed=seed)[1]
        np.testing.assert_array_equal(a["targets"], b["targets"])
        if map_name == "random":
            spec = generate_random_map(np.random.default_rng(seed), 3, RandomMapConfig())
            np.testing.assert_array_equal(a["targets"], spec.targets)
            np.testing.assert_array_equal(a["poses"], spec.starts)
            wedge = gym.make(env_id, map="random", formation="wedge").reset(seed=seed)[1]
            np.testing.assert_array_equal(wedge["targets"], a["targets"])
        else:
            np.testing.assert_array_equal(a["targets"], load_map(map_name).targets)


@pytest.mark.parametrize("front", ["gym", "vector", "parallel"])
def test_the_formation_keyword_reaches_every_front(front: str) -> None:
    kwargs = {"map": "random", "n_robots": 6, "formation": "circle"}
    if front == "gym":
        env = gym.make(FO, **kwargs)
        targets = env.reset(seed=2)[1]["targets"]
    elif front == "vector":
        env = gym.make_vec(FO, num_envs=2, **kwargs)
        targets = env.reset(seed=2)[1]["targets"][1]
    else:
        env = formation_v0.parallel_env(**kwargs)
        targets = env.reset(seed=2)[1]["robot_0"]["targets"]
    relative, expected = shape_offsets(targets, "circle")
    np.testing.assert_allclose(relative, expected, atol=1e-9)


# ------------------------------------------------------------------ random teams start clear
@pytest.mark.parametrize("shape", FORMATION_SHAPES)
@pytest.mark.parametrize("n", [6, 10, 16])
def test_random_teams_start_and_end_clear_for_200_seeds(n: int, shape: str) -> None:
    env = gym.make(FO, map="random", n_robots=n, formation=shape)
    radius = PARAMS.robot_radius
    x0, x1, y0, y1 = PARAMS.workspace
    for seed in range(200):
        _, info = env.reset(seed=seed)
        scenario = env.unwrapped.scenario
        for poses in (scenario.starts, scenario.targets):
            xy = poses[:, :2]
            assert np.all((xy - radius >= [x0, y0]) & (xy + radius <= [x1, y1])), seed
            gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
            np.fill_diagonal(gaps, np.inf)
            assert gaps.min() >= 2 * radius, (seed, gaps.min())
            obstacles = scenario.obstacles
            clear = np.linalg.norm(xy[:, None] - obstacles[None, :, :2], axis=-1) - obstacles[:, 2] - radius
            assert clear.min() >= RandomMapConfig.clearance - 1e-9, (seed, clear.min())
        _, _, terminated, _, info = env.step(np.zeros(2 * n))
        assert not info["collision"] and not terminated, (seed, info["collision_code"])


# ------------------------------------------------------------------ team size and the maps
def test_the_six_robot_maps_hold_six_and_a_smaller_team_takes_the_first_robots() -> None:
    for name, env_id in (("map7", TR), ("map8", FO)):
        spec = load_map(name)
        assert spec.max_robots == 6
        _, info = gym.make(env_id, map=name, n_robots=6).reset(seed=0)
        np.testing.assert_array_equal(info["poses"], spec.starts)
        _, info = gym.make(env_id, map=name, n_robots=4).reset(seed=0)
        np.testing.assert_array_equal(info["poses"], spec.starts[:4])
        np.testing.assert_array_equal(info["targets"], spec.targets[:4])
    # map8's offsets are the 2 x 3 grid of formations.py with the default spacing, heading east
    np.testing.assert_allclose(
        load_map("map8").formation_offsets, formation_offsets_for("grid", 6, SPACING, 0.0), atol=1e-12
    )


@pytest.mark.parametrize("env_id, map_name", [(TR, "map7"), (FO, "map8")])
def test_check_env_on_the_six_robot_maps(env_id: str, map_name: str) -> None:
    for slip in ("high", "drift"):
        env = gym.make(env_id, map=map_name, n_robots=6, slip=slip)
        check_env(env.unwrapped, skip_render_check=True)
    env = gym.make(env_id, map=map_name, n_robots=6, render_mode="rgb_array")
    check_env(env.unwrapped)


@pytest.mark.parametrize("module, map_name", [(target_reaching_v0, "map7"), (formation_v0, "map8")])
def test_parallel_api_on_the_six_robot_maps(module, map_name: str) -> None:
    parallel_api_test(module.parallel_env(map=map_name, n_robots=6, slip="high"), num_cycles=300)
    env = module.parallel_env(map=map_name, n_robots=6)
    assert env.possible_agents == [f"robot_{i}" for i in range(6)]


def test_check_env_and_parallel_api_with_a_shape() -> None:
    check_env(gym.make(FO, map="random", n_robots=10, formation="grid").unwrapped, skip_render_check=True)
    parallel_api_test(
        target_reaching_v0.parallel_env(map="random", n_robots=6, formation="column"), num_cycles=100
    )


def _free_path(spec, start: np.ndarray, target: np.ndarray, radius: float, cell: float = 0.05) -> bool:
    """Whether a disc of ``radius`` can move from ``start`` to ``target`` among the obstacles
    alone (flood fill on a grid of the free space, obstacles grown by the radius and a cell)."""
    x0, x1, y0, y1 = PARAMS.workspace
    xs = np.arange(x0 + radius, x1 - radius + 1e-9, cell)
    ys = np.arange(y0 + radius, y1 - radius + 1e-9, cell)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    free = np.ones(gx.shape, dtype=bool)
    for ox, oy, r in spec.obstacles:
        free &= np.hypot(gx - ox, gy - oy) > r + radius + cell

    def index(point: np.ndarray) -> tuple[int, int]:
        return round((point[0] - xs[0]) / cell), round((point[1] - ys[0]) / cell)

    reached = np.zeros_like(free)
    reached[index(start)] = free[index(start)]
    while True:
        grown = reached.copy()
        grown[1:] |= reached[:-1]
        grown[:-1] |= reached[1:]
        grown[:, 1:] |= reached[:, :-1]
        grown[:, :-1] |= reached[:, 1:]
        grown &= free
        if grown[index(target)]:
            return True
        if (grown == reached).all():
            return False
        reached = grown


@pytest.mark.parametrize("name", koopman_envs.BUILTIN_MAPS)
def test_every_robot_of_a_shipped_map_has_a_path_to_its_target(name: str) -> None:
    """No obstacle closes a robot's way: among the obstacles alone, a free path exists from every
    start to its target (with a cell of margin)."""
    spec = load_map(name)
    for i, (start, target) in enumerate(zip(spec.starts, spec.targets)):
        assert _free_path(spec, start[:2], target[:2], PARAMS.robot_radius), (name, i)


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "env_id, kwargs, message",
    [
        (
            FO,
            {"formation": "diamond"},
            r"formation='diamond' is not one of \['wedge', 'line', 'column', 'circle', 'grid'\] or None",
        ),
        (FO, {"formation": 3}, r"formation=3 is not one of \['wedge'"),
        (
            TR,
            {"map": "map1", "formation": "line"},
            (
                r"formation='line' applies to formation maps \(KoopNav-Formation-v0\) or to map='random'; "
                r"map 'map1' of target reaching keeps its own targets"
            ),
        ),
        (
            TR,
            {"map": "map7", "n_robots": 6, "formation": "circle"},
            r"formation='circle' applies to formation maps",
        ),
        (
            FO,
            {"map": "map4", "formation": "wedge"},
            (
                r"formation='wedge' does not fit map 'map4' with n_robots=3 \(spacing 0.9 m\): target of robot 1 at "
                r"\[.*\] overlaps obstacle 3 \[0.2, 1.2, 0.3\]; allowed: .*try another of \['wedge'"
            ),
        ),
        (
            TR,
            {"n_robots": 4},
            (
                r"n_robots=4 is larger than map 'map1' supports \(1..3\): it holds 3 robots; allowed: n_robots <= 3, "
                r"or map='random' \(any team size\) or a map with more starts"
            ),
        ),
        (
            FO,
            {"map": "map8", "n_robots": 7},
            r"n_robots=7 is larger than map 'map8' supports \(1..6\): it holds 6",
        ),
        (
            FO,
            {"map": "random", "formation": "line", "random_map": {"formation": "grid"}},
            r"formation='line' and random_map's formation='grid' differ",
        ),
        (
            FO,
            {"map": "random", "random_map": {"formation": "ring"}},
            r"formation='ring' is not one of \['auto', 'wedge'",
        ),
    ],
)
def test_bad_team_input(env_id: str, kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make(env_id, **kwargs)
    with pytest.raises(ValueError, match=message):
        gym.make_vec(env_id, num_envs=2, **kwargs)
    module = formation_v0 if env_id == FO else target_reaching_v0
    with pytest.raises(ValueError, match=message):
        module.parallel_env(**kwargs)
