"""The CBF safety filter: exact QP, the barrier condition on adversarial states, closed loops, options, registry."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import controllers
from controllers.base import BaseController
from controllers.safety import BarrierFilter, SafetyFilter, SafetyOptions
from controllers.solvers.two_variable_qp import solve_qp2
from evaluation.run.configs import parse_controller, split_controller_list
from koopman_envs.episodes.single import run_episode
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario
from koopman_envs.sim.dynamics import rk4_step
from koopman_envs.sim.maps.map_spec import MapSpec

OPTIONS = SafetyOptions()  # the defaults, checked below as the filter runs them


def scenario(obstacles, starts) -> Scenario:
    """A scenario with the paper's limits, workspace and dt (targets are irrelevant to the filter)."""
    starts = np.asarray(starts, dtype=float)
    n = len(starts)
    return Scenario(
        task="target_reaching",
        map_name="test",
        n_robots=n,
        obstacles=np.asarray(obstacles, dtype=float).reshape(-1, 3),
        robot_radius=np.full(n, PARAMS.robot_radius),
        starts=starts,
        targets=starts.copy(),
        formation_offsets=np.zeros((n, 2)),
        leader=0,
        v_max=PARAMS.v_max,
        omega_max=PARAMS.omega_max,
        workspace=PARAMS.workspace,
        dt=PARAMS.dt,
        goal_tolerance=PARAMS.goal_tolerance,
        settle_steps=PARAMS.settle_steps,
    )


def barriers(sc: Scenario, poses, options: SafetyOptions = OPTIONS) -> list[tuple[str, float, np.ndarray]]:
    """Every barrier of the team, written out independently of the filter: (kind, h, gradient of h
    with respect to all look-ahead points, shape (N, 2))."""
    l, margin, n = options.lookahead, options.margin, sc.n_robots
    poses = np.asarray(poses, dtype=float)
    p = poses[:, :2] + l * np.column_stack([np.cos(poses[:, 2]), np.sin(poses[:, 2])])
    out = []
    for i in range(n):
        for cx, cy, radius in sc.obstacles:
            d = p[i] - (cx, cy)
            grad = np.zeros((n, 2))
            grad[i] = d / np.linalg.norm(d)
            out.append(("obstacle", np.linalg.norm(d) - (radius + sc.robot_radius[i] + l + margin), grad))
        for j in range(i + 1, n):
            d = p[i] - p[j]
            grad = np.zeros((n, 2))
            grad[i], grad[j] = d / np.linalg.norm(d), -d / np.linalg.norm(d)
            out.append(
                (
                    "robot",
                    np.linalg.norm(d) - (sc.robot_radius[i] + sc.robot_radius[j] + 2 * l + margin),
                    grad,
                )
            )
        x0, x1, y0, y1 = sc.workspace
        for normal, h in (
            ((1, 0), p[i, 0] - x0),
            ((-1, 0), x1 - p[i, 0]),
            ((0, 1), p[i, 1] - y0),
            ((0, -1), y1 - p[i, 1]),
        ):
            grad = np.zeros((n, 2))
            grad[i] = normal
            out.append(("wall", h - (l + margin), grad))
    return out


def lookahead_velocity(poses, command, l: float = OPTIONS.lookahead) -> np.ndarray:
    """Velocity of each look-ahead point under the nominal kinematics, (N, 2)."""
    theta = np.asarray(poses, dtype=float)[:, 2]
    v, w = np.asarray(command, dtype=float).reshape(-1, 2).T
    return np.column_stack(
        [v * np.cos(theta) - l * w * np.sin(theta), v * np.sin(theta) + l * w * np.cos(theta)]
    )


def check_barrier_conditions(sc: Scenario, poses, command, options: SafetyOptions = OPTIONS) -> None:
    """dh/dt + gamma h >= 0 for every barrier (continuous time) and h(t + dt) >= (1 - gamma dt) h(t)
    after one slip-free period (sampled time), for a state where every h >= 0."""
    before = barriers(sc, poses, options)
    assert min(h for _, h, _ in before) >= -1e-12
    rate = lookahead_velocity(poses, command, options.lookahead)
    after = barriers(
        sc, rk4_step(poses, np.asarray(command).reshape(-1, 2), np.zeros((sc.n_robots, 3))), options
    )
    for (kind, h, grad), (_, h_next, _) in zip(before, after):
        assert (grad * rate).sum() + options.gamma * h >= -1e-9, (kind, h, (grad * rate).sum())
        assert h_next >= (1 - options.gamma * sc.dt) * h - 1e-9, (kind, h, h_next)


