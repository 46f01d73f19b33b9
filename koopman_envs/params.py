"""The paper's defaults, defined once.

Every number the paper fixes (SPEC sections 1, 3 and 5) lives here and nowhere else: the
simulator, the tasks, the env registrations, the controllers and the docstring tables all read
this module. Values the paper leaves open are marked ``(ours)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_choice, check_number

__all__ = [
    "DRIFT_MEAN_INTERVAL",
    "FAULT_STOPPED_SPEED",
    "FRICTION_MAX",
    "INSTALL_HINT",
    "LIMITS",
    "MAX_EPISODES_PER_CELL",
    "MAX_ROBOTS",
    "PARAMS",
    "PHYSICS",
    "PLANTS",
    "PaperParams",
    "PhysicsParams",
    "RANDOM_SLIP_MAX",
    "SLIP_SETTINGS",
    "SLIP_MAX_LAMBDA",
    "STRICT_CLEARANCE_MARGIN",
    "PATH_RATIO_MIN_DISTANCE",
    "SLIP_SURFACES",
    "SURFACES",
    "SURFACE_LAMBDA_BOUNDS",
    "SizeLimits",
    "slip_lambdas",
]


@dataclass(frozen=True)
class PaperParams:
    """Physical, task and controller defaults of the paper (SPEC sections 1, 3, 5).

    Attributes
    ----------
    dt : float
        Control / integration period T_s [s].
    v_max : float
        Forward speed limit ``|v| <= v_max`` [m/s].
    omega_max : float
        Turn-rate limit ``|omega| <= omega_max`` [rad/s].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m]; a robot centre outside it has left the workspace.
    robot_radius : float
        Disc radius of every robot [m] (ours).
    n_robots : int
        Team size used by the paper.
    goal_tolerance : float
        Position tolerance of a settled robot [m] (ours, from the issue: 0.1 m).
    settle_time : float
        How long every robot must stay within tolerance for success [s] (ours: 2 s).
    max_episode_steps : int
        Time limit of an episode in control periods (ours: 60 s of simulated time).
    formation_spacing : float
        Distance between neighbouring robots of a named formation shape [m] (ours: the ``formation``
        env keyword and the random maps' layouts, :mod:`koopman_envs.sim.formations`).
    horizon : int
        NMPC prediction horizon in steps (the paper's "T = 20", read as steps).
    q_leader, q_follower, r_input : tuple of float
        Diagonals of the per-robot stage-cost weights Q_i (4 entries) and R_i (2 entries).
    obstacle_offset : float
        Extra safety distance kept from obstacles by the NMPC [m].
    koopman_trajectories, koopman_steps : int
        Size of the Koopman training set (trajectories x sampling periods).
    koopman_input_bound, koopman_state_bound : float
        Training inputs are uniform on [-b, b]^2 per robot, initial states uniform on [-b, b]^3.
    """

    dt: float = 0.1
    v_max: float = 0.6
    omega_max: float = math.pi / 4
    workspace: tuple[float, float, float, float] = (-10.0, 10.0, -10.0, 10.0)
    robot_radius: float = 0.2  # (ours)
    n_robots: int = 3
    goal_tolerance: float = 0.1  # (ours, issue 3)
    settle_time: float = 2.0  # (ours, issue 3)
    max_episode_steps: int = 600  # (ours) 60 s: paths are a few metres at <= 0.6 m/s
    formation_spacing: float = 0.9  # (ours) two robot diameters plus 0.5 m
    horizon: int = 20
    q_leader: tuple[float, float, float, float] = (4.0, 4.0, 0.1, 0.1)
    q_follower: tuple[float, float, float, float] = (1.0, 1.0, 0.1, 0.1)
    r_input: tuple[float, float] = (0.1, 0.1)
    obstacle_offset: float = 0.015
    koopman_trajectories: int = 1000
    koopman_steps: int = 1000
    koopman_input_bound: float = 1.0
    koopman_state_bound: float = 10.0

    @property
    def settle_steps(self) -> int:
        """Number of consecutive control periods that make ``settle_time``."""
        return int(round(self.settle_time / self.dt))

    @property
    def calibration_budget(self) -> int:
        """Team-transitions a controller may simulate to calibrate: the paper's data set size."""
        return self.koopman_trajectories * self.koopman_steps


PARAMS = PaperParams()


#: The plants an environment can run on (the ``plant`` env keyword): the paper's kinematic
#: unicycle with drawn slip (the default), or the MuJoCo differential-drive robots of
#: :mod:`koopman_envs.sim.physics` (extra ``[physics]``).
PLANTS = ("kinematic", "mujoco")
#: How to install the physics plant's dependency (``mujoco``): the one message every refusal names
INSTALL_HINT = "pip install 'koopnav[physics]'"


@dataclass(frozen=True)
class PhysicsParams:
    """The physics plant's robot and simulation (``plant="mujoco"``, docs/physics.md).

    The robot is a TurtleBot3 Waffle Pi (ROBOTIS e-Manual, "TurtleBot3 specifications", and the
    ``turtlebot3_description`` URDF ``turtlebot3_waffle_pi.urdf.xacro``): 1.8 kg with computer,
    battery and sensors; wheel radius 0.033 m; wheel separation 0.287 m (joints at y = +-0.144 m in
    the URDF); base link centre of mass 0.064 m behind the wheel axle, ball casters 0.177 m behind
    it; base yaw inertia 1.4612727e-2 kg m^2 at the URDF's 1.3729 kg; two Dynamixel XM430-W210-T
    (stall torque 3.0 N m, no-load speed 77 rpm = 8.06 rad/s at 12 V).

    **Departures from the datasheet** (ours, so that the model can fly the paper's envelope):
    the paper's limits are ``|v| <= 0.6`` m/s and ``|omega| <= pi/4`` rad/s with a 0.2 m disc, while a
    Waffle Pi tops out at 0.26 m/s. The motors are therefore geared ``gear_factor`` = 3 times
    faster than an XM430-W210: 24.2 rad/s no-load (0.80 m/s at the rim, room for 0.6 m/s plus a
    turn at pi/4 rad/s: 21.6 rad/s on the outer wheel) at a third of the torque (1.0 N m), the
    same power. The chassis mass is the datasheet's 1.8 kg less the wheels, its yaw inertia the
    URDF's scaled by that mass; the two rear ball casters are one frictionless sphere on the
    centre line. The disc of ``robot_radius`` (0.2 m) bounds the 281 x 306 mm footprint
    (half-diagonal 0.208 m: 4 % more), and collisions are judged on it, as on the kinematic plant.

    Attributes
    ----------
    timestep : float
        Physics step [s] (ours: 5 ms, 20 substeps per 0.1 s control period; the contacts' time
        constant, 0.02 s, is four steps).
    mass : float
        Chassis mass [kg] (1.8 kg less two 0.0285 kg wheels).
    yaw_inertia : float
        Chassis inertia about the vertical axis through its centre of mass [kg m^2]
        (1.4612727e-2 x 1.743 / 1.3729).
    roll_pitch_inertia : float
        Chassis inertia about the horizontal axes [kg m^2] (the URDF's 8.7e-3 scaled alike).
    com_offset : float
        Centre of mass behind the wheel axle [m] (URDF: 0.064 m).
    wheel_radius, wheel_separation : float
        [m] (datasheet and URDF).
    wheel_mass, wheel_inertia : float
        Per wheel [kg], [kg m^2] about its axle (URDF: 2.8498940e-2 kg, 2.0712558e-5 kg m^2).
    armature : float
        Rotor inertia reflected through the gearbox, per wheel [kg m^2] (ours, an estimate: a
        coreless rotor of about 1e-7 kg m^2 through the XM430's 212.6:1 gear made 3 times faster,
        1e-7 x 70.9^2). It also keeps the stiff speed loop well inside the 5 ms step's stability
        when a wheel spins free on ice (with 2e-4 the implicit step let the chassis run ahead of
        its wheels at start-up by 40 %, a numerical artefact checked against RK4).
    caster_offset, caster_radius : float
        Position behind the axle [m] (URDF: 0.177 m) and radius [m] (ours: 0.01 m).
    gear_factor : float
        How much faster than an XM430-W210 the model's motors are geared (ours, see above).
    wheel_speed_max : float
        Wheel-speed set-point limit [rad/s]: the XM430-W210's 8.06 rad/s times ``gear_factor``.
    wheel_torque_max : float
        Torque limit per wheel [N m]: the XM430-W210's 3.0 N m stall torque over ``gear_factor``.
    motor_time_constant : float
        The first-order lag of each wheel's speed set-point [s] (ours: the drive's current loop
        and ramp): a step in the commanded speed reaches 63 % within this plus the speed loop's
        own lag (``speed_loop_time_constant``) on carpet.
    speed_kp : float
        Proportional gain of the PI wheel-speed controller [N m s/rad] (ours): with the inertia a
        wheel drives straight ahead, ``wheel_inertia + armature + (mass + 2 wheel_mass) r^2 / 2``,
        the speed loop's time constant is that inertia over ``speed_kp``.
    speed_ki : float
        Integral gain [N m/rad] (ours): removes the steady error of the rolling load, a slow
        zero well below the loop's bandwidth.

    Raises ``ValueError`` naming a value that is not a finite number > 0 (>= 0: ``com_offset``,
    ``speed_ki``) or a ``timestep`` that does not divide ``PARAMS.dt`` into whole steps. The
    limits stay fields, not properties of ``gear_factor``: the calibration key hashes the fields
    (``CalibrationPlant``); tests/test_physics_params.py checks their derivation instead.
    """

    timestep: float = 0.005
    mass: float = 1.8 - 2 * 2.8498940e-2
    yaw_inertia: float = 1.4612727e-2 * (1.8 - 2 * 2.8498940e-2) / 1.3729096
    roll_pitch_inertia: float = 8.7002718e-3 * (1.8 - 2 * 2.8498940e-2) / 1.3729096
    com_offset: float = 0.064
    wheel_radius: float = 0.033
    wheel_separation: float = 0.287
    wheel_mass: float = 2.8498940e-2
    wheel_inertia: float = 2.0712558e-5
    armature: float = 5.0e-4
    caster_offset: float = 0.177
    caster_radius: float = 0.01
    gear_factor: float = 3.0
    wheel_speed_max: float = 77.0 * 2.0 * math.pi / 60.0 * 3.0
    wheel_torque_max: float = 3.0 / 3.0
    motor_time_constant: float = 0.1
    speed_kp: float = 0.12
    speed_ki: float = 0.6

    def __post_init__(self) -> None:
        for f in fields(self):  # a centre of mass on the axle and a P-only loop are models too
            low = (None, 0.0) if f.name in ("com_offset", "speed_ki") else (0.0, None)
            check_number(f.name, getattr(self, f.name), above=low[0], at_least=low[1])
        steps = PARAMS.dt / self.timestep  # 0.1 / 0.005 is 20.000000000000004: a tolerance
        if steps < 1.0 or abs(steps - round(steps)) > 1e-9 * steps:
            raise ValueError(
                f"timestep={self.timestep!r} must divide the control period PARAMS.dt={PARAMS.dt!r} "
                f"into whole physics steps (e.g. 0.005, 20 per period); it gives {steps!r}"
            )

    @property
    def wheel_radial_inertia(self) -> float:
        """A wheel's radial inertia [kg m^2]: the URDF wheel's 1.1175580e-5 per 2.0712558e-5 axial."""
        return self.wheel_inertia * 1.1175580 / 2.0712558

    @property
    def substeps(self) -> int:
        """Physics steps per control period ``PARAMS.dt``."""
        return int(round(PARAMS.dt / self.timestep))

    @property
    def drive_inertia(self) -> float:
        """The inertia one wheel drives when the robot goes straight [kg m^2]."""
        half_mass = (self.mass + 2.0 * self.wheel_mass) / 2.0
        return self.wheel_inertia + self.armature + half_mass * self.wheel_radius**2

    @property
    def speed_loop_time_constant(self) -> float:
        """The PI speed loop's own time constant straight ahead, ``drive_inertia / speed_kp`` [s]."""
        return self.drive_inertia / self.speed_kp


PHYSICS = PhysicsParams()

#: Wheel-ground surfaces of the physics plant (ours): the range [low, high] of the Coulomb
#: friction coefficient between a rubber tyre and the floor, each episode drawing uniformly
#: from it (per robot for the floor, per zone for a map's zones). Carpet and dry indoor floors
#: give rubber 0.9-1.1, gravel and wet tiles 0.4-0.6, ice 0.05-0.15.
SURFACES: dict[str, tuple[float, float]] = {"carpet": (0.9, 1.1), "gravel": (0.4, 0.6), "ice": (0.05, 0.15)}
#: The floor of each named slip setting on the physics plant: ``slip="high"`` is low friction
SLIP_SURFACES: dict[str, str] = {"nominal": "carpet", "low": "gravel", "high": "ice"}
#: A slip zone without a ``surface`` key on the physics plant: its lambda (the largest of a
#: per-robot list) names the surface, carpet up to the first bound, gravel up to the second,
#: ice beyond (ours: the midpoints between the named settings' top lambdas 0, 0.1, 0.2)
SURFACE_LAMBDA_BOUNDS: tuple[float, float] = (0.05, 0.15)
#: The friction coefficients a user may give (a number for ``slip`` or a zone's ``surface``):
#: (0, FRICTION_MAX]; beyond 2 no tyre grips, and 0 would be no traction at all
FRICTION_MAX = 2.0


@dataclass(frozen=True)
class SizeLimits:
    """Upper bounds on every size a user sets (ours): each refused, naming the keyword, the value
    and the allowed range, before anything is allocated or planned.

    Every array of an environment grows with one of these numbers, so an unbounded one lets a
    typo (``comm=dict(latency=10**9)``) allocate tens of GiB. Each bound is far beyond real use
    and its reason is given per attribute; the env keyword table
    (:data:`koopman_envs.engine.keywords.ENV_KEYWORDS`) states them, and the evaluator's CLI and CI
    action read :data:`MAX_EPISODES_PER_CELL` and :data:`MAX_ROBOTS` from here.

    Attributes
    ----------
    robots : int
        ``n_robots``. The random maps' grid fits teams of up to 205 robots at the default spacing
        and no built-in map has more than 6 starts; the per-environment arrays grow as N^2 (every
        robot's block lists every team-mate), about 0.2 M features per step at 256.
    obstacle_obs : int
        ``n_obstacle_obs``: observation slots per robot (3 features each); 4 times the random
        maps' largest obstacle count.
    episode_steps : int
        ``max_episode_steps`` / ``max_cycles``: 10^6 periods = 27.8 h of simulated time (the
        paper's episodes are 600); the compiled kernels take it as a 64-bit integer.
    latency : int
        ``comm.latency`` [control periods]: the radio keeps latency + 1 periods of messages per
        environment; 100 periods = 10 s, a hundred times indoor Wi-Fi's and 33 times the "harsh"
        preset's (a pose 10 s old is 6 m stale at the robots' top speed).
    actuation_delay : int
        ``actuation_delay`` [control periods]: the command queue holds that many periods; 100
        periods = 10 s, 50 times the "harsh" preset's command pipeline.
    lidar_beams : int
        ``lidar.beams``: the scan holds (robots x beams) readings and every beam is cast each
        period; 4096 is above the densest planar lidars (0.1 deg resolution: 3600 beams).
    lidar_range : float
        ``lidar.range`` [m]: longer than any planar lidar (SICK LMS5xx: 80 m) and than the
        workspace's diagonal (28.3 m: a longer range reads the same); the observation holds the
        readings in single precision.
    movers : int
        ``movers.count`` and ``movers.observed``: placement is quadratic in the count, the
        crowd's ORCA steps every mover and each environment keeps a pool of 272 uniforms per
        mover. At the default radius the roomiest built-in map holds 206 movers (map7; map1
        112), so 512 leaves room for smaller movers (16 is the largest count of the reported
        experiments).
    mover_speed : float
        ``movers.speed`` [m/s]: a brisk walk, 3.3 times the robots' limit. A mover then moves
        0.2 m per period, half a default mover's diameter, so the per-period collision check
        sees every contact; and movers are placed ``speed`` x 1 s from every start and target,
        which at 2 m/s still leaves room for movers on every built-in map (at 3 m/s not on
        map1, map2, map5).
    mover_pause : float
        ``movers.pause`` [s]: one hour, the longest pause that is not "never moves again"; the
        kernels count it in 64-bit periods.
    random_obstacles : int
        ``random_map.n_obstacles``: the generator places them in the corridor between starts and
        targets, where more than a few dozen never fit (each failed layout retries every one).
    slip_zones : int
        ``random_map.n_slip_zones``: the zone table holds (zones x robots) per environment.
    map_attempts : int
        ``random_map.max_attempts``: layouts tried per reset (twice the default, which succeeds
        within a few); an impossible setting then fails within seconds instead of spinning (64
        obstacles that never fit: about 5 s).
    start_noise : float
        ``start_noise`` [m and rad]: five times the workspace's side (beyond its side a disc
        already leaves the workspace from most starts, and the heading turn is a full one
        beyond pi), so that the draw's range stays finite (``start_noise=9e307`` overflowed
        numpy's uniform); a value too large for the map fails at reset, naming it.
    pose_noise : float
        Every field of ``pose_noise`` (std [m], [rad], random-walk rates per sqrt(s)): an error
        the size of the workspace's side is no estimate at all, and the draws scaled by it stay
        finite (``pose_noise=5e307`` made the observation infinite).
    slip_lambda : float
        Every slip mean lambda (``slip``, slip zones, schedules): 50 times the paper's "high"
        level; the Exponential draws stay finite, so a step never turns the state into inf/NaN.
    map_file_bytes : int
        A map file given to ``map`` [bytes], checked before it is read whole: the built-in maps
        are under 1 KB, and 16 MiB lists some 300,000 obstacles (``map="/dev/zero"`` read forever).
    num_envs : int
        ``num_envs`` of the vector env: every array is batched over it; beyond, the memory
        estimate below is the binding limit anyway.
    engine_bytes : int
        The arrays of one batched engine [bytes], estimated from its settings before any is
        allocated (:func:`koopman_envs.engine.engine.engine_array_bytes`): 4 GiB.
    episodes_per_cell : int
        The evaluator's episodes per (controller, map, setting) cell: the 95% confidence
        interval of a success rate is then +-1 percentage point, finer than any comparison
        resolves, and planning lists every episode in memory.
    """

    robots: int = 256
    obstacle_obs: int = 256
    episode_steps: int = 1_000_000
    latency: int = 100
    actuation_delay: int = 100
    lidar_beams: int = 4096
    lidar_range: float = 100.0
    movers: int = 512
    mover_speed: float = 2.0
    mover_pause: float = 3600.0
    random_obstacles: int = 64
    slip_zones: int = 64
    map_attempts: int = 20_000
    start_noise: float = 100.0
    pose_noise: float = 20.0
    slip_lambda: float = 10.0
    map_file_bytes: int = 16 * 2**20
    num_envs: int = 16_384
    engine_bytes: int = 4 * 2**30
    episodes_per_cell: int = 10_000


#: the bounds of every user-set size (:class:`SizeLimits`), declared once
LIMITS = SizeLimits()
#: the evaluator's largest episode count per cell (``--episodes``, the CI action's ``episodes``)
MAX_EPISODES_PER_CELL = LIMITS.episodes_per_cell
#: the largest team (``n_robots``; the evaluator's ``--env-kwargs n_robots=``)
MAX_ROBOTS = LIMITS.robots

#: Below this speed [m/s] a robot counts as stopped when a mover touches it, so the contact is
#: not its fault (the fault rule of docs/movers.md, "Who is at fault"). Ours: a robot told to
#: hold still is seldom at exactly zero (an NMPC's commands settle at 1e-3 m/s, not 0), and
#: 0.05 m/s, a twelfth of ``v_max``, moves it 5 mm in a period, a fortieth of its radius: too
#: little to run into anything.
FAULT_STOPPED_SPEED = 0.05

#: A success is strict when every robot kept more than this clearance [m] from every obstacle,
#: team-mate and mover all episode (``strict_success`` in the evaluator's records). Ours: 5 cm is
#: the localization error the robustness sweep's pose-noise level and the people tracker's
#: detection noise assume, so a team that passes closer than that touched nothing only because
#: its poses were exact. It is also the margin of ``near_obstacle_share`` (the share of a robot's
#: periods that end within this clearance of an obstacle): one margin, so that a strict success
#: is one with no such period.
STRICT_CLEARANCE_MARGIN = 0.05

#: A robot whose start lies within this distance [m] of its target is left out of the path-length
#: ratio (``path_ratio`` in the evaluator's records): its straight-line distance is too small to
#: divide by. Ours: 10 cm, the default goal tolerance: a robot that starts within tolerance of its
#: target has no path to rate (a parked team-mate, a robot placed on its slot).
PATH_RATIO_MIN_DISTANCE = 0.1

#: Named slip settings: lambda of the most-slipping robot. Robot 1 is always slip-free and the
#: others are spaced linearly up to this value, which for 3 robots gives exactly SPEC's table:
#: nominal (0, 0, 0), low (0, 0.05, 0.1), high (0, 0.1, 0.2). The spacing rule is (ours).
SLIP_MAX_LAMBDA: dict[str, float] = {"nominal": 0.0, "low": 0.1, "high": 0.2}
SLIP_SETTINGS = tuple(SLIP_MAX_LAMBDA)
#: ``slip="random"``: each episode draws its own constant levels (see RANDOM_SLIP_MAX)
RANDOM_SLIP = "random"
#: ``slip="drift"``: every robot's level is redrawn at random times (see DRIFT_MEAN_INTERVAL)
DRIFT_SLIP = "drift"

#: Largest slip mean of the settings that draw their levels (ours: covers and exceeds "high").
#: ``slip="random"`` draws the most-slipping robot's lambda uniformly on [0, RANDOM_SLIP_MAX] once
#: per episode (the others spaced linearly from robot 1's 0); ``slip="drift"`` draws every level
#: of every robot uniformly on [0, RANDOM_SLIP_MAX].
RANDOM_SLIP_MAX = 0.25

#: ``slip="drift"`` (ours): every robot's slip mean is piecewise constant in time and changes at
#: the events of its own Poisson process, i.e. after holding times ~ Exponential with this mean
#: [s], independent across robots. At each event (and at reset) the new level is uniform on
#: [0, RANDOM_SLIP_MAX], independent of the old one. A change at time t applies from the first
#: control period that starts at or after t, so the level of a period is the one drawn last up to
#: the period's start. Exact draw order: koopman_envs.sim.slip.schedule.SlipClock.
DRIFT_MEAN_INTERVAL = 5.0

#: Every named slip setting and what it means: the one table the env docs, the CLI help and the
#: errors read (per-robot lambdas and (time, lambdas) schedules are the unnamed forms).
SLIP_NAMES: dict[str, str] = {
    **{
        name: f"constant levels, robot 1 slip-free, the others spaced linearly up to lambda = {top:g}"
        for name, top in SLIP_MAX_LAMBDA.items()
    },
    RANDOM_SLIP: f"constant levels drawn per episode (largest lambda uniform on [0, {RANDOM_SLIP_MAX:g}])",
    DRIFT_SLIP: f"every robot's level redrawn on [0, {RANDOM_SLIP_MAX:g}] at random times "
    f"(mean interval {DRIFT_MEAN_INTERVAL:g} s)",
}


def slip_lambdas(slip: str | object, n_robots: int) -> NDArray[np.float64]:
    """Resolve a slip setting to per-robot Exponential means lambda_i.

    Parameters
    ----------
    slip : str or sequence of float
        ``"nominal"``, ``"low"``, ``"high"``, or one lambda >= 0 per robot.
    n_robots : int
        Team size.

    Returns
    -------
    ndarray, shape (n_robots,)
        lambda_i >= 0 (dimensionless mean of the slip coefficients alpha, beta, gamma).

    Raises
    ------
    ValueError
        Unknown name, wrong length, negative, non-finite or too large (``LIMITS.slip_lambda``) lambda.
    """
    if isinstance(slip, str):
        check_choice(
            "slip",
            slip,
            SLIP_SETTINGS,
            " (or 'random' for a new level per episode, 'drift' for levels that change within an "
            "episode, a sequence of per-robot lambda >= 0, or a list of (time [s], lambdas) pairs)",
            suggest=SLIP_NAMES,
        )
        if n_robots == 1:
            return np.zeros(1)
        return np.linspace(0.0, SLIP_MAX_LAMBDA[slip], n_robots)
    if isinstance(slip, (bool, np.bool_)) or (
        isinstance(slip, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in slip)
    ):
        raise ValueError(
            f"slip={slip!r} is a boolean; allowed: a name in {list(SLIP_SETTINGS)}, 'random', 'drift', "
            "one lambda >= 0 per robot, or a list of (time [s], lambdas) pairs (slip-free: 'nominal')"
        )
    try:
        lam = np.asarray(slip, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"slip={slip!r} is neither a name in {list(SLIP_SETTINGS)} nor a sequence of numbers"
        ) from exc
    if lam.ndim == 0:
        lam = np.full(n_robots, float(lam))
    if lam.shape != (n_robots,):
        raise ValueError(f"slip={slip!r} has {lam.size} values; expected one lambda per robot ({n_robots})")
    if not np.all(np.isfinite(lam)):
        raise ValueError(f"slip={slip!r} contains a non-finite lambda; allowed: finite lambda >= 0")
    if np.any(lam < 0):
        raise ValueError(f"slip={slip!r} contains a negative lambda; allowed: lambda >= 0")
    if np.any(lam > LIMITS.slip_lambda):
        raise ValueError(
            f"slip={slip!r} contains a lambda above {LIMITS.slip_lambda:g}; allowed: 0 <= lambda <= "
            f"{LIMITS.slip_lambda:g} (LIMITS.slip_lambda: the draws it scales stay finite)"
        )
    return lam
