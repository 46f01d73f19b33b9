"""One attempt at an NMPC's problem of the period: the real-time iteration's QP(s), or an
``nlpsol`` plugin solved to convergence, as a :class:`SolveOutcome` (the controller chains them:
main solver, fallback solver, then the rest of its last plan; :mod:`controllers.mpc.controller`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover - typing only
    from controllers.mpc.config import NMPCConfig
    from controllers.mpc.problem import Problem

__all__ = ["SolveOutcome", "solve_nlp", "solve_rti"]


@dataclass
class SolveOutcome:
    """One attempt at the period's problem: (success, status, plan, multipliers, iterations)."""

    success: bool
    status: str
    w: NDArray | None = None
    lam_x: NDArray | None = None
    lam_g: NDArray | None = None
    iterations: int = 0


def solve_rti(
    problem: Problem,
    config: NMPCConfig,
    params: NDArray,
    guess: dict[str, NDArray],
    iterations: int | None = None,
) -> SolveOutcome:
    """The real-time iteration's QP(s) (``iterations``: the configured number when None). A
    failed QP fails, and so does a plan with a large slack when there is a fallback solver to
    rescue it; without one that plan is used, with the status ``"rti_large_slack"``."""
    more = {} if iterations is None else {"iterations": iterations}
    step = problem.real_time_iteration().solve(guess["x0"], guess["lam_x0"], guess["lam_g0"], params, **more)
    if not step.success:
        return SolveOutcome(False, f"qp_failed({step.status})", iterations=step.iterations)
    if step.max_slack > config.slack_tolerance:
        if config.fallback_solver is not None:
            return SolveOutcome(False, "large_slack", iterations=step.iterations)
        # no rescue to call: the soft plan is the best there is (it steers back out of the
        # violated margins), better than replaying an older plan; counted, not failed
        return SolveOutcome(True, "rti_large_slack", step.w, step.lam_x, step.lam_g, step.iterations)
    return SolveOutcome(True, "rti", step.w, step.lam_x, step.lam_g, step.iterations)


def solve_nlp(
    problem: Problem, name: str, params: NDArray, guess: dict[str, NDArray], cold: bool
) -> SolveOutcome:
    """One ``nlpsol`` call of plugin ``name`` to convergence (``cold``: without the warm-start
    options, :data:`controllers.mpc.config.WARM_START_OPTIONS`)."""
    solver = problem.solver_for(name, cold)
    try:
        sol = solver(p=params, **problem.bounds, **guess)
    except RuntimeError as exc:  # CasADi raises on evaluation errors (e.g. NaN in a function)
        return SolveOutcome(False, f"error: {exc}".splitlines()[0][:80])
    stats = solver.stats()
    status = str(stats.get("return_status", "unknown"))
    w = np.asarray(sol["x"]).reshape(-1)
    success = bool(stats.get("success", False)) and bool(np.all(np.isfinite(w)))
    if not np.all(np.isfinite(w)):
        status = "non_finite_solution"
    return SolveOutcome(
        success,
        status,
        w,
        np.asarray(sol["lam_x"]).reshape(-1),
        np.asarray(sol["lam_g"]).reshape(-1),
        int(stats.get("iter_count", 0)),
    )
