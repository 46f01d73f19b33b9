"""NMPC solve time per control step over a closed-loop episode (Map 1, 3 robots, horizon 20).

Usage::

    python bench/nmpc_solve.py [--map map1] [--slip nominal] [--compiled] [--cache-timing] [--no-do-mpc]
                               [--qp-solvers hpipm osqp piqp daqp]

For Koopman-NMPC and nominal NMPC it runs the same closed-loop episode (seed 0) once per
optimizer and prints one row each, side by side:

``RTI <qp solver>``
    The real-time iteration (``solver="rti"``): one structured QP per control period, linearized
    at the previous plan shifted by one period, i.e. warm-started as in any closed loop, with
    each QP solver ``hpipm`` (the default), ``osqp``, ``piqp`` and ``daqp``. A QP solver whose
    median exceeds 50 ms (checked from the 20th step on) or whose steps add up to more than
    30 s is stopped mid-episode and dropped, with a printed note saying why.
``IPOPT uncompiled``
    ``nlpsol`` IPOPT solved to convergence at every period, uncompiled (the previous default).
``IPOPT compiled`` and ``fatrop compiled`` (only with ``--compiled``)
    The NLP compiled to C, cached on disk by :mod:`controllers.solvers.compiled`. The first run on
    a machine waits for the compile (minutes per problem structure on a loaded 2-core machine,
    not in the per-step times), which is why these rows are opt-in.
``do-mpc (IPOPT)``
    When ``do-mpc`` is installed (and without ``--no-do-mpc``): the same nominal problem (same
    model, horizon, weights, hard obstacle and inter-robot constraints, IPOPT) in do-mpc.

Columns: median / p95 / max wall time of a control step's solve [ms] over the episode (its
first step, a cold start, included); ``cold``: median time of the first step after a reset
over 5 resets (seeds 0-4), i.e. solving from the cold initial guess (hold the measured state,
zero commands, zero multipliers), measured after the episode (not for do-mpc); ``iter``: mean
iterations per step (RTI: QPs, plus IPOPT's iterations on fallback steps; IPOPT, fatrop,
do-mpc: interior-point iterations); ``fallbacks``: steps where the RTI's QP failed or its plan
kept a large slack and IPOPT solved the step instead; ``failures``: steps without any solution
(the controller drove on its last plan or stopped); then the episode's outcome, its length and
the robots' mean final distance to target [cm], from which "same closed loop" can be read off.
Last, the speed-up of the default real-time iteration (RTI hpipm) over IPOPT and over do-mpc as
ratios of medians.

Building is not in the per-step times: a controller builds its CasADi problem at its first
reset and its solvers (the RTI's QP solver, each ``nlpsol``: IPOPT has one for a cold and one
for a warm start, and the RTI's IPOPT fallback) on first use, inside a step's timed call (about
0.15 s each). Every controller is therefore warmed up before its timed episode: one reset, two
steps (a cold, then a warm start) and its fallback solver built. do-mpc builds its NLP in
``setup()``, before its episode. ``--cache-timing`` prints the build time to the first command
in fresh processes instead: for compiled IPOPT with an empty and a filled cache, and for the
real-time iteration (nothing compiled, nothing cached).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import controllers
import koopman_envs  # noqa: F401
from controllers.calibration import calibrate_controller
from controllers.mpc.config import IPOPT_OPTIONS, NMPCConfig
from controllers.mpc.models import UnicycleModel
from controllers.mpc.rti import QP_SOLVERS
from controllers.solvers.compiled import solver_cache_dir
from koopman_envs import EpisodeResult, env_id_for_map, run_episode

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the bench modules beside this one
from nmpc_build_time import cache_timing  # noqa: E402

#: QP solvers of the real-time iteration compared by default (``--qp-solvers`` picks others of
#: :data:`controllers.mpc.rti.QP_SOLVERS`, e.g. DAQP or proxQP)
QP_ROWS = ("hpipm", "osqp", "piqp", "daqp")
#: a QP solver slower than this per step (median) is dropped: it is no real-time option
MEDIAN_LIMIT = 0.050
#: steps before the median is judged (the first steps, near the start, are not typical)
MEDIAN_FROM = 20
#: total solve time [s] after which a QP solver is dropped: a solver whose QPs hit their iteration
#: limit (qrqp did: ~10 s each, before the IPOPT fallback; it left the table) would hold the run up
TOTAL_LIMIT = 30.0
#: resets behind the ``cold`` column
COLD_RESETS = 5
#: episode time limit of every row [control periods]; None: the env's (``--steps``, for quick checks)
EPISODE_STEPS: int | None = None


def make_env(env_id: str, map_name: str, slip: str, **env_kwargs: Any) -> gym.Env:
    """The env of every row (the time limit of ``--steps`` when given)."""
    limit = {} if EPISODE_STEPS is None else {"max_episode_steps": EPISODE_STEPS}
    return gym.make(env_id, map=map_name, slip=slip, **limit, **env_kwargs)


@dataclass
class Row:
    """One optimizer's closed-loop episode.

    Attributes
    ----------
    times : ndarray
        Solve time of each step [s].
    result : EpisodeResult
        The episode's outcome.
    failures : int
        Steps without a solution.
    iterations : list of int
        Iterations per step (empty when not known).
    fallbacks : int or None
        Steps solved by the fallback solver (None: the controller has none).
    cold : ndarray
        First-step times after resets [s] (empty: not measured).
    """

    times: NDArray[np.float64]
    result: EpisodeResult
    failures: int = 0
    iterations: list[int] | None = None
    fallbacks: int | None = None
    cold: NDArray[np.float64] | None = None

    @property
    def median(self) -> float:
        """Median solve time per step [s]."""
        return float(np.median(self.times))


class TooSlow(Exception):
    """Raised from the episode's step hook to stop a solver that is no real-time option."""


