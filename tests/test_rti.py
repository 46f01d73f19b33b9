"""The real-time iteration (controllers/mpc/rti.py): same KKT point as IPOPT when iterated, the
fallback chain, option checks, and determinism across processes.

The tests that build an NMPC without calibrating it build ``nominal-nmpc-v0``, the hand-set
defaults: the tuned ``nominal-nmpc`` (controllers/tuned/nominal-nmpc.json) widens its margins by
the calibrated residual, so it acts only after ``calibrate`` (as ``_problem_after`` does)."""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys
from pathlib import Path

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401
from controllers.calibration import calibrate_controller
from controllers.mpc.config import IPOPT_OPTIONS
from controllers.mpc.models import encode_state
from controllers.mpc.rti import QP_SOLVERS, RTIStep

ROOT = Path(__file__).resolve().parents[1]


def _problem_after(name: str, env_id: str, map_name: str, steps: int, **options):
    """A controller with the real-time iteration after ``steps`` closed-loop steps, and its data."""
    env = gym.make(env_id, map=map_name)
    obs, info = env.reset(seed=0)
    ctrl = controllers.make(name, solver="rti", **options)
    calibrate_controller(ctrl, env)
    ctrl.reset(env)
    for _ in range(steps):
        obs, _, _, _, info = env.step(ctrl.act(obs, info))
    prob = ctrl.problem
    state = encode_state(info["poses"], prob.coding)
    params = ctrl.parameter_vector()
    params[prob.layout["x_meas"]] = state
    return ctrl, prob, state, params


def _tight_ipopt(prob, params, guess):
    options = {k: v for k, v in IPOPT_OPTIONS.items() if "warm" not in k and k != "ipopt.mu_init"}
    solver = ca.nlpsol(
        "tight",
        "ipopt",
        prob.nlp,
        {**options, "ipopt.tol": 1e-12, "ipopt.acceptable_iter": 0, "ipopt.max_iter": 500},
    )
    sol = solver(x0=guess, p=params, **prob.bounds)
    assert solver.stats()["success"], solver.stats()["return_status"]
    return np.asarray(sol["x"]).ravel(), np.asarray(sol["lam_g"]).ravel()


@pytest.mark.parametrize(
    "name, env_id, map_name, steps",
    [
        ("nominal-nmpc", "KoopNav-TargetReaching-v0", "map1", 0),
        # slow: 30 periods of the formation's Koopman NMPC first, about 2 CPU-s (issue 61)
        pytest.param("koopman-nmpc-v0", "KoopNav-Formation-v0", "map4", 30, marks=pytest.mark.slow),
    ],
)
def test_iterated_to_convergence_it_reaches_ipopts_kkt_point(name, env_id, map_name, steps) -> None:
    ctrl, prob, state, params = _problem_after(name, env_id, map_name, steps)
    w_ipopt, lam_ipopt = _tight_ipopt(prob, params, ctrl._initial_guess(state))
    rti = prob.real_time_iteration()
    w, lam_x, lam_g = ctrl._initial_guess(state), np.zeros(prob.n_vars), np.zeros(prob.n_cons)  # a cold start
    for _ in range(40):
        step = rti.solve(w, lam_x, lam_g, params)
        assert step.success, step.status
        change = np.max(np.abs(step.w - w))
        w, lam_x, lam_g = step.w, step.lam_x, step.lam_g
        if change < 1e-10:
            break
    assert change < 1e-10  # converged (full steps, exact Hessian: a few iterations)
    np.testing.assert_allclose(w, w_ipopt, atol=1e-5)
    np.testing.assert_allclose(lam_g, lam_ipopt, atol=1e-6 * max(1.0, np.max(np.abs(lam_ipopt))) * 100)


def _failed_step(self, w, lam_x, lam_g, params, **_) -> RTIStep:
    return RTIStep(False, "1", w, lam_x, lam_g, 1, np.inf)


def test_a_failed_qp_falls_back_to_ipopt_and_is_counted(monkeypatch) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1", max_episode_steps=4)
    ctrl = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver="ipopt")
    obs, info = env.reset(seed=0)
    ctrl.reset(env)
    ctrl.act(obs, info)  # a real QP
    monkeypatch.setattr(type(ctrl.problem.real_time_iteration()), "solve", _failed_step)
    command = ctrl.act(obs, info)
    stats = ctrl.stats()
    assert np.all(np.isfinite(command))
    assert stats.counts["fallback_ipopt"] == 1 and stats.failures == 0
    assert stats.statuses["rti"] == 1
    assert any(key.startswith("rti:qp_failed(1) -> ipopt:") for key in stats.statuses)


