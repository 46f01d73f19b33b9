"""koopman_envs.sim.perception replayed to the bit from its documented rules (issue 41, mutation
testing): a fault in how the sensor noise is laid out, drawn, refilled, delivered or delayed would
change every result silently, so each period of a :class:`Perception` is compared with a plain
Python replay of the rules in its docstrings, driven by the same generator.

The documented protocol replayed here: the noise comes from ``rng.spawn(1)[0]`` (a child of the
env's generator), drawn in blocks of ``block`` periods (float32; normals then uniforms, each block
environment by environment); a period's row holds the pose white noise and bias steps (6 per robot:
x, y, theta noise then x, y, theta bias step), then the lidar reading noise (one per beam);
its uniforms the message losses (one per ordered pair i != j), then the beam dropouts. The pose
is truth + bias + white noise, the bias a random walk from the second period on; a message sent at
period s arrives at s + latency unless lost or sent from beyond the range; a dropped beam reads the
range, the others get Gaussian noise when below it, clipped to [0, range]; a command acts
``actuation_delay`` periods after it is given.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from koopman_envs.settings import CommConfig, LidarConfig, PoseNoise
from koopman_envs.sim import perception as perception_module
from koopman_envs.sim.dynamics import wrap_scalar
from koopman_envs.sim.lidar import beam_angles, cast_beams
from koopman_envs.sim.perception import (
    BLOCK_NUMBERS,
    SENSOR_MODEL,
    Perception,
    child_generator,
    observed_info,
)

DT = 0.1
#: the kernels compiled by numba, or run as Python (mutation testing strips @njit to mutate them): a
#: Python float times a float32 is a float64 product in numba and a float32 one in NumPy (NEP 50)
COMPILED = hasattr(perception_module._perceive, "py_func")
WORKSPACE = (-10.0, 10.0, -10.0, 10.0)
RADIUS = np.full(3, 0.2)
#: two obstacle discs per environment (x, y, r), fixed
# two environments' obstacle sets (K, 3, M): rows x, y, radius
OBSTACLES = np.stack(
    (
        np.array([[1.5, -2.0], [0.5, 2.5]]),
        np.array([[0.5, 1.0], [-1.5, 0.0]]),
        np.array([[0.4, 0.6], [0.3, 0.5]]),
    ),
    axis=1,
)


class Replay:
    """The documented rules of one environment, in plain Python, fed by the same child generator."""

    def __init__(self, rng, n, noise, comm, lidar, block):
        self.child = rng.spawn(1)[0]  # a fresh generator of the same seed spawns the same child
        self.n, self.noise, self.comm, self.lidar, self.block = n, noise, comm, lidar, block
        beams = 0 if lidar is None else lidar.beams
        self.beams = beams
        self.width_n = (6 * n if noise.active else 0) + (n * beams if lidar and lidar.noise > 0 else 0)
        self.width_u = (n * (n - 1) if comm.drop > 0 else 0) + (
            n * beams if lidar and lidar.dropout > 0 else 0
        )
        self.cursor = block
        self.start_episode()

    def start_episode(self):
        n = self.n
        self.t = 0
        self.bias = np.zeros((3, n))
        self.known = np.zeros((n, n, 3))
        self.age = np.full((n, n), -1)
        self.sent = {}  # period -> (observed (3, N), true positions (2, N))
        self.commands = []

    def _row(self):
        if self.width_n + self.width_u == 0:
            return None, None
        if self.cursor >= self.block:
            self.normals = (
                self.child.standard_normal((self.block, self.width_n), dtype=np.float32)
                if self.width_n
                else None
            )
            self.uniforms = (
                self.child.random((self.block, self.width_u), dtype=np.float32) if self.width_u else None
            )
            self.cursor = 0
        row = self.cursor
        self.cursor += 1
        pick = lambda a: None if a is None else [float(v) for v in a[row]]  # noqa: E731
        return pick(self.normals), pick(self.uniforms)

    def period(self, truth, exact_ranges):
        """Observed (3, N), known (N, N, 3), age (N, N), ranges (N, B) after one period at ``truth``."""
        n, noise, comm, lidar, t = self.n, self.noise, self.comm, self.lidar, self.t
        normal, uniform = self._row()
        at_n = at_u = 0
        std = [noise.xy, noise.xy, noise.heading]
        drift = np.array([noise.drift_xy, noise.drift_xy, noise.drift_heading]) * math.sqrt(DT)
        observed = np.zeros((3, n))
        for i in range(n):
            for c in range(3):
                value = float(truth[c, i])
                if noise.active:
                    if t > 0:
                        self.bias[c, i] += drift[c] * normal[at_n + 3 + c]
                    value += self.bias[c, i] + std[c] * normal[at_n + c]
                observed[c, i] = wrap_scalar(value) if c == 2 else value
            if noise.active:
                at_n += 6
        self.sent[t] = (observed.copy(), truth[:2].copy())
        for i in range(n):
            for j in range(n):
                if i == j:
                    self.known[i, i] = observed[:, i]
                    self.age[i, i] = 0
                    continue
                lost = False
                if comm.drop > 0:
                    lost = uniform[at_u] < comm.drop
                    at_u += 1
                delivered = False
                if t >= comm.latency and not lost:
                    poses, positions = self.sent[t - comm.latency]
                    dx, dy = positions[:, j] - positions[:, i]
                    delivered = dx * dx + dy * dy <= comm.range * comm.range
                if delivered:
                    self.known[i, j] = poses[:, j]
                    self.age[i, j] = comm.latency
                elif self.age[i, j] >= 0:
                    self.age[i, j] += 1
        ranges = np.zeros((n, self.beams))
        for i in range(n):
            for b in range(self.beams):
                value = float(exact_ranges[i, b])
                if lidar.dropout > 0:
                    if uniform[at_u] < lidar.dropout:
                        value = lidar.range
                    at_u += 1
                if lidar.noise > 0:
                    if value < lidar.range:
                        if COMPILED:
                            value += lidar.noise * normal[at_n]
                        else:
                            value += float(np.float32(lidar.noise) * np.float32(normal[at_n]))
                    at_n += 1
                ranges[i, b] = min(max(value, 0.0), lidar.range)
        self.t += 1
        return observed, self.known.copy(), self.age.copy(), ranges

    def act(self, command, delay):
        self.commands.append(command.copy())
        s = len(self.commands) - 1
        return self.commands[s - delay] if s >= delay else np.zeros_like(command)


def _exact_ranges(state, lidar, obstacles=OBSTACLES):
    """Exact ranges (K, N, B) of the true poses (the kernel, tested in tests/test_uncertainty.py)."""
    k, _, n = state.shape
    out = np.zeros((k, n, 0 if lidar is None else lidar.beams))
    if lidar is not None:
        angles = beam_angles(lidar.beams, lidar.fov)
        cast_beams(state, obstacles, np.full(n, 0.2), angles, lidar.range, np.asarray(WORKSPACE), out)
    return out


def _truths(periods, seed=11):
    """True poses (K=2, 3, N=3) per period: a random walk, headings across the +-pi seam."""
    rng = np.random.default_rng(seed)
    state = np.array(
        [
            [[-2.0, 0.0, 2.0], [0.0, 1.0, -1.0], [3.1, -3.1, 0.0]],
            [[1.0, -1.5, 0.0], [-2.0, 2.0, 0.5], [0.5, 3.0, -3.0]],
        ]
    )
    out = []
    for _ in range(periods):
        state = state + rng.normal(0.0, 0.08, state.shape)
        out.append(state.copy())
    return out


SCENES = {
    # name: pose noise, comm, lidar, delay, the block size by hand
    "perfect": (PoseNoise(), CommConfig(), None, 0, 256),  # no draws at all
    "pose": (PoseNoise(0.1, 0.05, 0.02, 0.01), CommConfig(), None, 0, 256),  # 8192 // 18 = 455 -> 256
    "radio": (PoseNoise(0.03, 0.02), CommConfig(latency=2, drop=0.3, range=3.0), None, 1, 256),  # 24 -> 341
    "lossless-late": (PoseNoise(), CommConfig(latency=3, range=2.5), None, 0, 256),
    # 18 + 3*40 normals, 6 + 3*40 uniforms: 8192 // 264 = 31 periods a block
    "lidar": (
        PoseNoise(0.02, 0.01, 0.01, 0.0),
        CommConfig(latency=1, drop=0.2),
        LidarConfig(beams=40, range=3.0, noise=0.05, dropout=0.2),
        2,
        31,
    ),
    # 3*120 normals only: 8192 // 360 = 22
    "lidar-noise": (PoseNoise(), CommConfig(), LidarConfig(beams=120, range=2.0, noise=0.3), 0, 22),
    # 6 + 3*200 uniforms only: 8192 // 606 = 13
    "lidar-dropout": (
        PoseNoise(),
        CommConfig(drop=0.5),
        LidarConfig(beams=200, range=2.5, dropout=0.3),
        3,
        13,
    ),
    # 3 * 4000 beams: 8192 // 24000 = 0 -> at least 8 periods a block
    "wide-lidar": (PoseNoise(), CommConfig(), LidarConfig(beams=4000, range=1.0, dropout=0.01), 0, 8),
}


@pytest.mark.parametrize("scene", list(SCENES))
def test_every_period_equals_the_replay_of_the_documented_rules(scene: str) -> None:
    noise, comm, lidar, delay, block = SCENES[scene]
    periods = 40
    perception = Perception(2, 3, noise, comm, lidar, delay, DT, WORKSPACE)
    assert perception.block == block
    rngs = [np.random.default_rng(101), np.random.default_rng(202)]
    replays = [Replay(np.random.default_rng(s), 3, noise, comm, lidar, block) for s in (101, 202)]
    truths = _truths(periods + 1)
    for k in range(2):
        perception.reset_env(k, rngs[k])
    commands = np.random.default_rng(5).normal(size=(periods, 2, 3, 2))
    for t, state in enumerate(truths):
        if t == 0:
            perception.flush(state, OBSTACLES, RADIUS)  # the first readings of a reset
        else:
            acting = perception.delayed(commands[t - 1], np.arange(2))
            for k in range(2):
                np.testing.assert_array_equal(
                    acting[k], replays[k].act(commands[t - 1, k], delay), strict=True
                )
            perception.update(state, OBSTACLES, RADIUS, np.arange(2))
        exact = _exact_ranges(state, lidar)
        info = observed_info(perception, state.transpose(0, 2, 1))
        for k in range(2):
            observed, known, age, ranges = replays[k].period(state[k], exact[k])
            where = f"{scene}, period {t}, env {k}"
            np.testing.assert_array_equal(perception.observed[k], observed, err_msg=where, strict=True)
            np.testing.assert_array_equal(info["observed_poses"][k], observed.T, err_msg=where, strict=True)
            np.testing.assert_array_equal(info["known_poses"][k], known, err_msg=where, strict=True)
            np.testing.assert_array_equal(info["message_age"][k], age, err_msg=where)
            if lidar is not None:
                np.testing.assert_array_equal(info["lidar_ranges"][k], ranges, err_msg=where, strict=True)
        assert (lidar is not None) == ("lidar_ranges" in info)
    assert perception.clock.tolist() == [periods + 1] * 2


def test_environments_stepped_apart_and_reset_mid_run_draw_as_alone() -> None:
    """Each environment draws from its own child whatever the others do; a reset with the same
    generator keeps its child and its place in the block (zero bias, no messages, an idle queue),
    a reset with another generator starts that generator's child afresh."""
    noise, comm, lidar, delay, block = SCENES["lidar"]
    perception = Perception(2, 3, noise, comm, lidar, delay, DT, WORKSPACE)
    rngs = [np.random.default_rng(7), np.random.default_rng(8)]
    replays = [Replay(np.random.default_rng(s), 3, noise, comm, lidar, block) for s in (7, 8)]
    for k in range(2):
        perception.reset_env(k, rngs[k])
    truths = _truths(80, seed=3)
    schedule = [np.arange(2)] * 10 + [np.array([1])] * 7 + [np.array([0])] * 30 + [np.arange(2)] * 30
    first = True
    for t, rows in enumerate(schedule):
        state = truths[t]
        if t == 25:  # env 0 starts a new episode with the same generator (an auto-reset)
            perception.reset_env(0, rngs[0])
            replays[0].start_episode()
        if t == 40:  # env 1 is reseeded: a new child, a fresh block
            rngs[1] = np.random.default_rng(99)
            perception.reset_env(1, rngs[1])
            replays[1] = Replay(np.random.default_rng(99), 3, noise, comm, lidar, block)
        pending = set(perception._pending)
        chosen = sorted(set(rows.tolist()) | pending)
        command = np.full((2, 3, 2), float(t))
        if first:
            perception.flush(state, OBSTACLES, RADIUS)
            first = False
        else:
            acting = perception.delayed(command, rows)
            for k in range(2):
                expected = replays[k].act(command[k], delay) if k in rows else command[k]
                np.testing.assert_array_equal(acting[k], expected, err_msg=f"period {t}")
            before = observed_info(perception, state.transpose(0, 2, 1))
            perception.update(state, OBSTACLES, RADIUS, rows)
        exact = _exact_ranges(state, lidar)
        info = observed_info(perception, state.transpose(0, 2, 1))
        for k in range(2):
            if k in chosen:
                observed, known, age, ranges = replays[k].period(state[k], exact[k])
                np.testing.assert_array_equal(info["observed_poses"][k], observed.T, err_msg=f"period {t}")
                np.testing.assert_array_equal(info["known_poses"][k], known, err_msg=f"period {t}")
                np.testing.assert_array_equal(info["message_age"][k], age, err_msg=f"period {t}")
                np.testing.assert_array_equal(info["lidar_ranges"][k], ranges, err_msg=f"period {t}")
            elif t > 0:  # not stepped: unchanged
                for key in info:
                    np.testing.assert_array_equal(info[key][k], before[key][k], err_msg=f"period {t}")