def warm_up(env: gym.Env, ctrl: Any) -> None:
    """Build everything ``ctrl`` builds on first use, so that its timed episode times solving only.

    The CasADi problem is built at reset, but each solver at its first call, inside the step's
    timed region: the RTI's QP solver at the first step, IPOPT's cold-start and warm-start
    ``nlpsol`` at the first and second, the RTI's IPOPT fallback at the first step that needs it.
    """
    obs, info = env.reset(seed=0)
    reset = getattr(ctrl, "reset", None)
    if callable(reset):
        reset(env, seed=0)
    for _ in range(2):  # a cold start, then a warm start
        obs, *_, info = env.step(np.asarray(ctrl.act(obs, info), dtype=float).reshape(-1))
    problem, config = getattr(ctrl, "_problem", None), getattr(ctrl, "config", None)
    fallback = getattr(config, "fallback_solver", None)
    if problem is not None and fallback and fallback != config.solver:
        for cold in (False, True):
            problem.solver_for(fallback, cold)


def wait_for_compiles(poll: float = 1.0) -> float:
    """Wait until no background compile is pending in the solver cache; returns the seconds waited."""
    start = time.perf_counter()
    while list(solver_cache_dir().glob("*.c")):  # a pending compile's source sits in the cache
        time.sleep(poll)
    return time.perf_counter() - start


