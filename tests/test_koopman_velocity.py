"""The Koopman lift with the velocity memory (issue 62): the robots' last move in the lifted state."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.calibration import DataSpec, TrajectoryData, poses_before, position_residual
from controllers.koopman import KoopmanModel, ModelFileError, calibrated_model, fit_bilinear, get_dictionary
from controllers.koopman.dictionary import lift_velocity
from controllers.mpc.models import coding_size, coding_velocity, decode_state, encode_state
from koopman_envs import make_plant

DT = 0.1
TURN = 0.3  # a robot's heading change when it is told to turn [rad per period]


def _inert_team(
    steps: int = 150, batch: int = 40, n: int = 2, seed: int = 0, keep: float = 0.6, binary: bool = True
):
    """Robots with inertia: a period's move keeps ``keep`` of the last one plus the push of the
    speed command along the heading, and a robot told to turn (omega command 1, else 0) turns by
    TURN. From rest. Its next pose is bilinear in the velocity lift: x_k+1 = x_k + keep (forward
    cos - lateral sin) + 0.4 dt v cos, and cos(theta + TURN w) is affine in w in {0, 1}. Without
    the move in the lift the lag reaches back forever: no window of commands holds it exactly.
    ``binary=False``: omega commands in [-1, 1] and the turn with the same inertia as the move (not
    bilinear then; without the turn's lag a lift with memory would hold the turn twice, collinear)."""
    rng = np.random.default_rng(seed)
    commands = rng.uniform(-1.0, 1.0, (steps, batch, n, 2))
    if binary:
        commands[..., 1] = rng.integers(0, 2, (steps, batch, n))
    states = np.empty((steps + 1, batch, n, 3))
    states[0] = rng.uniform(-1.0, 1.0, (batch, n, 3))
    move, turn = np.zeros((batch, n, 2)), np.zeros((batch, n))
    for t in range(steps):
        heading = states[t, ..., 2]
        push = 0.4 * DT * commands[t, ..., 0]
        move = keep * move + push[..., None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
        states[t + 1, ..., :2] = states[t, ..., :2] + move
        turn = TURN * commands[t, ..., 1] + (0.0 if binary else keep * turn)
        states[t + 1, ..., 2] = heading + turn
    return states, commands


def _model(states, commands, **lift) -> KoopmanModel:
    dictionary = get_dictionary("minimal")
    fit = fit_bilinear(states, commands, dictionary, **lift)
    return KoopmanModel(fit.A, fit.N, fit.B, fit.C, dictionary, states.shape[2], DT, **lift)


def test_velocity_lift_recovers_an_inert_system_the_others_cannot() -> None:
    states, commands = _inert_team()
    held_states, held_commands = _inert_team(seed=1)
    velocity = _model(states, commands, velocity=True)
    assert velocity.size == 9 + 2 * 9 and velocity.coding == "cs+v"
    # held-out trajectories, 150 periods open loop, each prediction re-lifted (as the NMPC does)
    error = np.abs(velocity.rollout(held_states[0], held_commands)[..., :2] - held_states[..., :2])
    assert error.max() < 1e-9
    for lift in ({}, {"memory": 3}):
        other = _model(states, commands, **lift)
        other_error = np.abs(other.rollout(held_states[0], held_commands)[..., :2] - held_states[..., :2])
        assert other_error.max() > 0.1, lift  # the lag reaches further back than any window
    # one step from the middle of a trajectory: the pose before it carries the robot's move
    t = 40
    step = velocity.step(held_states[t], held_commands[t], before=held_states[t - 1])
    np.testing.assert_allclose(step[..., :2], held_states[t + 1, ..., :2], rtol=0, atol=1e-12)
    # one-step residuals, the pose before each period from the data (chunks must not matter)
    data = TrajectoryData(held_states, held_commands, DataSpec(40, 150))
    assert position_residual(velocity.step, data, chunk=7, velocity=True).max() < 1e-12
    assert position_residual(_model(states, commands).step, data).min() > 1e-3


def test_velocity_observables_are_the_move_in_the_body_frame() -> None:
    poses = np.array([[[1.0, 2.0, np.pi / 2], [0.0, 0.0, 3.1]]])
    before = np.array([[[1.0, 1.5, np.pi / 2 - 0.1], [0.0, 0.0, -3.1]]])
    terms = lift_velocity(poses, before).reshape(2, 9)
    # robot 0 faces +y and moved 0.5 along +y: forward 0.5, no lateral, turned 0.1
    np.testing.assert_allclose(terms[0, :3], [0.5, 0.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(terms[0, 3:], [0.0, 0.5, 0.0, 0.0, 0.0, 0.1], atol=1e-12)
    # robot 1 turned across the wrap: 3.1 - (-3.1) is -(2 pi - 6.2), not 6.2
    np.testing.assert_allclose(terms[1, 2], 6.2 - 2 * np.pi, atol=1e-12)
    states = np.arange(12.0).reshape(4, 1, 1, 3)
    np.testing.assert_array_equal(poses_before(states)[[0, 1, 3]], states[[0, 0, 2]])


def test_velocity_model_casadi_step_and_file_round_trip(tmp_path) -> None:
    states, commands = _inert_team()
    model = _model(states, commands, velocity=True)
    path = tmp_path / "velocity.npz"
    model.save(path)
    loaded = KoopmanModel.load(path, n_robots=2, dt=DT)
    assert loaded.velocity and loaded.memory == 0 and "velocity" not in loaded.metadata
    np.testing.assert_array_equal(loaded.rollout(states[0], commands), model.rollout(states[0], commands))
    loaded.save(tmp_path / "again.npz")
    assert (tmp_path / "again.npz").read_bytes() == path.read_bytes()
    # the NMPC's step carries the pose before in its state: (x, y, cos, sin, x-, y-, cos-, sin-)
    t, b = 7, 3
    state = encode_state(states[t, b], model.coding, before=states[t - 1, b])
    assert coding_size(model.coding) == 8 and coding_velocity(model.coding)
    nlp = np.asarray(model.casadi_nlp_step()(state, commands[t, b].ravel())).ravel()
    parametric = model.casadi_nlp_step_parametric()(state, commands[t, b].ravel(), model.nlp_parameters())
    np.testing.assert_allclose(np.asarray(parametric).ravel(), nlp, atol=1e-12)
    expected = model.step(states[t, b], commands[t, b], before=states[t - 1, b])
    np.testing.assert_allclose(decode_state(nlp, model.coding), expected, atol=1e-12)
    # the next state's pose before is this state's pose
    np.testing.assert_array_equal(nlp.reshape(2, 8)[:, 4:], state.reshape(2, 8)[:, :4])
    # with memory as well: the commands first, then the pose before ("cs+u1+v")
    states, commands = _inert_team(binary=False)
    both = _model(states, commands, memory=1, velocity=True)
    assert both.coding == "cs+u1+v" and coding_size(both.coding) == 10
    state = encode_state(states[t, b], both.coding, commands[t - 1, b][None], states[t - 1, b])
    nlp = np.asarray(both.casadi_nlp_step()(state, commands[t, b].ravel())).ravel()
    expected = both.step(states[t, b], commands[t, b], commands[t - 1, b][None], states[t - 1, b])
    np.testing.assert_allclose(decode_state(nlp, both.coding), expected, atol=1e-12)
    np.testing.assert_array_equal(nlp.reshape(2, 10)[:, 4:6], commands[t, b])


@pytest.mark.parametrize("velocity", [1, 0, "yes", None, 1.0])
def test_bad_velocity_is_refused_by_name(velocity) -> None:
    states, commands = _inert_team(steps=20, batch=5)
    with pytest.raises(ValueError, match=r"velocity=.* must be True or False"):
        fit_bilinear(states, commands, get_dictionary("minimal"), velocity=velocity)
    model = _model(states, commands)
    with pytest.raises(ValueError, match=r"velocity"):
        KoopmanModel(model.A, model.N, model.B, model.C, model.dictionary, 2, DT, velocity=velocity)
    import controllers

    with pytest.raises(ValueError, match=r"velocity"):
        controllers.make("koopman-nmpc", velocity=velocity)


def test_velocity_beside_the_per_robot_structure_or_online_updates_is_refused_by_name(tmp_path) -> None:
    import controllers

    plant = make_plant("KoopNav-TargetReaching-v0", budget=100, seed=0)
    with pytest.raises(ValueError, match=r"velocity=True needs structure='stacked'"):
        calibrated_model(plant, 0, structure="per-robot", velocity=True)
    with pytest.raises(ValueError, match=r"velocity=True needs structure='stacked'"):
        controllers.make("koopman-nmpc", velocity=True, structure="per-robot")
    states, commands = _inert_team(n=3)
    model = _model(states, commands, velocity=True)
    with pytest.raises(ValueError, match=r"robot_block needs a model without memory or velocity"):
        model.robot_block(0)
    with pytest.raises(ValueError, match=r"pose-only model online.*velocity=True"):
        controllers.make("adaptive-koopman-nmpc", model=model)
    bad = _model(states, commands)
    bad.metadata["velocity"] = "yes"  # a file whose velocity key is bad is refused on reading
    bad.save(tmp_path / "bad.npz")
    with pytest.raises(ModelFileError, match=r"velocity"):
        KoopmanModel.load(tmp_path / "bad.npz")


def test_koopman_nmpc_with_velocity_solves_from_the_poses_it_measured() -> None:
    """The NMPC's measured state holds the poses of the period before (the first predicted
    step's velocity) and its plan follows the velocity model from there."""
    import gymnasium as gym

    import koopman_envs  # noqa: F401 - registers the ids
    from controllers.mpc.variants import KoopmanNMPC
    from koopman_envs.scenario import scenario_of

    states, commands = _inert_team(n=3, steps=200, batch=60)
    model = _model(states, commands, velocity=True)
    controller = KoopmanNMPC(model=model, solver="ipopt")
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    observation, info = env.reset(seed=0)
    controller.reset(scenario_of(env), seed=0)
    problem = controller.problem
    assert problem is not None and problem.coding == "cs+v" and problem.nx == 3 * 8
    before, moves = None, []  # standing before the first period
    for _ in range(4):
        poses = np.asarray(env.unwrapped.engine.poses, dtype=np.float64).reshape(3, 3)  # type: ignore[attr-defined]
        command = controller.act(observation, info).reshape(3, 2)
        assert controller.stats().failures == 0
        assert controller.last_plan is not None
        plan_commands, plan_poses = controller.last_plan
        np.testing.assert_array_equal(plan_commands[0], command)
        # the first predicted pose: the model's step from the pose with the pose before it
        np.testing.assert_allclose(plan_poses[0], model.step(poses, command, before=before), atol=1e-6)
        if before is not None:
            moves.append(np.abs(poses - before).max())
        before = poses
        observation, _, _, _, info = env.step(command.reshape(-1))
    assert max(moves) > 1e-3  # it moved, so the velocity mattered
    env.close()
