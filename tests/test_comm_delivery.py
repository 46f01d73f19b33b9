"""The team's radio (CommConfig, simulated in koopman_envs.sim.perception) against expectations
computed by hand from its documented rules:

* the message a robot sends at period s reaches a team-mate at s + latency unless lost, or unless
  the two were more than ``range`` apart *when it was sent* (not when it arrives);
* a robot keeps the last message it received from each team-mate; its age (``message_age``)
  grows by one every period in which no newer message arrives, -1 while none has.

The scenes are exact: no slip, one robot standing, the other driving straight at 0.5 m/s
(0.05 m per period), so every distance is known to the period.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.sim.maps.map_spec import MapSpec

TR = "KoopNav-TargetReaching-v0"
STEP = 0.05  # metres per period at 0.5 m/s
DRIVE = np.array([0.0, 0.0, 0.5, 0.0])  # robot 0 stands, robot 1 drives straight ahead


def _pair(start_1: tuple[float, float, float]) -> MapSpec:
    """Robot 0 standing at the origin, robot 1 at ``start_1``; targets far away (no episode end)."""
    return MapSpec(
        "pair",
        obstacles=[],
        starts=[[0.0, 0.0, 0.0], list(start_1)],
        targets=[[0.0, -6.0, 0.0], [-8.0, 6.0, 0.0]],
    )


def _run(spec: MapSpec, steps: int, comm: dict, action=DRIVE, **kw) -> list[dict]:
    """Infos of periods 0 (the reset) to ``steps``."""
    env = gym.make(TR, map=spec, n_robots=2, comm=comm, max_episode_steps=steps + 5, **kw)
    _, info = env.reset(seed=0)
    infos = [info]
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated)
        infos.append(info)
    return infos


def _assert_heard(info: dict, receiver: int, sender: int, pose, age: int) -> None:
    assert info["message_age"][receiver, sender] == age
    np.testing.assert_array_equal(info["known_poses"][receiver, sender], pose)


def test_range_is_measured_at_send_time_when_the_robots_part() -> None:
    """Robot 1 starts 1 m from robot 0 and drives away: d(s) = 1 + 0.05 s. With range 1.525
    the last message in range is sent at s = 10 (1.50 m; at s = 11 it is 1.55 m). With latency
    4 it arrives at t = 14, and the messages sent at 7..10 arrive at 11..14, when the robots are
    already 1.55-1.70 m apart. After that nothing arrives: both keep the pose of period 10, aged
    t - 10."""
    latency, last, comm_range = 4, 10, 1.0 + STEP * 10.5
    infos = _run(_pair((1.0, 0.0, 0.0)), 30, {"latency": latency, "range": comm_range})
    truth = [info["poses"] for info in infos]
    for t, poses in enumerate(truth):  # the scene is as computed
        assert poses[1, 0] == pytest.approx(1.0 + STEP * t, abs=1e-9) and poses[0].tolist() == [0, 0, 0]
    for t, info in enumerate(infos):
        if t < latency:
            assert (info["message_age"] == [[0, -1], [-1, 0]]).all(), t
            continue
        sent = min(t - latency, last)
        if last < t <= last + latency:  # delivered, though the robots are out of range now
            assert np.linalg.norm(truth[t][1, :2] - truth[t][0, :2]) > comm_range
        for receiver, sender in ((0, 1), (1, 0)):
            _assert_heard(info, receiver, sender, truth[sent][sender], t - sent)
    assert infos[-1]["message_age"][0, 1] == 30 - last  # stale, and ageing


def test_range_is_measured_at_send_time_when_the_robots_meet() -> None:
    """Robot 1 starts 3 m away and drives toward robot 0: d(s) = 3 - 0.05 s, within range
    2.475 from s = 11 on. With latency 4 the first message arrives at t = 15; at t = 11..14 the
    robots are within range, but every message then in flight was sent from farther away."""
    latency, first = 4, 11
    infos = _run(_pair((3.0, 0.0, math.pi)), 24, {"latency": latency, "range": 3.0 - STEP * 10.5})
    truth = [info["poses"] for info in infos]
    for t, poses in enumerate(truth):
        assert poses[1, 0] == pytest.approx(3.0 - STEP * t, abs=1e-9)
    for t, info in enumerate(infos):
        if t < first + latency:
            assert (info["message_age"] == [[0, -1], [-1, 0]]).all(), t
            assert (info["known_poses"][[0, 1], [1, 0]] == 0).all()  # nothing received: zeros
        else:
            for receiver, sender in ((0, 1), (1, 0)):
                _assert_heard(info, receiver, sender, truth[t - latency][sender], latency)
    assert np.linalg.norm(truth[first][1, :2]) <= 2.475 < np.linalg.norm(truth[first - 1][1, :2])


@pytest.mark.parametrize(("comm_range", "heard"), [(2.0, True), (1.999, False)])
def test_a_message_from_exactly_the_range_arrives(comm_range: float, heard: bool) -> None:
    """Robots standing exactly 2 m apart: range 2 (not "more than range apart") delivers, 1.999
    does not."""
    infos = _run(_pair((2.0, 0.0, 0.0)), 3, {"range": comm_range}, action=np.zeros(4))
    for t, info in enumerate(infos):
        if heard:
            _assert_heard(info, 0, 1, [2.0, 0.0, 0.0], 0)
            _assert_heard(info, 1, 0, [0.0, 0.0, 0.0], 0)
        else:
            assert (info["message_age"] == [[0, -1], [-1, 0]]).all(), t


def test_a_lost_message_keeps_the_last_one_and_its_age_grows() -> None:
    """Lossy, late radio with pose noise (the messages carry the senders' estimates, which change
    every period): every period and pair, either the message sent ``latency`` periods ago
    arrives (age = latency, the sender's estimate of then), or the receiver keeps what it had,
    bit for bit, one period older. Both happen, and runs of losses make ages well past the
    latency."""
    latency, drop = 2, 0.5
    env = gym.make(
        TR,
        comm={"latency": latency, "drop": drop},
        pose_noise={"xy": 0.05, "heading": 0.02},
        max_episode_steps=300,
    )
    _, info = env.reset(seed=3)
    infos = [info]
    for _ in range(200):
        _, _, terminated, truncated, info = env.step(np.tile([0.0, 0.4], 3))  # turning on the spot
        assert not (terminated or truncated)
        infos.append(info)
    off = ~np.eye(3, dtype=bool)
    arrived = kept = 0
    for t in range(1, len(infos)):
        now, before = infos[t], infos[t - 1]
        for i, j in zip(*np.nonzero(off), strict=True):
            age = now["message_age"][i, j]
            if t >= latency and age == latency:
                arrived += 1
                np.testing.assert_array_equal(
                    now["known_poses"][i, j], infos[t - latency]["observed_poses"][j]
                )
                assert not np.array_equal(
                    now["known_poses"][i, j], infos[t - latency]["poses"][j]
                )  # an estimate
            else:
                kept += 1
                np.testing.assert_array_equal(now["known_poses"][i, j], before["known_poses"][i, j])
                previous = before["message_age"][i, j]
                assert age == (previous + 1 if previous >= 0 else -1), (t, i, j)
                if age > 0:  # the kept pose is stale: not the sender's estimate of latency ago
                    assert not np.array_equal(
                        now["known_poses"][i, j], infos[t - latency]["observed_poses"][j]
                    )
    total = arrived + kept
    assert abs(arrived - total * (1 - drop)) < 4 * math.sqrt(total * drop * (1 - drop)) + 6 * latency
    ages = np.array([info["message_age"][off] for info in infos])
    assert ages.max() >= latency + 5  # five losses in a row happen in 200 periods at drop 0.5
    # the diagonal is each robot's own estimate, of age 0
    for info in infos:
        assert (np.diagonal(info["message_age"]) == 0).all()
        np.testing.assert_array_equal(info["known_poses"][np.arange(3), np.arange(3)], info["observed_poses"])


def test_drop_one_delivers_nothing() -> None:
    env = gym.make(TR, comm={"drop": 1.0}, max_episode_steps=40)
    _, info = env.reset(seed=0)
    off = ~np.eye(3, dtype=bool)
    for _ in range(30):
        assert (info["message_age"][off] == -1).all() and (info["known_poses"][off] == 0).all()
        *_, info = env.step(np.tile([0.2, 0.0], 3))
