"""The levers of the model-based controllers' estimator, one at a time (the ablation's rows), and
the mis-specified datasheet (``estimator="realistic"``): controllers/estimation/."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.estimation import ABLATIONS, LEVERS, PoseFrontEnd, front_end_for
from controllers.mpc.controller import NMPCController
from koopman_envs import Observed
from koopman_envs.settings import UNCERTAINTY_PRESETS


def _views(front_end, steps: int = 30, **env_kwargs):
    """The (measured, handed-on) Observed pairs of ``steps`` periods of a weaving team."""
    env = gym.make("KoopNav-TargetReaching-v0", slip="high", max_episode_steps=200, **env_kwargs)
    _, info = env.reset(seed=3)
    front_end.reset(env.unwrapped.scenario)
    pairs = []
    for t in range(steps):
        measured = Observed.from_info(info)
        pairs.append((measured, front_end.view(measured)))
        command = np.tile([0.3, 0.4 * np.sin(0.2 * t)], 3)
        front_end.sent(command)
        _, _, _, _, info = env.step(command)
    return pairs


def test_the_realistic_datasheet_is_the_presets_values_held_whatever_the_team_has() -> None:
    preset = UNCERTAINTY_PRESETS["realistic"]
    front_end = front_end_for("realistic")
    assert front_end is not None
    options = front_end.options
    assert (options.delay, options.position_std, options.heading_std) == (
        preset.actuation_delay,
        preset.pose_noise.xy,
        preset.pose_noise.heading,
    )
    # a team that localizes exactly and acts at once: the datasheet still filters and predicts
    # one period ahead (mis-specified), where "auto" identifies nothing and hands the poses on
    pairs = _views(front_end)
    assert front_end.delay == 1 and pairs[-1][1].pose_covariance is not None
    assert not np.array_equal(pairs[-1][0].observed_poses, pairs[-1][1].observed_poses)
    auto = front_end_for("auto")
    assert all(np.array_equal(m.observed_poses, v.observed_poses) for m, v in _views(auto))
    assert front_end_for("none") is None


def test_the_estimation_lever_hands_on_the_measured_poses_with_the_measurement_noise() -> None:
    """``ablate="estimation"``: no filter. With no delay assumed the poses handed on are the
    measured ones, bit for bit, with the assumed measurement noise as their covariance; with
    a delay they are predicted from the measured poses."""
    front_end = front_end_for("realistic", ablate="estimation")
    assert front_end is not None and not front_end.options.filter_poses
    for measured, view in _views(front_end, uncertainty="realistic")[1:]:
        assert not np.array_equal(measured.observed_poses, view.observed_poses)
    unfiltered = PoseFrontEnd(delay=0, position_std=0.03, heading_std=0.02, filter_poses=False)
    expected = np.broadcast_to(np.diag([0.03**2, 0.03**2, 0.02**2]), (3, 3, 3))
    for measured, view in _views(unfiltered, uncertainty="realistic"):
        np.testing.assert_array_equal(measured.observed_poses, view.observed_poses)
        np.testing.assert_allclose(view.pose_covariance, expected)
    filtered = PoseFrontEnd(delay=0, position_std=0.03, heading_std=0.02)
    assert all(
        not np.array_equal(m.observed_poses, v.observed_poses)
        for m, v in _views(filtered, uncertainty="realistic")[1:]
    )


def test_the_delay_compensation_lever_hands_on_the_filtered_pose_now() -> None:
    on = _views(front_end_for("realistic"), actuation_delay=1)
    off = _views(front_end_for("realistic", ablate="delay_compensation"), actuation_delay=1)
    # the same filter: the compensated pose is the uncompensated one driven one period further
    moved = [np.linalg.norm(a[1].observed_poses[:, :2] - b[1].observed_poses[:, :2]) for a, b in zip(on, off)]
    assert max(moved[2:]) > 0.02  # 0.3 m/s for one period of 0.1 s, per robot
    # and its covariance is the filter's own, smaller than the one grown over the delay
    assert np.all(off[-1][1].pose_covariance[:, 0, 0] < on[-1][1].pose_covariance[:, 0, 0])


@pytest.mark.parametrize("lever, method", [("tightening", "_tighten"), ("settling", "_settle")])
def test_the_nmpc_levers_switch_off_their_part_alone(lever: str, method: str, monkeypatch) -> None:
    """Under ``realistic`` every lever of the NMPC acts (the margins are widened and the settling
    rule runs on every successful solve); with ``ablate=lever`` that part never runs."""
    calls: dict[str, int] = {}
    original = getattr(NMPCController, method)

    def counted(self, *args, **kwargs):
        calls[self.config.ablate] = calls.get(self.config.ablate, 0) + 1
        return original(self, *args, **kwargs)

    monkeypatch.setattr(NMPCController, method, counted)
    for ablate in ("none", lever):
        env = gym.make("KoopNav-TargetReaching-v0", uncertainty="realistic", max_episode_steps=20)
        # the hand-set NMPC, built without a calibration (the tuned nominal-nmpc's margins need one)
        ctrl = controllers.make(
            "nominal-nmpc-v0", solver="rti", horizon=8, estimator="realistic", ablate=ablate
        )
        obs, info = env.reset(seed=0)
        ctrl.reset(env, seed=0)
        for _ in range(10):
            obs, *_, info = env.step(ctrl.act(obs, info))
    assert calls.get("none", 0) >= 9 and lever not in calls


@pytest.mark.parametrize(
    "name, options, message",
    [
        (
            "nominal-nmpc",
            {"ablate": "tightenin"},
            r"ablate='tightenin' is not one of .*did you mean 'tightening'",
        ),
        ("dmpc-nominal", {"ablate": "settling", "estimator": "none"}, r"estimator='none' has none"),
        (
            "consensus",
            {"ablate": "tightening"},
            r"ablate='tightening' is not one of \['none', 'estimation', 'delay_compensation'\]",
        ),
        (
            "koopman-nmpc",
            {"estimator": "harsh"},
            r"estimator='harsh' is not one of \['auto', 'realistic', 'none'\]",
        ),
        ("consensus", {"estimator": "ekf"}, r"estimator='ekf' is not one of"),
    ],
)
def test_bad_levers_name_the_value(name: str, options: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        controllers.make(name, **options)


def test_every_lever_is_a_choice_of_the_option_spec() -> None:
    from controllers.option_spec import options

    nmpc = {o.name: o for o in options("koopman-nmpc").options}
    assert nmpc["ablate"].choices == ABLATIONS and set(LEVERS) < set(ABLATIONS)
    consensus = {o.name: o for o in options("consensus").options}
    assert consensus["ablate"].choices == ("none", "estimation", "delay_compensation")
    assert consensus["estimator"].choices == nmpc["estimator"].choices == ("auto", "realistic", "none")