def test_a_reset_clears_the_episode_state_and_the_first_readings_wait_for_flush() -> None:
    noise, comm, lidar, delay, _ = SCENES["lidar"]
    perception = Perception(1, 3, noise, comm, lidar, delay, DT, WORKSPACE)
    rng = np.random.default_rng(1)
    perception.reset_env(0, rng)
    state = _truths(1)[0][:1]
    obstacles = OBSTACLES[:1]
    perception.flush(state, obstacles, RADIUS)
    for _ in range(5):
        perception.delayed(np.ones((1, 3, 2)), np.array([0]))
        perception.update(state, obstacles, RADIUS, np.array([0]))
    assert perception.clock[0] == 6 and perception.queue.any() and perception.bias.any()
    perception.reset_env(0, rng)
    assert perception.clock[0] == 0 and perception._pending == [0]
    assert not perception.bias.any() and not perception.known.any() and not perception.queue.any()
    assert (perception.age == -1).all()
    cursor = int(perception.cursor[0])
    assert cursor == 6  # the same generator: its child and its place in the block are kept
    perception.flush(state, obstacles, RADIUS)
    assert perception._pending == [] and perception.clock[0] == 1 and perception.cursor[0] == 7
    perception.flush(state, obstacles, RADIUS)  # nothing pending: nothing read
    assert perception.clock[0] == 1 and perception.cursor[0] == 7


