"""The physics plant (``plant="mujoco"``) beyond tests/test_physics_plant.py: pickling a world
mid-episode, rendering the bodies' poses, straight-line lag per surface, friction zones, and
PettingZoo's target-reaching front."""

from __future__ import annotations

import pickle
from typing import Any, cast

import gymnasium as gym
import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import controllers  # noqa: E402
import koopman_envs  # noqa: E402, F401 - registers the ids
from koopman_envs.params import PARAMS  # noqa: E402

TR = "KoopNav-TargetReaching-v0"
SPEED = 0.5  # [m/s] a speed the robots reach on every floor


def test_a_physics_env_pickled_mid_episode_steps_on_bit_for_bit() -> None:
    """The world drops the ``mujoco`` module, its thread pool and its array views from a pickle
    and makes them again on load; the loaded env and the original then step alike."""
    env: Any = gym.make(TR, plant="mujoco", slip="low", map="map1").unwrapped
    env.reset(seed=5)
    actions = np.random.default_rng(5).uniform(-1, 1, (40, 6)).astype(np.float32) * env.action_space.high
    for action in actions[:10]:
        env.step(action)
    copy = pickle.loads(pickle.dumps(env))
    for action in actions[10:]:
        one, two = env.step(action), copy.step(action)
        np.testing.assert_array_equal(one[0], two[0])
        assert one[1:4] == two[1:4]
        np.testing.assert_array_equal(one[4]["poses"], two[4]["poses"])
        if one[2] or one[3]:
            break
    # the views are the loaded world's own arrays, not copies: a write reaches MuJoCo's data
    world = copy.engine.physics
    world._ctrl_views[0][0] = 123.0
    assert world.datas[0].ctrl[0] == 123.0


def test_a_pickled_vector_world_steps_on_its_threads() -> None:
    """A batch pickled after a threaded period (pool made) loads without the pool and makes it again."""
    venv = gym.make_vec(TR, num_envs=2, plant="mujoco")
    venv.reset(seed=1)
    actions = np.random.default_rng(1).uniform(-0.5, 0.5, (12, 2, 6)).astype(np.float32)
    for action in actions[:4]:
        venv.step(action)
    world = cast(Any, venv.unwrapped).engine.physics
    assert world.threads > 1 and world._pool is not None
    copy = pickle.loads(pickle.dumps(venv.unwrapped))
    assert copy.engine.physics._pool is None
    for action in actions[4:]:
        one, two = venv.step(action), copy.step(action)
        np.testing.assert_array_equal(one[0], two[0])
        np.testing.assert_array_equal(one[1], two[1])
    venv.close()


def test_driving_straight_the_robot_lags_its_commanded_path_more_on_ice_than_on_carpet() -> None:
    """At 0.6 m/s straight ahead for 3 s: on carpet the robot trails the commanded path by the
    speed times the stated time constant (a first-order lag's steady trail: 6.7 cm measured
    against 6.75), on ice its wheels spin at the start and it trails by 19.9 cm (measured)."""
    from test_physics_plant import _drive, _world

    from koopman_envs.params import PHYSICS, SURFACES

    speed, periods = PARAMS.v_max, 30
    commanded = speed * periods * PARAMS.dt
    lag = {}
    for surface in SURFACES:
        x, y, theta = _drive(_world(surface), (speed, 0.0), periods)
        assert abs(y) < 1e-6 and abs(theta) < 1e-6  # straight: it only trails
        lag[surface] = commanded - x
    stated = speed * (PHYSICS.motor_time_constant + PHYSICS.speed_loop_time_constant)
    assert lag["carpet"] == pytest.approx(stated, rel=0.1)
    assert lag["ice"] > 2.0 * lag["carpet"] and lag["ice"] > lag["carpet"] + 0.1


def test_rendering_draws_the_bodies_poses_as_they_move() -> None:
    """The frame changes as the robots drive, and the robots drawn are the MuJoCo bodies' planar
    poses (not the kinematic plant's: the same seed and commands there draw another frame)."""
    from koopman_envs.rendering.renderer import Renderer
    from koopman_envs.sim.physics.world import planar_poses

    drawn: list[np.ndarray] = []
    frames: dict[str, Any] = {}
    draw = Renderer.draw

    def spy(self: Renderer, scenario: Any, trail: np.ndarray, *args: Any, **kwargs: Any) -> Any:
        drawn.append(np.asarray(trail)[-1].copy())
        return draw(self, scenario, trail, *args, **kwargs)

    for plant in ("mujoco", "kinematic"):
        env = gym.make(TR, plant=plant, map="map1", render_mode="rgb_array")
        env.reset(seed=0)
        before: Any = env.render()
        for _ in range(15):
            env.step(np.tile([SPEED, 0.3], 3).astype(np.float32))
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(Renderer, "draw", spy)
            frames[plant] = env.render()
        assert before is not None and frames[plant] is not None
        assert not np.array_equal(before, frames[plant])  # the robots moved in the picture
        if plant == "mujoco":
            world = cast(Any, env.unwrapped).engine.physics
            bodies = np.empty((3, 3))
            planar_poses(world.datas[0].qpos, world._qpos, bodies)
            np.testing.assert_array_equal(drawn[-1], bodies.T)
        env.close()
    assert not np.array_equal(frames["mujoco"], frames["kinematic"])