def closed_loop(
    env_id: str,
    map_name: str,
    slip: str,
    make_controller: Callable[[], Any],
    *,
    limit: bool = False,
    compiled: bool = False,
    cold_resets: int = COLD_RESETS,
    env_kwargs: dict[str, Any] | None = None,
) -> Row:
    """Warm up, run one timed episode (seed 0), then time ``cold_resets`` cold first steps.

    Parameters
    ----------
    make_controller : callable
        Returns the controller (any :class:`controllers.base.Controller`).
    limit : bool
        Stop the episode with :class:`TooSlow` when the solver exceeds :data:`MEDIAN_LIMIT`
        (median, from step :data:`MEDIAN_FROM` on) or :data:`TOTAL_LIMIT` (sum).
    compiled : bool
        The controller's solver is compiled: when the warm-up started a background compile,
        wait for it and use a new controller (which loads the compiled solver from the cache).
    cold_resets : int
        Resets behind :attr:`Row.cold` (0: none).
    env_kwargs : dict, optional
        Further env keywords (``movers``).

    Raises
    ------
    TooSlow
        With ``limit``; its message says why.
    """
    env = make_env(env_id, map_name, slip, **(env_kwargs or {}))
    ctrl = make_controller()
    calibrate_controller(ctrl, env)
    warm_up(env, ctrl)
    if compiled and wait_for_compiles() > 0:
        ctrl = make_controller()
        calibrate_controller(ctrl, env)
        warm_up(env, ctrl)

    def check(step: int, action: NDArray, info: dict[str, Any]) -> None:
        times = ctrl.stats().solve_times
        total = sum(times)
        if total > TOTAL_LIMIT:
            median = 1e3 * np.median(times)
            raise TooSlow(
                f"{total:.0f} s of solving in {step} steps (limit {TOTAL_LIMIT:.0f} s), median "
                f"{median:.{1 if median < 100 else 0}f} ms, slowest step {max(times):.1f} s"
            )
        if step >= MEDIAN_FROM and np.median(times) > MEDIAN_LIMIT:
            median = 1e3 * np.median(times)
            raise TooSlow(f"median {median:.0f} ms over {step} steps (limit {1e3 * MEDIAN_LIMIT:.0f} ms)")

    try:
        result = run_episode(env, ctrl, seed=0, on_step=check if limit else None)
    except TooSlow as exc:
        counts = ctrl.stats().counts
        fallbacks = sum(v for k, v in counts.items() if k.startswith("fallback_"))
        raise TooSlow(f"{exc}, {fallbacks} IPOPT fallbacks") from None
    stats = ctrl.stats()  # reset() below starts a new record; this one stays the episode's
    cold = []
    for seed in range(cold_resets):
        obs, info = env.reset(seed=seed)
        ctrl.reset(env, seed=seed)
        ctrl.act(obs, info)
        cold.append(ctrl.stats().solve_times[0])
    has_fallback = getattr(getattr(ctrl, "config", None), "fallback_solver", None) is not None
    fallbacks = sum(v for k, v in stats.counts.items() if k.startswith("fallback_")) if has_fallback else None
    return Row(
        np.asarray(stats.solve_times),
        result,
        stats.failures,
        list(stats.iterations),
        fallbacks,
        np.asarray(cold),
    )