def test_when_ipopt_fails_too_the_last_plan_then_a_stop(monkeypatch) -> None:
    from controllers.mpc.controller import NMPCController
    from controllers.mpc.controller import SolveOutcome as _SolveOutcome

    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    ctrl = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver="ipopt")
    obs, info = env.reset(seed=0)
    ctrl.reset(env)
    ctrl.act(obs, info)
    plan, _ = ctrl.last_plan
    monkeypatch.setattr(type(ctrl.problem.real_time_iteration()), "solve", _failed_step)
    monkeypatch.setattr(
        NMPCController, "_solve_nlp", lambda *_: _SolveOutcome(False, "Infeasible_Problem_Detected")
    )
    commands = [ctrl.act(obs, info) for _ in range(ctrl.config.horizon + 2)]
    stats = ctrl.stats()
    assert stats.statuses["rti:qp_failed(1) -> ipopt:Infeasible_Problem_Detected"] == len(commands)
    assert stats.counts["fallback_ipopt"] == len(commands) and stats.failures == len(commands)
    np.testing.assert_allclose(commands[0], plan[1].reshape(-1))  # the rest of the last plan
    np.testing.assert_array_equal(commands[-1], np.zeros(6))  # then a stop


def test_without_a_fallback_solver_a_failed_qp_goes_to_the_last_plan(monkeypatch) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    ctrl = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver=None)
    obs, info = env.reset(seed=0)
    ctrl.reset(env)
    ctrl.act(obs, info)
    monkeypatch.setattr(type(ctrl.problem.real_time_iteration()), "solve", _failed_step)
    ctrl.act(obs, info)
    assert ctrl.stats().statuses["qp_failed(1)"] == 1 and ctrl.stats().failures == 1


@pytest.mark.parametrize("soft", [True, False])
def test_the_real_time_iterations_problem_keeps_every_collision_row(soft: bool) -> None:
    """The terminal rows move to the last stage (with a slack of their own when soft); none is lost."""
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    env.reset(seed=0)
    counts = {}
    for solver in ("ipopt", "rti"):
        ctrl = controllers.make("nominal-nmpc-v0", solver=solver, soft_constraints=soft, horizon=4)
        ctrl.reset(env)
        counts[solver] = ctrl.problem.n_cons
        if solver == "rti":
            prob = ctrl.problem
            assert prob.stage_rows[-1] == 0 and prob.terminal_rows.size == prob.stage_rows[1] - prob.nx
    assert counts["rti"] == counts["ipopt"]


def test_a_plan_with_a_large_slack_goes_to_ipopt(monkeypatch) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    ctrl = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver="ipopt", slack_tolerance=1e-300)
    obs, info = env.reset(seed=0)
    ctrl.reset(env)
    real = type(ctrl.problem.real_time_iteration()).solve

    def slack(self, *args, **kwargs):
        step = real(self, *args, **kwargs)
        step.max_slack = 1.0
        return step

    monkeypatch.setattr(type(ctrl.problem.real_time_iteration()), "solve", slack)
    ctrl.act(obs, info)
    assert ctrl.stats().counts["fallback_ipopt"] == 1
    assert any(key.startswith("rti:large_slack -> ipopt:") for key in ctrl.stats().statuses)


def test_without_a_fallback_solver_a_plan_with_a_large_slack_is_used_and_counted(monkeypatch) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    obs, info = env.reset(seed=0)
    commands = {}
    for fallback in ("ipopt", None):
        ctrl = controllers.make(
            "nominal-nmpc-v0", solver="rti", fallback_solver=fallback, slack_tolerance=1e-300
        )
        ctrl.reset(env)
        real = type(ctrl.problem.real_time_iteration()).solve

        def slack(self, *args, real=real):
            step = real(self, *args)
            step.max_slack = 1.0
            return step

        monkeypatch.setattr(type(ctrl.problem.real_time_iteration()), "solve", slack)
        commands[fallback] = ctrl.act(obs, info)
        monkeypatch.undo()
    stats = ctrl.stats()
    assert stats.counts["large_slack_accepted"] == 1 and stats.failures == 0
    assert stats.statuses["rti_large_slack"] == 1 and "fallback_ipopt" not in stats.counts
    # the QP's own plan, not IPOPT's and not a stop
    assert not np.allclose(commands[None], commands["ipopt"]) and np.any(commands[None] != 0)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"solver": "sqp"}, "solver='sqp' is not one of"),
        ({"qp_solver": "gurobi"}, "qp_solver='gurobi' is not one of"),
        ({"rti_iterations": 0}, "rti_iterations=0 must be an integer >= 1"),
        ({"rti_iterations": 1.5}, "rti_iterations=1.5 must be an integer >= 1"),
        ({"hessian": "bfgs"}, "hessian='bfgs' is not one of"),
        ({"slack_tolerance": -1}, "slack_tolerance=-1 must be a finite number > 0"),
        ({"fallback_solver": "rti"}, "fallback_solver='rti' is not one of"),
    ],
)
def test_bad_solver_options_name_the_value(options, message) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("[", r"\[")):
        controllers.make("koopman-nmpc", **options)


