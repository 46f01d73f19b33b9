"""Whose fault a collision is (docs/movers.md, "Who is at fault"), on hand-made scenes with exact
outcomes; the same info on every front; the evaluator's record of it, of the strict success and
of success with the unavoidable collisions excused; and a digest of rollouts among movers that
holds everything else bit for bit as it was before the rule existed."""

from __future__ import annotations

import hashlib
import math
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from controllers.base import ControllerStats
from evaluation.episodes.records import json_safe, record_problem
from evaluation.execution.worker import _result_fields
from koopman_envs import target_reaching_v0
from koopman_envs.episodes.single import EpisodeRecorder, EpisodeResult
from koopman_envs.params import FAULT_STOPPED_SPEED, STRICT_CLEARANCE_MARGIN
from koopman_envs.sim.collision import CollisionFault, CollisionKind
from koopman_envs.sim.maps.map_spec import MapSpec

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
#: one constant mover, exact (no tracker), set by hand after each reset
MOVER = dict(count=1, speed=0.3, tracking=False)
#: a lone robot at the origin facing +x, its target 3 m ahead; nothing else on the map
LANE = MapSpec("lane", obstacles=[], starts=[[0.0, 0.0, 0.0]], targets=[[3.0, 0.0, 0.0]])
#: the same robot with a team-mate parked 2.5 m to its left (it touches nothing)
PAIR = MapSpec(
    "pair",
    obstacles=[],
    starts=[[0.0, 0.0, 0.0], [0.0, 2.5, 0.0]],
    targets=[[3.0, 0.0, 0.0], [0.0, 2.5, 0.0]],
)


def _place_mover(engine: Any, k: int, x: float, vx: float) -> None:
    """Environment ``k``'s one mover on the x axis at ``x`` [m], moving at ``vx`` [m/s]."""
    engine.movers.position[k, 0] = (x, 0.0)
    engine.movers.velocity[k, 0] = (vx, 0.0)


def _drive(env: gym.Env, v: float, steps: int = 30) -> dict[str, Any]:
    """Robot 0 at ``v`` [m/s] straight ahead, the others still, until the episode ends; its last info."""
    n = env.unwrapped.config.n_robots
    command = np.zeros((n, 2))
    command[0, 0] = v
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(command.reshape(-1))
        if terminated or truncated:
            assert terminated
            return info
    raise AssertionError(f"no contact within {steps} periods")


# (robot 0's speed [m/s], the mover's x [m] and vx [m/s], whose fault)
SCENES = {
    "a mover drives into a parked robot": (0.0, 0.5, -0.5, "mover"),
    "a robot drives into a standing mover": (0.5, 0.5, 0.0, "robot"),
    "a robot moving away is caught by a faster mover": (0.3, -0.5, 1.0, "mover"),
    "a head-on meeting": (0.5, 0.85, -0.5, "robot"),
    # the stopped speed's threshold, each side of it, into a standing mover 2-3 mm away
    "a robot creeping below the stopped speed": (0.8 * FAULT_STOPPED_SPEED, 0.402, 0.0, "mover"),
    "a robot just above the stopped speed": (1.2 * FAULT_STOPPED_SPEED, 0.403, 0.0, "robot"),
}


@pytest.mark.parametrize("scene", list(SCENES))
def test_whose_fault_a_mover_contact_is(scene: str) -> None:
    v, x, vx, fault = SCENES[scene]
    env = gym.make(TR, map=LANE, n_robots=1, movers=MOVER)
    env.reset(seed=0)
    _place_mover(env.unwrapped.engine, 0, x, vx)
    info = _drive(env, v)
    assert info["collision_code"] == CollisionKind.MOVER
    assert [CollisionFault.describe(code) for code in info["collision_fault"]] == [fault]
    assert (info["robots_at_fault"], info["robots_not_at_fault"]) == ((1, 0) if fault == "robot" else (0, 1))


def test_a_static_obstacle_is_the_robot_s_fault() -> None:
    lane = MapSpec("wall", obstacles=[[0.7, 0.0, 0.3]], starts=LANE.starts, targets=[[0.0, -2.0, 0.0]])
    env = gym.make(TR, map=lane, n_robots=1)
    env.reset(seed=0)
    info = _drive(env, 0.6)
    assert info["collision_code"] == CollisionKind.OBSTACLE
    assert info["collision_fault"].tolist() == [CollisionFault.ROBOT]
    assert (info["robots_at_fault"], info["robots_not_at_fault"]) == (1, 0)


