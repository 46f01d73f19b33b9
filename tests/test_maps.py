"""Shipped maps, map files and the seeded random-map generator."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import target_reaching_v0
from koopman_envs.sim.maps.generator import RandomMapConfig, generate_random_map
from koopman_envs.sim.maps.map_spec import BUILTIN_MAPS, MapSpec, load_map


@pytest.mark.parametrize("name", BUILTIN_MAPS)
def test_shipped_maps_are_valid_and_not_trivial(name: str) -> None:
    spec = load_map(name)
    spec.validate(spec.max_robots)
    travel = np.linalg.norm(spec.targets[:, :2] - spec.starts[:, :2], axis=1)
    assert np.all((travel > 3.0) & (travel < 8.0))  # paths of a few metres
    # at least one obstacle blocks some robot's straight path from start to target
    blocked = 0
    for start, target in zip(spec.starts[:, :2], spec.targets[:, :2]):
        seg = target - start
        t = np.clip(((spec.obstacles[:, :2] - start) @ seg) / (seg @ seg), 0, 1)
        closest = start + t[:, None] * seg
        gap = np.linalg.norm(spec.obstacles[:, :2] - closest, axis=1) - spec.obstacles[:, 2] - 0.2
        blocked += int((gap < 0).any())
    assert blocked >= 2


def test_formation_maps_have_equal_travel() -> None:
    for name in ("map3", "map4", "map6", "map8"):
        spec = load_map(name)
        travel = spec.targets[:, :2] - spec.starts[:, :2]
        np.testing.assert_allclose(travel, np.broadcast_to(travel[0], travel.shape), atol=1e-9)


def test_the_task_table_lists_every_shipped_map_once() -> None:
    """map5 to map8 belong to their tasks but not to the paper's map lists (SPEC section 5)."""
    from koopman_envs.tasks.base import TASKS, env_id_for_map

    listed = [name for spec in TASKS.values() for name in spec.maps]
    assert sorted(listed) == sorted(BUILTIN_MAPS)
    assert TASKS["target_reaching"].paper_maps == ("map1", "map2")
    assert TASKS["formation"].paper_maps == ("map3", "map4")
    assert env_id_for_map("map5") == "KoopNav-TargetReaching-v0"
    assert env_id_for_map("map6") == "KoopNav-Formation-v0"
    assert env_id_for_map("map7") == "KoopNav-TargetReaching-v0"
    assert env_id_for_map("map8") == "KoopNav-Formation-v0"


def test_map3_reuses_map1_obstacles() -> None:
    np.testing.assert_array_equal(load_map("map3").obstacles, load_map("map1").obstacles)


def test_random_maps_are_valid_for_1000_seeds() -> None:
    cfg = RandomMapConfig()
    for seed in range(1000):
        spec = generate_random_map(np.random.default_rng(seed), 3)
        spec.validate(3)
        poses = np.vstack([spec.starts[:, :2], spec.targets[:, :2]])
        obs = spec.obstacles
        assert obs.shape == (cfg.n_obstacles, 3)
        gaps = np.linalg.norm(poses[:, None] - obs[None, :, :2], axis=-1) - obs[:, 2] - 0.2
        assert gaps.min() >= cfg.clearance - 1e-12
        pair = (
            np.linalg.norm(obs[:, None, :2] - obs[None, :, :2], axis=-1) - obs[:, None, 2] - obs[None, :, 2]
        )
        np.fill_diagonal(pair, np.inf)
        assert pair.min() >= cfg.gap - 1e-12
        travel = np.linalg.norm(spec.targets[0, :2] - spec.starts[0, :2])
        assert cfg.travel[0] <= travel <= cfg.travel[1]


@pytest.mark.parametrize("n_robots", [1, 2, 5, 8])
def test_random_maps_scale_to_other_team_sizes(n_robots: int) -> None:
    for seed in range(50):
        generate_random_map(np.random.default_rng(seed), n_robots).validate(n_robots)


def test_random_map_is_reproducible_and_new_per_reset() -> None:
    env = gym.make("KoopNav-Formation-v0", map="random")
    env.reset(seed=4)
    first = env.unwrapped.scenario
    env.reset()
    second = env.unwrapped.scenario
    env.reset(seed=4)
    again = env.unwrapped.scenario
    np.testing.assert_array_equal(first.obstacles, again.obstacles)
    np.testing.assert_array_equal(first.starts, again.starts)
    assert not np.array_equal(first.obstacles, second.obstacles)