def _zone_friction(zones: list[dict[str, Any]], seed: int = 0) -> np.ndarray:
    """Every robot's friction after one period on map1 with ``zones`` under its starts."""
    from koopman_envs.sim.maps.map_spec import MapSpec, load_map

    spec = load_map("map1").to_dict()
    spec["slip_zones"] = zones
    env = gym.make(TR, plant="mujoco", map=MapSpec.from_dict(spec), slip="nominal")
    env.reset(seed=seed)
    env.step(np.zeros(6, dtype=np.float32))
    friction = cast(Any, env.unwrapped).friction
    assert friction is not None and friction.shape == (3,)
    return friction


#: a rectangle under map1's three starts
UNDER_STARTS = [-3.5, -2.0, -2.5, 2.0]


@pytest.mark.parametrize(("lam", "surface"), [(0.0, "carpet"), (0.1, "gravel"), (0.3, "ice")])
def test_a_zone_without_a_surface_takes_the_one_its_lambda_names(lam: float, surface: str) -> None:
    from koopman_envs.params import SURFACES
    from koopman_envs.sim.physics.surfaces import surface_for_lambda
    from koopman_envs.sim.physics.world import zone_surface
    from koopman_envs.sim.slip.zones import SlipZone

    assert surface_for_lambda(lam) == surface
    assert zone_surface(SlipZone("rect", tuple(UNDER_STARTS), lam)) == surface
    assert zone_surface(SlipZone("rect", tuple(UNDER_STARTS), (0.0, lam, 0.0))) == surface  # the largest
    friction = _zone_friction([{"rect": UNDER_STARTS, "lambda": lam}])
    low, high = SURFACES[surface]
    assert np.all((friction >= low) & (friction <= high)) and len(set(friction)) == 1  # one draw per zone


def test_a_named_surface_zone_is_drawn_anew_every_episode() -> None:
    from koopman_envs.params import SURFACES

    draws = [
        _zone_friction([{"rect": UNDER_STARTS, "lambda": 0.0, "surface": "gravel"}], seed)[0]
        for seed in range(3)
    ]
    low, high = SURFACES["gravel"]
    assert all(low <= d <= high for d in draws) and len(set(draws)) == 3


def test_an_add_zone_does_not_add_friction_the_last_zone_listed_sets_it() -> None:
    replace = {"rect": UNDER_STARTS, "lambda": 0.0, "surface": 0.07}
    add = {"rect": UNDER_STARTS, "lambda": 0.1, "mode": "add", "surface": 0.3}
    np.testing.assert_array_equal(_zone_friction([replace, add]), 0.3)  # not 0.37
    np.testing.assert_array_equal(_zone_friction([add, replace]), 0.07)
    # an add zone without a surface takes its lambda's (gravel), not the replace zone's plus more
    from koopman_envs.params import SURFACES

    friction = _zone_friction([replace, {k: v for k, v in add.items() if k != "surface"}])
    assert np.all((friction >= SURFACES["gravel"][0]) & (friction <= SURFACES["gravel"][1]))


def test_pettingzoo_target_reaching_api_and_seed_tests_on_the_physics_plant() -> None:
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    from koopman_envs import target_reaching_v0

    parallel_api_test(target_reaching_v0.parallel_env(plant="mujoco", max_cycles=40), num_cycles=40)
    parallel_seed_test(
        lambda: target_reaching_v0.parallel_env(plant="mujoco", slip="high", max_cycles=40), num_cycles=20
    )


@pytest.mark.slow
@pytest.mark.parametrize("name", controllers.available())
def test_every_registered_controller_runs_on_the_physics_plant(name: str) -> None:
    """8 periods of Map 1 on the physics plant, calibrated (where the controller calibrates) on
    its calibration plant with a budget of 2,000 team-transitions: finite actions within the
    action space (62 s for the 24 controllers on the shared machine, 24 of them rl-ppo's import)."""
    from controllers.calibration import calibrate_controller
    from koopman_envs import run_episode

    env = gym.make(TR, plant="mujoco", map="map1", max_episode_steps=8)
    ctrl = controllers.make(name)
    summary = calibrate_controller(ctrl, env, budget=2000)
    assert summary is None or summary["budget"] == 2000
    actions: list[np.ndarray] = []
    result = run_episode(env, ctrl, seed=0, on_step=lambda _s, action, _i: actions.append(np.asarray(action)))
    assert result.steps == len(actions) > 0
    for action in actions:
        flat = action.reshape(-1).astype(np.float32)
        assert np.all(np.isfinite(flat)) and env.action_space.contains(flat), (name, action)


def test_the_friction_accessor_is_the_physics_worlds_last_period_and_none_on_the_kinematic_plant() -> None:
    """``env.unwrapped.friction`` (the docs' way to read the ground truth, instead of the engine's
    internals) is a copy of the world's row; the kinematic plant has none."""
    assert cast(Any, gym.make(TR, slip="nominal").unwrapped).friction is None
    friction = _zone_friction([{"rect": UNDER_STARTS, "lambda": 0.0, "surface": "ice"}])
    env = gym.make(TR, plant="mujoco", map="map1", slip="nominal")
    env.reset(seed=0)
    env.step(np.zeros(6, dtype=np.float32))
    seen = cast(Any, env.unwrapped).friction
    seen[:] = -1.0  # a copy: the world's row is untouched
    assert (cast(Any, env.unwrapped).friction > 0).all()
    assert not np.array_equal(friction, cast(Any, env.unwrapped).friction)  # ice under the starts differs