#: daqp reports success on the tuned nominal-nmpc's QP with a step up to 1.2 away from the one
#: hpipm, piqp, osqp and proxqp agree on (to 2e-6); the tuned input weight alone (r_input 0.084
#: against the hand-set 0.1) makes the difference (measured on 2026-11-29). Strict: the mark goes
#: when daqp agrees again.
_DAQP_OFF = pytest.mark.xfail(strict=True, reason="daqp: another step on the tuned input weight's QP")


@pytest.mark.parametrize(
    ("controller", "name"),
    [
        pytest.param(c, q, marks=[_DAQP_OFF] if (c, q) == ("nominal-nmpc", "daqp") else [])
        for c in ("nominal-nmpc-v0", "nominal-nmpc")
        for q in sorted(QP_SOLVERS)
    ],
)
def test_every_qp_solver_of_the_table_gives_the_same_step(controller: str, name: str) -> None:
    ctrl, prob, _, params = _problem_after(controller, "KoopNav-TargetReaching-v0", "map1", 3, horizon=5)
    guess = (ctrl._warm["x"], ctrl._warm["lam_x"], ctrl._warm["lam_g"])
    reference = prob.real_time_iteration().solve(*guess, params)
    # the same problem structure with another QP solver, solved at the first one's data
    _, prob_q, _, _ = _problem_after(
        controller, "KoopNav-TargetReaching-v0", "map1", 0, horizon=5, qp_solver=name
    )
    step = prob_q.real_time_iteration().solve(*guess, params)
    assert step.success, (name, step.status)
    np.testing.assert_allclose(step.w, reference.w, atol=1e-4)


_EPISODE = """
import gymnasium as gym, koopman_envs, controllers, numpy as np
from koopman_envs.episodes.single import run_episode
env = gym.make('KoopNav-Formation-v0', map='map3', slip='high', max_episode_steps=60)
ctrl = controllers.make('nominal-nmpc-v0', solver='rti')
result = run_episode(env, ctrl, seed=3)
print(result.trajectory.tobytes().hex(), result.steps)
"""


# slow: an episode here and in a fresh interpreter, about 2 CPU-s (issue 61)
@pytest.mark.slow
def test_same_seed_same_closed_loop_here_and_in_another_process() -> None:
    here = io.StringIO()
    with contextlib.redirect_stdout(here):
        exec(_EPISODE, {})
    other = subprocess.run(
        [sys.executable, "-c", _EPISODE], capture_output=True, text=True, cwd=ROOT, timeout=300, check=False
    )
    assert other.returncode == 0, other.stderr
    assert here.getvalue().strip() and here.getvalue() == other.stdout


# ----------------------------------------------------------------------------- the evaluator
def test_with_solver_sets_every_nmpc_that_names_none() -> None:
    from evaluation.run.configs import parse_controller, with_solver

    configs = [
        parse_controller(t)
        for t in ("koopman-nmpc", "consensus", "safe:nominal-nmpc", "nominal-nmpc:solver=fatrop,label=fixed")
    ]
    out = with_solver(configs, "ipopt")
    assert dict(out[0].options)["solver"] == "ipopt" and out[0].label == "koopman-nmpc"
    assert out[1] == configs[1]  # consensus has no solver
    assert dict(out[2].options)["solver"] == "ipopt"
    assert dict(out[3].options)["solver"] == "fatrop"  # a configuration's own choice wins
    assert with_solver(configs, None) == configs
    with pytest.raises(ValueError, match=r"--solver 'sqp' is not one of \['rti', 'ipopt', 'fatrop'\]"):
        with_solver(configs, "sqp")


