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

from koopman_envs.params import PHYSICS, PhysicsParams
from koopman_envs.sim.dynamics import saturate_teams, wrap_scalar
from koopman_envs.sim.perception import child_generator
from koopman_envs.sim.physics.model import OBSTACLE_HEIGHT, robot_mjcf
from koopman_envs.sim.physics.surfaces import SurfaceSetting, draw_friction, surface_for_lambda
from koopman_envs.sim.zones import SlipZone, ZoneTable

__all__ = ["INSTALL_HINT", "PhysicsWorld", "import_mujoco", "planar_poses", "wheel_setpoints", "zone_surface"]

#: how to get the physics plant's dependency
INSTALL_HINT = "pip install 'koopnav[physics]'"


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


def wheel_setpoints(
    v: NDArray[np.float64], omega: NDArray[np.float64], params: PhysicsParams = PHYSICS
) -> NDArray[np.float64]:
    """The actuators' controls of robots commanded ``(v [m/s], omega [rad/s])`` (arrays of one
    shape S): shape S + (4,), the left wheel's speed set-point [rad/s] twice (its P and I drives)
    then the right wheel's, the model's order (MuJoCo clamps them to the motors' speed limit)."""
    turn = omega * (params.wheel_separation / 2.0)
    left, right = (v - turn) / params.wheel_radius, (v + turn) / params.wheel_radius
    return np.stack([left, left, right, right], axis=-1)


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
        Every robot's wheel-ground friction of the last period stepped (ground truth).
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
        self._zones = ZoneTable(num_envs, n_zones, n_robots) if n_zones else None
        self._streams: list[np.random.Generator | None] = [None] * num_envs
        self._parents: list[np.random.Generator | None] = [None] * num_envs
        #: MuJoCo's thread pool and one scratch MjData per thread, made at the first threaded period
        self._pool: Any = None
        self._scratch: list[Any] = []

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
        saturated = np.empty_like(commands)
        saturate_teams(commands, active, command_low, command_high, effort_scale, saturated, effort)
        if self._zones is not None:
            self._zones.slip_means(state, self.base_friction, self.friction)
        else:
            self.friction[:] = self.base_friction
        ctrl = wheel_setpoints(saturated[..., 0], saturated[..., 1], self.params).reshape(
            len(self.models), -1
        )
        rows = np.flatnonzero(active)
        wheel_friction = np.repeat(self.friction, 2, axis=1)  # (K, 2N): the wheels' order
        for k in rows:
            self.models[k].geom_friction[self._wheels, 0] = wheel_friction[k]
            self.datas[k].ctrl[:] = ctrl[k]
        if len(rows) > 1 and self.threads > 1:
            self._step_threaded(rows, ctrl)
        else:
            for k in rows:
                self._mujoco.mj_step(self.models[k], self.datas[k], nstep=self.params.substeps)
        new_state[:] = state
        for k in rows:
            planar_poses(self.datas[k].qpos, self._qpos, new_state[k])

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
