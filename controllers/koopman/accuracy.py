"""The paper's circle test of a Koopman model (SPEC section 2).

Every robot drives v = 0.3 m/s, omega = 0.3 rad/s from (0, 0, 0), (-1, -1, 0), (1, 1, 0) for 210
periods; the model predicts open loop (re-lifting every step) and is compared with the
simulator. Under slip the truth is random, so the test reports the RMSE against one fixed-seed
realization, mean +- SD of the RMSE over ``repetitions`` realizations, the mean Hausdorff
distance over them, and the RMSE against the mean true trajectory. ``hausdorff_floor`` is what
the mean true trajectory itself scores against the realizations: no deterministic prediction
can be expected to do much better, which puts the slip-dominated Hausdorff figures in scale.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.koopman.model import KoopmanModel
from koopman_envs import rollout

__all__ = ["CircleReport", "circle_starts", "circle_test", "hausdorff", "rmse_percent"]

CIRCLE_V, CIRCLE_OMEGA, CIRCLE_STEPS = 0.3, 0.3, 210


def circle_starts(n_robots: int) -> NDArray[np.float64]:
    """The paper's starts (0,0,0), (-1,-1,0), (1,1,0), continued as (-2,-2,0), (2,2,0), ..."""
    starts = np.zeros((n_robots, 3))
    for i in range(1, n_robots):
        k = (i + 1) // 2
        starts[i, :2] = -k if i % 2 else k
    return starts


def rmse_percent(truth: NDArray, prediction: NDArray) -> NDArray[np.float64]:
    """Per-robot RMSE(%) = 100 sqrt(sum_t ||p_t - p^_t||^2 / T) over positions, t = 1..T.

    Parameters
    ----------
    truth, prediction : ndarray, shape (T + 1, N, 3)
    """
    diff = truth[1:, :, :2] - prediction[1:, :, :2]
    return 100.0 * np.sqrt((diff * diff).sum(-1).mean(axis=0))


def hausdorff(a: NDArray, b: NDArray) -> float:
    """Symmetric Hausdorff distance between two planar point sets (P, 2) and (Q, 2) [m]."""
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


@dataclass
class CircleReport:
    """Circle-test figures, one entry per robot."""

    rmse_fixed_seed: list[float]
    rmse_mean: list[float]
    rmse_sd: list[float]
    hausdorff_mean: list[float]
    rmse_vs_mean_truth: list[float]
    hausdorff_floor: list[float]  # mean Hausdorff of the mean true trajectory to the realizations
    repetitions: int
    seed: int
    lambdas: list[float]

    def to_dict(self) -> dict:
        """Plain-JSON form."""
        return asdict(self)


def circle_test(
    model: KoopmanModel,
    lambdas: NDArray,
    repetitions: int = 30,
    seed: int = 0,
) -> tuple[CircleReport, NDArray, NDArray]:
    """Run the circle test.

    Parameters
    ----------
    model : KoopmanModel
        The model under test.
    lambdas : ndarray, shape (N,)
        Slip means of the simulated robots (the truth).
    repetitions : int
        Slip realizations (the paper uses 30).
    seed : int
        Seed of the realizations; realization 0 is the "fixed-seed" one.

    Returns
    -------
    report : CircleReport
    prediction : ndarray, shape (T + 1, N, 3)
    truths : ndarray, shape (T + 1, repetitions, N, 3)
    """
    n = model.n_robots
    start = circle_starts(n)
    commands = np.tile([CIRCLE_V, CIRCLE_OMEGA], (CIRCLE_STEPS, n, 1))
    prediction = model.rollout(start, commands)
    truths = rollout(
        np.broadcast_to(start, (repetitions, n, 3)),
        np.broadcast_to(commands[:, None], (CIRCLE_STEPS, repetitions, n, 2)),
        np.asarray(lambdas, dtype=np.float64),
        np.random.default_rng(seed),
        dt=model.dt,
    )
    per_rep = np.stack([rmse_percent(truths[:, r], prediction) for r in range(repetitions)])
    haus = np.array(
        [[hausdorff(truths[:, r, i, :2], prediction[:, i, :2]) for i in range(n)] for r in range(repetitions)]
    )
    mean_truth = truths.mean(axis=1)
    floor = np.array(
        [[hausdorff(truths[:, r, i, :2], mean_truth[:, i, :2]) for i in range(n)] for r in range(repetitions)]
    )
    report = CircleReport(
        rmse_fixed_seed=per_rep[0].tolist(),
        rmse_mean=per_rep.mean(axis=0).tolist(),
        rmse_sd=per_rep.std(axis=0, ddof=1).tolist() if repetitions > 1 else [0.0] * n,
        hausdorff_mean=haus.mean(axis=0).tolist(),
        rmse_vs_mean_truth=rmse_percent(mean_truth, prediction).tolist(),
        hausdorff_floor=floor.mean(axis=0).tolist(),
        repetitions=repetitions,
        seed=seed,
        lambdas=[float(v) for v in lambdas],
    )
    return report, prediction, truths