@pytest.mark.parametrize("front", ["gym", "vector", "parallel"])
def test_random_map_settings_reach_every_front(front: str) -> None:
    settings = {"n_obstacles": 2, "travel": (1.0, 1.5)}
    if front == "gym":
        env = gym.make("KoopNav-TargetReaching-v0", map="random", random_map=settings)
        env.reset(seed=0)
        scenario = env.unwrapped.scenario
    elif front == "vector":
        env = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, map="random", random_map=settings)
        env.reset(seed=0)
        scenario = env.unwrapped.scenario(1)
    else:
        env = target_reaching_v0.parallel_env(map="random", random_map=settings)
        env.reset(seed=0)
        scenario = env.unwrapped.scenario
    assert scenario.obstacles.shape == (2, 3)
    travel = np.hypot(*(scenario.targets[0, :2] - scenario.starts[0, :2]))
    assert 1.0 <= travel <= 1.5 + 1e-9


def test_swapped_targets_cross_and_stay_valid() -> None:
    config = RandomMapConfig(swap_targets=1.0, n_obstacles=5)
    plain = [generate_random_map(np.random.default_rng(seed), 3) for seed in range(40)]
    swapped = [generate_random_map(np.random.default_rng(seed), 3, config) for seed in range(40)]
    for spec in swapped:
        spec.validate(3)
        assert spec.obstacles.shape == (5, 3)
    # targets keep the formation's shape as a set but some robots get another robot's target
    reordered = 0
    for spec in swapped:
        travel = spec.targets[:, :2] - spec.starts[:, :2]
        reordered += not np.allclose(travel, travel[0])
    assert reordered >= 25  # 5 of 6 permutations of 3 robots are not the identity
    assert all(np.allclose(np.diff(p.targets[:, :2] - p.starts[:, :2], axis=0), 0) for p in plain)
    with pytest.raises(ValueError, match="swap_targets=1.5 must be a probability"):
        RandomMapConfig(swap_targets=1.5)


def test_map_file_round_trip(tmp_path) -> None:
    path = tmp_path / "mine.json"
    load_map("map4").save(path)
    loaded = load_map(str(path))
    np.testing.assert_array_equal(loaded.targets, load_map("map4").targets)
    env = gym.make("KoopNav-Formation-v0", map=str(path))
    _, info = env.reset(seed=0)
    np.testing.assert_array_equal(info["targets"], loaded.targets)


def test_leader_target_form(tmp_path) -> None:
    data = {
        "obstacles": [[0.0, 0.0, 0.5]],
        "starts": [[-3, 0, 0], [-4, 1, 0]],
        "leader_target": [3, 0, 0.5],
        "formation_offsets": [[0, 0], [-1, 1]],
    }
    spec = MapSpec.from_dict(data)
    np.testing.assert_allclose(spec.targets, [[3, 0, 0.5], [2, 1, 0.5]])
    np.testing.assert_allclose(spec.formation_offsets, [[0, 0], [-1, 1]])


def test_random_layouts_are_the_documented_ones_for_their_seeds() -> None:
    """The compiled obstacle sampler draws exactly as the Python one did: same seed, same layout
    (reference layouts recorded from the Python implementation, tests/data/random_layouts.json)."""
    import json
    from pathlib import Path

    from koopman_envs.sim.maps.generator import RandomMapConfig, generate_random_map

    reference = json.loads((Path(__file__).parent / "data" / "random_layouts.json").read_text())
    for case in reference:
        config = RandomMapConfig(**case.get("random_map", {}))
        spec = generate_random_map(np.random.default_rng(case["seed"]), case["n_robots"], config)
        for key in ("obstacles", "starts", "targets"):
            expected = np.asarray(case[key], dtype=float).reshape(getattr(spec, key).shape)
            # to the last bit or so: a numba/LLVM release may round the compiled trigonometry
            # differently in the last place (seen: 9e-16 with numba 0.68); within one install the
            # layouts are bit-identical (tests/test_determinism.py)
            np.testing.assert_allclose(
                getattr(spec, key), expected, rtol=0, atol=1e-12, err_msg=f"{case['seed']} {key}"
            )


