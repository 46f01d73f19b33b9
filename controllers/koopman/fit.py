"""Least-squares fit of the bilinear lifted model z+ = A z + N (u kron z) + B u, x = C z.

The regression matrix Phi = [Z; U kron Z; U] (1M rows x 97 columns for 3 robots) is never
formed whole: its Gram matrix and right-hand sides are accumulated chunk by chunk, which keeps
memory at a few tens of MB. With the constant observable in the dictionary the columns
``u kron 1`` of the bilinear block repeat the columns of ``U`` exactly, so the problem is
rank-deficient by construction; the fit removes that duplication explicitly, solves the
remaining positive definite normal equations by a column-scaled Cholesky factorization (no
explicit inverse), and splits the shared coefficients evenly between N and B, which is the
minimum-norm minimizer that the Moore-Penrose solution of SPEC eq. 9 returns. An optional ridge
term regularizes the scaled equations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.calibration import poses_before, previous_commands
from controllers.koopman.dictionary import (
    Dictionary,
    check_memory,
    check_velocity,
    lift_state,
    lifted_size,
)

__all__ = [
    "STRUCTURES",
    "BilinearFit",
    "MomentAccumulator",
    "accumulate_bilinear",
    "fit_bilinear",
    "fit_lifted",
    "fit_per_robot",
]

#: how a team model couples its robots: ``"stacked"`` (the paper's: one regression over the whole
#: team, every robot's next observables may depend on every robot's) or ``"per-robot"`` (each
#: robot's observables depend on its own state and commands only, fitted robot by robot)
STRUCTURES = ("stacked", "per-robot")


@dataclass(frozen=True)
class BilinearFit:
    """Fitted matrices and diagnostics.

    Attributes
    ----------
    A : ndarray, shape (D, D)
    N : ndarray, shape (D, m D)
        Bilinear term, acting on ``kron(u, z)``.
    B : ndarray, shape (D, m)
    C : ndarray, shape (4 N_r, D)
        Projection onto (x, y, cos theta, sin theta) of every robot.
    residual : float
        RMS one-step residual in the lifted space over the training data.
    rank : int
        Numerical rank of the regression matrix.
    coordinate_residual : ndarray, shape (D,)
        RMS one-step residual of each lifted coordinate over the training data.
    """

    A: NDArray[np.float64]
    N: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    residual: float
    rank: int
    coordinate_residual: NDArray[np.float64]


def _cholesky_solve(gram: NDArray, rhs: NDArray, ridge: float, rcond: float) -> NDArray:
    """Solve gram @ W = rhs for a symmetric positive definite ``gram``, columns scaled first.

    Written with elementwise numpy operations only: LAPACK's factorizations call threaded BLAS
    whose rounding depends on the thread count, and a refit must reproduce a model bit for bit
    on any machine. At the sizes involved (~100 unknowns) this costs a few milliseconds.

    Raises
    ------
    ValueError
        When a pivot falls below ``rcond`` times the largest diagonal entry, i.e. the regression
        matrix is (numerically) rank deficient beyond the structural duplication handled by the
        caller; a ``ridge > 0`` makes the system definite.
    """
    scale = np.sqrt(np.diag(gram)).copy()
    scale[scale == 0] = 1.0
    lower = gram / np.multiply.outer(scale, scale)
    n = lower.shape[0]
    lower[np.arange(n), np.arange(n)] += ridge
    tol = rcond * lower.diagonal().max()
    for k in range(n):
        pivot = lower[k, k]
        if not pivot > tol:
            raise ValueError(
                f"the regression matrix is rank deficient (pivot {pivot:.3e} of column {k}); "
                "the data do not excite every observable: pass ridge > 0"
            )
        root = np.sqrt(pivot)
        lower[k, k] = root
        column = lower[k + 1 :, k] / root
        lower[k + 1 :, k] = column
        lower[k + 1 :, k + 1 :] -= np.multiply.outer(column, column)
    b = rhs / scale[:, None]
    y = np.empty_like(b)
    for k in range(n):
        y[k] = (b[k] - (lower[k, :k, None] * y[:k]).sum(axis=0)) / lower[k, k]
    x = np.empty_like(b)
    for k in range(n - 1, -1, -1):
        x[k] = (y[k] - (lower[k + 1 :, k, None] * x[k + 1 :]).sum(axis=0)) / lower[k, k]
    return x / scale[:, None]


class MomentAccumulator:
    """Running moments of the augmented regression rows ``[z, kron(u, z), z_next]``.

    The ``u`` block of the regression rows is not accumulated: with the constant observable
    first, ``kron(u, z)`` already holds it (columns ``d + i d``), and :meth:`solve` restores it.

    Parameters
    ----------
    d : int
        Lifted dimension D (observable 0 must be the constant 1).
    m : int
        Input dimension.
    """

    def __init__(self, d: int, m: int) -> None:
        self.d, self.m = d, m
        self.p = d + m * d + m  # regressors of the full problem [z, kron(u, z), u]
        self.q = d + m * d  # regressors accumulated
        self.moments = np.zeros((self.q + d, self.q + d))
        self.count = 0

    def add(self, z: NDArray, u: NDArray, z_next: NDArray) -> None:
        """Accumulate samples: z, z_next of shape (S, D) and u of shape (S, m)."""
        s, d, q = z.shape[0], self.d, self.q
        rows = np.empty((s, q + d))
        rows[:, :d] = z
        np.multiply(u[:, :, None], z[:, None, :], out=rows[:, d:q].reshape(s, self.m, d))
        rows[:, q:] = z_next
        # one symmetric rank-k update (BLAS syrk) gives the Gram matrix, the right-hand sides
        # and |z_next|^2 together, and unlike a general product it is bit-identical for any
        # number of BLAS threads
        self.moments += rows.T @ rows
        self.count += s

    def solve(
        self, state_rows: NDArray, ridge: float = 0.0, rcond: float = 1e-12
    ) -> tuple[NDArray, NDArray, NDArray, NDArray, float, int, NDArray]:
        """Least-squares [A, N, B], C = X Z^+ (X = the ``state_rows`` of Z), residual, rank and
        per-coordinate residual."""
        d, m, p, q = self.d, self.m, self.p, self.q
        gram, rhs = self.moments[:q, :q], self.moments[:q, q:]
        target_sq = np.diag(self.moments[q:, q:])
        # The columns u_i kron 1 (index d + i d: the constant is observable 0) equal the columns
        # of U: solve without the U block, then split each duplicated coefficient evenly between
        # N and B, which is exactly the minimum-norm (Moore-Penrose) solution of the full problem.
        reduced = _cholesky_solve(gram, rhs, ridge, rcond)
        # residual from the moments: ||Z' - Phi W||^2 = |Z'|^2 - 2 W.H + W.G W; the split
        # below leaves the fitted values Phi W unchanged, so the reduced system gives it
        fitted = np.einsum("ij,jk->ik", gram, reduced)
        sq = target_sq - 2 * np.einsum("ij,ij->j", reduced, rhs) + np.einsum("ij,ij->j", reduced, fitted)
        residual = float(np.sqrt(max(sq.sum(), 0.0) / (max(self.count, 1) * d)))
        coordinate_residual = np.sqrt(np.maximum(sq, 0.0) / max(self.count, 1))
        solution = np.zeros((p, d))
        solution[:q] = reduced
        shared = d + d * np.arange(m)
        solution[shared] *= 0.5
        solution[q:] = solution[shared]
        weights = solution.T  # (d, p)
        # C = X Z^+ with X = rows of Z: the Z-block of the same Gram matrix
        c_matrix = _cholesky_solve(gram[:d, :d], gram[:d, :d][:, state_rows], 0.0, rcond)
        a_matrix = weights[:, :d].copy()
        n_matrix = weights[:, d:q].copy()
        b_matrix = weights[:, q:].copy()
        return a_matrix, n_matrix, b_matrix, c_matrix.T.copy(), residual, p - m, coordinate_residual


def fit_lifted(
    z: NDArray, u: NDArray, z_next: NDArray, state_rows: NDArray, ridge: float = 0.0
) -> BilinearFit:
    """Fit from lifted samples directly (observable 0 of z must be the constant 1).

    Parameters
    ----------
    z, z_next : ndarray, shape (S, D)
    u : ndarray, shape (S, m)
    state_rows : ndarray of int
        Rows of z that C projects onto.
    ridge : float
        Tikhonov term of the column-scaled normal equations.
    """
    acc = MomentAccumulator(z.shape[1], u.shape[1])
    acc.add(np.asarray(z, float), np.asarray(u, float), np.asarray(z_next, float))
    return BilinearFit(*acc.solve(np.asarray(state_rows).reshape(-1), ridge))


def fit_bilinear(
    states: NDArray,
    commands: NDArray,
    dictionary: Dictionary,
    ridge: float = 0.0,
    rcond: float = 1e-12,
    chunk: int = 32_768,
    memory: int = 0,
    velocity: bool = False,
) -> BilinearFit:
    """Fit [A, N, B] = Z' [Z; U kron Z; U]^+ and C = X Z^+ (SPEC eq. 9).

    Parameters
    ----------
    states : ndarray, shape (T + 1, B, N, 3)
        Trajectories (see :class:`controllers.koopman.data.TrajectoryData`).
    commands : ndarray, shape (T, B, N, 2)
        Commands; u_k stacks every robot's (v, omega), robot by robot (m = 2N).
    dictionary : Dictionary
        Observables.
    ridge : float
        Tikhonov term added to the column-scaled normal equations (0 = plain least squares).
    rcond : float
        Relative pivot tolerance that flags a rank-deficient problem.
    chunk : int
        Transitions per accumulation chunk (memory ~ chunk x 104 x 8 bytes for 3 robots).
    memory : int
        Previous commands in the lift (:func:`~controllers.koopman.dictionary.lift_memory`;
        0: the paper's pose-only lift). Every trajectory is taken to start at rest, as the
        calibration plant's teams do: the commands before its first period count as zero.
    velocity : bool
        Also the last period's move in the lift
        (:func:`~controllers.koopman.dictionary.lift_velocity`); at a trajectory's start the
        robots stand (no move before it).

    Returns
    -------
    BilinearFit
    """
    acc = accumulate_bilinear(states, commands, dictionary, chunk, memory, velocity)
    n = commands.shape[2]
    return BilinearFit(*acc.solve(dictionary.state_rows(n).reshape(-1), ridge, rcond))


def accumulate_bilinear(
    states: NDArray,
    commands: NDArray,
    dictionary: Dictionary,
    chunk: int = 32_768,
    memory: int = 0,
    velocity: bool = False,
) -> MomentAccumulator:
    """The moments of :func:`fit_bilinear`'s regression on trajectories (arguments as there), to
    solve or to add further samples to (:mod:`controllers.koopman.refit`)."""
    steps, batch, n = commands.shape[:3]
    if states.shape[:3] != (steps + 1, batch, n):
        raise ValueError(f"states {states.shape} and commands {commands.shape} do not match")
    memory, velocity = check_memory(memory), check_velocity(velocity)
    d = lifted_size(dictionary, n, memory, velocity)
    m = 2 * n
    acc = MomentAccumulator(d, m)
    flat_u = commands.reshape(steps * batch, m)
    previous = previous_commands(commands, memory) if memory else None  # (T + 1, B, memory, N, 2)
    # chunks run over whole periods so z_k and z_k+1 come from contiguous slices
    per_chunk = max(1, chunk // batch)
    for t0 in range(0, steps, per_chunk):
        t1 = min(steps, t0 + per_chunk)
        z_all = lift_state(  # (t1 - t0 + 1, batch, d)
            dictionary,
            states[t0 : t1 + 1],
            memory,
            None if previous is None else previous[t0 : t1 + 1],
            velocity,
            # the pose before period t0 is the last of the previous chunk (the start's own at t0 = 0)
            poses_before(states, t0, t1 + 1) if velocity else None,
        )
        acc.add(z_all[:-1].reshape(-1, d), flat_u[t0 * batch : t1 * batch], z_all[1:].reshape(-1, d))
    return acc


def fit_per_robot(
    states: NDArray, commands: NDArray, dictionary: Dictionary, ridge: float = 0.0, rcond: float = 1e-12
) -> BilinearFit:
    """The team model with the ``"per-robot"`` structure: robot r's rows from its own data only.

    The robots' kinematics do not couple (slip is drawn per robot), so the stacked model's
    cross-robot coefficients are zero up to estimation noise; fitting each robot's one-robot
    model and placing it block-diagonally keeps that structure exactly. Regressors per robot:
    1 + p + 2 (1 + p) (p observables per robot) instead of (1 + pN)(1 + 2N) for the team, so the
    fit and the NMPC's problem grow linearly with N. Arguments as :func:`fit_bilinear`; the
    residuals are per lifted coordinate of the team, ``residual`` their RMS.
    """
    n = commands.shape[2]
    p = dictionary.per_robot
    d, d1, m = dictionary.size(n), 1 + p, 2 * n
    a, b = np.zeros((d, d)), np.zeros((d, m))
    bilinear = np.zeros((d, m * d))
    a[0, 0] = 1.0  # the constant stays 1
    coordinate = np.zeros(d)
    rank = 0
    for r in range(n):
        one = fit_bilinear(states[:, :, r : r + 1], commands[:, :, r : r + 1], dictionary, ridge, rcond)
        index = np.concatenate([[0], 1 + p * r + np.arange(p)])  # robot r's observables in the team's z
        rows = index[1:]
        a[np.ix_(rows, index)] = one.A[1:]
        for k in range(2):  # v_r, omega_r
            column = (2 * r + k) * d + index
            bilinear[np.ix_(rows, column)] = one.N[1:, k * d1 : (k + 1) * d1]
            b[rows, 2 * r + k] = one.B[1:, k]
        coordinate[rows] = one.coordinate_residual[1:]
        rank += one.rank
    c = np.zeros((4 * n, d))
    c[np.arange(4 * n), dictionary.state_rows(n).reshape(-1)] = 1.0
    residual = float(np.sqrt(np.mean(coordinate[1:] ** 2)))
    return BilinearFit(a, bilinear, b, c, residual, rank, coordinate)