def do_mpc_closed_loop(env_id: str, map_name: str, slip: str, horizon: int) -> Row | None:
    """The nominal problem in do-mpc: discrete RK4 unicycle model, hard constraints, IPOPT."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import do_mpc
    except ImportError:
        return None
    import casadi as ca

    if hasattr(ca.GlobalOptions, "setNumpyMode"):
        ca.GlobalOptions.setNumpyMode(-1)  # do-mpc calls numpy on casadi values; keep it quiet
    env = make_env(env_id, map_name, slip)
    _, info = env.reset(seed=0)
    sc = env.unwrapped.scenario
    n = sc.n_robots
    model = do_mpc.model.Model("discrete")
    x = model.set_variable("_x", "x", (3 * n, 1))
    u = model.set_variable("_u", "u", (2 * n, 1))
    model.set_rhs("x", UnicycleModel(n, sc.dt).casadi_step()(x, u))
    model.setup()
    mpc = do_mpc.controller.MPC(model)
    mpc.settings.n_horizon = horizon
    mpc.settings.t_step = sc.dt
    mpc.settings.store_full_solution = False
    mpc.settings.nlpsol_opts = {k: v for k, v in IPOPT_OPTIONS.items() if not k.startswith("ipopt.warm")}
    cfg = NMPCConfig()
    cost = 0
    for i in range(n):
        tx, ty, tth = sc.targets[i]
        qx, qy, qc, qs = cfg.q_leader
        th = x[3 * i + 2]
        cost += qx * (x[3 * i] - tx) ** 2 + qy * (x[3 * i + 1] - ty) ** 2
        cost += qc * (ca.cos(th) - np.cos(tth)) ** 2 + qs * (ca.sin(th) - np.sin(tth)) ** 2
    r = np.tile(cfg.r_input, n)
    mpc.set_objective(lterm=cost + ca.dot(r, u * u), mterm=cost)
    mpc.set_rterm(u=np.zeros(2 * n))
    lower = np.tile([-sc.v_max, -sc.omega_max], n)
    mpc.bounds["lower", "_u", "u"] = lower
    mpc.bounds["upper", "_u", "u"] = -lower
    mpc.bounds["lower", "_x", "x"] = np.tile([sc.workspace[0], sc.workspace[2], -np.inf], n)
    mpc.bounds["upper", "_x", "x"] = np.tile([sc.workspace[1], sc.workspace[3], np.inf], n)
    for i in range(n):
        px, py = x[3 * i], x[3 * i + 1]
        for k, (ox, oy, orad) in enumerate(sc.obstacles):
            gap = (sc.robot_radius[i] + orad + cfg.obstacle_offset) ** 2 - (px - ox) ** 2 - (py - oy) ** 2
            mpc.set_nl_cons(f"obs_{i}_{k}", gap, ub=0.0)
        for j in range(i + 1, n):
            gap = (
                (sc.robot_radius[i] + sc.robot_radius[j]) ** 2
                - (px - x[3 * j]) ** 2
                - (py - x[3 * j + 1]) ** 2
            )
            mpc.set_nl_cons(f"rob_{i}_{j}", gap, ub=0.0)
    mpc.setup()  # builds the NLP: before the timed episode, as the warm-up does for ours
    mpc.x0 = info["poses"].reshape(-1, 1)
    mpc.set_initial_guess()

    class DoMPCPolicy:
        """do-mpc behind the runner's act(), timed per step, with IPOPT's statistics."""

        def __init__(self) -> None:
            self.times: list[float] = []
            self.iterations: list[int] = []
            self.failures = 0

        def act(self, observation, step_info):
            start = time.perf_counter()
            action = np.asarray(mpc.make_step(step_info["poses"].reshape(-1, 1))).reshape(-1)
            self.times.append(time.perf_counter() - start)
            solver_stats = getattr(mpc, "solver_stats", None) or {}  # IPOPT's stats() of the last solve
            if "iter_count" in solver_stats:
                self.iterations.append(int(solver_stats["iter_count"]))
            self.failures += not solver_stats.get("success", True)
            return action

    policy = DoMPCPolicy()
    result = run_episode(env, policy, seed=0)
    return Row(np.asarray(policy.times), result, policy.failures, policy.iterations)


def line(label: str, row: Row) -> str:
    """One report row: per-step times, cold start, iterations, fallbacks, failures, outcome."""
    t = 1e3 * row.times
    episode = row.result
    cold = f"{1e3 * np.median(row.cold):6.1f}" if row.cold is not None and row.cold.size else f"{'-':>6s}"
    iters = f"{np.mean(row.iterations):5.1f}" if row.iterations else f"{'-':>5s}"
    fallbacks = f"{row.fallbacks:3d}" if row.fallbacks is not None else f"{'-':>3s}"
    return (
        f"{label:20s} median {np.median(t):6.1f}  p95 {np.percentile(t, 95):6.1f}  max {t.max():6.1f}  "
        f"cold {cold} ms  iter {iters}  fallbacks {fallbacks}  failures {row.failures:2d}  "
        f"{episode.outcome:10s} {episode.steps:3d} steps  final {100 * np.mean(episode.final_distance):4.1f} cm"
    )


def mover_overhead(
    env_id: str, map_name: str, slip: str, count: int, qp: str, results: dict[tuple[str, str], Row]
) -> None:
    """Per-step time of the default RTI with ``count`` constant movers beside the same rows
    without (the rows above; run here when they were dropped), and their ratio."""
    print(f"with {count} constant movers (0.3 m/s), RTI {qp}:")
    for name in ("nominal-nmpc", "koopman-nmpc"):
        options = {"solver": "rti", "qp_solver": qp}
        without = results.get((name, f"RTI {qp}")) or closed_loop(
            env_id, map_name, slip, lambda n=name, o=options: controllers.make(n, **o)
        )
        moving = closed_loop(
            env_id, map_name, slip, lambda n=name, o=options: controllers.make(n, **o),
            env_kwargs={"movers": {"count": count}},
        )  # fmt: skip
        print("  " + line(f"{name} movers", moving))
        print(
            f"  {name}: median {1e3 * moving.median:.1f} ms with movers vs {1e3 * without.median:.1f} ms "
            f"without: {moving.median / without.median:.2f}x (target <= 1.5x)",
            flush=True,
        )


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", default="map1")
    parser.add_argument("--slip", default="nominal")
    parser.add_argument(
        "--compiled",
        action="store_true",
        help="add IPOPT and fatrop compiled to C (the first run on a machine waits for the compile)",
    )
    parser.add_argument(
        "--cache-timing",
        action="store_true",
        help="also time building compiled IPOPT with an empty and a filled cache, and the RTI",
    )
    parser.add_argument("--no-do-mpc", action="store_true")
    parser.add_argument(
        "--movers",
        type=int,
        default=8,
        help="also time the default RTI with this many constant movers (its mover slots: the 4 "
        "nearest, predicted over the horizon) against none; target <= 1.5x (default 8; 0: skip)",
    )
    parser.add_argument(
        "--steps",
        type=int,
        help="episode time limit [control periods] (default: the env's; for quick checks)",
    )
    parser.add_argument(
        "--qp-solvers",
        nargs="+",
        default=list(QP_ROWS),
        choices=sorted(QP_SOLVERS),
        metavar="QP",
        help=f"QP solvers of the RTI rows (default: {' '.join(QP_ROWS)}; the first is the one "
        "the speed-ups are given for)",
    )
    return parser


def setups(args: argparse.Namespace) -> list[tuple[str, dict[str, Any], bool, bool]]:
    """Every row's (label, options, compiled, subject to the real-time limits)."""
    rows: list[tuple[str, dict[str, Any], bool, bool]] = [
        (f"RTI {qp}", {"solver": "rti", "qp_solver": qp}, False, True) for qp in args.qp_solvers
    ]
    rows.append(("IPOPT uncompiled", {"solver": "ipopt", "jit": False}, False, False))
    if args.compiled:
        rows += [
            ("IPOPT compiled", {"solver": "ipopt", "jit": True}, True, False),
            ("fatrop compiled", {"solver": "fatrop", "jit": True}, True, False),
        ]
    return rows


