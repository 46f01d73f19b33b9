"""The physics plant's batch of worlds: K MuJoCo worlds of N robots, one control period at a time.

One model is compiled per batch (:func:`~koopman_envs.sim.physics.model.robot_mjcf`) and every
environment gets a copy of it (a memory copy, not a recompilation) and its own ``MjData``: the
wheels' friction (the surface under each robot) and the obstacles' places differ per
environment and live in the model, so a shared model would make them the batch's. A control
period is ``PHYSICS.substeps`` physics steps with the wheel-speed set-points held (the PI
controllers and the motor lag run inside MuJoCo at every step). With more than one environment
and ``threads`` > 1, the period runs through :func:`mujoco.rollout.rollout` on that many
threads (MuJoCo's own, outside the GIL); otherwise ``mj_step`` runs environment by environment.
Both paths give the same numbers bit for bit: the solver's warm start is disabled (so a period
depends only on the state ``mj_getState`` copies exactly), and each environment's arithmetic is
its own whatever thread runs it.

Surfaces: each robot's floor friction is drawn per episode from the floor's surface
(:func:`~koopman_envs.sim.physics.surfaces.draw_friction`), each slip zone's per episode from its
own; a robot inside a zone takes the zone's friction (the last listed zone that contains its
centre), taken where the robot is at the start of the period, as slip zones are on the
kinematic plant. Draws come from a child of the environment's generator, after every other
draw of the reset, so the layout, starts, movers and sensor noise of an episode are those of
the kinematic plant with the same seed.
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.params import INSTALL_HINT, PHYSICS, PhysicsParams
from koopman_envs.sim.dynamics import saturated_command, wrap_scalar
from koopman_envs.sim.perception import child_generator
from koopman_envs.sim.physics.model import OBSTACLE_HEIGHT, robot_mjcf
from koopman_envs.sim.physics.surfaces import SurfaceSetting, draw_friction, surface_for_lambda
from koopman_envs.sim.slip.zones import SlipZone, ZoneTable

__all__ = [
    "PhysicsWorld",
    "drive_setpoints",
    "import_mujoco",
    "planar_poses",
    "wheel_setpoints",
    "zone_surface",
]


def import_mujoco() -> Any:
    """The ``mujoco`` module, or ModuleNotFoundError naming the plant and the install command."""
    try:
        import mujoco
    except ImportError as exc:
        raise ModuleNotFoundError(
            f"plant='mujoco' needs the mujoco package, which is not installed: {INSTALL_HINT}"
        ) from exc
    return mujoco


def zone_surface(zone: SlipZone) -> SurfaceSetting:
    """A slip zone's surface on the physics plant: its ``surface``, else the one its slip mean
    names (the largest of a per-robot list, :func:`surface_for_lambda`)."""
    if zone.surface is not None:
        return zone.surface
    lam = zone.lam
    return surface_for_lambda(max(lam) if isinstance(lam, tuple) else lam)


@njit(cache=True)
def planar_poses(qpos: NDArray[np.float64], address: NDArray[np.int64], out: NDArray[np.float64]) -> None:
    """The planar poses of free bodies from a world's ``qpos`` (compiled).

    Parameters
    ----------
    qpos : ndarray
        The world's positions; body i's free joint starts at ``address[i]``: x, y, z [m], then
        its orientation quaternion w, x, y, z.
    address : ndarray of int, shape (N,)
    out : ndarray, shape (3, N)
        Output rows x [m], y [m], yaw [rad] wrapped to [-pi, pi).
    """
    for i in range(address.shape[0]):
        a = address[i]
        w, qx, qy, qz = qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6]
        out[0, i] = qpos[a]
        out[1, i] = qpos[a + 1]
        out[2, i] = wrap_scalar(math.atan2(2.0 * (w * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz)))


@njit(cache=True)
def _wheel_speeds(v: Any, omega: Any, half_track: float, wheel_radius: float) -> tuple[Any, Any]:
    """The left and right wheel speeds [rad/s] of robots commanded ``(v [m/s], omega [rad/s])``,
    floats or 1-D arrays (compiled; the one rule of :func:`wheel_setpoints` and
    :func:`drive_setpoints`)."""
    turn = omega * half_track
    return (v - turn) / wheel_radius, (v + turn) / wheel_radius


def wheel_setpoints(
    v: NDArray[np.float64], omega: NDArray[np.float64], params: PhysicsParams = PHYSICS
) -> NDArray[np.float64]:
    """The actuators' controls of robots commanded ``(v [m/s], omega [rad/s])`` (arrays of one
    shape S): shape S + (4,), the left wheel's speed set-point [rad/s] twice (its P and I drives)
    then the right wheel's, the model's order (MuJoCo clamps them to the motors' speed limit)."""
    v, omega = np.broadcast_arrays(np.asarray(v, dtype=np.float64), np.asarray(omega, dtype=np.float64))
    left, right = _wheel_speeds(
        np.ravel(v), np.ravel(omega), params.wheel_separation / 2.0, params.wheel_radius
    )
    return np.stack([left, left, right, right], axis=-1).reshape(v.shape + (4,))


@njit(cache=True)
def drive_setpoints(
    commands: NDArray[np.float64],
    active: NDArray[np.bool_],
    command_low: NDArray[np.float64],
    command_high: NDArray[np.float64],
    effort_scale: NDArray[np.float64],
    half_track: float,
    wheel_radius: float,
    ctrl: NDArray[np.float64],
    effort: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """The physics plant's command pass of K teams of N robots, in one compiled loop: every
    command saturated to the limits (:func:`~koopman_envs.sim.dynamics.saturated_command`) and
    turned into its wheels' set-points, into ``ctrl`` (K, 4 N: the model's actuator order, as
    :func:`wheel_setpoints`), its effort into ``effort`` (K, N). Inactive environments get zero
    set-points and zero effort."""
    n_envs, n_robots, _ = commands.shape
    for k in range(n_envs):
        for i in range(n_robots):
            left = right = 0.0
            effort[k, i] = 0.0
            if active[k]:
                v, omega, effort[k, i] = saturated_command(
                    commands[k, i, 0], commands[k, i, 1], command_low, command_high, effort_scale
                )
                left, right = _wheel_speeds(v, omega, half_track, wheel_radius)
            ctrl[k, 4 * i] = ctrl[k, 4 * i + 1] = left
            ctrl[k, 4 * i + 2] = ctrl[k, 4 * i + 3] = right


class PhysicsWorld:
    """K MuJoCo worlds of N differential-drive robots (see the module docstring).

    Parameters
    ----------
    num_envs : int
        Batch size K.
    n_robots, n_obstacles, n_zones : int
        Robots N, obstacles M and slip zones Z per environment.
    robot_radius : float
        The robots' disc radius [m] (the drawn chassis).
    floor : str or float
        The floor's surface (a name of :data:`~koopman_envs.params.SURFACES`) or friction.
    params : PhysicsParams
        The robot and the simulation.

    Attributes
    ----------
    threads : int
        Threads a batch of more than one environment is stepped on (default: up to 2, the
        cores there are); 1 steps environment by environment. The results do not depend on it.
    friction : ndarray, shape (K, N)
        Every robot's wheel-ground friction (ground truth): the floor's drawn at each reset and,
        on a map with zones, the one under the robot in the last period stepped.
    """

    def __init__(
        self,
        num_envs: int,
        n_robots: int,
        n_obstacles: int,
        n_zones: int,
        robot_radius: float,
        floor: SurfaceSetting,
        params: PhysicsParams = PHYSICS,
    ) -> None:
        mujoco = import_mujoco()
        self._mujoco = mujoco
        self.params = params
        self.floor = floor
        self.threads = min(2, os.cpu_count() or 1)
        model = mujoco.MjModel.from_xml_string(robot_mjcf(n_robots, n_obstacles, robot_radius, params))
        # no warm start: a period then depends on the copied state alone (the two paths agree)
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_WARMSTART
        self.models = [model] + [copy.copy(model) for _ in range(num_envs - 1)]
        self.datas = [mujoco.MjData(m) for m in self.models]
        name = mujoco.mjtObj
        geom = [[model.geom(f"wheel_{s}_{i}").id for s in ("left", "right")] for i in range(n_robots)]
        #: the wheel geoms, robot by robot, left then right (their friction is the surface's)
        self._wheels = np.array(geom, dtype=np.int64).reshape(-1)
        joints = [mujoco.mj_name2id(model, name.mjOBJ_JOINT, f"robot_{i}") for i in range(n_robots)]
        self._qpos = np.array([model.jnt_qposadr[j] for j in joints], dtype=np.int64)
        self._obstacles = np.array(
            [model.geom(f"obstacle_{j}").id for j in range(n_obstacles)], dtype=np.int64
        )
        self._spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._state_size = mujoco.mj_stateSize(model, self._spec)
        self.base_friction = np.ones((num_envs, n_robots))
        self.friction = np.ones((num_envs, n_robots))
        # the wheels' friction as written into each model: a model is written only when its
        # robots' surfaces change (at a reset, or a robot crossing into another zone)
        self._applied = np.full((num_envs, n_robots), np.nan)
        self._take_views()
        self._ctrl = np.zeros((num_envs, 4 * n_robots))
        self._every = np.arange(num_envs)
        self._zones = ZoneTable(num_envs, n_zones, n_robots) if n_zones else None
        self._streams: list[np.random.Generator | None] = [None] * num_envs
        self._parents: list[np.random.Generator | None] = [None] * num_envs
        #: MuJoCo's thread pool and one scratch MjData per thread, made at the first threaded period
        self._pool: Any = None
        self._scratch: list[Any] = []

    def _take_views(self) -> None:
        """Views of each world's arrays, taken once (every access of a MuJoCo field makes a new
        one); a pickled view would be a copy, no longer the world's, so a load takes them anew."""
        self._geom_friction = [m.geom_friction for m in self.models]
        self._ctrl_views = [d.ctrl for d in self.datas]
        self._qpos_views = [d.qpos for d in self.datas]

    def __getstate__(self) -> dict[str, Any]:
        """What a pickle holds: the models, the data and the draws, without the ``mujoco``
        module, the thread pool and its scratch data, or the views into the worlds' arrays
        (made again on load: the views by :meth:`__setstate__`, the pool at the first threaded
        period). ``MjModel`` and ``MjData`` pickle whole, so a loaded world steps on bit for bit."""
        state = self.__dict__.copy()
        for name in ("_mujoco", "_pool", "_scratch", "_geom_friction", "_ctrl_views", "_qpos_views"):
            del state[name]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Load a pickled world: its state, the module imported again, the views taken again."""
        self.__dict__.update(state)
        self._mujoco = import_mujoco()
        self._pool, self._scratch = None, []
        self._take_views()

    def close(self) -> None:
        """Shut the thread pool down (a later threaded period makes a new one)."""
        if self._pool is not None:
            self._pool.close()
            self._pool, self._scratch = None, []

    # ------------------------------------------------------------------ reset
    def reset_env(
        self,
        index: int,
        rng: np.random.Generator,
        starts: NDArray[np.float64],
        obstacles: NDArray[np.float64],
        zones: Sequence[SlipZone] = (),
    ) -> None:
        """Start environment ``index``'s episode: robots at rest at ``starts`` (N, 3), the
        obstacle cylinders at ``obstacles`` (M, 3: x, y, r), this episode's frictions drawn."""
        if self._parents[index] is not rng:  # a new generator (a new seed): a new child stream
            self._parents[index] = rng
            self._streams[index] = child_generator(rng)
        stream = self._streams[index]
        assert stream is not None  # attached just above
        n = self.base_friction.shape[1]
        self.base_friction[index] = draw_friction(stream, self.floor, n)
        if self._zones is not None:
            values = [draw_friction(stream, zone_surface(zone), 1)[0] for zone in zones]
            self._zones.set_env(index, zones, values)
        self.friction[index] = self.base_friction[index]
        self._write_friction(index)
        model, data = self.models[index], self.datas[index]
        self._mujoco.mj_resetData(model, data)
        starts = np.asarray(starts, dtype=np.float64)
        half = 0.5 * starts[:, 2]
        for i, adr in enumerate(self._qpos):
            data.qpos[adr : adr + 7] = (
                starts[i, 0], starts[i, 1], self.params.wheel_radius, np.cos(half[i]), 0.0, 0.0, np.sin(half[i])
            )  # fmt: skip
        if self._obstacles.size:
            model.geom_pos[self._obstacles, :2] = obstacles[:, :2]
            model.geom_pos[self._obstacles, 2] = OBSTACLE_HEIGHT / 2.0
            model.geom_size[self._obstacles, 0] = obstacles[:, 2]

    # ------------------------------------------------------------------- step
    def advance(
        self,
        state: NDArray[np.float64],
        commands: NDArray[np.float64],
        active: NDArray[np.bool_],
        command_low: NDArray[np.float64],
        command_high: NDArray[np.float64],
        effort_scale: NDArray[np.float64],
        new_state: NDArray[np.float64],
        effort: NDArray[np.float64],
    ) -> None:
        """One control period of every active environment (the engine's physics pass).

        Parameters
        ----------
        state : ndarray, shape (K, 3, N)
            The poses at the start of the period (x [m], y [m], theta [rad] rows): where the
            surfaces are looked up.
        commands : ndarray, shape (K, N, 2)
            Requested (v [m/s], omega [rad/s]); saturated to ``command_low``/``command_high`` and
            turned into wheel-speed set-points.
        active : ndarray of bool, shape (K,)
            Inactive environments keep their state and report zero effort.
        command_low, command_high, effort_scale : ndarray, shape (2,)
            Actuation limits and the effort weight of each channel.
        new_state : ndarray, shape (K, 3, N)
            Output: the bodies' planar poses, theta wrapped to [-pi, pi).
        effort : ndarray, shape (K, N)
            Output ``scale_v v^2 + scale_omega omega^2`` of the saturated commands.
        """
        half_track, radius = self.params.wheel_separation / 2.0, self.params.wheel_radius
        ctrl = self._ctrl
        drive_setpoints(
            commands, active, command_low, command_high, effort_scale, half_track, radius, ctrl, effort
        )
        rows = self._every if active.all() else np.flatnonzero(active)
        if self._zones is not None:  # the surface under each robot: write the models whose changed
            self._zones.slip_means(state, self.base_friction, self.friction)
            for k in rows[(self.friction[rows] != self._applied[rows]).any(axis=1)]:
                self._write_friction(k)
        for k in rows:
            self._ctrl_views[k][:] = ctrl[k]
        if len(rows) > 1 and self.threads > 1:
            self._step_threaded(rows, ctrl)
        else:
            step, substeps = self._mujoco.mj_step, self.params.substeps
            for k in rows:
                step(self.models[k], self.datas[k], nstep=substeps)
        new_state[:] = state
        for k in rows:
            planar_poses(self._qpos_views[k], self._qpos, new_state[k])

    def _write_friction(self, index: int) -> None:
        """Write environment ``index``'s :attr:`friction` into its model's wheel geoms."""
        self._geom_friction[index][self._wheels, 0] = np.repeat(self.friction[index], 2)
        self._applied[index] = self.friction[index]

    def _step_threaded(self, rows: NDArray[np.int64], ctrl: NDArray[np.float64]) -> None:
        """The period of ``rows`` through :func:`mujoco.rollout.rollout` on :attr:`threads`
        threads, the final states copied back into each environment's data."""
        mujoco = self._mujoco
        if self._pool is None or len(self._scratch) != self.threads:
            from mujoco import rollout

            self.close()
            self._pool = rollout.Rollout(nthread=self.threads)
            self._scratch = [mujoco.MjData(self.models[0]) for _ in range(self.threads)]
        spec, steps = self._spec, self.params.substeps
        initial = np.empty((len(rows), self._state_size))
        for b, k in enumerate(rows):
            mujoco.mj_getState(self.models[k], self.datas[k], initial[b], spec)
        controls = np.repeat(ctrl[rows][:, None, :], steps, axis=1)
        states = np.empty((len(rows), steps, self._state_size))
        self._pool.rollout(
            [self.models[k] for k in rows],
            self._scratch,
            initial,
            controls,
            nstep=steps,
            state=states,
            sensordata=np.empty((len(rows), steps, 0)),
            skip_checks=True,
        )
        # the poses are read from qpos, which the state holds: no mj_forward needed
        for b, k in enumerate(rows):
            mujoco.mj_setState(self.models[k], self.datas[k], states[b, -1], spec)
