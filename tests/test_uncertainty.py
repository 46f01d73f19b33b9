"""Runtime uncertainty beyond slip (koopman_envs.settings.uncertainty, sim.perception, sim.lidar): exact
lidar ranges, noise and loss statistics within their intervals, latency and actuation delay to
the period, determinism, every front through the official checkers, and bad input."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.settings import UNCERTAINTY_PRESETS
from koopman_envs.sim.lidar import beam_angles, cast_beams

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
#: half-width of the acceptance intervals in standard deviations (normal approximations of the
#: chi-square and binomial laws at these sample sizes; a false alarm about once in 16,000 runs)
Z = 4.0


def chi2_bounds(n: int) -> tuple[float, float]:
    """Interval of a chi-square variable with n degrees of freedom (mean n, variance 2n)."""
    return n - Z * math.sqrt(2 * n), n + Z * math.sqrt(2 * n)


WORKSPACE = np.array([-10.0, 10.0, -10.0, 10.0])


def _scan(robots, obstacles, angles, max_range=5.0, radius=0.2):
    """Exact ranges of one env: robots (N, 3), obstacles (M, 3)."""
    robots, obstacles = np.asarray(robots, float), np.asarray(obstacles, float).reshape(-1, 3)
    n = robots.shape[0]
    out = np.empty((1, n, len(angles)))
    cast_beams(
        np.ascontiguousarray(robots.T[None]),
        np.ascontiguousarray(obstacles.T[None]),
        np.full(n, radius),
        np.asarray(angles, float),
        max_range,
        WORKSPACE,
        out,
    )
    return out[0]


# ----------------------------------------------------------------------- lidar, analytic
@pytest.mark.parametrize("bearing", [0.0, 0.7, -2.1, math.pi / 2])
def test_a_circle_at_a_known_distance_and_bearing_reads_its_exact_range(bearing: float) -> None:
    heading, d, r = 0.3, 2.5, 0.4
    centre = (d * math.cos(heading + bearing), d * math.sin(heading + bearing), r)
    ranges = _scan([(0.0, 0.0, heading)], [centre], [bearing])
    assert ranges[0, 0] == pytest.approx(d - r, abs=1e-12)


def test_a_beam_that_meets_nothing_reads_the_range_and_one_that_grazes_past_misses() -> None:
    ranges = _scan([(0.0, 0.0, 0.0)], [(3.0, 1.0, 0.5)], [0.0, math.pi])
    assert ranges[0].tolist() == [5.0, 5.0]  # passes 1 m beside a 0.5 m disc; behind: nothing
    far = _scan([(0.0, 0.0, 0.0)], [(6.0, 0.0, 0.5)], [0.0])
    assert far[0, 0] == 5.0  # the surface at 5.5 m is past the range


def test_beams_hit_other_robots_and_the_walls() -> None:
    ranges = _scan([(0.0, 0.0, 0.0), (1.5, 0.0, 2.0)], [], [0.0], max_range=20.0, radius=0.25)
    assert ranges[0, 0] == pytest.approx(1.25)  # robot 1's disc of radius 0.25 at 1.5 m
    walls = _scan([(8.0, -9.0, 0.0)], [], [0.0, -math.pi / 2, math.pi / 4], max_range=20.0)
    assert walls[0, 0] == pytest.approx(2.0) and walls[0, 1] == pytest.approx(1.0)
    assert walls[0, 2] == pytest.approx(2.0 * math.sqrt(2))  # the corner direction meets x = 10 first


def test_a_robot_inside_an_obstacle_reads_zero() -> None:
    assert (_scan([(0.0, 0.0, 0.0)], [(0.1, 0.0, 0.5)], beam_angles(8, 2 * math.pi)) == 0).all()


@pytest.mark.parametrize("beams, fov", [(32, 2 * math.pi), (7, 2.0), (1, 1.0), (90, 2 * math.pi)])
def test_the_kernel_equals_a_beam_by_beam_search(beams: int, fov: float) -> None:
    """The kernel tests only the beams within a disc's angular width: on random scenes it reads
    what testing every beam against every disc and wall reads."""
    rng = np.random.default_rng(beams)
    angles = beam_angles(beams, fov)
    for _ in range(40):
        robots = np.column_stack(
            [rng.uniform(-9.5, 9.5, 3), rng.uniform(-9.5, 9.5, 3), rng.uniform(-4, 4, 3)]
        )
        obstacles = np.column_stack(
            [rng.uniform(-10, 10, 6), rng.uniform(-10, 10, 6), rng.uniform(0.1, 1.5, 6)]
        )
        ranges = _scan(robots, obstacles, angles, max_range=6.0)
        for i, (x, y, theta) in enumerate(robots):
            discs = [tuple(o) for o in obstacles] + [
                (rx, ry, 0.2) for j, (rx, ry, _) in enumerate(robots) if j != i
            ]
            if any(math.hypot(cx - x, cy - y) <= r for cx, cy, r in discs):
                assert (ranges[i] == 0).all()
                continue
            for b, angle in enumerate(angles):
                c, s = math.cos(theta + angle), math.sin(theta + angle)
                best = 6.0
                for wall, d in ((10 - x, c), (-10 - x, c), (10 - y, s), (-10 - y, s)):
                    if d != 0 and wall / d > 0:
                        best = min(best, wall / d)
                for cx, cy, r in discs:
                    along = (cx - x) * c + (cy - y) * s
                    across2 = (cx - x) ** 2 + (cy - y) ** 2 - along**2
                    if along > 0 and across2 < r * r:
                        best = min(best, along - math.sqrt(r * r - across2))
                assert ranges[i, b] == pytest.approx(best, abs=1e-9)


def test_beam_angles_span_the_field_of_view() -> None:
    assert np.allclose(beam_angles(4, 2 * math.pi), [0, math.pi / 2, math.pi, 3 * math.pi / 2])
    assert np.allclose(beam_angles(3, math.pi), [-math.pi / 2, 0, math.pi / 2])
    assert beam_angles(1, 1.0).tolist() == [0.0]


def test_the_env_scan_equals_the_kernel_at_the_true_poses() -> None:
    env = gym.make(TR, sensing="lidar", lidar={"beams": 16, "range": 6.0})
    _, info = env.reset(seed=3)
    scenario = env.unwrapped.scenario
    for robot in range(3):
        others = np.delete(info["poses"], robot, axis=0)
        expected = _scan(
            np.vstack([info["poses"][robot], others]), scenario.obstacles, beam_angles(16, 2 * math.pi), 6.0
        )[0]
        assert np.allclose(info["lidar_ranges"][robot], expected)


# ------------------------------------------------------------------ noise and loss statistics
def _rollout(env_id: str, steps: int, seed: int = 0, action: float = 0.0, **kw):
    env = gym.make(env_id, max_episode_steps=steps + 5, **kw)
    _, info = env.reset(seed=seed)
    infos = [info]
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(np.tile([action, 0.0], 3))
        infos.append(info)
        if terminated or truncated:
            break
    return infos


def test_pose_noise_has_the_asked_standard_deviation() -> None:
    sigma, heading = 0.05, 0.02
    infos = _rollout(TR, 400, pose_noise={"xy": sigma, "heading": heading})
    error = np.array([i["observed_poses"] - i["poses"] for i in infos]).reshape(-1, 3)
    n = error.shape[0]
    for column, std in ((0, sigma), (1, sigma), (2, heading)):
        e = error[:, column]
        assert abs(e.mean()) < 4 * std / math.sqrt(n)
        # chi-square interval of the sum of squares at 99.9%
        low, high = chi2_bounds(n)
        assert low < (e**2).sum() / std**2 < high


def test_the_bias_drifts_as_a_random_walk() -> None:
    """Without white noise the error is the bias; its increments have std rate * sqrt(dt)."""
    rate = 0.02
    infos = _rollout(TR, 300, pose_noise={"drift_xy": rate})
    error = np.array([i["observed_poses"][:, 0] - i["poses"][:, 0] for i in infos])
    steps = np.diff(error, axis=0).reshape(-1)
    std = rate * math.sqrt(0.1)
    low, high = chi2_bounds(steps.size)
    assert low < (steps**2).sum() / std**2 < high
    assert (error[0] == 0).all()  # the bias starts at 0


def test_message_loss_within_the_binomial_interval() -> None:
    drop = 0.3
    infos = _rollout(TR, 400, comm={"drop": drop})
    ages = np.array([i["message_age"] for i in infos[1:]])
    off = ~np.eye(3, dtype=bool)
    arrived = (ages[:, off] == 0).sum()
    total = ages[:, off].size
    mean, sd = total * (1 - drop), math.sqrt(total * drop * (1 - drop))
    assert mean - Z * sd <= arrived <= mean + Z * sd


@pytest.mark.parametrize("latency", [1, 3])
def test_a_team_mate_is_seen_as_it_was_latency_periods_ago(latency: int) -> None:
    infos = _rollout(TR, 30, action=0.4, comm={"latency": latency})
    for t in range(latency):
        assert (infos[t]["message_age"][~np.eye(3, dtype=bool)] == -1).all()  # nothing arrived yet
    for t in range(latency, len(infos)):
        known, truth = infos[t]["known_poses"], infos[t - latency]["poses"]
        for i in range(3):
            for j in range(3):
                if i != j:
                    assert np.array_equal(known[i, j], truth[j])
                    assert infos[t]["message_age"][i, j] == latency
        assert np.array_equal(infos[t]["known_poses"][np.arange(3), np.arange(3)], infos[t]["poses"])


def test_no_message_arrives_from_beyond_the_range() -> None:
    infos = _rollout(TR, 10, comm={"range": 0.5})  # the starts of map1 are farther apart
    assert all((i["message_age"][~np.eye(3, dtype=bool)] == -1).all() for i in infos)


def test_the_observation_carries_ages_and_arrival_flags() -> None:
    env = gym.make(TR, comm={"latency": 2})
    obs, _ = env.reset(seed=0)
    plain = gym.make(TR).observation_space.shape[0]
    assert obs.shape[0] == plain + 3 * 4  # 2 entries per other robot per block
    block = obs.reshape(3, -1)
    assert (block[:, -4:] == [100, 0, 100, 0]).all()  # nothing heard: age AGE_MAX, flag 0
    assert (block[:, 9:15] == [0, 0, 30, 0, 0, 30]).all()  # and the team-mates read absent
    for _ in range(2):
        obs, *_ = env.step(np.zeros(6))
    assert (obs.reshape(3, -1)[:, -4:] == [2, 1, 2, 1]).all()


# ------------------------------------------------------------------------ actuation delay
@pytest.mark.parametrize("delay", [1, 2])
def test_a_command_acts_delay_periods_later(delay: int) -> None:
    commands = [np.tile([0.5, 0.3 * (t % 3 - 1)], 3) for t in range(12)]
    late = gym.make(TR, actuation_delay=delay)
    now = gym.make(TR)
    late.reset(seed=4)
    now.reset(seed=4)
    shifted = [np.zeros(6)] * delay + commands
    for t in range(len(commands)):
        _, _, _, _, a = late.step(commands[t])
        _, _, _, _, b = now.step(shifted[t])
        assert np.array_equal(a["poses"], b["poses"]), t


# ----------------------------------------------------------------- replay, determinism, fronts
def test_perfect_settings_replay_the_plain_env_bit_for_bit() -> None:
    plain = _rollout(FO, 40, seed=7, action=0.3, slip="high")
    perfect = _rollout(
        FO,
        40,
        seed=7,
        action=0.3,
        slip="high",
        pose_noise=0.0,
        comm={"latency": 0, "drop": 0.0},
        actuation_delay=0,
    )
    for a, b in zip(plain, perfect):
        assert all(np.array_equal(a[key], b[key]) for key in a)


def test_noise_draws_leave_the_slip_and_map_draws_unchanged() -> None:
    """The sensor stream is a child of the env's generator: the same seed gives the same true
    trajectory at every noise level (paired sweeps), with the same commands."""
    quiet = _rollout(TR, 30, seed=2, action=0.4, map="random", slip="high")
    noisy = _rollout(
        TR, 30, seed=2, action=0.4, map="random", slip="high", pose_noise=0.2, comm={"drop": 0.5}
    )
    assert all(np.array_equal(a["poses"], b["poses"]) for a, b in zip(quiet, noisy))


HARSH = {"uncertainty": "harsh", "sensing": "lidar", "map": "random"}


def _digest(kwargs: dict) -> str:
    infos = _rollout(FO, 25, seed=11, action=0.3, **kwargs)
    import hashlib

    h = hashlib.sha256()
    for info in infos:
        for key in sorted(info):
            h.update(np.asarray(info[key]).tobytes())
    return h.hexdigest()


def test_same_seed_same_result_across_processes() -> None:
    here = str(Path(__file__).resolve().parent)
    code = f"import sys; sys.path.insert(0, {here!r}); from test_uncertainty import _digest, HARSH; print(_digest(HARSH))"
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert other.stdout.strip() == _digest(HARSH)


def test_the_vector_env_matches_single_envs() -> None:
    kwargs = {"uncertainty": "harsh", "sensing": "lidar", "map": "random"}
    vec = gym.make_vec(FO, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(FO, **kwargs) for _ in range(3)]
    obs, _ = vec.reset(seed=20)
    for i, env in enumerate(singles):
        single, _ = env.reset(seed=20 + i)
        assert np.array_equal(obs[i], single)
    rng = np.random.default_rng(0)
    for _ in range(15):
        actions = rng.uniform(-0.5, 0.5, size=(3, 6)).astype(np.float32)
        obs, *_ = vec.step(actions)
        for i, env in enumerate(singles):
            single, *_ = env.step(actions[i])
            assert np.array_equal(obs[i], single)


@pytest.mark.parametrize("preset", list(UNCERTAINTY_PRESETS))
@pytest.mark.parametrize("sensing", ["state", "lidar"])
def test_every_preset_passes_the_official_checkers(preset: str, sensing: str) -> None:
    for env_id in (TR, FO):
        check_env(gym.make(env_id, uncertainty=preset, sensing=sensing).unwrapped, skip_render_check=True)
    for module in (target_reaching_v0, formation_v0):
        parallel_api_test(module.parallel_env(uncertainty=preset, sensing=sensing), num_cycles=30)
        parallel_seed_test(lambda module=module: module.parallel_env(uncertainty=preset, sensing=sensing))


def test_a_preset_sets_the_settings_and_a_keyword_beside_it_wins() -> None:
    config = gym.make(TR, uncertainty="realistic").unwrapped.config
    preset = UNCERTAINTY_PRESETS["realistic"]
    assert config.pose_noise == preset.pose_noise and config.comm == preset.comm
    assert config.actuation_delay == 1 and config.slip_label == "low"
    mixed = gym.make(TR, uncertainty="realistic", slip="nominal", comm={"drop": 0.0}).unwrapped.config
    assert mixed.slip_label == "nominal" and mixed.comm.drop == 0.0 and mixed.comm.latency == 1


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"pose_noise": {"xy": -0.1}}, r"pose_noise.xy=-0.1 must be a finite number >= 0"),
        (
            {"pose_noise": {"heding": 0.1}},
            r"pose_noise has unknown field 'heding' \(did you mean 'heading'\?\)",
        ),
        ({"comm": {"latency": 1.5}}, r"comm.latency=1.5 must be an integer >= 0"),
        ({"comm": {"latency": -1}}, r"comm.latency=-1 must be an integer >= 0"),
        ({"comm": {"drop": -0.1}}, r"comm.drop=-0.1 must be a finite number >= 0 <= 1"),
        ({"comm": {"range": 0}}, r"comm.range=0 must be a finite number > 0"),
        ({"sensing": "lidar", "lidar": {"beams": 0}}, r"lidar.beams=0 must be an integer >= 1"),
        ({"sensing": "lidar", "lidar": {"fov": 7.0}}, r"lidar.fov=7.0 must be a finite number > 0 <= 6.28"),
        ({"sensing": "lidar", "lidar": {"fov": 0.0}}, r"lidar.fov=0.0 must be a finite number > 0"),
        ({"sensing": "lidar", "lidar": {"dropout": 2}}, r"lidar.dropout=2 must be a finite number >= 0 <= 1"),
        ({"uncertainty": "hrash"}, r"uncertainty='hrash' is not one of .*did you mean 'harsh'"),
        ({"actuation_delay": 1.0}, r"actuation_delay=1.0 must be an integer >= 0"),
    ],
)
def test_bad_settings_are_refused_by_name(kwargs: dict, message: str) -> None:
    for make in (lambda: gym.make(TR, **kwargs), lambda: formation_v0.parallel_env(**kwargs)):
        with pytest.raises(ValueError, match=message):
            make()