def test_team_mates_that_meet_are_both_at_fault_and_the_others_at_none() -> None:
    # robots 0 and 1 face each other 0.7 m apart; robot 2 stands 3 m away
    starts = [[0.0, 0.0, 0.0], [0.7, 0.0, math.pi], [0.0, 3.0, 0.0]]
    team = MapSpec(
        "meet", obstacles=[], starts=starts, targets=[[3.0, 0.0, 0.0], [-3.0, 0.0, 0.0], starts[2]]
    )
    env = gym.make(TR, map=team, movers=MOVER)  # a mover elsewhere changes nothing
    env.reset(seed=0)
    command = np.array([[0.6, 0.0], [0.6, 0.0], [0.0, 0.0]])
    for _ in range(10):
        _, _, terminated, _, info = env.step(command.reshape(-1))
        if terminated:
            break
    assert info["collision_code"] == CollisionKind.ROBOT
    assert [CollisionFault.describe(c) for c in info["collision_fault"]] == ["robot", "robot", ""]
    assert (info["robots_at_fault"], info["robots_not_at_fault"]) == (2, 0)


def test_without_a_collision_nobody_is_at_fault() -> None:
    env = gym.make(TR, map=PAIR, n_robots=2, movers=MOVER)
    _, info = env.reset(seed=0)
    assert info["collision_fault"].tolist() == [0, 0]
    assert (info["robots_at_fault"], info["robots_not_at_fault"]) == (0, 0)
    assert CollisionFault.describe(0) == ""
    with pytest.raises(ValueError, match=r"collision fault code 3 is not one of \[0, 1, 2\]"):
        CollisionFault.describe(3)


def test_an_environment_that_does_not_step_keeps_its_verdict() -> None:
    """A finished environment left standing (``active`` False) still reports its collision; the
    fault is judged on the period of the contact, not re-judged on one where nothing moved."""
    env = gym.make(TR, map=LANE, n_robots=1, movers=MOVER)
    env.reset(seed=0)
    engine = env.unwrapped.engine
    _place_mover(engine, 0, 0.5, 0.0)
    assert _drive(env, 0.5)["collision_fault"].tolist() == [CollisionFault.ROBOT]
    engine.step(np.zeros((1, 1, 2)), active=np.array([False]))
    info = engine.info(0)
    assert info["collision"] and info["collision_fault"].tolist() == [CollisionFault.ROBOT]


# ------------------------------------------------------------------------------- every front
FRONT_SCENES = ("a mover drives into a parked robot", "a robot drives into a standing mover")


def _front_infos() -> dict[str, list[dict[str, Any]]]:
    """The last info of each of FRONT_SCENES on the two-robot map, per front."""
    keys = ("collision_code", "robot_collision", "collision_fault", "robots_at_fault", "robots_not_at_fault")
    out: dict[str, list[dict[str, Any]]] = {"gym": [], "parallel": [], "vector": []}
    for scene in FRONT_SCENES:
        v, x, vx, _ = SCENES[scene]
        env = gym.make(TR, map=PAIR, n_robots=2, movers=MOVER)
        env.reset(seed=0)
        _place_mover(env.unwrapped.engine, 0, x, vx)
        info = _drive(env, v)
        out["gym"].append({key: np.asarray(info[key]).tolist() for key in keys})
        par = target_reaching_v0.parallel_env(map=PAIR, n_robots=2, movers=MOVER)
        par.reset(seed=0)
        _place_mover(par.engine, 0, x, vx)
        for _ in range(30):
            _, _, terminations, _, infos = par.step({"robot_0": np.array([v, 0.0]), "robot_1": np.zeros(2)})
            if any(terminations.values()):
                break
        assert infos["robot_0"]["collision_fault"].tolist() == infos["robot_1"]["collision_fault"].tolist()
        out["parallel"].append({key: np.asarray(infos["robot_0"][key]).tolist() for key in keys})
    # the vector env: the two scenes side by side in one batch
    vec = gym.make_vec(
        TR, num_envs=2, vectorization_mode="vector_entry_point", map=PAIR, n_robots=2, movers=MOVER
    )
    vec.reset(seed=0)
    engine = vec.unwrapped.engine
    actions = np.zeros((2, 4))
    for k, scene in enumerate(FRONT_SCENES):
        v, x, vx, _ = SCENES[scene]
        _place_mover(engine, k, x, vx)
        actions[k, 0] = v
    rows: list[dict[str, Any] | None] = [None, None]
    for _ in range(30):
        _, _, terminated, _, info = vec.step(actions)
        for k in np.flatnonzero(terminated):
            rows[k] = rows[k] or {key: np.asarray(info[key])[k].tolist() for key in keys}
        actions[terminated] = 0.0  # the ended one is reset next step (NextStep); keep it still
        if all(row is not None for row in rows):
            break
    out["vector"] = rows  # type: ignore[assignment]
    return out