def test_without_a_delay_the_commands_act_at_once_and_a_delay_queues_each_environment() -> None:
    perception = Perception(2, 1, PoseNoise(), CommConfig(), None, 0, DT, WORKSPACE)
    commands = np.ones((2, 1, 2))
    assert perception.delayed(commands, np.arange(2)) is commands
    assert perception.queue.shape == (2, 1, 1, 2)
    delayed = Perception(2, 1, PoseNoise(), CommConfig(), None, 3, DT, WORKSPACE)
    assert delayed.queue.shape == (2, 3, 1, 2)
    acting = delayed.delayed(commands, np.array([1]))
    assert acting is not commands
    np.testing.assert_array_equal(acting[0], commands[0])  # not queued: acts as given
    np.testing.assert_array_equal(acting[1], np.zeros((1, 2)))  # queued: the idle command
    np.testing.assert_array_equal(commands, np.ones((2, 1, 2)))  # the caller's array is untouched


def test_the_buffers_have_the_documented_shapes_and_start_empty() -> None:
    noise, comm, lidar, delay, block = SCENES["lidar"]
    p = Perception(4, 3, noise, comm, lidar, delay, DT, WORKSPACE)
    assert p.observed.shape == (4, 3, 3) and p.bias.shape == (4, 3, 3) and p.known.shape == (4, 3, 3, 3)
    assert p.age.shape == (4, 3, 3) and (p.age == -1).all() and p.age.dtype == np.int64
    assert p.ranges.shape == (4, 3, 40) and p.max_range == 3.0
    np.testing.assert_array_equal(p.angles, beam_angles(40, 2 * math.pi))
    assert p.sent.shape == (4, 2, 5, 3)  # the estimates sent, then the true positions
    assert p.model.dtype == SENSOR_MODEL and p.model.shape == (1,) and p.model[0]["max_range"] == 3.0
    assert (p._normals, p._uniforms) == (18 + 120, 6 + 120)
    assert p.normal.shape == (block, 4, 138) and p.normal.dtype == np.float32
    assert p.uniform.shape == (block, 4, 126) and p.uniform.dtype == np.float32
    assert p.cursor.tolist() == [block] * 4 and p.clock.tolist() == [0] * 4
    assert p.streams.generators == [None] * 4 and p.dt == 0.1 and p.delay == 2
    np.testing.assert_array_equal(p.workspace, WORKSPACE)
    bare = Perception(2, 3, PoseNoise(), CommConfig(), None, 0, DT, WORKSPACE)
    assert bare.ranges.shape == (2, 3, 0) and bare.angles.shape == (0,) and bare.max_range == 0.0
    assert (bare._normals, bare._uniforms, bare.block) == (0, 0, 256)
    # the block: as many periods as BLOCK_NUMBERS numbers allow, 8 to 256
    assert BLOCK_NUMBERS == 8192
    one = Perception(1, 2, PoseNoise(0.1), CommConfig(drop=0.1), None, 0, DT, WORKSPACE)
    assert (one._normals, one._uniforms, one.block) == (12, 2, 256)  # 8192 // 14 = 585
    many = Perception(1, 40, PoseNoise(0.1), CommConfig(drop=0.1), None, 0, DT, WORKSPACE)
    assert (many._normals, many._uniforms, many.block) == (240, 1560, 8)  # 8192 // 1800 = 4


