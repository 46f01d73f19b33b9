"""Recursive least squares on the lifted bilinear regression: a Koopman model updated online.

The offline fit (:mod:`controllers.koopman.fit`) solves z+ = A z + N (u kron z) + B u once, on
calibration data. Online, each new transition (z, u, z+) of the running episode refines the rows
of [A, N, B] that the NMPC reads back through C (the lifted x, y, cos, sin of every robot) by
exponentially weighted recursive least squares, starting from the calibrated model.

The regression and its prior
----------------------------
With the constant observable first, ``u kron z`` already holds the columns of ``u`` (its
``u_i * 1`` entries), so the regressor is ``psi = [z, u kron z]`` (q = D + m D entries), as in
:class:`controllers.koopman.fit.MomentAccumulator`; a change of a merged coefficient goes to N
(or to B where N has no entry). The prior is the calibrated model, worth ``prior_weight``
transitions spread like the calibration data (states uniform on the identification box,
commands uniform on its input box): its information matrix is ``prior_weight * E[psi psi^T]``
under that distribution, estimated once from a fixed-seed sample.

Guards
------
Forgetting (factor ``forgetting`` in (0, 1]) divides the covariance P by the factor every step.
With closed-loop data that excite few directions this "winds up" P in the others, and a later
transition can then throw the model far off. Two guards keep it well conditioned:

* the covariance never grows beyond the prior's: when forgetting would lift trace(P) above
  trace(P0), that step does not forget (bounded-trace RLS);
* P is kept symmetric, and an update that produces a non-finite value or a negative
  denominator is rejected (the model stays as it was; :attr:`RecursiveBilinearFit.rejected`).

Everything is computed with ``numpy.einsum`` and elementwise operations, not BLAS, so the result
is bit-identical for any number of BLAS threads (as the offline fit).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.koopman.fit import _cholesky_solve
from controllers.koopman.model import KoopmanModel
from koopman_envs.checks import check_choice
from koopman_envs.params import PARAMS

__all__ = ["ADAPTED_TERMS", "RecursiveBilinearFit", "check_adapted", "check_forgetting", "check_prior_weight"]

# a fixed seed: the prior's information matrix must not depend on anything but the model
_PRIOR_SAMPLE_SEED = 0x52_4C_53  # "RLS"
_PRIOR_SAMPLES = 4096


def check_forgetting(value: float) -> float:
    """``value`` as a forgetting factor, or ValueError naming it and the allowed range (0, 1]."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not 0.0 < value <= 1.0:
        raise ValueError(f"forgetting={value!r} must be a number in (0, 1] (1: no forgetting)")
    return float(value)


#: which coefficients the online update may change: every free one, or only those multiplied by
#: a command (N and B: how commands move the robots; A, the motion without commands, stays calibrated)
ADAPTED_TERMS = ("all", "input")


def check_adapted(value: str) -> str:
    """``value`` as a choice of adapted coefficients, or ValueError naming it and the choices."""
    return str(check_choice("adapted", value, ADAPTED_TERMS))