def test_with_solver_sets_or_turns_off_every_nmpcs_fallback_solver() -> None:
    from evaluation.run.configs import parse_controller, with_solver

    configs = [
        parse_controller(t)
        for t in (
            "koopman-nmpc",
            "consensus",
            "dmpc-nominal",
            "nominal-nmpc:fallback_solver=fatrop,label=own",
        )
    ]
    # the real-time iteration without a rescue is every NMPC's default: nothing changes
    assert with_solver(configs, "rti", "none") == configs
    out = with_solver(configs, "ipopt", "fatrop")
    assert dict(out[0].options) == {"solver": "ipopt", "fallback_solver": "fatrop"}
    assert out[1] == configs[1]  # consensus has no fallback solver
    assert dict(out[2].options) == {"solver": "ipopt", "fallback_solver": "fatrop"}
    assert dict(out[3].options)["fallback_solver"] == "fatrop"  # a configuration's own choice wins
    assert out[0].build().config.fallback_solver == "fatrop" and out[2].build().config.solver == "ipopt"
    assert dict(with_solver(configs, None, "fatrop")[0].options) == {"fallback_solver": "fatrop"}
    # the default rescue (none) changes no configuration (nor so a resumed run's signature)
    assert with_solver(configs, None, "none") == configs
    with pytest.raises(
        ValueError, match=r"--fallback-solver 'rti' is not one of \['ipopt', 'fatrop', 'none'\]"
    ):
        with_solver(configs, None, "rti")
    # from the command line, JSON's null and Python's None both mean no fallback solver
    for text in ("nominal-nmpc:fallback_solver=null", "nominal-nmpc:fallback_solver=None"):
        assert parse_controller(text).build().config.fallback_solver is None
    with pytest.raises(
        ValueError, match=r"fallback_solver='none' is not one of \['ipopt', 'fatrop'\] or None"
    ):
        parse_controller("nominal-nmpc:fallback_solver=none").validate()


def test_the_report_names_each_rows_solver_and_the_terminal_gets_a_compact_board(tmp_path) -> None:
    import evaluate as ev

    spec = ev.RunSpec(
        "KoopNav-TargetReaching-v0",
        ["nominal-nmpc:solver=rti,horizon=5", "consensus"],
        maps=["map1"],
        slips=["nominal"],
        episodes=1,
        env_kwargs={"max_episode_steps": 20},
    )
    results = ev.evaluate(spec, workers=1)
    rows = {row["controller"]: row for row in results.leaderboard()}
    assert rows["nominal-nmpc:solver=rti,horizon=5"]["solver"] == "rti/hpipm"
    assert rows["consensus"]["solver"] is None
    paths = results.write(tmp_path)
    summary = results.terminal_summary(paths)
    assert "rti/hpipm" in summary and str(paths["markdown"]) in summary
    assert "McNemar" not in summary  # the paired tables go to the files
    assert "McNemar" in paths["markdown"].read_text()


def test_cli_rejects_an_unknown_solver_before_any_episode(tmp_path, capsys) -> None:
    import evaluate as ev

    with pytest.raises(SystemExit) as exit_info:
        ev.main(["--solver", "sqp", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "invalid choice: 'sqp'" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_paper_protocol_keeps_ipopt_and_the_quick_board_runs_the_real_time_iteration() -> None:
    from evaluation.experiments.protocols import ablation_protocol, paper_protocol, quick_protocol

    assert paper_protocol().solver == "ipopt" and paper_protocol(strict=True).solver == "ipopt"
    assert ablation_protocol().solver == "ipopt"
    assert quick_protocol().solver == "rti"
    from controllers.mpc.config import NMPCConfig

    assert NMPCConfig().solver == "rti" and NMPCConfig().fallback_solver is None  # real time by default


def test_paper_with_named_controllers_says_their_solver_is_their_own(capsys) -> None:
    """``--paper --controllers ...`` keeps the named controllers' default solver (the real-time
    iteration); a note says so and how to get the paper's, and --solver ipopt silences it."""
    from evaluation.cli import build_parser, spec_from_args

    parser = build_parser()
    spec = spec_from_args(parser.parse_args(["--paper", "--controllers", "koopman-nmpc"]))
    assert spec.solver is None
    assert "--solver ipopt sets it for them" in capsys.readouterr().err
    spec = spec_from_args(
        parser.parse_args(["--paper", "--controllers", "koopman-nmpc", "--solver", "ipopt"])
    )
    assert spec.solver == "ipopt" and capsys.readouterr().err == ""
    spec_from_args(parser.parse_args(["--controllers", "koopman-nmpc"]))  # the quick board: rti, no note
    assert capsys.readouterr().err == ""
