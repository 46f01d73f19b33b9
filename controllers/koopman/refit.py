"""Refits of a fitted Koopman model on its own open-loop rollouts (issue 62, docs/physics.md).

The least-squares fit (:func:`~controllers.koopman.fit.fit_bilinear`) minimizes the one-step
error on the identification data, where every lifted state is a measured one. The NMPC feeds the
model its own predictions for a horizon of periods, whose lifted states drift away from any
measured one (on ice the predicted speed lags the robots'), and the one-step fit never saw such
states. A refit adds them ("data as demonstrator", Venkatraman, Hebert and Bagnell, AAAI 2015):
the model predicts ``horizon`` periods open loop from windows of the identification data, and
every predicted lifted state, with the period's command, becomes a further regression sample
whose target is what the robots really did next, aggregated with the data and every earlier
refit's samples; the fit is solved again and the next refit rolls out the new model.

The target is the true next lifted state moved rigidly (per robot: the rotation and translation
that take the true pose onto the predicted one), so that it is the robot's true move made from
the predicted pose: an error of position or heading that the lifted state cannot know (the
robots' motion is the same everywhere on a uniform floor) is not asked to be undone, while the
predicted velocity and remembered commands are asked to produce the true move.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from controllers.calibration import poses_before, previous_commands
from controllers.koopman.dictionary import Dictionary, lift_state
from controllers.koopman.fit import BilinearFit, accumulate_bilinear
from controllers.koopman.model import KoopmanModel
from koopman_envs.checks import check_int
from koopman_envs.params import PARAMS

__all__ = [
    "MAX_ROLLOUT_REFITS",
    "ROLLOUT_STRIDE",
    "check_rollout_refits",
    "moved_rigidly",
    "refit_on_rollouts",
]

#: the most refits a calibration may ask for (each costs about one fit of the data)
MAX_ROLLOUT_REFITS = 5
#: periods between the starts of two rollout windows of a trajectory (every 10th period: a tenth of
#: the periods start a window, so a refit adds about (horizon - 1) / 10 samples per transition)
ROLLOUT_STRIDE = 10


def check_rollout_refits(refits: object) -> int:
    """``rollout_refits`` as an int in [0, :data:`MAX_ROLLOUT_REFITS`], else ``ValueError`` naming it."""
    return check_int(
        "rollout_refits",
        refits,
        0,
        maximum=MAX_ROLLOUT_REFITS,
        note="refits of the model on its own open-loop rollouts; 0: the one-step least squares",
    )


def moved_rigidly(poses: NDArray, source: NDArray, target: NDArray) -> NDArray[np.float64]:
    """``poses`` (..., N, 3) moved, robot by robot, by the rigid motion that takes the pose
    ``source`` (..., N, 3) onto ``target`` (..., N, 3) (rotation by the heading difference about
    ``source``, then the translation)."""
    turn = target[..., 2] - source[..., 2]
    c, s = np.cos(turn), np.sin(turn)
    dx, dy = poses[..., 0] - source[..., 0], poses[..., 1] - source[..., 1]
    return np.stack(
        [target[..., 0] + c * dx - s * dy, target[..., 1] + s * dx + c * dy, poses[..., 2] + turn], axis=-1
    )


def refit_on_rollouts(
    states: NDArray,
    commands: NDArray,
    dictionary: Dictionary,
    model_of: Callable[[BilinearFit], KoopmanModel],
    refits: int,
    memory: int = 0,
    velocity: bool = False,
    ridge: float = 0.0,
    horizon: int = PARAMS.horizon,
) -> BilinearFit:
    """The bilinear fit of trajectories, refitted ``refits`` times on the model's own rollouts.

    Parameters
    ----------
    states : ndarray, shape (T + 1, B, N, 3)
        Identification trajectories (poses), every one starting at rest.
    commands : ndarray, shape (T, B, N, 2)
        Their commands.
    dictionary : Dictionary
        Observables.
    model_of : callable
        Makes the model whose :meth:`~controllers.koopman.model.KoopmanModel.rollout` predicts
        the windows from a fit (the caller's, so that its rollout is the NMPC's).
    refits : int
        Refits (0: :func:`~controllers.koopman.fit.fit_bilinear`'s fit, unchanged).
    memory, velocity
        The lift (:func:`~controllers.koopman.dictionary.lift_state`).
    ridge : float
        Tikhonov term of every solve.
    horizon : int
        Periods of a rollout window (default: the NMPC's horizon).

    Returns
    -------
    BilinearFit
        The last solve's matrices; its residuals are over the data and the added samples.
    """
    refits = check_rollout_refits(refits)
    steps, _, n = commands.shape[:3]
    rows = dictionary.state_rows(n).reshape(-1)
    acc = accumulate_bilinear(states, commands, dictionary, memory=memory, velocity=velocity)
    fit = BilinearFit(*acc.solve(rows, ridge))
    if not refits:
        return fit
    starts = np.arange(0, steps - horizon + 1, ROLLOUT_STRIDE)
    if not len(starts):
        raise ValueError(f"trajectories of {steps} periods are shorter than a rollout window of {horizon}")
    window = starts[None, :] + np.arange(horizon)[:, None]  # (H, W)
    # the commands before every period (T + 1, B, memory, N, 2); none remembered without memory
    previous = previous_commands(commands, memory) if memory else np.zeros((steps + 1, 1, 0, n, 2))
    before = poses_before(states)  # (T + 1, B, N, 3)
    d = acc.d
    for _ in range(refits):
        predicted = model_of(fit).rollout(
            states[starts], commands[window], previous[starts] if memory else None, before[starts]
        )
        # predicted[t]: the model's poses t periods into each window (period starts + t); t = 0 is
        # measured, and already in the data
        for t in range(1, horizon):
            now = starts + t
            z_model = lift_state(dictionary, predicted[t], memory, previous[now], velocity, predicted[t - 1])
            truth = moved_rigidly(states[now + 1], states[now], predicted[t])
            z_next = lift_state(dictionary, truth, memory, previous[now + 1], velocity, predicted[t])
            acc.add(z_model.reshape(-1, d), commands[now].reshape(-1, 2 * n), z_next.reshape(-1, d))
        fit = BilinearFit(*acc.solve(rows, ridge))
    return fit