def check_prior_weight(value: float) -> float:
    """``value`` as a prior weight, or ValueError naming it and the allowed range (> 0, finite)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.floating))
        or not (np.isfinite(value) and value > 0)
    ):
        raise ValueError(f"prior_weight={value!r} must be a finite number > 0 (calibration transitions)")
    return float(value)


def _lifted_regressors(model: KoopmanModel, poses: NDArray, commands: NDArray) -> NDArray[np.float64]:
    """psi = [z, u kron z] for poses (S, N, 3) and commands (S, N, 2) -> (S, D + m D)."""
    z = model.lift(poses)
    u = np.asarray(commands, dtype=np.float64).reshape(z.shape[0], -1)
    d, m = z.shape[1], u.shape[1]
    psi = np.empty((z.shape[0], d + m * d))
    psi[:, :d] = z
    np.multiply(u[:, :, None], z[:, None, :], out=psi[:, d:].reshape(z.shape[0], m, d))
    return psi


class RecursiveBilinearFit:
    """Online RLS estimate of the rows of [A, N, B] that C projects onto.

    Parameters
    ----------
    model : KoopmanModel
        The calibrated model: the starting point and the prior. Its dictionary's observable 0
        must be the constant (true of every shipped dictionary).
    forgetting : float
        Exponential forgetting factor in (0, 1]: the data of k steps ago weigh ``forgetting**k``
        (0.98: a memory of ~50 periods = 5 s). 1 never forgets.
    prior_weight : float
        How many calibration-like transitions the prior model is worth (> 0). Small values adapt
        fast and trust the episode's few, correlated closed-loop transitions more.
    adapted : {"all", "input"}
        ``"all"``: every free coefficient of the projected rows; ``"input"``: only those of the
        command terms ``N (u kron z) + B u``. Slip changes how commands move a robot, never how it
        moves without one, so ``"input"`` keeps A (and the estimate's behaviour at rest) calibrated.

    Attributes
    ----------
    updates, rejected : int
        Transitions used and transitions rejected by the guards since :meth:`reset`.
    """

    def __init__(
        self, model: KoopmanModel, forgetting: float = 0.98, prior_weight: float = 200.0, adapted: str = "all"
    ) -> None:
        self.forgetting = check_forgetting(forgetting)
        self.prior_weight = check_prior_weight(prior_weight)
        self.adapted = check_adapted(adapted)
        self.model = model
        d, m = model.A.shape[0], 2 * model.n_robots
        self.d, self.m = d, m
        # output j is the lifted coordinate that row j of C selects (C is a selector up to rounding)
        self.outputs = np.argmax(np.abs(model.C), axis=1)
        rows = self.outputs
        weights = np.empty((d + m * d, rows.size))
        weights[:d] = model.A[rows].T
        weights[d:] = model.N[rows].T
        merged = d + d * np.arange(m)  # the u_i * 1 columns: N's entry plus B's
        weights[merged] += model.B[rows].T
        self._prior_weights = weights
        # entries that are structural zeros of the model stay zero (the NMPC's compiled problem
        # keeps the model's sparsity); a merged entry is free when N or B has it
        free = np.empty_like(weights, dtype=bool)
        free[:d] = model.A[rows].T != 0
        free[d:] = model.N[rows].T != 0
        free[merged] |= model.B[rows].T != 0
        if adapted == "input":
            free[:d] = False
        self._free = free
        # outputs whose free regressors coincide share one covariance: one group for the paper's
        # stacked model, one per robot for the per-robot structure (whose RLS then costs
        # N small updates instead of one of size (D + m D)^2)
        groups: dict[bytes, list[int]] = {}
        for j in range(rows.size):
            groups.setdefault(np.packbits(free[:, j]).tobytes(), []).append(j)
        self._groups = [(np.flatnonzero(free[:, outs[0]]), np.asarray(outs)) for outs in groups.values()]
        self._prior_covariances = self._prior_covariances_of(model)
        self._trace_bounds = [float(np.trace(p0)) for p0 in self._prior_covariances]
        self._base_theta = model.nlp_parameters()
        self._selection: tuple[NDArray, NDArray] | None = None
        self.reset()

    def _prior_covariances_of(self, model: KoopmanModel) -> list[NDArray[np.float64]]:
        rng = np.random.default_rng(_PRIOR_SAMPLE_SEED)
        n, b, ib = model.n_robots, PARAMS.koopman_state_bound, PARAMS.koopman_input_bound
        poses = rng.uniform(-b, b, size=(_PRIOR_SAMPLES, n, 3))
        commands = rng.uniform(-ib, ib, size=(_PRIOR_SAMPLES, n, 2))
        psi = _lifted_regressors(model, poses, commands)
        covariances = []
        for regressors, _ in self._groups:
            sample = psi[:, regressors]
            information = self.prior_weight * np.einsum("si,sj->ij", sample, sample) / _PRIOR_SAMPLES
            covariances.append(_cholesky_solve(information, np.eye(regressors.size), 0.0, 1e-14))
        return covariances

    def reset(self) -> None:
        """Back to the calibrated model and the prior covariance (every episode starts here)."""
        self.weights = self._prior_weights.copy()
        self.covariances = [p0.copy() for p0 in self._prior_covariances]
        self.updates = 0
        self.rejected = 0

    def predict(self, poses: NDArray, commands: NDArray) -> NDArray[np.float64]:
        """C z+ of the current estimate for one team: poses (N, 3), commands (N, 2) -> (4N,)."""
        psi = _lifted_regressors(self.model, np.asarray(poses)[None], np.asarray(commands)[None])[0]
        return np.einsum("qj,q->j", self.weights, psi)

    def update(self, poses: NDArray, commands: NDArray, next_poses: NDArray) -> NDArray[np.float64]:
        """Fold in one transition; returns its a-priori error (4N,) of the lifted (x, y, cos, sin).

        Parameters
        ----------
        poses, next_poses : ndarray, shape (N, 3)
            Measured poses before and after the period.
        commands : ndarray, shape (N, 2)
            The commands applied in between.
        """
        psi = _lifted_regressors(self.model, np.asarray(poses)[None], np.asarray(commands)[None])[0]
        target = self.model.lift(np.asarray(next_poses)[None])[0][self.outputs]
        error = target - np.einsum("qj,q->j", self.weights, psi)
        if not np.all(np.isfinite(error)):
            self.rejected += 1
            return error
        weights = self.weights.copy()
        covariances = []
        for (regressors, outs), covariance, bound in zip(self._groups, self.covariances, self._trace_bounds):
            x = psi[regressors]
            p_x = np.einsum("ij,j->i", covariance, x)
            denominator = self.forgetting + float(np.einsum("i,i->", x, p_x))
            if not (np.isfinite(denominator) and denominator > 0):
                self.rejected += 1
                return error
            gain = p_x / denominator
            weights[np.ix_(regressors, outs)] += gain[:, None] * error[None, outs]
            covariance = covariance - gain[:, None] * p_x[None, :]
            covariance = 0.5 * (covariance + covariance.T)
            forgotten = covariance / self.forgetting
            # bounded trace: forget only while the covariance stays within the prior's
            covariances.append(forgotten if np.trace(forgotten) <= bound else covariance)
        if not (np.all(np.isfinite(weights)) and all(np.all(np.isfinite(c)) for c in covariances)):
            self.rejected += 1
            return error
        self.weights, self.covariances = weights, covariances
        self.updates += 1
        return error

    def nlp_parameters(self) -> NDArray[np.float64]:
        """The current estimate as the NMPC's model parameters (``KoopmanModel.nlp_parameters`` layout).

        The same values as ``model.nlp_parameters_of(*self.matrices())`` up to rounding, for a
        fraction of the cost: every free weight lands in exactly one coefficient, so the map is
        a selection, found once (:meth:`_parameter_selection`).
        """
        if self._selection is None:
            self._selection = self._parameter_selection()
        theta_index, weight_index = self._selection
        theta = self._base_theta.copy()
        theta[theta_index] += (self.weights - self._prior_weights).reshape(-1)[weight_index]
        return theta

    def _parameter_selection(self) -> tuple[NDArray, NDArray]:
        """(theta index, flat weight index) pairs: push each weight's number through
        :meth:`matrices` and the model's parameter layout and see where it lands."""
        saved = self.weights
        codes = np.arange(1, saved.size + 1, dtype=np.float64).reshape(saved.shape)
        self.weights = self._prior_weights + np.where(self._free, codes, 0.0)
        try:
            landed = np.rint(self.model.nlp_parameters_of(*self.matrices()) - self._base_theta).astype(
                np.int64
            )
        finally:
            self.weights = saved
        theta_index = np.flatnonzero(landed)
        return theta_index, landed[theta_index] - 1

    def matrices(self) -> tuple[NDArray, NDArray, NDArray]:
        """(A, N, B) of the current estimate: the model's, with the C-projected rows replaced."""
        d, m, rows = self.d, self.m, self.outputs
        a, n, b = self.model.A.copy(), self.model.N.copy(), self.model.B.copy()
        a[rows] = self.weights[:d].T
        n_rows = self.weights[d:].T.copy()
        # a merged coefficient: B keeps its calibrated value and N takes the rest, unless N has
        # no entry there (structural zero), then B takes it all
        merged = d * np.arange(m)
        b_rows = self.model.B[rows].copy()
        n_has = self.model.N[rows][:, merged] != 0
        b_rows = np.where(n_has, b_rows, n_rows[:, merged])
        n_rows[:, merged] = np.where(n_has, n_rows[:, merged] - b_rows, 0.0)
        n[rows] = n_rows
        b[rows] = b_rows
        return a, n, b