def test_a_step_before_any_reset_is_refused_by_environment() -> None:
    perception = Perception(2, 3, PoseNoise(0.1), CommConfig(), None, 0, DT, WORKSPACE)
    perception.reset_env(0, np.random.default_rng(0))
    state = _truths(1)[0]
    with pytest.raises(RuntimeError, match=r"^Perception: environment 1 was stepped before reset\(\)$"):
        perception.update(state, OBSTACLES, RADIUS, np.arange(2))


def test_without_perception_the_info_is_the_truth_in_copies() -> None:
    poses = np.arange(2 * 3 * 3, dtype=float).reshape(2, 3, 3)
    info = observed_info(None, poses)
    assert sorted(info) == ["known_poses", "message_age", "observed_poses"]
    np.testing.assert_array_equal(info["observed_poses"], poses, strict=True)
    for i in range(3):
        np.testing.assert_array_equal(info["known_poses"][:, i], poses, strict=True)  # every row: the truth
    np.testing.assert_array_equal(info["message_age"], np.zeros((2, 3, 3), dtype=np.int64), strict=True)
    info["observed_poses"][:] = -1.0
    info["known_poses"][:] = -1.0
    assert poses.min() == 0.0  # copies, not views
    assert info["known_poses"].flags.writeable


def test_the_believed_state_is_handed_out_in_copies() -> None:
    noise, comm, lidar, delay, _ = SCENES["lidar"]
    perception = Perception(2, 3, noise, comm, lidar, delay, DT, WORKSPACE)
    for k in range(2):
        perception.reset_env(k, np.random.default_rng(k))
    state = _truths(1)[0]
    perception.flush(state, OBSTACLES, RADIUS)
    info = observed_info(perception, state.transpose(0, 2, 1))
    kept = {key: value.copy() for key, value in info.items()}
    for value in info.values():
        value[...] = -7
    again = observed_info(perception, state.transpose(0, 2, 1))
    for key in kept:
        np.testing.assert_array_equal(again[key], kept[key], strict=True)


