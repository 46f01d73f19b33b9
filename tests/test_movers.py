"""Moving obstacles (``movers`` keyword, docs/movers.md): kinematics, placement, the crowd, the
collision kind, the observation, determinism and every front through the official checkers."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.settings import MoverConfig, parse_movers
from koopman_envs.sim.collision import CollisionKind
from koopman_envs.sim.movers.field import MOVER_FEATURES, MoverField
from koopman_envs.sim.movers.placement import PlacementError, mover_arena, place_movers_batch

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
WORKSPACE = (-10.0, 10.0, -10.0, 10.0)
DT = 0.1


def _field(behaviour: str, count: int, **kw) -> MoverField:
    return MoverField(1, MoverConfig(count=count, behaviour=behaviour, **kw), 3, DT, WORKSPACE)


def _reset_open_field(field: MoverField, seed: int = 0) -> None:
    """Reset on an obstacle-free 8 m square (starts and targets at its corners)."""
    corners = np.array([[-4.0, -4.0, 0.0], [4.0, 4.0, 0.0], [-4.0, 4.0, 0.0]])
    field.reset_env(0, np.random.default_rng(seed), np.zeros((0, 3)), corners, -corners, 0.2)


# --------------------------------------------------------------------------- kinematics
def test_a_constant_mover_moves_in_a_straight_line_at_its_speed() -> None:
    field = _field("constant", 1, speed=0.3)
    _reset_open_field(field)
    field.position[0, 0] = (0.0, 0.0)
    field.velocity[0, 0] = (0.3 * 0.6, 0.3 * 0.8)
    rows = np.array([0])
    for _ in range(10):
        field.step(np.zeros((1, 3, 3)), np.zeros((1, 3, 3)), rows)
    assert np.allclose(field.position[0, 0], (0.18, 0.24), atol=1e-12)
    assert np.allclose(field.velocity[0, 0], (0.18, 0.24), atol=1e-15)


def test_a_constant_mover_reflects_at_the_arena_edge() -> None:
    field = _field("constant", 1, speed=0.5, radius=0.2)
    _reset_open_field(field)
    x_max = field.arena[0, 1] - 0.2
    field.position[0, 0] = (x_max - 0.02, 0.0)
    field.velocity[0, 0] = (0.5, 0.0)
    field.step(np.zeros((1, 3, 3)), np.zeros((1, 3, 3)), np.array([0]))
    # 0.05 m of travel: 0.02 to the edge, 0.03 back
    assert np.allclose(field.position[0, 0], (x_max - 0.03, 0.0), atol=1e-12)
    assert np.allclose(field.velocity[0, 0], (-0.5, 0.0))


def test_a_constant_mover_reflects_off_a_static_obstacle() -> None:
    field = _field("constant", 1, speed=0.5, radius=0.2)
    obstacle = np.array([[1.0, 0.0, 0.5]])
    corners = np.array([[-4.0, -4.0, 0.0], [4.0, 4.0, 0.0], [-4.0, 4.0, 0.0]])
    field.reset_env(0, np.random.default_rng(0), obstacle, corners, -corners, 0.2)
    field.position[0, 0] = (1.0 - 0.7 - 0.01, 0.0)  # 1 cm short of touching, heading straight at it
    field.velocity[0, 0] = (0.5, 0.0)
    field.step(np.zeros((1, 3, 3)), np.zeros((1, 3, 3)), np.array([0]))
    assert np.allclose(field.velocity[0, 0], (-0.5, 0.0))
    assert np.hypot(*(field.position[0, 0] - obstacle[0, :2])) >= 0.7 - 1e-12


def test_waypoint_walkers_keep_to_the_arena_below_their_speed() -> None:
    field = _field("waypoints", 6, speed=0.4, pause=0.5)
    _reset_open_field(field, seed=3)
    rows = np.array([0])
    before = field.position.copy()
    paused = 0
    for _ in range(400):
        field.step(np.zeros((1, 3, 3)), np.zeros((1, 3, 3)), rows)
        step = np.hypot(*(field.position[0] - before[0]).T)
        assert (step <= 0.4 * DT + 1e-12).all()
        paused += int((step == 0).sum())
        before = field.position.copy()
        x_min, x_max, y_min, y_max = field.arena[0]
        assert (field.position[0, :, 0] >= x_min).all() and (field.position[0, :, 0] <= x_max).all()
        assert (field.position[0, :, 1] >= y_min).all() and (field.position[0, :, 1] <= y_max).all()
    assert paused > 0  # they do pause at their waypoints


# --------------------------------------------------------------------------- placement
@pytest.mark.parametrize("env_id", [TR, FO])
@pytest.mark.parametrize("map_name", ["map1", "map2", "random"])
def test_no_mover_starts_on_a_start_or_a_target_or_an_obstacle(env_id: str, map_name: str) -> None:
    env = gym.make(env_id, map=map_name, movers=dict(count=8, speed=0.4))
    engine = env.unwrapped.engine
    radius = float(engine.config.robot_radius[0])
    for seed in range(20):
        _, info = env.reset(seed=seed)
        movers = info["movers"][:, :2]
        assert info["collision_code"] == 0
        keep_clear = np.vstack([info["poses"][:, :2], info["targets"][:, :2]])
        gaps = np.hypot(*(movers[:, None] - keep_clear[None]).transpose(2, 0, 1)) - radius - 0.2
        assert gaps.min() >= 0.5, seed  # START_CLEARANCE: a second of travel or more
        obstacles = np.asarray(engine.maps[0].obstacles).reshape(-1, 3)
        if len(obstacles):
            reach = np.hypot(*(movers[:, None] - obstacles[None, :, :2]).transpose(2, 0, 1))
            assert (reach >= obstacles[None, :, 2] + 0.2).all(), seed


def test_placement_draws_and_places_as_on_main_before_its_kernels_were_merged() -> None:
    """Crowded arenas, so that most environments need further blocks of candidates (each then
    placed by the batch kernel on a batch of one): the placements, the refusals and every
    generator's next number hashed, against the digest computed on main at 4a00b79 (where a
    separate single-environment kernel placed the further blocks)."""
    digest = hashlib.sha256()
    for seed in range(40):
        draw = np.random.default_rng(seed)
        batch, count, radius = 3, int(draw.integers(2, 12)), float(draw.uniform(0.2, 0.6))
        arenas = np.tile([-3.0, 3.0, -3.0, 3.0], (batch, 1)) * draw.uniform(0.6, 1.2, (batch, 1))
        obstacles = draw.uniform(-3, 3, (batch, 5, 3))
        obstacles[..., 2] = draw.uniform(0.2, 0.8, (batch, 5))
        starts, targets = draw.uniform(-3, 3, (batch, 3, 3)), draw.uniform(-3, 3, (batch, 3, 3))
        rngs = [np.random.default_rng(seed * 10 + b) for b in range(batch)]
        try:
            digest.update(
                place_movers_batch(rngs, count, radius, arenas, obstacles, starts, targets, 0.3).tobytes()
            )
        except PlacementError as error:
            digest.update(str(error).encode())
        digest.update(np.array([rng.random() for rng in rngs]).tobytes())  # the draws each made
    assert digest.hexdigest() == "51a19e0e7bd40f690cb367628126c68325828fc63b8a58da65c81ae87becc841"


def test_the_arena_covers_the_map_with_a_margin_inside_the_workspace() -> None:
    starts = np.array([[0.0, 0.0, 0.0]])
    targets = np.array([[9.5, 2.0, 0.0]])
    arena = mover_arena(starts, targets, np.array([[3.0, -1.0, 0.5]]), WORKSPACE)
    assert np.allclose(arena, (-1.5, 10.0, -3.0, 3.5))


def test_too_many_movers_for_the_arena_are_refused_by_name() -> None:
    env = gym.make(TR, movers=dict(count=400, radius=0.5))
    with pytest.raises(ValueError, match="no free place for mover"):
        env.reset(seed=0)


# --------------------------------------------------------------------------- the crowd
def test_two_pedestrians_head_on_pass_without_contact() -> None:
    pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    field = _field("crowd", 2, speed=0.4, radius=0.2, pause=0.0)
    _reset_open_field(field)
    # rebuild the simulators with the two walkers facing each other on one line
    from koopman_envs.sim.movers.crowd import orca_simulator

    field.position[0] = [(-2.0, 0.0), (2.0, 0.0)]
    field.goal[0] = [(2.0, 0.0), (-2.0, 0.0)]
    field.leg_speed[0] = 0.4
    field.waiting[0] = 0
    field._orca[0] = orca_simulator(np.zeros((0, 3)), field.position[0], field.config, 3, 0.2, DT)
    closest, furthest = np.inf, np.zeros(2)
    for _ in range(100):  # 10 s: 4 m of walking at 0.4 m/s
        field.step(np.zeros((1, 3, 3)), np.zeros((1, 3, 3)), np.array([0]))
        closest = min(closest, float(np.hypot(*(field.position[0, 0] - field.position[0, 1]))))
        furthest = np.maximum(furthest, field.position[0, :, 0] * (1, -1))
    assert closest >= 0.4 - 1e-6  # never closer than the two radii
    assert (furthest > 1.5).all()  # and each got past the other, close to its goal


def test_an_aware_crowd_avoids_a_standing_robot_and_an_oblivious_one_walks_into_it() -> None:
    pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    hits = {}
    for aware in (False, True):
        env = gym.make(
            TR, movers=dict(count=12, behaviour="crowd", aware=aware, speed=0.4), max_episode_steps=600
        )
        hits[aware] = 0
        for seed in range(4):
            env.reset(seed=seed)
            for _ in range(600):
                _, _, terminated, truncated, info = env.step(np.zeros(6))
                if terminated or truncated:
                    break
            hits[aware] += bool(info["collision_code"] & CollisionKind.MOVER)
    assert hits[False] >= 1 and hits[True] == 0, hits


# --------------------------------------------------------------------------- collisions
def test_touching_a_mover_ends_the_episode_with_the_mover_kind() -> None:
    env = gym.make(TR, movers=dict(count=2, speed=0.0))
    env.reset(seed=0)
    engine = env.unwrapped.engine
    engine.movers.position[0, 0] = engine.poses[0][1, :2] + (0.3, 0.0)  # 0.1 m from robot 1's body
    _, _, terminated, _, info = env.step(np.zeros(6))
    assert terminated and info["collision"]
    assert info["collision_code"] == CollisionKind.MOVER
    assert CollisionKind.describe(info["collision_code"]) == "mover"
    assert info["robot_collision"].tolist() == [False, True, False]


# --------------------------------------------------------------------------- observation
def test_each_robot_lists_its_nearest_movers_and_masks_absent_slots() -> None:
    env = gym.make(TR, movers=dict(count=2, observed=3, speed=0.3, tracking=False))
    plain = gym.make(TR)
    obs, info = env.reset(seed=4)
    plain_obs, _ = plain.reset(seed=4)
    n = 3
    block = obs.reshape(n, -1)
    assert block.shape[1] == plain_obs.reshape(n, -1).shape[1] + 3 * MOVER_FEATURES
    assert np.array_equal(block[:, : -3 * MOVER_FEATURES], plain_obs.reshape(n, -1))  # appended after
    slots = block[:, -3 * MOVER_FEATURES :].reshape(n, 3, MOVER_FEATURES)
    poses, movers = info["poses"], info["movers"]
    for i in range(n):
        x, y, theta = poses[i]
        gaps = np.hypot(movers[:, 0] - x, movers[:, 1] - y) - 0.2 - 0.2
        order = np.argsort(gaps)
        for slot, m in enumerate(order):
            dx, dy = movers[m, 0] - x, movers[m, 1] - y
            c, s = np.cos(theta), np.sin(theta)
            expected = [
                c * dx + s * dy,
                c * dy - s * dx,
                c * movers[m, 2] + s * movers[m, 3],
                c * movers[m, 3] - s * movers[m, 2],
                gaps[m],
            ]
            assert np.allclose(slots[i, slot], expected, atol=1e-5)
        assert np.array_equal(slots[i, 2], np.float32([0, 0, 0, 0, 30]))  # the absent third
    assert env.observation_space.contains(obs)


def test_lidar_beams_hit_the_movers_and_the_observation_lists_none() -> None:
    kwargs = dict(sensing="lidar", lidar=dict(beams=32, noise=0.0, dropout=0.0))
    env = gym.make(TR, movers=dict(count=1, speed=0.0), **kwargs)
    plain = gym.make(TR, **kwargs)
    obs, _ = env.reset(seed=0)
    plain.reset(seed=0)
    assert obs.shape == plain.observation_space.shape
    engine = env.unwrapped.engine
    x, y, theta = engine.poses[0][0]
    engine.movers.position[0, 0] = (x + 1.0 * np.cos(theta), y + 1.0 * np.sin(theta))  # 1 m ahead of robot 0
    _, _, _, _, info = env.step(np.zeros(6))
    ranges = info["lidar_ranges"] if "lidar_ranges" in info else engine.observed_info()["lidar_ranges"][0]
    ahead = ranges[0][np.argmin(np.abs(np.angle(np.exp(1j * engine.perception.angles))))]
    assert ahead == pytest.approx(1.0 - 0.2, abs=1e-9)  # from the robot's centre to the mover's surface


def test_info_holds_the_true_mover_states_and_without_tracking_the_view_too() -> None:
    from koopman_envs import Observed

    env = gym.make(FO, movers=dict(count=3, behaviour="waypoints", tracking=False))
    _, info = env.reset(seed=2)
    for _ in range(5):
        _, _, _, _, info = env.step(np.zeros(6))
    assert info["movers"].shape == (3, 4)
    view = Observed.from_info(info)
    assert np.array_equal(view.observed_movers, info["movers"])


# --------------------------------------------------------------------------- replay, seeds, fronts
def _rollout(env_id: str, steps: int, seed: int, **kw) -> list[dict]:
    env = gym.make(env_id, max_episode_steps=steps + 5, **kw)
    _, info = env.reset(seed=seed)
    infos = [info]
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(np.tile([0.3, 0.1], 3))
        infos.append(info)
        if terminated or truncated:
            break
    return infos


def test_no_movers_replay_the_plain_env_bit_for_bit() -> None:
    plain = _rollout(FO, 40, 7, slip="high", map="random")
    for setting in (0, None, dict(count=0, behaviour="crowd")):
        same = _rollout(FO, 40, 7, slip="high", map="random", movers=setting)
        assert len(same) == len(plain)
        for a, b in zip(plain, same):
            assert a.keys() == b.keys() and all(np.array_equal(a[key], b[key]) for key in a)


def test_movers_leave_the_team_s_draws_unchanged() -> None:
    """The movers draw from a child of the env's generator: with the same seed the map, starts
    and slip are those of the episode without movers (paired comparisons)."""
    plain = _rollout(TR, 1, 3, map="random", slip="high")[0]
    moving = _rollout(TR, 1, 3, map="random", slip="high", movers=6)[0]
    assert np.array_equal(plain["poses"], moving["poses"]) and np.array_equal(
        plain["targets"], moving["targets"]
    )


SETTINGS = {
    "constant": {"map": "random", "movers": dict(count=6)},
    "waypoints": {"movers": dict(count=6, behaviour="waypoints"), "uncertainty": "realistic"},
    "crowd": {"map": "random", "movers": dict(count=6, behaviour="crowd", aware=True)},
}


def _digest(behaviour: str) -> str:
    h = hashlib.sha256()
    for info in _rollout(FO, 30, 11, **SETTINGS[behaviour]):
        for key in sorted(info):
            h.update(np.asarray(info[key]).tobytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def digests_of_another_process() -> dict[str, str]:
    """Each behaviour's :func:`_digest` computed in one fresh interpreter (one start-up for all
    of them; the crowd, which needs pyrvo, only where pyrvo is installed: the test skips it too)."""
    here = str(Path(__file__).resolve().parent)
    code = (
        f"import importlib.util, json, sys; sys.path.insert(0, {here!r}); from test_movers import SETTINGS, _digest\n"
        "runs = [b for b in SETTINGS if b != 'crowd' or importlib.util.find_spec('pyrvo') is not None]\n"
        "print(json.dumps({behaviour: _digest(behaviour) for behaviour in runs}))"
    )
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(other.stdout)


@pytest.mark.parametrize("behaviour", list(SETTINGS))
def test_same_seed_same_result_across_processes(behaviour: str, digests_of_another_process) -> None:
    if behaviour == "crowd":
        pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    assert digests_of_another_process[behaviour] == _digest(behaviour)


@pytest.mark.parametrize("behaviour", list(SETTINGS))
def test_the_vector_env_matches_single_envs(behaviour: str) -> None:
    if behaviour == "crowd":
        pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    kwargs = SETTINGS[behaviour]
    vec = gym.make_vec(FO, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(FO, **kwargs) for _ in range(3)]
    obs, infos = vec.reset(seed=20)
    for i, env in enumerate(singles):
        single, info = env.reset(seed=20 + i)
        assert np.array_equal(obs[i], single) and np.array_equal(infos["movers"][i], info["movers"])
    rng = np.random.default_rng(0)
    for _ in range(15):
        actions = rng.uniform(-0.5, 0.5, size=(3, 6)).astype(np.float32)
        obs, _, _, _, infos = vec.step(actions)
        for i, env in enumerate(singles):
            single, _, _, _, info = env.step(actions[i])
            assert np.array_equal(obs[i], single) and np.array_equal(infos["movers"][i], info["movers"])


@pytest.mark.parametrize("behaviour", list(SETTINGS))
def test_every_front_passes_the_official_checkers(behaviour: str) -> None:
    if behaviour == "crowd":
        pytest.importorskip("pyrvo", reason="the crowd needs pyrvo: the [crowd] extra")
    kwargs = SETTINGS[behaviour]
    for env_id in (TR, FO):
        check_env(gym.make(env_id, **kwargs).unwrapped, skip_render_check=True)
    for module in (target_reaching_v0, formation_v0):
        parallel_api_test(module.parallel_env(**kwargs), num_cycles=30)
        parallel_seed_test(lambda module=module: module.parallel_env(**kwargs))


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("value", "message"),
    [
        (dict(count=-1), "movers.count=-1"),
        (-2, "movers=-2"),
        (dict(radius=-0.1), "movers.radius=-0.1"),
        (dict(radius=0), "movers.radius=0"),
        (dict(speed=-1.0), "movers.speed=-1.0"),
        (dict(behaviour="crwod"), "did you mean 'crowd'"),
        (dict(behavior="crowd"), "did you mean 'behaviour'"),
        (dict(aware=True), "applies to behaviour='crowd'"),
        (dict(aware="yes", behaviour="crowd"), "movers.aware='yes'"),
        ("many", "movers='many'"),
    ],
)
def test_bad_settings_are_refused_by_name(value, message: str) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        gym.make(TR, movers=value)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        target_reaching_v0.parallel_env(movers=value)


def test_a_count_is_that_many_constant_movers() -> None:
    assert parse_movers("movers", 5) == MoverConfig(count=5)
    assert parse_movers("movers", None) == MoverConfig() and not MoverConfig().active


# --------------------------------------------------------------------------- rendering
def test_movers_are_drawn_with_trails_and_blitting_matches_a_full_redraw() -> None:
    from koopman_envs.rendering.renderer import MOVER_TRAIL, Renderer, frame_title

    env = gym.make(FO, movers=dict(count=4, behaviour="waypoints", speed=0.4), render_mode="rgb_array")
    env.reset(seed=2)
    engine = env.unwrapped.engine
    plain = gym.make(FO, render_mode="rgb_array")
    plain.reset(seed=2)
    history = []
    for _ in range(30):
        env.render()  # turns the trail on at the first frame
        history.append(engine.movers.position[0].copy())
        env.step(np.tile([0.3, 0.05], 3))
        plain.step(np.tile([0.3, 0.05], 3))
    history.append(engine.movers.position[0].copy())
    trail = engine.movers.trail_of(0)
    assert trail.shape == (MOVER_TRAIL, 4, 2)
    np.testing.assert_array_equal(trail, np.array(history[-MOVER_TRAIL:]))
    base = env.unwrapped
    args = (base.scenario, np.asarray(base._trail), frame_title(base.config), 3.0)
    fast = Renderer().draw(*args, movers=trail)
    full = Renderer(blit=False).draw(*args, movers=trail)
    assert np.abs(fast.astype(int) - full.astype(int)).mean() < 0.1
    without = Renderer().draw(*args)
    assert np.abs(fast.astype(int) - without.astype(int)).mean() > 0.1  # the movers show


def test_read_only_map_arrays_are_accepted() -> None:
    """The evaluator's maps are frozen (read-only arrays): placement and the arena take them."""
    starts = np.array([[-4.0, -4.0, 0.0], [4.0, 4.0, 0.0]])
    targets = -starts
    obstacles = np.array([[1.0, 0.0, 0.5]])
    for array in (starts, targets, obstacles):
        array.setflags(write=False)
    field = _field("constant", 3)
    field.reset_env(0, np.random.default_rng(0), obstacles, starts, targets, 0.2)
    assert np.isfinite(field.position).all()
    assert np.allclose(mover_arena(starts, targets, obstacles, WORKSPACE), (-5.5, 5.5, -5.5, 5.5))
