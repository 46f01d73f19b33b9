"""The NMPCs' collision margins beyond the fixed offsets: the spread of the prediction model's
calibrated residual (``uncertainty_margin``) and the chance-constrained widening by an
estimator's pose covariance (``chance_risk``). Both are per robot toward obstacles and movers,
and per pair between robots; the central and the distributed NMPC use the same functions."""

from __future__ import annotations

import statistics

import numpy as np
from numpy.typing import NDArray

__all__ = ["chance_tightening", "margin_spread", "offset_margins"]


def margin_spread(name: str, k: float, residual: NDArray | None, n_robots: int) -> NDArray[np.float64] | None:
    """``k`` times each robot's calibrated RMS one-step position residual [m], the spread that
    widens the margins (None for k = 0).

    Raises
    ------
    ValueError
        k > 0 without a residual for ``n_robots`` robots (calibration has not run).
    """
    if k == 0:
        return None
    if residual is None or len(residual) != n_robots:
        raise ValueError(
            f"{name}: uncertainty_margin={k} needs the prediction model's residual for "
            f"{n_robots} robots; call calibrate(plant) first (the evaluator does)"
        )
    return k * np.asarray(residual, dtype=float)


def chance_tightening(
    covariance: NDArray | None, risk: float, n_robots: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """How much to widen the collision margins for the pose estimate's uncertainty.

    Parameters
    ----------
    covariance : ndarray, shape (N, 3, 3), or None
        Each robot's pose covariance (x, y, heading), as an estimator hands it on.
    risk : float
        Risk level in (0, 0.5): the margin is z sigma with z the standard normal quantile of
        ``1 - risk``.
    n_robots : int
        N.

    Returns
    -------
    per_robot : ndarray, shape (N,)
        z sigma_i [m], sigma_i the position standard deviation along the worst direction (the
        square root of the largest eigenvalue of the 2x2 position block): added toward obstacles
        and movers. Zeros without a covariance.
    per_pair : ndarray, shape (N (N - 1) / 2,)
        z sqrt(sigma_i^2 + sigma_j^2) for each pair i < j (the difference of two independent
        errors): added between robots.
    """
    pairs = [(i, j) for i in range(n_robots) for j in range(i + 1, n_robots)]
    if covariance is None:
        return np.zeros(n_robots), np.zeros(len(pairs))
    cov = np.asarray(covariance, dtype=np.float64)
    if cov.shape != (n_robots, 3, 3) or not np.all(np.isfinite(cov)):
        raise ValueError(
            f"pose_covariance has shape {cov.shape} or a non-finite entry; expected finite ({n_robots}, 3, 3)"
        )
    variance = np.maximum(np.linalg.eigvalsh(cov[:, :2, :2])[:, -1], 0.0)
    z = statistics.NormalDist().inv_cdf(1.0 - risk)
    per_pair = np.array([z * np.sqrt(variance[i] + variance[j]) for i, j in pairs])
    return z * np.sqrt(variance), per_pair.reshape(len(pairs))


def offset_margins(
    n_robots: int, obstacle_offset: float, robot_offset: float, k: float, residual: NDArray | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The margins added to the radii: per robot toward obstacles (N,), per robot pair i < j.

    The offsets, widened to ``k`` times each robot's RMS one-step position residual [m] (pairs:
    the sum of both robots' spreads) when that is larger; the offsets only for ``k = 0`` or no
    residual.
    """
    n = n_robots
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    obstacle = np.full(n, obstacle_offset)
    pair = np.full(len(pairs), robot_offset)
    if k > 0 and residual is not None:
        spread = k * np.asarray(residual, dtype=float)
        obstacle = np.maximum(obstacle, spread)
        pair = np.maximum(pair, np.array([spread[i] + spread[j] for i, j in pairs]))
    return obstacle, pair
