"""Refits of the Koopman model on its own open-loop rollouts (issue 62): ``rollout_refits``."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.calibration import data_spec_for
from controllers.koopman import KoopmanModel, fit_bilinear, get_dictionary
from controllers.koopman.refit import MAX_ROLLOUT_REFITS, moved_rigidly, refit_on_rollouts
from controllers.koopman.store import _model_key, calibrated_model, fit_on_plant
from koopman_envs import make_plant
from tests.test_koopman_velocity import DT, _inert_team

ENV = "KoopNav-TargetReaching-v0"
DICTIONARY = get_dictionary("minimal")


def _plant(budget: int = 2000):
    return make_plant(ENV, slip="high", budget=budget, seed=0)


def _model_of(n: int, **lift):
    def model_of(fit) -> KoopmanModel:
        return KoopmanModel(fit.A, fit.N, fit.B, fit.C, DICTIONARY, n, DT, **lift)

    return model_of


@pytest.mark.parametrize("refits", [-1, MAX_ROLLOUT_REFITS + 1, 1.5, "1", True, None])
def test_bad_rollout_refits_are_refused_by_name(refits) -> None:
    import controllers

    for make in (
        lambda: controllers.make("koopman-nmpc", rollout_refits=refits),
        lambda: calibrated_model(_plant(200), 0, rollout_refits=refits),
        lambda: fit_on_plant(_plant(200), data_spec_for(200, 0), rollout_refits=refits),
    ):
        with pytest.raises(ValueError, match=rf"rollout_refits={refits!r} must be an integer"):
            make()


def test_rollout_refits_beside_the_per_robot_structure_are_refused_by_name() -> None:
    import controllers

    with pytest.raises(ValueError, match=r"rollout_refits=1 needs structure='stacked'"):
        controllers.make("koopman-nmpc", structure="per-robot", rollout_refits=1)
    with pytest.raises(ValueError, match=r"rollout_refits=2 needs structure='stacked'"):
        calibrated_model(_plant(200), 0, structure="per-robot", rollout_refits=2)


def test_no_refit_is_the_least_squares_fit_bit_for_bit() -> None:
    states, commands = _inert_team(binary=False)
    for lift in ({}, {"velocity": True}, {"memory": 2, "velocity": True}):
        plain = fit_bilinear(states, commands, DICTIONARY, **lift)
        same = refit_on_rollouts(states, commands, DICTIONARY, _model_of(2, **lift), 0, **lift)
        for name in ("A", "N", "B", "C"):
            assert getattr(plain, name).tobytes() == getattr(same, name).tobytes()


def test_a_refit_keeps_a_model_the_lift_holds_exactly() -> None:
    # the inert team is bilinear in the velocity lift: every rollout is exact, so every added
    # sample (the model's state, the period's command, the true move from it) is one more exact
    # transition, and the refit is the same model; a sample paired with the wrong period, command
    # or pose before would not be, and would spoil the fit
    states, commands = _inert_team()
    held_states, held_commands = _inert_team(seed=1)
    model_of = _model_of(2, velocity=True)
    for refits in (1, 2):
        fit = refit_on_rollouts(states, commands, DICTIONARY, model_of, refits, velocity=True)
        error = np.abs(model_of(fit).rollout(held_states[0], held_commands)[..., :2] - held_states[..., :2])
        assert error.max() < 1e-9, refits


def test_a_refit_changes_an_inexact_model_and_is_deterministic() -> None:
    states, commands = _inert_team(binary=False)
    model_of = _model_of(2, memory=1)
    plain = refit_on_rollouts(states, commands, DICTIONARY, model_of, 0, memory=1)
    first, second = (refit_on_rollouts(states, commands, DICTIONARY, model_of, 1, memory=1) for _ in range(2))
    assert first.A.tobytes() == second.A.tobytes() and first.N.tobytes() == second.N.tobytes()
    assert np.abs(first.A - plain.A).max() > 1e-6  # the rollouts' states are new samples


def test_the_target_is_the_true_move_made_from_the_predicted_pose() -> None:
    rng = np.random.default_rng(0)
    source, target = rng.uniform(-2, 2, (5, 3, 3)), rng.uniform(-2, 2, (5, 3, 3))
    after = rng.uniform(-2, 2, (5, 3, 3))
    moved = moved_rigidly(after, source, target)
    np.testing.assert_allclose(moved_rigidly(source, source, target), target, atol=1e-12)

    # the move in the body frame and the heading's change are kept
    def body_move(pose, start):
        c, s = np.cos(start[..., 2]), np.sin(start[..., 2])
        dx, dy = pose[..., 0] - start[..., 0], pose[..., 1] - start[..., 1]
        return np.stack([c * dx + s * dy, -s * dx + c * dy, pose[..., 2] - start[..., 2]], axis=-1)

    np.testing.assert_allclose(body_move(moved, target), body_move(after, source), atol=1e-12)


def test_rollout_refits_are_part_of_the_key_and_the_model_file() -> None:
    plant, spec = _plant(), data_spec_for(2000, 0)
    assert _model_key(plant, spec, "minimal", 0.0, velocity=True) == _model_key(
        plant, spec, "minimal", 0.0, velocity=True, rollout_refits=0
    )
    keys = {k: _model_key(plant, spec, "minimal", 0.0, velocity=True, rollout_refits=k) for k in (0, 1, 2)}
    assert len(set(keys.values())) == 3
    model = fit_on_plant(_plant(), spec, velocity=True, rollout_refits=1)
    assert model.metadata["rollout_refits"] == 1 and model.metadata["cache_key"] == keys[1]
    assert "rollout_refits" not in fit_on_plant(_plant(), spec, velocity=True).metadata


def test_koopman_nmpc_calibrates_with_rollout_refits() -> None:
    import controllers
    from controllers.mpc.variants import KoopmanNMPC

    ctrl = KoopmanNMPC(velocity=True, rollout_refits=1)
    summary = ctrl.calibrate(_plant(), seed=0)
    assert ctrl.model is not None and ctrl.model.metadata["rollout_refits"] == 1
    assert summary["key"] == _model_key(
        _plant(), data_spec_for(2000, 0), "minimal", 0.0, velocity=True, rollout_refits=1
    )
    assert controllers.options("koopman-nmpc").option("rollout_refits").default == 0