# ---------------------------------------------------------------------------------------- the QP


def test_two_variable_qp_matches_qpoases_and_detects_infeasibility() -> None:
    import casadi as ca

    rng = np.random.default_rng(1)
    n_problems, m = 300, 8
    box = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    A = np.concatenate(
        [rng.normal(size=(n_problems, m, 2)), np.broadcast_to(box, (n_problems, 4, 2))], axis=1
    )
    b = np.concatenate([rng.normal(size=(n_problems, m)) - 1.6, np.full((n_problems, 4), -1.0)], axis=1)
    target, weight = rng.normal(size=(n_problems, 2)), np.array([1.0, 0.3])
    u, feasible = solve_qp2(target, weight, A, b)
    qp = ca.conic(
        "qp",
        "qpoases",
        {"h": ca.DM.eye(2).sparsity(), "a": ca.DM.ones(m + 4, 2).sparsity()},
        {"printLevel": "none", "error_on_fail": False},
    )
    for k in range(n_problems):
        sol = qp(h=2 * np.diag(weight), g=-2 * weight * target[k], a=A[k], lba=b[k], uba=np.inf)
        assert bool(qp.stats()["success"]) == feasible[k], k
        if feasible[k]:
            np.testing.assert_allclose(u[k], np.asarray(sol["x"]).ravel(), atol=1e-7)
    assert 0 < (~feasible).sum() < n_problems  # both kinds were exercised
    with pytest.raises(ValueError, match="weight"):
        solve_qp2(target, [1.0, 0.0], A, b)


# ------------------------------------------------------------------------------- single commands


def test_a_safe_command_far_from_everything_is_left_alone() -> None:
    sc = scenario([[5.0, 5.0, 0.5]], [[-3.0, -3.0, 0.3], [0.0, -3.0, 2.0], [-3.0, 0.0, -1.0]])
    flt = BarrierFilter(sc, OPTIONS)
    rng = np.random.default_rng(0)
    for _ in range(20):
        command = rng.uniform(-1, 1, size=(3, 2)) * [PARAMS.v_max, PARAMS.omega_max]
        step = flt.filter(sc.starts, command)
        np.testing.assert_array_equal(step.command, command)
        assert not step.changed.any() and not step.infeasible.any() and step.constraints == 0
    # beyond the limits: clipped (as the env would saturate), which is not counted as a change
    step = flt.filter(sc.starts, np.tile([2.0, -3.0], (3, 1)))
    np.testing.assert_array_equal(step.command, np.tile([PARAMS.v_max, -PARAMS.omega_max], (3, 1)))
    assert not step.changed.any()


@pytest.mark.parametrize("gap", [0.0, 0.01, 0.05, 0.1, 0.2, 0.35, 0.6, 1.0])
@pytest.mark.parametrize("heading", [0.0, 0.3, -0.6, 1.2])
def test_full_speed_into_an_obstacle_a_robot_or_a_wall_is_made_safe(gap: float, heading: float) -> None:
    """Adversarial commands: full speed (and turning) straight at an obstacle, at an oncoming robot
    and at the right wall, from clearances ``gap`` (barrier value) of 0 to 1 m."""
    l, margin = OPTIONS.lookahead, OPTIONS.margin
    reach_obstacle = 0.5 + PARAMS.robot_radius + l + margin
    reach_pair = 2 * PARAMS.robot_radius + 2 * l + margin
    x_wall = PARAMS.workspace[1] - l - margin
    # look-ahead points at barrier value ``gap``, headings turned by ``heading`` off the threat
    points = np.array(
        [
            [-(reach_obstacle + gap), 0.0],  # robot 0 -> obstacle at the origin
            [0.0, 4.0],
            [reach_pair + gap, 4.0],  # robots 1 and 2 head-on
            [x_wall - gap, -4.0],
        ]
    )  # robot 3 -> right wall
    theta = np.array([0.0, 0.0, math.pi, 0.0]) + heading * np.array([1, 1, -1, 1])
    poses = np.column_stack([points - l * np.column_stack([np.cos(theta), np.sin(theta)]), theta])
    sc = scenario([[0.0, 0.0, 0.5]], poses)
    flt = BarrierFilter(sc, OPTIONS)
    for turn in (0.0, PARAMS.omega_max, -PARAMS.omega_max):
        command = np.tile([PARAMS.v_max, turn], (4, 1))
        step = flt.filter(poses, command)
        assert not step.infeasible.any()
        check_barrier_conditions(sc, poses, step.command)
        if gap == 0.0 and heading == 0.0:  # on the boundary, head-on: the only safe forward speed is 0
            assert np.all(step.command[:, 0] <= 1e-9) and step.changed.all()