def test_the_child_generator_consumes_nothing_of_the_env_stream() -> None:
    rng = np.random.default_rng(42)
    child = child_generator(rng)
    assert rng.random() == np.random.default_rng(42).random()
    assert child.random() == np.random.default_rng(42).spawn(1)[0].random()
    # one child is derived: the next one spawned from the env's generator is its second
    assert rng.spawn(1)[0].random() == np.random.default_rng(42).spawn(2)[1].random()


@pytest.mark.parametrize(
    "lidar",
    [LidarConfig(beams=1, range=2.0, noise=0.1), LidarConfig(beams=1, range=2.0, dropout=0.4)],
    ids=["one-normal", "one-uniform"],
)
def test_a_single_random_number_per_period_is_drawn_and_refilled(lidar) -> None:
    """One robot with one beam: a period draws one normal (noise) or one uniform (dropout); the
    block holds 256 periods and is drawn again after them."""
    perception = Perception(1, 1, PoseNoise(), CommConfig(), lidar, 0, DT, WORKSPACE)
    assert (perception._normals, perception._uniforms, perception.block) == (
        int(lidar.noise > 0),
        int(lidar.dropout > 0),
        256,
    )
    obstacles = np.array([[[1.0], [0.0], [0.3]]])  # 0.7 m ahead of the robot
    replay = Replay(np.random.default_rng(3), 1, PoseNoise(), CommConfig(), lidar, 256)
    perception.reset_env(0, np.random.default_rng(3))
    state = np.zeros((1, 3, 1))
    exact = _exact_ranges(state, lidar, obstacles)
    assert exact[0, 0, 0] == pytest.approx(0.7)
    perception.flush(state, obstacles, np.full(1, 0.2))
    for t in range(300):
        if t:
            perception.update(state, obstacles, np.full(1, 0.2), np.arange(1))
        ranges = replay.period(state[0], exact[0])[3]
        np.testing.assert_array_equal(perception.ranges[0], ranges, err_msg=f"period {t}", strict=True)


