"""Real-time iteration (RTI) of the NMPC: one SQP step per control period.

At every period the NLP of :class:`controllers.mpc.problem.Problem` is linearized at the previous
plan shifted by one step, and the quadratic program

    min_d   1/2 d' H d + grad f(w)' d
    s.t.    lbg - g(w) <= J_g(w) d <= ubg - g(w),   lbw - w <= d <= ubw - w

is solved by a QP solver shipped in the CasADi wheel (HPIPM by default, which exploits the
stage-wise block structure; OSQP, PIQP, DAQP, proxQP generically). ``H`` is, by default, the
exact Hessian of the Lagrangian at the current multipliers with every stage block's
eigenvalues clipped at :data:`REGULARIZATION` (the Hessian is block diagonal by stage), or the
Gauss-Newton Hessian ``2 J_r' J_r`` of the cost written as a sum of squared residuals
(``hessian="gauss-newton"``; it diverged on the NMPC problems: along the headings its curvature
is about ten times too small). The new plan is ``w + d``; the QP's multipliers are the new
multiplier estimates. Iterated, the steps converge to a KKT point of the same NLP (the gradient
and the constraints are exact, the Hessian only shapes the path), which is what the tests check
against IPOPT.

Nothing here is compiled: the linearization is one CasADi SX function evaluated by CasADi's
virtual machine, built in a fraction of a second for every problem structure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from controllers.solvers.compiled import blas_threads
from koopman_envs.checks import check_choice, check_int

__all__ = [
    "HESSIANS",
    "QP_SOLVERS",
    "RTIStep",
    "RealTimeIteration",
    "StagedNLP",
    "bind_buffer",
    "check_rti_options",
]


class StagedNLP(Protocol):
    """What the real-time iteration reads of a built problem (:class:`controllers.mpc.problem.Problem`):
    the NLP, its bounds, and its stage structure (decision vector stage by stage)."""

    nlp: dict[str, Any]  # "x", "f", "g", "p"
    least_squares: tuple[Any, Any]  # (residuals, linear cost)
    lbw: NDArray[np.float64]
    ubw: NDArray[np.float64]
    lbg: NDArray[np.float64]
    ubg: NDArray[np.float64]
    n_vars: int
    horizon: int
    nx: int
    nu: int
    ns: int
    stage_size: int
    stage_rows: list[int]


#: QP solvers of the CasADi wheel the real-time iteration can use, with their options (quiet).
#: ``hpipm`` gets the OCP structure of the problem (stage sizes) on top of these.
QP_SOLVERS: dict[str, dict[str, Any]] = {
    # "speed": 5 interior-point iterations where "balance" takes 7, plans within 1e-7 of its
    # (Map 1, 3 robots); residual tolerances 1e-7 (1e-8 is out of reach at the scale of the slack
    # penalty: a cold start's QP was solved to 1e-10 of PIQP's solution and still ran out of iterations)
    "hpipm": {
        "hpipm": {
            "mode": "speed",
            "iter_max": 100,
            "res_g_max": 1e-7,
            "res_b_max": 1e-7,
            "res_d_max": 1e-7,
            "res_m_max": 1e-7,
        }
    },
    "osqp": {
        "osqp": {"verbose": False, "eps_abs": 1e-7, "eps_rel": 1e-7, "max_iter": 20000, "polish": True},
        "warm_start_primal": True,
    },
    "piqp": {"piqp": {"verbose": False}},
    "daqp": {},
    "proxqp": {"proxqp": {"verbose": False}},
}

#: Diagonal added to the Gauss-Newton Hessian: makes it positive definite (stage 0's state has
#: no cost) without moving the fixed point of the iteration (the gradient stays exact).
REGULARIZATION = 1e-6

#: Hessians of the QP: ``"exact"`` (the Lagrangian's, each stage block's eigenvalues clipped at
#: :data:`REGULARIZATION`) or ``"gauss-newton"`` (``2 J_r' J_r`` of the least-squares cost).
HESSIANS = ("exact", "gauss-newton")


@dataclass
class RTIStep:
    """Outcome of :meth:`RealTimeIteration.solve`.

    Attributes
    ----------
    success : bool
        Every QP was solved and the plan is finite.
    status : str
        The QP solver's status of the last QP.
    w, lam_x, lam_g : ndarray
        New plan (decision vector) and multiplier estimates.
    iterations : int
        QPs solved.
    max_slack : float
        Largest slack of the new plan (0 without slacks).
    """

    success: bool
    status: str
    w: NDArray[np.float64]
    lam_x: NDArray[np.float64]
    lam_g: NDArray[np.float64]
    iterations: int
    max_slack: float


def check_rti_options(qp_solver: str, iterations: int, hessian: str) -> None:
    """Raise ``ValueError`` naming a bad real-time-iteration option and what is allowed."""
    check_choice("qp_solver", qp_solver, sorted(QP_SOLVERS))
    check_int("rti_iterations", iterations, 1)
    check_choice("hessian", hessian, HESSIANS)


def bind_buffer(function: ca.Function, inputs: list[NDArray], outputs: list[NDArray]) -> tuple[Any, Any]:
    """``function.buffer()`` bound to the arrays (in input and output order): ``(buffer, evaluate)``.

    CasADi converts a numpy argument element by element (~0.1 us each); a buffer reads and
    writes the arrays in place. Keep the buffer alive as long as ``evaluate`` is used.
    """
    buffer, evaluate = function.buffer()
    # two type stub gaps, not errors: casadi's stub requires set_arg/set_res's ``size``, which its
    # runtime takes from the memoryview (the documented call is ``set_arg(0, memoryview(a))``);
    # numpy's stub gives ndarray ``__buffer__`` (the Buffer protocol) only for Python >= 3.12
    for i, array in enumerate(inputs):
        buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
    for i, array in enumerate(outputs):
        buffer.set_res(i, memoryview(array))  # type: ignore[call-arg, arg-type]
    return buffer, evaluate


class RealTimeIteration:
    """SQP on a built NMPC problem, ``iterations`` QPs per call (see the module docstring).

    Parameters
    ----------
    problem : StagedNLP
        The built NLP (its decision layout, bounds, least-squares cost and stage sizes).
    qp_solver : str
        One of :data:`QP_SOLVERS`.
    iterations : int
        QPs per control period (1: the classic real-time iteration).
    hessian : str
        One of :data:`HESSIANS`.
    """

    def __init__(
        self, problem: StagedNLP, qp_solver: str = "hpipm", iterations: int = 1, hessian: str = "exact"
    ) -> None:
        check_rti_options(qp_solver, iterations, hessian)
        self.problem = problem
        self.qp_solver = qp_solver
        self.iterations = iterations
        self.hessian = hessian
        nlp = problem.nlp
        w, p, g, f = nlp["x"], nlp["p"], nlp["g"], nlp["f"]
        lam_g = ca.SX.sym("lam_g", g.shape[0])
        jac_g = ca.jacobian(g, w)
        # the Hessian is block diagonal by stage, [x_k, u_k, s_k] (x_T alone): its blocks, dense
        stage = problem.stage_size
        self._blocks = [
            np.arange(t * stage, min((t + 1) * stage, problem.n_vars)) for t in range(problem.horizon + 1)
        ]
        if hessian == "gauss-newton":
            residuals, _ = problem.least_squares
            jac_r = ca.jacobian(residuals, w)
            full = 2 * ca.mtimes(jac_r.T, jac_r)
        else:
            full = ca.hessian(f + ca.dot(lam_g, g), w)[0]
        blocks = [ca.densify(full[idx.tolist(), idx.tolist()]) for idx in self._blocks]
        self._linearize = ca.Function(
            "rti_linearize",
            [w, p, lam_g],
            [ca.vertcat(*[ca.vec(b) for b in blocks]), ca.densify(ca.gradient(f, w)), ca.densify(g), jac_g],
            ["w", "p", "lam_g"],
            ["blocks", "grad", "g", "a"],
        )
        # block-diagonal sparsity of the QP Hessian; the blocks are contiguous, so CasADi's
        # column-major nonzeros are the blocks' column-major entries one block after another
        self._block_groups = [(stage, problem.horizon), (problem.nx, 1)]
        rows = np.concatenate([np.tile(idx, idx.size) for idx in self._blocks])
        cols = np.concatenate([np.repeat(idx, idx.size) for idx in self._blocks])
        self._h_sparsity = ca.Sparsity.triplet(problem.n_vars, problem.n_vars, rows.tolist(), cols.tolist())
        structure = {"h": self._h_sparsity, "a": jac_g.sparsity()}
        options: dict[str, Any] = {"error_on_fail": False, **QP_SOLVERS[qp_solver]}
        if qp_solver == "hpipm":
            horizon = problem.horizon
            options.update(
                {
                    "N": horizon,
                    "nx": [problem.nx] * (horizon + 1),
                    "nu": [problem.nu + problem.ns] * horizon + [0],
                    # rows besides the dynamics gaps (which lead every stage but the last)
                    "ng": [count - problem.nx for count in problem.stage_rows[:-1]] + problem.stage_rows[-1:],
                }
            )
        self._qp = ca.conic("rti_qp", qp_solver, structure, options)
        self._slack_index = (
            np.concatenate(
                [
                    np.arange(t * stage + problem.nx + problem.nu, (t + 1) * stage)
                    for t in range(problem.horizon)
                ]
            )
            if problem.ns
            else np.zeros(0, dtype=int)
        )
        self._bind_buffers()

    def _bind_buffers(self) -> None:
        """Preallocated arrays for both functions; the linearization is bound to a buffer once.

        The linearization's gradient and Jacobian arrays are the QP's inputs directly. The QP
        gets a new buffer at every solve (see :meth:`solve`).
        """
        lin, qp = self._linearize, self._qp
        self._lin_in = {name: np.zeros(lin.nnz_in(i)) for i, name in enumerate(lin.name_in())}
        self._lin_out = {name: np.zeros(lin.nnz_out(i)) for i, name in enumerate(lin.name_out())}
        self._qp_in = {name: np.zeros(qp.nnz_in(i)) for i, name in enumerate(qp.name_in())}
        self._qp_in["g"] = self._lin_out["grad"]
        self._qp_in["a"] = self._lin_out["a"]
        self._qp_out = {name: np.zeros(qp.nnz_out(i)) for i, name in enumerate(qp.name_out())}
        self._lin_buffer, self._lin_eval = self._buffer(lin, self._lin_in, self._lin_out)

    @staticmethod
    def _buffer(
        function: ca.Function, inputs: dict[str, NDArray], outputs: dict[str, NDArray]
    ) -> tuple[Any, Any]:
        """:func:`bind_buffer` with the arrays given by input and output name."""
        return bind_buffer(
            function, [inputs[n] for n in function.name_in()], [outputs[n] for n in function.name_out()]
        )

    def solve(
        self, w: NDArray, lam_x: NDArray, lam_g: NDArray, params: NDArray, iterations: int | None = None
    ) -> RTIStep:
        """``iterations`` SQP steps (default: the instance's) from the guess ``(w, lam_x, lam_g)``
        (arrays are not modified), numpy's BLAS on one thread (:func:`blas_threads`)."""
        with blas_threads():
            return self._iterate(w, lam_x, lam_g, params, iterations)

    def _iterate(
        self, w: NDArray, lam_x: NDArray, lam_g: NDArray, params: NDArray, iterations: int | None
    ) -> RTIStep:
        """:meth:`solve`'s SQP steps."""
        iterations = self.iterations if iterations is None else iterations
        prob = self.problem
        lin_in, lin_out, qp_in, qp_out = self._lin_in, self._lin_out, self._qp_in, self._qp_out
        lin_in["p"][:] = params
        w = np.array(w, dtype=float)
        lam_x = np.array(lam_x, dtype=float)
        lam_g = np.array(lam_g, dtype=float)
        status = "not_run"
        for done in range(1, iterations + 1):
            lin_in["w"][:] = w
            lin_in["lam_g"][:] = lam_g
            try:
                self._lin_eval()
            except RuntimeError as exc:  # CasADi raises on evaluation errors
                return RTIStep(False, f"error: {exc}".splitlines()[0][:80], w, lam_x, lam_g, done, np.inf)
            g = lin_out["g"]
            if not (np.all(np.isfinite(g)) and np.all(np.isfinite(lin_out["blocks"]))):
                return RTIStep(False, "non_finite_linearization", w, lam_x, lam_g, done, np.inf)
            self._convex_hessian(lin_out["blocks"], qp_in["h"])
            np.subtract(prob.lbg, g, out=qp_in["lba"])
            np.subtract(prob.ubg, g, out=qp_in["uba"])
            np.subtract(prob.lbw, w, out=qp_in["lbx"])
            np.subtract(prob.ubw, w, out=qp_in["ubx"])
            qp_in["lam_x0"][:] = lam_x
            qp_in["lam_a0"][:] = lam_g
            # a new buffer (memory) per QP: HPIPM's interface keeps state in a reused one, and the
            # second QP solved through the same buffer came out wrong (steps of metres)
            qp_buffer, qp_eval = self._buffer(self._qp, qp_in, qp_out)
            try:
                qp_eval()
            except RuntimeError as exc:  # CasADi raises on ill-posed data (NaN, crossed bounds)
                return RTIStep(False, f"error: {exc}".splitlines()[0][:80], w, lam_x, lam_g, done, np.inf)
            stats = qp_buffer.stats()
            status = str(stats.get("return_status", "unknown"))
            step = qp_out["x"]
            if not stats.get("success", False) or not np.all(np.isfinite(step)):
                return RTIStep(False, status, w, lam_x, lam_g, done, np.inf)
            w = w + step
            lam_x = qp_out["lam_x"].copy()
            lam_g = qp_out["lam_a"].copy()
        max_slack = float(np.max(w[self._slack_index])) if self._slack_index.size else 0.0
        return RTIStep(True, status, w, lam_x, lam_g, iterations, max_slack)

    def _convex_hessian(self, flat: NDArray, out: NDArray) -> None:
        """Write into ``out`` (the QP Hessian's nonzeros) the stacked dense stage blocks of
        ``flat``, each made positive definite (eigenvalues clipped at :data:`REGULARIZATION`)."""
        offset = 0
        for size, count in self._block_groups:  # equal-sized blocks in one batched call
            end = offset + count * size * size
            stack = flat[offset:end].reshape(count, size, size)
            stack = 0.5 * (stack + stack.transpose(0, 2, 1))
            values, vectors = np.linalg.eigh(stack)
            convex = (vectors * np.maximum(values, REGULARIZATION)[:, None, :]) @ vectors.transpose(0, 2, 1)
            out[offset:end] = convex.reshape(-1)  # symmetric: row- and column-major agree
            offset = end