def test_random_states_and_commands_satisfy_the_barrier_conditions() -> None:
    """Property test: crowded random states (every barrier >= 0) and random commands."""
    rng = np.random.default_rng(7)
    obstacles = [[0.0, 0.0, 0.5], [1.6, 0.4, 0.3], [-1.2, 1.5, 0.4]]
    checked = changed = 0
    while checked < 150:
        poses = np.column_stack(
            [rng.uniform(-2.5, 2.5, 5), rng.uniform(-2.5, 2.5, 5), rng.uniform(-np.pi, np.pi, 5)]
        )
        if rng.random() < 0.3:  # some near the top-right corner of the workspace
            poses[:, :2] = rng.uniform(8.6, 9.7, (5, 2))
        sc = scenario(obstacles, poses)
        if min(h for _, h, _ in barriers(sc, poses)) < 0:
            continue
        command = rng.uniform(-1, 1, size=(5, 2)) * [PARAMS.v_max, PARAMS.omega_max]
        step = BarrierFilter(sc, OPTIONS).filter(poses, command)
        assert not step.infeasible.any()
        check_barrier_conditions(sc, poses, step.command)
        checked += 1
        changed += int(step.changed.sum())
    assert changed >= 50  # the filter had work to do (80 of the 750 robot commands with this seed)


def test_inside_a_margin_between_a_wall_and_an_obstacle_falls_back_to_the_least_violating_command() -> None:
    """Slip has pushed the look-ahead point inside both the wall's and an obstacle's margin: no
    command recovers both, the fallback lets neither barrier shrink, and the period is counted."""
    l, margin = OPTIONS.lookahead, OPTIONS.margin
    x_p = PARAMS.workspace[0] + l + margin - 0.01  # 1 cm inside the wall's margin
    obstacle = [x_p + 0.3 + PARAMS.robot_radius + l + margin - 0.01, 0.0, 0.3]  # 1 cm inside its margin
    poses = np.array([[x_p - l, 0.0, 0.0]])
    sc = scenario([obstacle], poses)
    step = BarrierFilter(sc, OPTIONS).filter(poses, [[PARAMS.v_max, 0.2]])
    assert step.infeasible.all() and step.relaxation[0] == 0.0
    assert step.barrier_min == pytest.approx(-0.01)
    after = barriers(sc, rk4_step(poses, step.command, np.zeros((1, 3))))
    for (_, h, _), (_, h_next, _) in zip(barriers(sc, poses), after):
        assert h_next >= h - 1e-9


# --------------------------------------------------------------------------------- closed loops


class Straight(BaseController):
    """Full speed ahead, whatever is in the way (the adversarial inner controller)."""

    name = "straight"

    def _act(self, observation, info):
        return np.tile([self.scenario.v_max, 0.0], self.scenario.n_robots)


CRASH = MapSpec(
    "crash",
    obstacles=[[2.0, -3.0, 0.5]],
    starts=[[0.0, -3.0, 0.0], [-3.0, 3.0, 0.0], [3.0, 3.1, math.pi], [7.5, -7.0, 0.0]],
    targets=[[4.0, -3.0, 0.0], [3.0, 5.0, 0.0], [-3.0, 5.0, 0.0], [7.5, -8.0, 0.0]],
)


def test_closed_loop_without_slip_never_collides_where_the_unfiltered_controller_does() -> None:
    """Into an obstacle, head-on into each other and into the wall at full speed, in the env."""
    env = gym.make("KoopNav-TargetReaching-v0", map=CRASH, n_robots=4, slip="nominal", max_episode_steps=150)
    crashed = run_episode(env, Straight(), seed=0)
    assert crashed.collision is not None and crashed.steps < 60
    ctrl = SafetyFilter(Straight())
    result = run_episode(env, ctrl, seed=0)
    assert result.collision is None and result.steps == 150
    stats = ctrl.stats()
    assert stats.barrier_min >= -1e-6  # the nominal guarantee: no barrier ever negative
    assert stats.infeasible == 0 and stats.changed > 0
    assert len(stats.filter_times) == len(stats.solve_times) == 150
    assert all(total >= own for total, own in zip(stats.solve_times, stats.filter_times))
    summary = stats.summary()
    assert summary["filter_changed"] == stats.changed and summary["filter_ms_median"] < 1.0