def test_a_flush_reads_only_the_environments_reset_since_the_last_update() -> None:
    noise, comm, lidar, delay, _ = SCENES["lidar"]
    perception = Perception(2, 3, noise, comm, lidar, delay, DT, WORKSPACE)
    for k in range(2):
        perception.reset_env(k, np.random.default_rng(k))
    state = _truths(1)[0]
    perception.flush(state, OBSTACLES, RADIUS)
    for _ in range(3):
        perception.update(state, OBSTACLES, RADIUS, np.arange(2))
    for reset in (1, 0):
        others = 1 - reset
        kept = observed_info(perception, state.transpose(0, 2, 1))
        clock, cursor = perception.clock.copy(), perception.cursor.copy()
        perception.reset_env(reset, np.random.default_rng(reset))
        perception.flush(state, OBSTACLES, RADIUS)
        after = observed_info(perception, state.transpose(0, 2, 1))
        for key in kept:
            np.testing.assert_array_equal(after[key][others], kept[key][others], strict=True)
        assert perception.clock[others] == clock[others] and perception.cursor[others] == cursor[others]
        assert perception.clock[reset] == 1


def test_a_step_of_some_environments_leaves_the_readings_of_the_others() -> None:
    """Four environments, three stepped: the fourth keeps its noisy readings (no exact re-cast)."""
    lidar = LidarConfig(beams=16, range=3.0, noise=0.05)
    perception = Perception(4, 2, PoseNoise(), CommConfig(), lidar, 0, DT, WORKSPACE)
    obstacles = np.concatenate([OBSTACLES, OBSTACLES])
    state = np.concatenate([_truths(1)[0], _truths(1, seed=5)[0]])[:, :, :2]
    radius = np.full(2, 0.2)
    for k in range(4):
        perception.reset_env(k, np.random.default_rng(10 + k))
    perception.flush(state, obstacles, radius)
    exact = _exact_ranges(state, lidar, obstacles)
    assert (perception.ranges != exact).any(axis=(1, 2)).all()  # every environment's readings are noisy
    before = perception.ranges[3].copy()
    perception.update(state, obstacles, radius, np.arange(3))
    np.testing.assert_array_equal(perception.ranges[3], before, strict=True)
    assert perception.clock.tolist() == [2, 2, 2, 1]