def run_rows(args: argparse.Namespace, env_id: str, name: str, results: dict[tuple[str, str], Row]) -> None:
    """``name``'s rows (each printed as it ends; a QP solver too slow dropped with a note), and for
    the nominal NMPC do-mpc's, added to ``results``."""
    print(name)
    for label, options, compiled, limit in setups(args):
        try:
            row = closed_loop(
                env_id,
                args.map,
                args.slip,
                lambda n=name, o=options: controllers.make(n, **o),
                limit=limit,
                compiled=compiled,
            )
        except TooSlow as exc:
            print(f"  note: {label} dropped, stopped mid-episode: {exc}", flush=True)
            continue
        results[(name, label)] = row
        print("  " + line(label, row), flush=True)
    if name == "nominal-nmpc" and not args.no_do_mpc:
        reference = do_mpc_closed_loop(env_id, args.map, args.slip, NMPCConfig().horizon)
        if reference is None:
            print("  do-mpc not installed: `pip install do-mpc` to compare on the same nominal problem")
        else:
            results[(name, "do-mpc")] = reference
            print("  " + line("do-mpc (IPOPT)", reference), flush=True)


def print_speedups(results: dict[tuple[str, str], Row], default: str) -> None:
    """The speed-up of the ``default`` rows over IPOPT and do-mpc, as ratios of medians."""
    print(f"speed-up of {default} (ratio of medians):")
    for name in ("nominal-nmpc", "koopman-nmpc"):
        if (name, default) not in results:
            print(f"  {name}: {default} was dropped")
            continue
        ours = results[(name, default)].median
        others = [
            (label, results[(name, label)])
            for label in ("IPOPT uncompiled", "IPOPT compiled", "do-mpc")
            if (name, label) in results
        ]
        ratios = ", ".join(f"{row.median / ours:.1f}x vs {label}" for label, row in others)
        print(f"  {name}: {ratios}")


def main() -> None:
    args = _parser().parse_args()
    global EPISODE_STEPS
    EPISODE_STEPS = args.steps
    env_id = env_id_for_map(args.map)
    print(
        f"{env_id} {args.map} slip={args.slip}, 3 robots, horizon {NMPCConfig().horizon}, one closed-loop "
        f"episode per row; solve time per step [ms], building excluded\n"
        f"cold: first step after a reset (median of {COLD_RESETS}); iter: per step, QPs (RTI) or interior-point "
        f"iterations; fallbacks: RTI steps solved by IPOPT; final: mean distance to target"
    )
    if args.cache_timing:
        cache_timing(env_id, args.map)
    results: dict[tuple[str, str], Row] = {}
    for name in ("nominal-nmpc", "koopman-nmpc"):
        run_rows(args, env_id, name, results)
    if args.movers:
        mover_overhead(env_id, args.map, args.slip, args.movers, args.qp_solvers[0], results)
    print_speedups(results, f"RTI {args.qp_solvers[0]}")


if __name__ == "__main__":
    main()
