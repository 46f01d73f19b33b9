"""The MJCF of the physics plant: N TurtleBot3-class differential-drive robots and M obstacles.

Each robot is a free body (the chassis, mass and inertia of :data:`~koopman_envs.params.PHYSICS`)
with two driven wheels on hinge joints and one frictionless caster sphere. Each wheel has a
PI speed controller on a first-order filtered set-point, run by MuJoCo at the physics rate as
two actuators on the wheel's joint (both fed the same set-point ``r`` [rad/s]):

* ``drive_p``: ``dyntype="filterexact"`` makes its activation the filtered set-point ``r_f``
  (time constant ``motor_time_constant``); its force is ``(kp - ki tau) r_f - kp w``.
* ``drive_i``: ``dyntype="integrator"`` makes its activation ``int r dt``; its force is
  ``ki (int r dt - theta)``.

Since ``tau dr_f/dt = r - r_f``, ``int r_f dt = int r dt - tau r_f`` (from rest), so the sum is
exactly ``kp (r_f - w) + ki int (r_f - w) dt``: a PI controller on the filtered set-point. The
joint's ``actuatorfrcrange`` clamps the sum to the motor's torque limit, ``ctrlrange`` the
set-point to its speed limit.

Contacts: only wheels and casters touch the floor (the floor's friction is the smallest, so a
wheel's contact takes the wheel's, which the world sets per period from the surface under the
robot; the caster's contact is frictionless, ``condim=1``). Robot-robot, robot-obstacle and
robot-mover contacts are left out of MuJoCo's solver: an episode ends at the first contact,
judged by the same geometric checks as on the kinematic plant (on the bodies' planar poses), so
the collision kinds stay identical, and the solver only ever resolves the wheels' contacts.
The obstacles are static cylinders without contacts (for a viewer; the world moves them to each
episode's map).
"""

from __future__ import annotations

from koopman_envs.params import PHYSICS, PhysicsParams

__all__ = ["OBSTACLE_HEIGHT", "arena_bytes", "robot_mjcf", "world_bytes"]

#: height of the obstacle cylinders [m] (drawn only)
OBSTACLE_HEIGHT = 0.3
#: the chassis disc's height [m] (drawn only; the inertia is the datasheet's)
_CHASSIS_HEIGHT = 0.1


def arena_bytes(n_robots: int) -> int:
    """The ``MjData`` arena [bytes] of a world of ``n_robots`` (MJCF ``<size memory>``): twice what
    a step was measured to use (22.6 KB at 3 robots, 0.29 MB at 16, 3.8 MB at 64: the dense
    constraint Jacobian grows as N^2) plus 64 KB. MuJoCo's default, sized for any model, is
    14 MB at 3 robots, which a vector env of thousands would reserve per environment."""
    return 2 * (1000 * n_robots * n_robots + 8192 * n_robots) + 65536


def world_bytes(n_robots: int, n_obstacles: int) -> int:
    """An estimate from above of one environment's MuJoCo memory [bytes]: its model copy and its
    data (measured: 34 KB and 24 KB of buffers at 3 robots, 11 KB and 8 KB per further robot)
    and the arena (:func:`arena_bytes`)."""
    return arena_bytes(n_robots) + 16384 * (1 + 2 * n_robots) + 1024 * n_obstacles