class _NoSeedSequence:
    def __init__(self, error: type[Exception]) -> None:
        self.error = error

    def spawn(self, count: int):
        raise self.error("no seed sequence")


@pytest.mark.parametrize("error", [TypeError, ValueError])
def test_a_generator_without_a_seed_sequence_is_refused_with_the_remedy(error) -> None:
    with pytest.raises(ValueError) as caught:
        child_generator(_NoSeedSequence(error))
    assert str(caught.value) == (
        "the env's generator has no seed sequence to derive the sensor noise from; "
        "call reset(seed=...) (or make the generator with numpy.random.default_rng)"
    )
    assert isinstance(caught.value.__cause__, error)


class _Drawn:
    """A generator that hands out chosen numbers: the kernel's comparisons at their boundaries."""

    def __init__(self, uniforms):
        self.uniforms = np.asarray(uniforms, dtype=np.float32)

    def spawn(self, count):
        return [self]

    def random(self, dtype, out):
        out[...] = self.uniforms

    def standard_normal(self, dtype, out):
        out[...] = 0.0


def test_a_uniform_equal_to_the_probability_is_no_loss_and_no_dropout() -> None:
    """A loss (or a dropout) happens when the uniform in [0, 1) is below the probability: then
    P(loss) is the probability itself, not a float32 step more."""
    drop, dropout = 0.5, 0.25
    perception = Perception(
        1,
        2,
        PoseNoise(),
        CommConfig(drop=drop),
        LidarConfig(beams=2, range=3.0, dropout=dropout),
        0,
        DT,
        WORKSPACE,
    )
    assert (perception._normals, perception._uniforms) == (0, 2 + 2 * 2)
    below = lambda p: np.nextafter(np.float32(p), np.float32(0))  # noqa: E731
    # messages 0 <- 1 and 1 <- 0, then the beams of robot 0 and of robot 1
    row = [drop, below(drop), dropout, below(dropout), 0.9, 0.0]
    perception.reset_env(0, _Drawn(np.tile(row, (perception.block, 1))))
    state = np.array([[[0.0, 0.0], [0.0, 1.0], [0.0, math.pi / 2]]])  # robot 1 north of robot 0
    # east and west of robot 0, north of robot 1 (and robot 0 south of it): every beam hits something
    obstacles = np.array([[[2.0, -2.0, 0.0], [0.0, 0.0, 3.0], [0.5, 0.5, 0.5]]])
    perception.flush(state, obstacles, np.full(2, 0.2))
    assert perception.age[0].tolist() == [[0, 0], [-1, 0]]  # 0 heard 1 (u = drop); 1 lost 0's message
    exact = _exact_ranges(state, perception.lidar, obstacles)[0]
    assert exact.tolist() == [[1.5, 1.5], [1.5, 0.8]]
    np.testing.assert_array_equal(perception.ranges[0], [[exact[0, 0], 3.0], [exact[1, 0], 3.0]], strict=True)