def test_every_front_reports_the_same_fault() -> None:
    infos = _front_infos()
    assert infos["gym"][0]["collision_fault"] == [CollisionFault.MOVER, CollisionFault.NONE]
    assert infos["gym"][1]["collision_fault"] == [CollisionFault.ROBOT, CollisionFault.NONE]
    assert infos["parallel"] == infos["gym"]
    assert infos["vector"] == infos["gym"]


# ------------------------------------------------------------------------------- records
def _recorded(env: gym.Env, v: float, x: float | None = None, vx: float = 0.0) -> EpisodeResult:
    """One episode measured as the evaluator measures it (EpisodeRecorder), robot 0 at ``v``,
    with the mover placed by hand when ``x`` is given."""
    _, info = env.reset(seed=0)
    if x is not None:
        _place_mover(env.unwrapped.engine, 0, x, vx)
        info = env.unwrapped.engine.info(0)
    recorder = EpisodeRecorder(env.unwrapped.scenario, info)
    command = np.array([[v, 0.0]])
    while True:
        _, reward, terminated, truncated, info = env.step(command.reshape(-1))
        recorder.record(command, float(reward), info)
        if terminated or truncated:
            return recorder.result(info, bool(truncated and not terminated))


def _record(result: EpisodeResult) -> dict[str, Any]:
    """The evaluator's record of ``result`` as written (its cell fields made up)."""
    cell = dict(key="k", status="ok", env_id=TR, controller="c", map="m", slip="nominal", trial=1, seed=0)
    record = json_safe({**cell, **_result_fields(SimpleNamespace(trial=1), result, ControllerStats())})
    assert record_problem(record) is None
    return record


@pytest.mark.parametrize(
    "target, v, x, vx, expected",
    [
        # a mover runs into a robot parked on its target: excused, the team had arrived
        ([0.0, 0.0, 0.0], 0.0, 0.5, -0.5, dict(collision_at_fault=False, success_excusing_unavoidable=True)),
        # ... parked on its way: no robot's fault, but it never arrived
        ([3.0, 0.0, 0.0], 0.0, 0.5, -0.5, dict(collision_at_fault=False, success_excusing_unavoidable=False)),
        # a robot that drives into a standing mover is at fault
        ([3.0, 0.0, 0.0], 0.5, 0.5, 0.0, dict(collision_at_fault=True, success_excusing_unavoidable=False)),
    ],
)
def test_the_record_holds_the_fault_and_the_excused_success(target, v, x, vx, expected) -> None:
    lane = MapSpec("lane", obstacles=[], starts=LANE.starts, targets=[target])
    result = _recorded(gym.make(TR, map=lane, n_robots=1, movers=MOVER), v, x, vx)
    record = _record(result)
    assert record["success"] is False and record["strict_success"] is False
    assert record["collision"] == "mover"
    assert {key: record[key] for key in expected} == expected


@pytest.mark.parametrize(
    "gap, strict", [(STRICT_CLEARANCE_MARGIN - 0.02, False), (STRICT_CLEARANCE_MARGIN + 0.03, True)]
)
def test_strict_success_needs_clearance_above_the_margin(gap: float, strict: bool) -> None:
    """A robot parked on its target succeeds after the settling time; an obstacle ``gap`` [m]
    from its body (3 and 8 cm) makes the success strict only when the gap is above the 5 cm margin."""
    parked = MapSpec(
        "parked", obstacles=[[0.2 + gap + 0.3, 0.0, 0.3]], starts=LANE.starts, targets=LANE.starts
    )
    result = _recorded(gym.make(TR, map=parked, n_robots=1), 0.0)
    record = _record(result)
    assert record["success"] and record["success_excusing_unavoidable"] and not record["collision_at_fault"]
    assert record["clearance_min_m"] == pytest.approx(gap, abs=1e-12)
    assert record["strict_success"] is strict


# ------------------------------------------------------------------------------- bit for bit
#: the info keys the fault rule added (everything else must stay as it was)
NEW_KEYS = {"collision_fault", "robots_at_fault", "robots_not_at_fault"}