def _robot(i: int, radius: float, p: PhysicsParams) -> str:
    r, half = p.wheel_radius, p.wheel_separation / 2.0
    wheel_axial = p.wheel_inertia
    wheel_radial = p.wheel_radial_inertia
    wheels = "".join(
        f"""
      <body name="wheel_{side}_{i}" pos="0 {y!r} 0">
        <joint name="wheel_{side}_{i}" type="hinge" axis="0 1 0" armature="{p.armature!r}"
               actuatorfrcrange="{-p.wheel_torque_max!r} {p.wheel_torque_max!r}"/>
        <inertial pos="0 0 0" mass="{p.wheel_mass!r}"
                  diaginertia="{wheel_radial!r} {wheel_axial!r} {wheel_radial!r}"/>
        <geom name="wheel_{side}_{i}" type="sphere" size="{r!r}" contype="1" conaffinity="0"
              condim="3" friction="1 0 0" rgba="0.1 0.1 0.1 1"/>
      </body>"""
        for side, y in (("left", half), ("right", -half))
    )
    return f"""
    <body name="robot_{i}" pos="{3.0 * i!r} 0 {r!r}">
      <freejoint name="robot_{i}"/>
      <inertial pos="{-p.com_offset!r} 0 0" mass="{p.mass!r}"
                diaginertia="{p.roll_pitch_inertia!r} {p.roll_pitch_inertia!r} {p.yaw_inertia!r}"/>
      <geom name="chassis_{i}" type="cylinder" size="{radius!r} {_CHASSIS_HEIGHT / 2!r}"
            pos="0 0 {_CHASSIS_HEIGHT / 2!r}" contype="0" conaffinity="0" mass="0" rgba="0.2 0.4 0.8 0.5"/>
      <geom name="caster_{i}" type="sphere" size="{p.caster_radius!r}"
            pos="{-p.caster_offset!r} 0 {p.caster_radius - r!r}" contype="1" conaffinity="0" condim="1"
            rgba="0.5 0.5 0.5 1"/>{wheels}
    </body>"""


def _drives(i: int, p: PhysicsParams) -> str:
    tau, kp, ki = p.motor_time_constant, p.speed_kp, p.speed_ki
    limit = p.wheel_speed_max
    return "".join(
        f"""
    <general name="drive_p_{side}_{i}" joint="wheel_{side}_{i}" dyntype="filterexact" dynprm="{tau!r}"
             gainprm="{kp - ki * tau!r}" biastype="affine" biasprm="0 0 {-kp!r}"
             ctrlrange="{-limit!r} {limit!r}"/>
    <general name="drive_i_{side}_{i}" joint="wheel_{side}_{i}" dyntype="integrator"
             gainprm="{ki!r}" biastype="affine" biasprm="0 {-ki!r} 0" ctrlrange="{-limit!r} {limit!r}"/>"""
        for side in ("left", "right")
    )


def robot_mjcf(n_robots: int, n_obstacles: int, robot_radius: float, p: PhysicsParams = PHYSICS) -> str:
    """The MJCF text of the world: a floor, ``n_obstacles`` cylinders and ``n_robots`` robots.

    Parameters
    ----------
    n_robots, n_obstacles : int
        Team size N and obstacles per map M (the world moves them per episode).
    robot_radius : float
        The chassis disc's radius [m] (drawn; collisions are judged on the env's disc).
    p : PhysicsParams
        The robot and the simulation.

    Returns
    -------
    str
        The model; bodies ``robot_<i>``, wheel joints, geoms and actuators ``wheel_<side>_<i>``,
        ``drive_p_<side>_<i>``, ``drive_i_<side>_<i>`` (side ``left``/``right``; ctrl order: robot by
        robot, left then right, P then I), geoms ``obstacle_<j>``.
    """
    obstacles = "".join(
        f"""
    <geom name="obstacle_{j}" type="cylinder" size="0.1 {OBSTACLE_HEIGHT / 2!r}"
          pos="0 0 {OBSTACLE_HEIGHT / 2!r}" contype="0" conaffinity="0" rgba="0.6 0.3 0.3 1"/>"""
        for j in range(n_obstacles)
    )
    robots = "".join(_robot(i, robot_radius, p) for i in range(n_robots))
    drives = "".join(_drives(i, p) for i in range(n_robots))
    return f"""<mujoco model="koopnav">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{p.timestep!r}" integrator="implicitfast" cone="pyramidal" jacobian="dense"/>
  <size memory="{arena_bytes(n_robots)}"/>
  <worldbody>
    <geom name="floor" type="plane" size="12 12 0.1" contype="0" conaffinity="1" condim="1"
          friction="1e-5 0 0" rgba="0.9 0.9 0.9 1"/>{obstacles}{robots}
  </worldbody>
  <actuator>{drives}
  </actuator>
</mujoco>
"""