def _route_fraction(spec: MapSpec) -> np.ndarray:
    """Where each obstacle centre lies along the route from the starts' to the targets' centroid."""
    a, b = spec.starts[:, :2].mean(axis=0), spec.targets[:, :2].mean(axis=0)
    return (spec.obstacles[:, :2] - a) @ (b - a) / np.dot(b - a, b - a)


def test_obstacles_can_be_drawn_beside_the_targets() -> None:
    near_targets = RandomMapConfig(n_obstacles=2, obstacle_along=(0.75, 0.95))
    default = RandomMapConfig(n_obstacles=2)
    for seed in range(20):
        beside = generate_random_map(np.random.default_rng(seed), 3, near_targets)
        assert np.all(_route_fraction(beside) > 0.7)
        assert np.all(_route_fraction(generate_random_map(np.random.default_rng(seed), 3, default)) < 0.8)
        gap = np.hypot(*(beside.targets[:, None, :2] - beside.obstacles[None, :, :2]).transpose(2, 0, 1))
        assert np.all(gap - beside.obstacles[:, 2] - 0.2 >= near_targets.clearance - 1e-9)


@pytest.mark.parametrize("along", [(0.5, 1.2), (0.7, 0.2), (-0.1, 0.5)])
def test_bad_obstacle_ranges_are_named(along) -> None:
    with pytest.raises(
        ValueError, match=r"obstacle_along=.* must be a \(low, high\) pair with 0 <= low <= high <= 1"
    ):
        RandomMapConfig(obstacle_along=along)


@pytest.mark.parametrize(
    # slow: the formation's 64 team sizes, about 3 CPU-s (issue 61); target reaching by default
    "env_id",
    ["KoopNav-TargetReaching-v0", pytest.param("KoopNav-Formation-v0", marks=pytest.mark.slow)],
)
def test_every_team_size_up_to_64_resets_on_random_maps(env_id: str) -> None:
    """The default layout (formation "auto": the wedge while it fits, the grid beyond) resets on
    every seed for N = 2..64 (issue 31: the wedge alone failed from 23 robots on)."""
    shapes = {}
    for n in range(2, 65):
        env = gym.make(env_id, map="random", n_robots=n)
        for seed in range(20):
            _, info = env.reset(seed=seed)
            assert info["poses"].shape == (n, 3)
        shapes[n] = env.unwrapped.engine.config.random_map.shape_for(n)
        env.close()
    assert {n for n, shape in shapes.items() if shape == "wedge"} == set(range(2, 21))
    assert {n for n, shape in shapes.items() if shape == "grid"} == set(range(21, 65))


def test_a_named_shape_that_does_not_fit_fails_at_construction() -> None:
    with pytest.raises(ValueError, match=r"a wedge of n_robots=30 .* does not fit .* use formation='grid'"):
        gym.make("KoopNav-TargetReaching-v0", map="random", n_robots=30, formation="wedge")
    with pytest.raises(ValueError, match=r"a line of n_robots=24"):
        gym.make("KoopNav-Formation-v0", map="random", n_robots=24, random_map={"formation": "line"})
    with pytest.raises(
        ValueError, match=r"formation='wedgee' is not one of \['auto', 'wedge'.*did you mean 'wedge'"
    ):
        RandomMapConfig(formation="wedgee")
    # the wedge where it fits is the default's layout, draw for draw
    for seed in range(3):
        auto = generate_random_map(np.random.default_rng(seed), 12, RandomMapConfig())
        wedge = generate_random_map(np.random.default_rng(seed), 12, RandomMapConfig(formation="wedge"))
        np.testing.assert_array_equal(auto.targets, wedge.targets)


