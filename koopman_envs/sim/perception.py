"""What every robot believes: noisy localization, team-mates heard over a lossy radio, lidar readings.

:class:`Perception` runs beside the physics of :class:`~koopman_envs.engine.engine.NavigationEngine`
when any uncertainty setting of :mod:`koopman_envs.settings.uncertainty` is away from its perfect value.
After each step (and at reset) one compiled pass updates, per environment:

1. each robot's own pose estimate: truth + bias + white noise (the bias a random walk);
2. the radio: each robot broadcasts its estimate; the message sent ``latency`` periods ago
   reaches each team-mate unless lost (``drop``) or sent from beyond ``range``; a robot keeps
   the last message it received from each team-mate and its age;
3. the lidar readings' noise and dropouts (the exact ranges come from :mod:`koopman_envs.sim.lidar`).

Random numbers come from a child of the env's generator (``Generator.spawn``), made when the
env's generator changes (``reset(seed=...)``) and kept across episodes otherwise, and are drawn
in blocks per environment, as the slip draws are: every environment due for a block in a step
fills it in one compiled call (:mod:`koopman_envs.sim.pcg64`: NumPy's own PCG64 stream and
samplers, number for number). Spawning consumes nothing of the env's own stream, so the map,
start and slip draws of a seed are the same at every uncertainty level (a sweep's curves are
paired), and a sub-environment of a batch draws exactly as a lone env.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.settings.uncertainty import CommConfig, LidarConfig, PoseNoise
from koopman_envs.sim.dynamics import wrap_scalar
from koopman_envs.sim.lidar import beam_angles, cast_beams
from koopman_envs.sim.pcg64 import Streams, refill_f32

__all__ = ["SENSOR_MODEL", "Perception", "child_generator", "observed_info"]

#: random numbers drawn per environment and generator call, about (ours): a block of periods
#: this large amortizes the generator calls (a few microseconds each) and keeps the buffer of
#: 1024 environments at about 64 MiB
BLOCK_NUMBERS = 8192

#: the fixed terms of the sensors and the radio, one record per :class:`Perception` (made once,
#: not per step): numba reads its fields by name and types a record argument as fast as a plain
#: array (a named tuple it types field by field in Python, microseconds a call)
SENSOR_MODEL = np.dtype(
    [
        ("std", np.float64, (3,)),  # white noise of x, y [m] and heading [rad]
        ("drift", np.float64, (3,)),  # the bias's random-walk step per period (per sqrt(s) x sqrt(dt))
        ("noisy", np.bool_),  # any pose noise (else no normals are read for it)
        ("latency", np.int64),  # periods a message travels
        ("drop", np.float64),  # probability a message is lost
        ("range2", np.float64),  # the radio's range squared [m^2]
        ("lidar_noise", np.float64),  # a reading's standard deviation [m]
        ("lidar_dropout", np.float64),  # probability a reading is lost (reads max_range)
        ("max_range", np.float64),  # the lidar's range [m] (0 without lidar)
    ]
)
#: an environment's block of random numbers as the compiled pass takes it: ``normal`` and
#: ``uniform`` (block, K, width) float32 and each environment's ``cursor`` (K,) int64 into them
#: (plain tuples, made once per :class:`Perception`: numba types one at a call almost as fast as
#: loose arrays, a named tuple field by field in Python)
Draws = tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.int64]]
#: :class:`Perception`'s state as the compiled pass updates it: ``clock`` (K,) int64, ``bias``
#: (K, 3, N), ``observed`` (K, 3, N), ``sent`` (K, latency + 1, 5, N), ``known`` (K, N, N, 3),
#: ``age`` (K, N, N) int64, ``ranges`` (K, N, B)
Memory = tuple[
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int64],
    NDArray[np.float64],
]


def child_generator(rng: np.random.Generator) -> np.random.Generator:
    """An independent generator derived from ``rng``'s seed sequence without consuming its stream.

    Raises
    ------
    ValueError
        ``rng`` has no seed sequence to spawn from (a generator built from a raw bit-generator
        state); seed the env with ``reset(seed=...)`` instead.
    """
    try:
        return rng.spawn(1)[0]
    except (TypeError, ValueError) as exc:
        raise ValueError(
            "the env's generator has no seed sequence to derive the sensor noise from; "
            "call reset(seed=...) (or make the generator with numpy.random.default_rng)"
        ) from exc


class Perception:
    """Sensor, radio and actuation state of K environments of N robots.

    Parameters
    ----------
    num_envs, n_robots : int
        Batch size K and team size N.
    pose_noise : PoseNoise
    comm : CommConfig
    lidar : LidarConfig or None
        None without lidar sensing.
    actuation_delay : int
        Periods between a command and its action.
    dt : float
        Control period [s] (the bias random walk's time step).
    workspace : tuple of float
        x_min, x_max, y_min, y_max [m] (the lidar's walls).

    Attributes
    ----------
    observed : ndarray, shape (K, 3, N)
        Every robot's estimate of its own pose (rows x, y, theta).
    known : ndarray, shape (K, N, N, 3)
        ``known[k, i, j]``: robot i's last received pose of robot j (its own estimate on the
        diagonal; zeros before any message).
    age : ndarray of int, shape (K, N, N)
        Periods since that message was sent (0 on the diagonal, -1 while none has arrived).
    ranges : ndarray, shape (K, N, B)
        Lidar readings [m] (B = 0 without lidar).
    """

    def __init__(
        self,
        num_envs: int,
        n_robots: int,
        pose_noise: PoseNoise,
        comm: CommConfig,
        lidar: LidarConfig | None,
        actuation_delay: int,
        dt: float,
        workspace: tuple[float, float, float, float],
    ) -> None:
        k, n = num_envs, n_robots
        self.pose_noise, self.comm, self.lidar, self.delay = pose_noise, comm, lidar, int(actuation_delay)
        self.dt = float(dt)
        beams = 0 if lidar is None else lidar.beams
        self.angles = np.zeros(0) if lidar is None else beam_angles(lidar.beams, lidar.fov)
        self.max_range = 0.0 if lidar is None else float(lidar.range)
        self.workspace = np.asarray(workspace, dtype=np.float64)
        self.observed = np.zeros((k, 3, n))
        self.bias = np.zeros((k, 3, n))
        self.known = np.zeros((k, n, n, 3))  # the info's layout: its copy is one memcpy
        self.age = np.full((k, n, n), -1, dtype=np.int64)
        self.ranges = np.zeros((k, n, beams))
        self.clock = np.zeros(k, dtype=np.int64)
        #: the radio's last ``latency + 1`` broadcasts per environment: rows 0-2 the estimate
        #: each robot sent (x, y, theta), rows 3-4 where it truly was (x, y; the range check)
        self.sent = np.zeros((k, comm.latency + 1, 5, n))
        self.model = np.array(
            [
                (
                    (pose_noise.xy, pose_noise.xy, pose_noise.heading),
                    np.array([pose_noise.drift_xy, pose_noise.drift_xy, pose_noise.drift_heading])
                    * math.sqrt(self.dt),
                    pose_noise.active,
                    comm.latency,
                    comm.drop,
                    comm.range * comm.range,
                    0.0 if lidar is None else lidar.noise,
                    0.0 if lidar is None else lidar.dropout,
                    self.max_range,
                )
            ],
            dtype=SENSOR_MODEL,
        )
        # random numbers per period: pose white noise and bias steps (6 N), then the lidar's
        # reading noise (N B); uniforms: message losses (N (N - 1)), then beam dropouts (N B)
        noisy_lidar = lidar is not None and lidar.noise > 0
        lidar_dropout = lidar is not None and lidar.dropout > 0
        self._normals = (6 * n if pose_noise.active else 0) + (n * beams if noisy_lidar else 0)
        self._uniforms = (n * (n - 1) if comm.drop > 0 else 0) + (n * beams if lidar_dropout else 0)
        #: periods per block: as many as BLOCK_NUMBERS random numbers allow, 8 to 256
        self.block = int(np.clip(BLOCK_NUMBERS // max(1, self._normals + self._uniforms), 8, 256))
        # single precision: half the generator's time, and ample for noise (7 significant digits)
        # period-major (block, K, width): the environments' cursors move together (every
        # environment of a batch reads one period a step), so a step reads the buffer in order,
        # where an environment-major one costs a cache and TLB miss per environment (its rows
        # are a block apart); a refill writes one environment's column through a scratch row
        self.normal = np.zeros((self.block, k, self._normals), dtype=np.float32)
        self.uniform = np.zeros((self.block, k, self._uniforms), dtype=np.float32)
        self.cursor = np.full(k, self.block, dtype=np.int64)
        #: each environment's child generator (drawn in compiled code where it is a PCG64)
        self.streams = Streams(k)
        self._parents: list[np.random.Generator | None] = [None] * k
        self.queue = np.zeros((k, max(self.delay, 1), n, 2))
        self._pending: list[int] = []  # environments reset since the last update
        # the compiled pass's arguments (the same arrays, updated in place; a copy of the
        # object copies them once, as shared references)
        self._draws: Draws = (self.normal, self.uniform, self.cursor)
        self._memory: Memory = (
            self.clock,
            self.bias,
            self.observed,
            self.sent,
            self.known,
            self.age,
            self.ranges,
        )

    # ------------------------------------------------------------------ reset
    def reset_env(self, index: int, rng: np.random.Generator) -> None:
        """Start environment ``index``'s episode: zero bias, no messages, an idle command queue.

        Its first readings are taken by the next :meth:`update` or :meth:`flush` (with every
        other environment reset meanwhile: one compiled call for a batch of auto-resets).
        """
        if self._parents[index] is not rng:
            self._parents[index] = rng
            self.streams.attach(index, child_generator(rng))
            self.cursor[index] = self.block
        self.clock[index] = 0
        self.bias[index] = 0.0
        self.known[index] = 0.0
        self.age[index] = -1
        self.queue[index] = 0.0
        self._pending.append(index)

    def flush(
        self,
        state: NDArray[np.float64],
        discs: NDArray[np.float64],
        robot_radius: NDArray[np.float64],
    ) -> None:
        """Take the first readings of the environments reset since the last update."""
        if self._pending:
            self.update(state, discs, robot_radius, np.zeros(0, dtype=np.int64))

    # ------------------------------------------------------------------- step
    def delayed(self, commands: NDArray[np.float64], rows: NDArray[np.int64]) -> NDArray[np.float64]:
        """The commands that act this period: those given ``actuation_delay`` periods ago
        (zeros, standing still, at the start of an episode). ``commands`` (K, N, 2) are queued
        for the environments in ``rows``; the others keep their queue."""
        if self.delay == 0:
            return commands
        acting = commands.copy()
        _delay(commands, self.queue, self.clock, rows, acting)
        return acting

    def update(
        self,
        state: NDArray[np.float64],
        discs: NDArray[np.float64],
        robot_radius: NDArray[np.float64],
        rows: NDArray[np.int64],
    ) -> None:
        """Read the sensors and the radio of environments ``rows`` (and of those reset since the
        last update) at the true poses ``state`` (K, 3, N), then advance their clocks; the lidar's
        beams hit the robots and ``discs`` (K, 3, M: rows x, y, radius [m])."""
        if self._pending:  # a mask rather than a set union: O(K), and each environment once
            chosen = np.zeros(self.clock.shape[0], dtype=bool)
            chosen[rows] = True
            chosen[self._pending] = True
            rows = np.flatnonzero(chosen)
            self._pending.clear()
        self._refill(rows)
        if self.lidar is not None:
            if rows.shape[0] == state.shape[0]:  # every environment (a plain step): no copies
                cast_beams(
                    state,
                    discs,
                    robot_radius,
                    self.angles,
                    self.max_range,
                    self.workspace,
                    self.ranges,
                )
            else:
                exact = np.empty((rows.shape[0],) + self.ranges.shape[1:])
                cast_beams(
                    state[rows],
                    discs[rows],
                    robot_radius,
                    self.angles,
                    self.max_range,
                    self.workspace,
                    exact,
                )
                self.ranges[rows] = exact
        _perceive(self.model, state, rows, self._draws, self._memory)

    def _refill(self, rows: NDArray[np.int64]) -> None:
        """Draw a new block for every environment of ``rows`` that has used up its own: its
        normals, then its uniforms (one compiled call for every PCG64 generator)."""
        if self._normals == 0 and self._uniforms == 0:
            return
        due = rows[self.cursor[rows] >= self.block]
        if not due.shape[0]:
            return
        compiled, others = self.streams.split(due, "Perception")
        if compiled.shape[0]:
            refill_f32(self.streams.words, compiled, self.normal, self.uniform, self.cursor)
        for index, rng in others:
            normal = np.empty((self.block, self._normals), dtype=np.float32)
            uniform = np.empty((self.block, self._uniforms), dtype=np.float32)
            rng.standard_normal(dtype=np.float32, out=normal)
            rng.random(dtype=np.float32, out=uniform)
            self.normal[:, index], self.uniform[:, index] = normal, uniform
            self.cursor[index] = 0


@njit(cache=True)
def _delay(
    commands: NDArray[np.float64],
    queue: NDArray[np.float64],
    clock: NDArray[np.int64],
    rows: NDArray[np.int64],
    acting: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Swap the commands of environments ``rows`` with the queue's slot ``clock % delay``."""
    delay = queue.shape[1]
    for k in rows:
        slot = clock[k] % delay
        for i in range(commands.shape[1]):
            for c in range(2):
                acting[k, i, c] = queue[k, slot, i, c]
                queue[k, slot, i, c] = commands[k, i, c]


@njit(cache=True)
def _perceive(
    model: NDArray[np.void],
    truth: NDArray[np.float64],
    rows: NDArray[np.int64],
    draws: Draws,
    memory: Memory,
) -> None:  # pragma: no cover - compiled
    """One period of sensing and messaging for environments ``rows`` of the true poses ``truth``
    (K, 3, N) under ``model`` (:data:`SENSOR_MODEL`), drawing from each environment's block of
    ``normal`` and ``uniform`` at its ``cursor`` (``draws``, :data:`Draws`); ``memory``
    (:data:`Memory`) is :class:`Perception`'s state, updated in place."""
    normal, uniform, cursor = draws
    clock, bias, observed, sent, known, age, ranges = memory
    spec = model[0]
    std, drift, noisy, latency = spec.std, spec.drift, spec.noisy, spec.latency
    drop, range2 = spec.drop, spec.range2
    lidar_noise, lidar_dropout, max_range = spec.lidar_noise, spec.lidar_dropout, spec.max_range
    n = truth.shape[2]
    beams = ranges.shape[2]
    slots = sent.shape[1]
    for k in rows:
        t = clock[k]
        row = cursor[k]
        at_normal, at_uniform = 0, 0
        # 1. localization: the bias walks from its second period on (it is 0 at reset)
        for i in range(n):
            for c in range(3):
                value = truth[k, c, i]
                if noisy:
                    if t > 0:
                        bias[k, c, i] += drift[c] * normal[row, k, at_normal + 3 + c]
                    value += bias[k, c, i] + std[c] * normal[row, k, at_normal + c]
                observed[k, c, i] = wrap_scalar(value) if c == 2 else value
            if noisy:
                at_normal += 6
        # 2. the radio: this period's broadcast is stored; the one sent `latency` ago is delivered
        slot = t % slots
        for c in range(3):
            for j in range(n):
                sent[k, slot, c, j] = observed[k, c, j]
        for j in range(n):
            sent[k, slot, 3, j] = truth[k, 0, j]
            sent[k, slot, 4, j] = truth[k, 1, j]
        source = (t - latency) % slots
        for i in range(n):
            for j in range(n):
                if j == i:
                    for c in range(3):
                        known[k, i, i, c] = observed[k, c, i]
                    age[k, i, i] = 0
                    continue
                lost = False
                if drop > 0.0:
                    lost = uniform[row, k, at_uniform] < drop
                    at_uniform += 1
                delivered = False
                if t >= latency and not lost:
                    dx = sent[k, source, 3, j] - sent[k, source, 3, i]
                    dy = sent[k, source, 4, j] - sent[k, source, 4, i]
                    delivered = dx * dx + dy * dy <= range2
                if delivered:
                    for c in range(3):
                        known[k, i, j, c] = sent[k, source, c, j]
                    age[k, i, j] = latency
                elif age[k, i, j] >= 0:
                    age[k, i, j] += 1
        # 3. lidar readings: dropouts read the range, the others get Gaussian noise, clipped
        for i in range(n):
            for b in range(beams):
                value = ranges[k, i, b]
                if lidar_dropout > 0.0:
                    if uniform[row, k, at_uniform] < lidar_dropout:
                        value = max_range
                    at_uniform += 1
                if lidar_noise > 0.0:
                    if value < max_range:
                        value += lidar_noise * normal[row, k, at_normal]
                    at_normal += 1
                ranges[k, i, b] = min(max(value, 0.0), max_range)
        cursor[k] = row + (1 if (at_normal or at_uniform) else 0)
        clock[k] = t + 1


def observed_info(perception: Perception | None, poses: NDArray[np.float64]) -> dict[str, NDArray[Any]]:
    """What the robots believe, one array per key (copies), for K environments.

    Keys: ``observed_poses`` (K, N, 3) every robot's estimate of its own pose; ``known_poses``
    (K, N, N, 3), row i: robot i's last received pose of every robot (its own estimate at i,
    zeros where nothing has arrived); ``message_age`` (K, N, N) in control periods (0 at i
    itself, -1 where nothing has arrived); ``lidar_ranges`` (K, N, B) [m] with
    ``sensing="lidar"``. Without a ``perception`` (no uncertainty settings) they are the true
    ``poses`` (K, N, 3).
    """
    if perception is None:
        k, n, _ = poses.shape
        known = np.empty((k, n, n, 3))
        known[...] = poses[:, None]  # row i: every robot's pose (np.broadcast_to costs microseconds)
        return {
            "observed_poses": poses.copy(),
            "known_poses": known,
            "message_age": np.zeros((k, n, n), dtype=np.int64),
        }
    info = {
        "observed_poses": perception.observed.transpose(0, 2, 1).copy(),
        "known_poses": perception.known.copy(),
        "message_age": perception.age.copy(),
    }
    if perception.lidar is not None:
        info["lidar_ranges"] = perception.ranges.copy()
    return info
