"""The ekf: estimator (controllers/estimation/): a per-robot unicycle EKF in front of any
controller, closer to the truth than the raw localization, with checked options."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.estimation import PoseEstimator, PoseFrontEnd


class _Recorder(controllers.BaseController):
    """Drives at a constant command and keeps the poses it was given."""

    name = "recorder"

    def _reset(self, scenario, seed):
        self.seen = []

    def _act(self, observation, observed):
        self.seen.append(np.array(observed.observed_poses))
        return np.tile([0.3, 0.1], observed.n_robots)


def test_the_estimate_is_closer_to_the_truth_than_the_measurement() -> None:
    env = gym.make(
        "KoopNav-TargetReaching-v0", pose_noise={"xy": 0.1, "heading": 0.05}, max_episode_steps=200
    )
    inner = _Recorder()
    ekf = PoseEstimator(inner, position_std=0.1, heading_std=0.05)
    obs, info = env.reset(seed=3)
    ekf.reset(env, seed=3)
    raw, estimated = [], []
    for _ in range(80):
        command = ekf.act(obs, info)
        raw.append(info["observed_poses"][:, :2] - info["poses"][:, :2])
        estimated.append(inner.seen[-1][:, :2] - info["poses"][:, :2])
        obs, _, terminated, truncated, info = env.step(command)
        if terminated or truncated:
            break
    raw_rmse = np.sqrt(np.mean(np.square(raw[10:])))
    ekf_rmse = np.sqrt(np.mean(np.square(estimated[10:])))
    assert ekf_rmse < 0.7 * raw_rmse, (ekf_rmse, raw_rmse)
    assert "estimator" in ekf.stats().extra_times


def test_the_prefix_builds_any_controller_and_checks_its_options() -> None:
    ctrl = controllers.make("ekf:consensus", ekf_position_std=0.05, goal_gain=0.5)
    assert ctrl.name == "ekf:consensus" and ctrl.inner.goal_gain == 0.5
    with pytest.raises(
        ValueError, match=r"unknown estimator option 'ekf_positon_std' \(did you mean 'ekf_position_std'\?\)"
    ):
        controllers.make("ekf:consensus", ekf_positon_std=0.05)
    with pytest.raises(ValueError, match=r"ekf_delay=-1 must be an integer >= 0"):
        controllers.make("ekf:consensus", ekf_delay=-1)
    names = [o.name for o in controllers.options("ekf:nominal-nmpc").options]
    assert "ekf_position_std" in names and "horizon" in names


# --------------------------------------------------------------------------- delay compensation
class _Weaving(controllers.BaseController):
    """Changes its command every period (so a stale command is not the current one) and keeps
    what it was handed."""

    name = "weaving"

    def _reset(self, scenario, seed):
        self.seen, self.covariances, self.t = [], [], 0

    def _act(self, observation, observed):
        self.seen.append(np.array(observed.observed_poses))
        if observed.pose_covariance is not None:
            self.covariances.append(np.array(observed.pose_covariance))
        self.t += 1
        n = observed.n_robots
        return np.tile([0.2 + 0.3 * np.sin(0.3 * self.t), 0.6 * np.cos(0.2 * self.t)], n)


@pytest.mark.parametrize("delay", [1, 2, 3, 4])
def test_delay_compensation_is_exact_without_noise_or_slip(delay) -> None:
    """The pose handed on at period t is the true pose at t + delay, when the new command acts."""
    env = gym.make(
        "KoopNav-TargetReaching-v0", map="map1", slip="nominal", actuation_delay=delay, max_episode_steps=100
    )
    inner = _Weaving()
    ekf = PoseEstimator(inner, delay=delay)
    obs, info = env.reset(seed=1)
    ekf.reset(env, seed=1)
    truth = []
    for _ in range(40):
        truth.append(np.array(info["poses"]))
        obs, _, terminated, truncated, info = env.step(ekf.act(obs, info))
        assert not (terminated or truncated)
    truth.append(np.array(info["poses"]))
    for t in range(len(inner.seen) - delay):
        handed, actual = inner.seen[t], truth[t + delay]
        assert np.allclose(handed[:, :2], actual[:, :2], atol=1e-9), (t, handed - actual)
        assert np.allclose(np.cos(handed[:, 2] - actual[:, 2]), 1.0, atol=1e-12)
    # the robots moved: the check compares poses that differ from the pose at t
    assert np.linalg.norm(truth[-1][:, :2] - truth[0][:, :2]) > 0.5
    # without compensation the inner controller is handed the pose now, `delay` periods stale
    plain = _Weaving()
    uncompensated = PoseEstimator(plain, delay=delay, compensate_delay=False)
    obs, info = env.reset(seed=1)
    uncompensated.reset(env, seed=1)
    for _ in range(20):
        obs, *_, info = env.step(uncompensated.act(obs, info))
    assert np.allclose(plain.seen[10][:, :2], truth[10][:, :2], atol=1e-9)
    assert not np.allclose(plain.seen[10][:, :2], truth[10 + delay][:, :2], atol=1e-3)


def test_the_covariance_grows_with_each_compensated_period() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", pose_noise={"xy": 0.03, "heading": 0.02}, actuation_delay=3)
    spreads = {}
    for delay in (0, 1, 3):
        inner = _Weaving()
        ekf = PoseEstimator(inner, delay=delay, position_std=0.03, heading_std=0.02)
        obs, info = env.reset(seed=2)
        ekf.reset(env, seed=2)
        for _ in range(30):
            obs, *_, info = env.step(ekf.act(obs, info))
        cov = inner.covariances[-1]
        assert cov.shape == (3, 3, 3) and np.allclose(cov, np.swapaxes(cov, 1, 2))
        assert np.all(np.linalg.eigvalsh(cov) > 0)
        spreads[delay] = np.trace(cov[:, :2, :2], axis1=1, axis2=2)
    assert np.all(spreads[0] < spreads[1]) and np.all(spreads[1] < spreads[3])


@pytest.mark.parametrize(
    "options, message",
    [
        ({"ekf_delay": 101}, r"ekf_delay=101 must be an integer >= 0 and <= 100"),
        ({"ekf_compensate_delay": "yes"}, r"ekf_compensate_delay='yes' must be True or False"),
        ({"ekf_position_std": 0}, r"ekf_position_std=0 must be a finite number > 0"),
        (
            {"ekf_delay": "automatic"},
            r"ekf_delay='automatic' must be an integer >= 0 and <= 100 \(control periods, or 'auto'\)",
        ),
        ({"ekf_max_delay": 0}, r"ekf_max_delay=0 must be an integer >= 1 and <= 100"),
    ],
)
def test_bad_estimator_options_name_the_value(options, message) -> None:
    with pytest.raises(ValueError, match=message):
        controllers.make("ekf:consensus", **options)


# --------------------------------------------------------------------------- delay identification
def _identified(uncertainty: str, delay: int, seed: int, steps: int) -> int | None:
    env = gym.make(
        "KoopNav-TargetReaching-v0",
        uncertainty=uncertainty,
        actuation_delay=delay,
        slip="high",
        max_episode_steps=300,
    )
    ekf = PoseEstimator(_Weaving(), delay="auto")
    obs, info = env.reset(seed=seed)
    ekf.reset(env, seed=seed)
    for _ in range(steps):
        obs, *_, info = env.step(ekf.act(obs, info))
    return ekf._identifier.delay


@pytest.mark.parametrize("delay", [0, 1, 2, 3, 4])
def test_the_delay_is_identified_online_within_one_period(delay) -> None:
    """Stated: after 40 periods under `realistic` (3 cm, 0.02 rad of localization noise, high slip)
    and after 100 under `harsh` (10 cm), the identified delay is within one period of the truth
    (measured: exact in 59 of 60 realistic runs over delays 0-6, within one in all)."""
    for seed in range(4):
        assert abs(_identified("realistic", delay, seed, 40) - delay) <= 1, seed
        assert abs(_identified("harsh", delay, seed, 100) - delay) <= 1, seed


def test_without_noise_the_delay_is_exact_and_the_compensation_follows_it() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1", actuation_delay=3, max_episode_steps=100)
    inner = _Weaving()
    ekf = PoseEstimator(inner, delay="auto")
    obs, info = env.reset(seed=0)
    ekf.reset(env, seed=0)
    assert ekf.delay == 0  # nothing seen yet: no compensation
    truth = []
    for _ in range(30):
        truth.append(np.array(info["poses"]))
        obs, *_, info = env.step(ekf.act(obs, info))
    assert ekf.delay == 3 and ekf.stats().counts["identified_delay"] == 3
    # once identified, the pose handed on is the pose at which the command acts, as with delay=3
    # (to a fraction of a millimetre: the filter still carries the error of its first periods,
    # predicted with delay 0, while the exact measurements pull it back)
    assert np.allclose(inner.seen[-4][:, :2], truth[-1][:, :2], atol=1e-3)
    assert not np.allclose(inner.seen[-4][:, :2], truth[-4][:, :2], atol=1e-2)


# --------------------------------------------------------------------------- noise identification
def _episode_commands(ctrl, uncertainty: str, seed: int = 0, steps: int = 200) -> list[np.ndarray]:
    env = gym.make("KoopNav-Formation-v0", uncertainty=uncertainty, slip="high", max_episode_steps=steps)
    obs, info = env.reset(seed=seed)
    ctrl.reset(env, seed=seed)
    commands = []
    for _ in range(steps):
        commands.append(np.array(ctrl.act(obs, info)))
        obs, _, terminated, truncated, info = env.step(commands[-1])
        if terminated or truncated:
            break
    return commands


@pytest.mark.parametrize(
    "name, options",
    [
        ("consensus-v0", {}),
        # the tuned consensus (controllers/tuned/consensus.json) is not yet a no-op behind its
        # default front-end: with its larger gains the high slip's residuals pass the noise
        # floor for a while mid-episode and the filter moves the known poses (measured: from
        # period 12, headings by up to 7e-4 rad), though no level is left identified at the end;
        # strict, so the mark goes once the identifier stops mistaking slip for pose noise
        pytest.param(
            "consensus", {}, marks=pytest.mark.xfail(strict=True, reason="slip residuals read as pose noise")
        ),
        # slow: the NMPCs (issue 61: nominal-nmpc about 5 CPU-s, dmpc-nominal about 2,
        # koopman-nmpc about 6, the costliest case); consensus-v0 and the filtered consensus keep
        # the front-end's default path in the default run
        pytest.param("nominal-nmpc", {"solver": "rti"}, marks=pytest.mark.slow),
        pytest.param("koopman-nmpc", {"solver": "rti"}, marks=pytest.mark.slow),
        pytest.param("dmpc-nominal", {"solver": "rti"}, marks=pytest.mark.slow),
        ("safe:consensus-v0", {}),
    ],
)
def test_the_default_estimator_is_a_no_op_on_a_team_that_localizes_exactly(name, options) -> None:
    """No pose noise and no delay (high slip): the identified delay is 0 and the noise below its
    floor at every period, so the built-in controllers with their default ``estimator="auto"``
    act bit for bit as the paper's (``estimator="none"``), and as behind ``ekf:`` with
    everything identified."""
    from controllers.calibration import calibrate_controller
    from koopman_envs.engine.plant import make_plant

    def build(configuration: str, **extra):
        ctrl = controllers.make(configuration, **options, **extra)
        plant = make_plant("KoopNav-Formation-v0", slip="high", budget=1_000_000, seed=0)
        calibrate_controller(ctrl, plant, seed=0)
        return ctrl

    paper = _episode_commands(build(name, estimator="none"), "nominal")
    default = build(name)
    deployed = _episode_commands(default, "nominal")
    # the same front-end put in front by the ekf: prefix (which switches the controller's own off)
    identified = {"ekf_delay": "auto", "ekf_position_std": "auto", "ekf_heading_std": "auto"}
    wrapped = _episode_commands(build(f"ekf:{name}", **identified), "nominal")
    assert len(paper) == len(deployed) == len(wrapped) > 50
    for a, b, c in zip(paper, deployed, wrapped, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
    counts = default.stats().counts
    assert counts["identified_delay"] == 0
    assert counts["identified_position_std_mm"] == 0 and counts["identified_heading_std_mrad"] == 0


def test_the_noise_is_identified_online_and_then_filtered() -> None:
    """Under `realistic` (3 cm, 0.02 rad, one period of delay) the identified levels come within a
    third of the truth after 60 periods, and the covariance is handed on from then on."""
    inner = _Weaving()
    ekf = PoseEstimator(inner, delay="auto", position_std="auto", heading_std="auto")
    env = gym.make("KoopNav-TargetReaching-v0", uncertainty="realistic", slip="high", max_episode_steps=300)
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        ekf.reset(env, seed=seed)
        for _ in range(60):
            obs, *_, info = env.step(ekf.act(obs, info))
        position, heading = ekf.noise
        assert 0.02 <= position <= 0.04 and 0.013 <= heading <= 0.027, (seed, position, heading)
        assert ekf.delay == 1
        assert inner.covariances[-1].shape == (3, 3, 3)


def test_the_identified_delay_is_kept_once_the_team_has_moved_enough() -> None:
    """The delay, once the team has travelled lock_excitation metres of commands, stays for the
    episode: later data (here, made to follow the commands at once) cannot move it. Before the
    lock the same data would (the unlocked identifier's answer changes)."""
    from controllers.estimation import MotionIdentifier

    def drive(ident: MotionIdentifier, rng: np.random.Generator) -> list[int | None]:
        pose, queue, seen = np.zeros(3), [np.zeros(2)] * 2, []  # delay 2 for 100 periods, then 0
        for t in range(600):
            ident.observe((pose + rng.normal(0.0, [0.03, 0.03, 0.02]))[None])
            command = np.array([0.3 + 0.2 * np.sin(0.5 * t), 0.5 * np.cos(0.3 * t)])
            ident.sent(command[None])
            queue.append(command)
            v, omega = queue.pop(0) if t < 100 else command
            pose = pose + 0.1 * np.array([v * np.cos(pose[2]), v * np.sin(pose[2]), omega])
            seen.append(ident.delay)
        return seen

    locked = drive(MotionIdentifier(1, 5, 0.1, lock_excitation=3.0), np.random.default_rng(0))
    unlocked = drive(MotionIdentifier(1, 5, 0.1, lock_excitation=1e9), np.random.default_rng(0))
    assert locked[99] == unlocked[99] == 2
    assert set(locked[99:]) == {2}
    assert unlocked[-1] == 0


# --------------------------------------------------------------------------- the central radio
class _RadioRecorder(_Recorder):
    """A central controller on the leader's computer: hears the team over robot 0's radio."""

    radio_station = 0


def test_the_central_controller_hears_the_team_over_the_radio_and_carries_late_poses_forward() -> None:
    """Messages 2 periods late, no noise, no slip: the poses the central controller plans from
    are the team's as robot 0 heard them, carried forward through the commands sent since, so
    they equal the true poses (to rounding); the paper's controller (no front-end) gets the late
    ones as they are."""
    from controllers.base import over_the_radio
    from koopman_envs import Observed

    env = gym.make("KoopNav-TargetReaching-v0", map="map1", comm={"latency": 2}, max_episode_steps=40)
    carried, late = _RadioRecorder(), _RadioRecorder()
    carried.front_end = PoseFrontEnd(delay=0, position_std="auto", heading_std="auto")
    obs, info = env.reset(seed=0)
    for ctrl in (carried, late):
        ctrl.reset(env, seed=0)
    truth, heard = [], []
    for _ in range(30):
        truth.append(np.array(info["poses"]))
        heard.append(over_the_radio(Observed.from_info(info), 0, env.unwrapped.scenario.starts))
        command = carried.act(obs, info)
        late.act(obs, info)
        obs, *_, info = env.step(command)
    for t in range(5, 30):
        np.testing.assert_allclose(carried.seen[t], truth[t], atol=1e-9)
        np.testing.assert_array_equal(late.seen[t], heard[t].observed_poses)
        assert not np.allclose(late.seen[t][1:, :2], truth[t][1:, :2], atol=1e-3)  # 2 periods behind
        assert list(heard[t].pose_age) == [0, 2, 2]
    # before a first message arrives a robot stands at its planned start
    assert list(heard[0].pose_age) == [0, -1, -1]
    np.testing.assert_array_equal(heard[0].observed_poses[1:], env.unwrapped.scenario.starts[1:])


def test_a_radios_ages_in_a_handed_on_dict_stay_with_the_wrapper_that_heard_them() -> None:
    """A wrapper hands a controller of the earlier API its Observed as a dict (to_info), which
    carries the wrapper's radio ages (pose_age) and reads back whole (Observed.from_info); the
    controller behind drops them, as it drops those of an Observed handed on, so its own front
    end does not carry the poses forward by another radio's ages."""
    from koopman_envs import Observed

    env = gym.make("KoopNav-TargetReaching-v0", map="map1", comm={"latency": 2}, max_episode_steps=20)
    plain, handed = _Recorder(), _Recorder()
    for ctrl in (plain, handed):
        ctrl.front_end = PoseFrontEnd(delay=0, position_std="auto", heading_std="auto")
    obs, info = env.reset(seed=0)
    for ctrl in (plain, handed):
        ctrl.reset(env, seed=0)
    for _ in range(8):
        heard = {**Observed.from_info(info).to_info(), "pose_age": np.array([0, 2, 2])}
        assert Observed.from_info(heard).pose_age is heard["pose_age"]
        plain.act(obs, info)
        handed.act(obs, heard)
        obs, *_, info = env.step(np.tile([0.3, 0.1], 3))
    np.testing.assert_array_equal(np.array(handed.seen), np.array(plain.seen), strict=True)


def test_a_wrapper_hears_over_its_inner_central_controllers_radio() -> None:
    for prefix in ("ekf", "safe"):
        wrapped = controllers.make(f"{prefix}:nominal-nmpc")
        assert wrapped.radio_station == 0 and wrapped.inner.radio_station is None
    assert controllers.make("dmpc-nominal").radio_station is None
    assert controllers.make("consensus").radio_station is None