def test_placement_share_matches_the_generators_acceptance() -> None:
    """The fit rule's share equals the rejection loop's acceptance rate (within a binomial band)."""
    from koopman_envs.sim.formations import formation_shape
    from koopman_envs.sim.maps.generator import placement_share

    local = formation_shape("wedge", 16, 0.9)
    share = placement_share(local, (3.0, 6.5), 17.6, 17.6)
    rng = np.random.default_rng(0)
    draws = 200_000
    heading = rng.uniform(-np.pi, np.pi, draws)
    travel = rng.uniform(3.0, 6.5, draws)
    lead = rng.uniform(-8.8, 8.8, (draws, 2))
    c, s = np.cos(heading), np.sin(heading)
    x = lead[:, :1] + np.outer(c, local[:, 0]) - np.outer(s, local[:, 1])
    y = lead[:, 1:] + np.outer(s, local[:, 0]) + np.outer(c, local[:, 1])
    tx, ty = x + (travel * c)[:, None], y + (travel * s)[:, None]
    inside = np.all((np.abs(np.hstack([x, tx])) <= 8.8) & (np.abs(np.hstack([y, ty])) <= 8.8), axis=1)
    rate = inside.mean()
    band = 4 * np.sqrt(share * (1 - share) / draws)
    assert abs(rate - share) < band + 2e-3, (rate, share)


def _openblas_core() -> str | None:
    """The kernel family OpenBLAS chose on this CPU (``"Haswell"``, ``"SkylakeX"``...), or None when
    NumPy's BLAS is not OpenBLAS or does not say."""
    import ctypes

    with open("/proc/self/maps") as maps_file:
        libraries = sorted({line.split()[-1] for line in maps_file if "openblas" in line.lower()})
    for path in libraries:
        library = ctypes.CDLL(path)
        for name in (
            "scipy_openblas_get_corename64_",
            "scipy_openblas_get_corename",
            "openblas_get_corename",
        ):
            function = getattr(library, name, None)
            if function is not None:
                function.restype = ctypes.c_char_p
                return function().decode()
    return None


def _fma_exact(a: float, b: float, c: float) -> float:
    """``a * b + c`` rounded once, from exact rationals (``float`` of a Fraction is correctly
    rounded): the reference for the kernel's fused multiply-adds, with no hardware FMA involved."""
    from fractions import Fraction

    return float(Fraction(a) * Fraction(b) + Fraction(c))


def test_the_compiled_layout_arithmetic_equals_numpys() -> None:
    """The random-map kernel writes out the two products NumPy hands to BLAS, and the means, so
    that a seed gives the layout the NumPy generator gave (tests/data/random_layouts.json holds
    such layouts; this checks the pieces on many more inputs, team sizes 1 to 20). The kernel's
    arithmetic is fixed (each entry ``fma(l1, r1j, l0 * r0j)``, one row unfused) and checked bit for
    bit against that formula in exact rationals on every machine; against NumPy bit for bit where
    OpenBLAS runs its Haswell kernels (whose order the kernel copies), within 1e-15 where
    it picks another kernel (SkylakeX's rounds a few products otherwise)."""
    from koopman_envs.sim.maps.generator import _rotate, _row_mean, _spread

    numpy_bit_for_bit = _openblas_core() == "Haswell"
    rng = np.random.default_rng(0)
    for _ in range(2000):
        n = int(rng.integers(1, 21))
        local = rng.normal(size=(n, 2))
        heading = rng.uniform(-np.pi, np.pi)
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        rotated = _rotate(local, cos_h, sin_h)
        if n == 1:
            formula = [
                [local[0, 0] * cos_h + local[0, 1] * -sin_h, local[0, 0] * sin_h + local[0, 1] * cos_h]
            ]
        else:
            formula = [
                [_fma_exact(row[1], -sin_h, row[0] * cos_h), _fma_exact(row[1], cos_h, row[0] * sin_h)]
                for row in local.tolist()
            ]
        np.testing.assert_array_equal(rotated, np.array(formula))
        by_numpy = local @ np.array([[cos_h, sin_h], [-sin_h, cos_h]])
        if numpy_bit_for_bit:
            np.testing.assert_array_equal(rotated, by_numpy)
        else:
            np.testing.assert_allclose(rotated, by_numpy, rtol=0, atol=1e-15)
        centre = local.mean(axis=0)
        np.testing.assert_array_equal(_row_mean(local), centre)  # no BLAS: NumPy's own sum
        normal = rng.normal(size=2)
        assert abs(_spread(local, centre, normal) - np.abs((local - centre) @ normal).max()) <= 1e-12