def _bytes(value: Any) -> bytes:
    """The bytes a digest takes of ``value``: floats rounded to 1e-9 (and -0.0 made 0.0), so that a
    CPU whose NumPy rounds a transcendental in the last bit otherwise (SIMD kernels differ between
    AVX2 and AVX-512 machines) gives the same digest, while any change of substance still shows."""
    array = np.asarray(value)
    if array.dtype.kind == "f":
        array = np.round(array.astype(np.float64), 9) + 0.0
    return array.tobytes()


def _hash_info(digest: Any, info: dict[str, Any]) -> None:
    for key in sorted(info):
        if key.lstrip("_") not in NEW_KEYS:
            digest.update(key.encode())
            digest.update(_bytes(info[key]))


def _gym_digest(env_id: str, seed: int, steps: int, **kwargs: Any) -> str:
    env = gym.make(env_id, **kwargs)
    digest, rng = hashlib.sha256(), np.random.default_rng(seed)
    _, info = env.reset(seed=seed)
    _hash_info(digest, info)
    for _ in range(steps):
        action = rng.uniform(-1, 1, env.action_space.shape) * env.action_space.high
        obs, reward, terminated, truncated, info = env.step(action)
        digest.update(_bytes(obs) + _bytes(reward) + bytes([terminated, truncated]))
        _hash_info(digest, info)
        if terminated or truncated:
            _, info = env.reset()
            _hash_info(digest, info)
    return digest.hexdigest()


def _vector_digest(env_id: str, seed: int, steps: int, **kwargs: Any) -> str:
    env = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
    digest, rng = hashlib.sha256(), np.random.default_rng(seed)
    _, info = env.reset(seed=seed)
    _hash_info(digest, info)
    for _ in range(steps):
        action = rng.uniform(-1, 1, env.action_space.shape) * env.action_space.high
        obs, reward, terminated, truncated, info = env.step(action)
        digest.update(_bytes(obs) + _bytes(reward) + terminated.tobytes() + truncated.tobytes())
        _hash_info(digest, info)
    return digest.hexdigest()


def _parallel_digest(seed: int, steps: int, **kwargs: Any) -> str:
    env = target_reaching_v0.parallel_env(**kwargs)
    digest, rng = hashlib.sha256(), np.random.default_rng(seed)
    env.reset(seed=seed)
    for _ in range(steps):
        if not env.agents:
            env.reset()
        actions = {a: rng.uniform(-1, 1, 2) * env.action_space(a).high for a in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)
        for a in sorted(obs):
            digest.update(_bytes(obs[a]) + _bytes(np.float64(rewards[a])))
            digest.update(bytes([terminations[a], truncations[a]]))
            _hash_info(digest, infos[a])
    return digest.hexdigest()


#: random-action rollouts among movers on every front, each with collisions of both faults
#: (movers running into robots among them) and resets after them; the digests were computed
#: on main before the rule existed (22b3a48; floats rounded to 1e-9 by _bytes, computed there and
#: here alike)
ROLLOUTS = {
    "gym, constant movers": (
        lambda: _gym_digest(TR, 3, 300, map="map1", movers=dict(count=8, speed=0.5)),
        "9a8ca61c6e75bd678254eac8a65d93c093e20b49539463a91407e814f4ac95e6",
    ),
    "gym, waypoint walkers, realistic uncertainty": (
        lambda: _gym_digest(
            FO, 5, 300, map="random", movers=dict(count=8, behaviour="waypoints"), uncertainty="realistic"
        ),
        "0e3c523d5645b7df9823cbd0dc15360d29c51a95c280e5e5422082652ec7682c",
    ),
    "vector env, constant movers": (
        lambda: _vector_digest(FO, 7, 150, map="map3", movers=dict(count=10, speed=0.6, tracking=False)),
        "15f4e62e8acad727d1577870874458a856f27210c45a7daad154a297674485d0",
    ),
    "parallel env, waypoint walkers": (
        lambda: _parallel_digest(9, 150, map="map2", movers=dict(count=8, behaviour="waypoints", speed=0.6)),
        "0e271ec879c4c624c84cef4b0b0bcef09d6e625e687742840fc08f8065588ca8",
    ),
}


@pytest.mark.parametrize("rollout", list(ROLLOUTS))
def test_everything_but_the_fault_is_as_before_bit_for_bit(rollout: str) -> None:
    run, digest = ROLLOUTS[rollout]
    assert run() == digest