# ------------------------------------------------------------------------------- options, names


@pytest.mark.parametrize(
    "options, message",
    [
        ({"gamma": 0.0}, r"gamma=0.0 is out of range; allowed: \(0, 10\]"),
        ({"gamma": 10.5}, r"gamma=10.5 is out of range"),
        ({"gamma": float("nan")}, r"gamma=nan is out of range"),
        ({"margin": -0.01}, r"margin=-0.01 is out of range; allowed: \[0, 1\] m"),
        ({"lookahead": 0.0}, r"lookahead=0.0 is out of range; allowed: \(0, 0.5\] m"),
        ({"omega_weight": 0}, r"omega_weight=0 is out of range"),
        ({"margin": True}, r"margin=True is out of range"),
        ({"gama": 1.0}, r"unknown safety filter option 'gama' \(did you mean 'gamma'\?\)"),
    ],
)
def test_bad_options_raise_naming_the_value_and_the_range(options: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SafetyFilter(controllers.make("consensus"), **options)


def test_names_options_and_calibration_through_the_registry() -> None:
    ctrl = controllers.make("safe:nominal-nmpc-robust", horizon=10, safety_gamma=1.5, safety_margin=0.1)
    assert isinstance(ctrl, SafetyFilter) and ctrl.name == "safe:nominal-nmpc-robust"
    assert ctrl.inner.config.horizon == 10 and ctrl.options.gamma == 1.5 and ctrl.options.margin == 0.1
    from controllers.base import calibratable

    assert calibratable(ctrl) is ctrl.inner  # the inner NMPC calibrates, found down .inner
    assert calibratable(controllers.make("safe:consensus")) is None
    with pytest.raises(ValueError, match=r"controller 'mpc' is not one of \[.*'consensus'.*\]"):
        controllers.make("safe:mpc")
    with pytest.raises(ValueError, match=r"option safety_gamma=20 is out of range"):
        controllers.make("safe:consensus", safety_gamma=20)
    with pytest.raises(
        ValueError, match=r"unknown safety filter option 'safety_gama' \(did you mean 'safety_gamma'"
    ):
        controllers.make("safe:consensus", safety_gama=1)
    # the evaluator's syntax: inner options as usual, filter options prefixed
    config = parse_controller("safe:nominal-nmpc:horizon=10,safety_gamma=1")
    assert config.name == "safe:nominal-nmpc" and dict(config.options) == {"horizon": 10, "safety_gamma": 1}
    built = config.build()
    assert built.inner.config.horizon == 10 and built.options.gamma == 1
    assert split_controller_list(["safe:nominal-nmpc:horizon=10,safety_gamma=1,consensus"]) == [
        "safe:nominal-nmpc:horizon=10,safety_gamma=1",
        "consensus",
    ]
    with pytest.raises(ValueError, match="not one of"):
        parse_controller("safe:mpc").validate()


def test_safe_controller_runs_a_real_episode() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1", slip="high", max_episode_steps=120)
    ctrl = controllers.make("safe:consensus-free")
    result = run_episode(env, ctrl, seed=0)
    assert result.collision is None and result.steps == 120
    summary = ctrl.stats().summary()
    for key in (
        "filter_ms_median",
        "filter_ms_p95",
        "filter_changed",
        "filter_infeasible",
        "inner_ms_median",
    ):
        assert key in summary
    assert summary["steps"] == 120 and summary["failures"] == 0


def test_evaluator_ranks_a_safe_controller_beside_its_inner_one() -> None:
    from evaluation import RunSpec, evaluate

    spec = RunSpec(
        "KoopNav-TargetReaching-v0",
        ["safe:consensus-free", "consensus-free"],
        maps=["map1"],
        slips=["high"],
        episodes=1,
        env_kwargs={"max_episode_steps": 200},
    )
    results = evaluate(spec, workers=1)
    rows = {row["controller"]: row for row in results.leaderboard()}
    assert set(rows) == {"safe:consensus-free", "consensus-free"}
    outcomes = {r["controller"]: r for r in results.records}
    assert (
        outcomes["consensus-free"]["collision"] == "obstacle"
        and outcomes["safe:consensus-free"]["collision"] is None
    )
    assert outcomes["safe:consensus-free"]["controller_extra"]["filter_changed"] > 0
