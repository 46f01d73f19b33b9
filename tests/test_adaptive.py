"""The online Koopman update (RLS) and the adaptive Koopman-NMPC built on it."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the envs
from controllers.calibration import calibrate_controller
from controllers.koopman import KoopmanModel
from controllers.koopman.online import RecursiveBilinearFit
from controllers.mpc.variants import AdaptiveKoopmanNMPC
from koopman_envs.episodes.single import run_episode

SHIPPED = "controllers/koopman/models/nominal.npz"


@pytest.fixture(scope="module")
def shipped() -> KoopmanModel:
    from pathlib import Path

    return KoopmanModel.load(Path(__file__).resolve().parents[1] / SHIPPED)


def _faster(model: KoopmanModel, gain: float) -> KoopmanModel:
    """A 'true' system: the model with every command's effect scaled (as traction slip does)."""
    return dataclasses.replace(model, N=model.N * gain, B=model.B * gain, metadata={})


def _trajectory(true: KoopmanModel, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = true.n_robots
    poses = np.empty((steps + 1, n, 3))
    poses[0] = rng.uniform(-1, 1, (n, 3))
    commands = rng.uniform(-1.0, 1.0, (steps, n, 2))
    for t in range(steps):
        poses[t + 1] = true.step(poses[t], commands[t])
    return poses, commands


def test_rls_recovers_a_known_bilinear_system_from_its_own_trajectory(shipped):
    true = _faster(shipped, 1.5)
    fit = RecursiveBilinearFit(shipped, forgetting=1.0, prior_weight=1.0)
    poses, commands = _trajectory(true, 1000, seed=0)
    prior_errors, errors = [], []
    for t in range(1000):
        prior_errors.append(shipped.step(poses[t], commands[t])[:, :2] - poses[t + 1][:, :2])
        errors.append(fit.update(poses[t], commands[t], poses[t + 1]).reshape(-1, 4)[:, :2])
    assert fit.updates == 1000 and fit.rejected == 0
    # a-priori one-step errors (each made before its transition was folded in) over the last
    # 200 periods: the calibrated model misses the faster robots, the updated one does not
    prior_rms = np.sqrt(np.mean(np.square(prior_errors[800:])))
    rms = np.sqrt(np.mean(np.square(errors[800:])))
    assert prior_rms > 2e-3
    assert rms < 0.2 * prior_rms
    # the command gains themselves: robot r's x+ has v_r cos(theta_r) with coefficient ~1.5 dt
    d = shipped.A.shape[0]
    _, n_matrix, _ = fit.matrices()
    for r in range(3):
        row = fit.outputs[4 * r]  # the lifted x of robot r
        column = (2 * r) * d + 3 + 4 * r  # v_r times cos(theta_r)
        assert n_matrix[row, column] == pytest.approx(true.N[row, column], rel=0.05)
        assert abs(n_matrix[row, column] - shipped.N[row, column]) > 0.3 * abs(shipped.N[row, column])


def test_rls_parameters_match_the_model_layout_and_reset_restores_the_prior(shipped):
    fit = RecursiveBilinearFit(shipped, forgetting=0.95, prior_weight=50.0)
    assert np.array_equal(fit.nlp_parameters(), shipped.nlp_parameters())
    poses, commands = _trajectory(_faster(shipped, 1.3), 50, seed=2)
    for t in range(50):
        fit.update(poses[t], commands[t], poses[t + 1])
    theta = fit.nlp_parameters()
    assert not np.array_equal(theta, shipped.nlp_parameters())
    assert np.allclose(theta, shipped.nlp_parameters_of(*fit.matrices()), rtol=0, atol=1e-12)
    fit.reset()
    assert np.array_equal(fit.nlp_parameters(), shipped.nlp_parameters()) and fit.updates == 0


def test_rls_guards_keep_the_covariance_bounded_and_reject_non_finite_data(shipped):
    fit = RecursiveBilinearFit(shipped, forgetting=0.5, prior_weight=10.0)
    bounds = [np.trace(c) for c in fit.covariances]
    still = np.zeros((3, 3))
    for _ in range(200):  # no excitation at all: plain forgetting would blow P up by 2**200
        fit.update(still, np.zeros((3, 2)), still)
    assert all(np.trace(c) <= b * (1 + 1e-9) for c, b in zip(fit.covariances, bounds))
    assert np.all(np.isfinite(fit.weights))
    weights = fit.weights.copy()
    fit.update(still, np.zeros((3, 2)), np.full((3, 3), np.nan))
    assert fit.rejected == 1 and np.array_equal(fit.weights, weights)


def test_input_only_update_keeps_the_uncommanded_motion_and_still_learns_the_gains(shipped):
    true = _faster(shipped, 1.5)  # only the command terms differ, as with traction slip
    fit = RecursiveBilinearFit(shipped, forgetting=1.0, prior_weight=1.0, adapted="input")
    poses, commands = _trajectory(true, 600, seed=1)
    for t in range(600):
        fit.update(poses[t], commands[t], poses[t + 1])
    a_matrix, n_matrix, _ = fit.matrices()
    rows = fit.outputs
    assert np.array_equal(a_matrix[rows], shipped.A[rows])  # A untouched, bit for bit
    d = shipped.A.shape[0]
    for r in range(3):
        column = (2 * r) * d + 3 + 4 * r  # v_r times cos(theta_r) in robot r's lifted x
        assert n_matrix[rows[4 * r], column] == pytest.approx(true.N[rows[4 * r], column], rel=0.05)
    # the unrestricted update moves A too (on the same data)
    free = RecursiveBilinearFit(shipped, forgetting=1.0, prior_weight=1.0)
    for t in range(600):
        free.update(poses[t], commands[t], poses[t + 1])
    assert not np.array_equal(free.matrices()[0][rows], shipped.A[rows])


@pytest.mark.parametrize("value", ["inputs", "", None, "A"])
def test_adapted_terms_outside_the_choices_are_rejected(value, shipped):
    with pytest.raises(ValueError, match=r"adapted=.*'all', 'input'"):
        RecursiveBilinearFit(shipped, adapted=value)
    with pytest.raises(ValueError, match=r"adapted=.*'all', 'input'"):
        AdaptiveKoopmanNMPC(adapted=value)


@pytest.mark.parametrize("value", [0.0, -0.1, 1.5, float("nan"), True, "0.9"])
def test_forgetting_factor_out_of_range_is_rejected(value, shipped):
    with pytest.raises(ValueError, match=r"forgetting=.*\(0, 1\]"):
        RecursiveBilinearFit(shipped, forgetting=value)
    with pytest.raises(ValueError, match=r"forgetting=.*\(0, 1\]"):
        AdaptiveKoopmanNMPC(forgetting=value)


@pytest.mark.parametrize(
    ("option", "value"),
    [("prior_weight", 0.0), ("prior_weight", float("inf")), ("residual_window", 0), ("residual_window", 2.5)],
)
def test_adaptive_options_out_of_range_are_rejected(option, value):
    with pytest.raises(ValueError, match=option):
        AdaptiveKoopmanNMPC(**{option: value})


def _episode(controller, env_id="KoopNav-TargetReaching-v0", seed=0, **env_kwargs):
    env = gym.make(env_id, **env_kwargs)
    calibrate_controller(controller, env, seed=0)
    actions: list[np.ndarray] = []
    result = run_episode(
        env, controller, seed=seed, on_step=lambda step, action, info: actions.append(action)
    )
    return result, np.asarray(actions)


def test_adaptive_controller_learns_during_a_real_episode_and_is_reproducible():
    ctrl = controllers.make("adaptive-koopman-nmpc")
    first, actions = _episode(ctrl, map="map1", slip="high", max_episode_steps=25)
    summary = ctrl.stats().summary()
    assert first.steps == 25 and summary["failures"] == 0
    assert ctrl._estimator.updates == 24  # one transition per period after the first
    assert summary["online_update_ms_median"] > 0 and summary["online_updates_rejected"] == 0
    # the model the NMPC now uses differs from the calibrated one it started from
    assert not np.array_equal(ctrl.parameter("model"), ctrl.model.nlp_parameters())
    # a new episode starts from the calibrated model again: same seed, same commands, bit for bit
    again, actions_again = _episode(ctrl, map="map1", slip="high", max_episode_steps=25)
    assert np.array_equal(actions, actions_again)


def test_frozen_adaptive_controller_is_koopman_nmpc_with_residual_margins():
    frozen = controllers.make("adaptive-koopman-nmpc", adapt=False, uncertainty_margin=0.0)
    plain = controllers.make("koopman-nmpc-v0")  # the hand-set options the adaptive one keeps
    _, a = _episode(frozen, map="map1", slip="nominal", max_episode_steps=15)
    _, b = _episode(plain, map="map1", slip="nominal", max_episode_steps=15)
    assert np.array_equal(a, b)


def test_per_robot_models_adapt_robot_by_robot(shipped):
    """A per-robot (block-diagonal) model gets one small RLS per robot, and learns as the stacked one."""
    from controllers.koopman.dictionary import get_dictionary
    from controllers.koopman.fit import fit_per_robot

    poses, commands = _trajectory(shipped, 400, seed=4)  # data of the shipped model's own dynamics
    fit = fit_per_robot(poses[:, None], commands[:, None], get_dictionary("minimal"))
    block = dataclasses.replace(shipped, A=fit.A, N=fit.N, B=fit.B, C=fit.C, metadata={})
    online = RecursiveBilinearFit(block, forgetting=1.0, prior_weight=1.0)
    assert len(online._groups) == 3 and all(len(outs) == 4 for _, outs in online._groups)
    assert all(regressors.size == 15 for regressors, _ in online._groups)  # 1 + 4 + 2 x 5
    true = _faster(block, 1.5)
    poses, commands = _trajectory(true, 1000, seed=0)
    errors = [online.update(poses[t], commands[t], poses[t + 1]).reshape(-1, 4)[:, :2] for t in range(1000)]
    prior = [block.step(poses[t], commands[t])[:, :2] - poses[t + 1][:, :2] for t in range(800, 1000)]
    assert np.sqrt(np.mean(np.square(errors[800:]))) < 0.2 * np.sqrt(np.mean(np.square(prior)))
    # still block-diagonal: robot 0's rows use nothing of robot 1
    a, n, _ = online.matrices()
    assert not np.any(a[1:5, 5:9]) and np.array_equal(
        online.nlp_parameters().size, block.nlp_parameters().size
    )
