"""Exact solver for two-variable quadratic programs (the safety filter's per-robot QP), compiled.

Each problem is

    minimize    (u - target)^T diag(weight) (u - target)
    subject to  A u >= b          (m rows; a zero row means 0 >= b_k)

With ``z = sqrt(weight) * (u - target)`` it is the Euclidean projection of the origin onto the
polygon ``P = {z : G z >= c}`` (``G = A / sqrt(weight)``, ``c = b - A target``), and its unique
solution ``z*`` is one of a few candidates, each computed in closed form:

1. ``z = 0`` when it is feasible (the command is left alone);
2. otherwise the projection of 0 onto the line of a row k that 0 violates (``c_k > 0``): if that
   point is feasible it is optimal, because every point of P lies in row k's half-plane, which
   is at distance ``c_k / |G_k|`` from 0;
3. otherwise a vertex: the intersection of the lines of two non-parallel rows, one of which 0
   violates. (At ``z*`` the KKT conditions give ``z* = sum lambda_k G_k`` with ``lambda >= 0`` over
   the active rows, so ``0 < |z*|^2 = sum lambda_k c_k``: some active row with ``lambda_k > 0`` has
   ``c_k > 0``. If every active row is parallel to it, ``z*`` is case 2; else ``z*`` is the vertex
   of that row and a non-parallel active one.)

The feasible candidate of least cost is therefore ``z*``, and a problem without a feasible
candidate is infeasible (for a bounded polygon, e.g. when A contains box rows). No iteration and
no optimality tolerance; feasibility is checked with an absolute tolerance ``tol``. The work is
O(m) when nothing is violated and at most O(V m^2) for V violated rows. Compiled with numba
(the simulator's dependency), one problem costs microseconds.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["qp2_kernel", "solve_qp2"]


@njit(cache=True)
def _feasible(G: NDArray, c: NDArray, m: int, zx: float, zy: float, tol: float) -> bool:  # pragma: no cover
    for k in range(m):
        if G[k, 0] * zx + G[k, 1] * zy < c[k] - tol:
            return False
    return True


@njit(cache=True)
def qp2_kernel(
    tx: float, ty: float, wx: float, wy: float, A: NDArray, b: NDArray, m: int, tol: float, out: NDArray
) -> bool:  # pragma: no cover - compiled
    """Solve one problem over the first ``m`` rows of ``A`` (m', 2) and ``b`` (m',).

    Writes the solution into ``out`` (2,) and returns True, or returns False (``out`` untouched)
    when the problem is infeasible.
    """
    sx, sy = math.sqrt(wx), math.sqrt(wy)
    G = np.empty((m, 2))
    c = np.empty(m)
    violated = False
    for k in range(m):
        G[k, 0], G[k, 1] = A[k, 0] / sx, A[k, 1] / sy
        c[k] = b[k] - (A[k, 0] * tx + A[k, 1] * ty)
        violated |= c[k] > tol
    if not violated:  # case 1
        out[0], out[1] = tx, ty
        return True
    best, bx, by = math.inf, 0.0, 0.0
    for k in range(m):  # case 2
        norm2 = G[k, 0] ** 2 + G[k, 1] ** 2
        if c[k] > tol and norm2 > 0.0:
            zx, zy = G[k, 0] * c[k] / norm2, G[k, 1] * c[k] / norm2
            cost = zx * zx + zy * zy
            if cost < best and _feasible(G, c, m, zx, zy, tol):
                best, bx, by = cost, zx, zy
    if best == math.inf:
        for k in range(m):  # case 3
            norm_k = math.hypot(G[k, 0], G[k, 1])
            if c[k] <= tol or norm_k == 0.0:
                continue
            for j in range(m):
                det = G[k, 0] * G[j, 1] - G[k, 1] * G[j, 0]
                if j == k or abs(det) <= 1e-12 * norm_k * math.hypot(G[j, 0], G[j, 1]):
                    continue
                zx = (c[k] * G[j, 1] - G[k, 1] * c[j]) / det  # Cramer's rule for [G_k; G_j] z = [c_k; c_j]
                zy = (G[k, 0] * c[j] - c[k] * G[j, 0]) / det
                cost = zx * zx + zy * zy
                if cost < best and _feasible(G, c, m, zx, zy, tol):
                    best, bx, by = cost, zx, zy
    if best == math.inf:
        return False
    out[0], out[1] = tx + bx / sx, ty + by / sy
    return True


@njit(cache=True)
def _solve_batch(target, weight, A, b, counts, tol, out, feasible):  # pragma: no cover - compiled
    for i in range(target.shape[0]):
        feasible[i] = qp2_kernel(
            target[i, 0], target[i, 1], weight[i, 0], weight[i, 1], A[i], b[i], counts[i], tol, out[i]
        )
        if not feasible[i]:
            out[i, 0], out[i, 1] = target[i, 0], target[i, 1]


def solve_qp2(
    target: NDArray,
    weight: NDArray,
    A: NDArray,
    b: NDArray,
    tol: float = 1e-9,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Solve a batch of two-variable QPs exactly (see the module docstring).

    Parameters
    ----------
    target : ndarray, shape (B, 2)
        The unconstrained optimum of each problem.
    weight : ndarray, shape (2,) or (B, 2)
        Positive diagonal weights of the cost.
    A : ndarray, shape (B, m, 2)
        Constraint rows (``A u >= b``); zero rows are allowed (they only test ``0 >= b``).
    b : ndarray, shape (B, m)
        Right-hand sides.
    tol : float
        Absolute feasibility tolerance, in the units of ``b``.

    Returns
    -------
    u : ndarray, shape (B, 2)
        The solutions; ``target`` where the problem is infeasible.
    feasible : ndarray of bool, shape (B,)
        False for the problems with no point satisfying every row (within ``tol``).

    Raises
    ------
    ValueError
        Shapes that do not match, or a weight that is not positive and finite.
    """
    target = np.ascontiguousarray(target, dtype=np.float64)
    A = np.ascontiguousarray(A, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if (
        target.ndim != 2
        or target.shape[1] != 2
        or A.ndim != 3
        or A.shape[0] != target.shape[0]
        or A.shape[2] != 2
        or b.shape != A.shape[:2]
    ):
        raise ValueError(
            f"shapes target {target.shape}, A {A.shape}, b {b.shape} do not match; expected (B, 2), (B, m, 2), (B, m)"
        )
    weight = np.ascontiguousarray(np.broadcast_to(np.asarray(weight, dtype=np.float64), target.shape))
    if not np.all(np.isfinite(weight)) or np.any(weight <= 0):
        raise ValueError(f"weight={np.unique(weight, axis=0).tolist()!r} must be finite and > 0")
    out = np.empty_like(target)
    feasible = np.empty(target.shape[0], dtype=np.bool_)
    counts = np.full(target.shape[0], A.shape[1], dtype=np.int64)
    _solve_batch(target, weight, A, b, counts, float(tol), out, feasible)
    return out, feasible
