"""Control-barrier-function (CBF) safety filter for unicycle teams, usable around any controller.

``SafetyFilter(inner, gamma=..., margin=...)`` is itself a controller: each period it asks the
inner controller for a joint command and replaces it by the nearest command (weighted least
squares on (v, omega)) that keeps every robot away from the obstacles, the other robots and the
workspace boundary. By name: ``controllers.make("safe:consensus-free")``; in the evaluator's
syntax inner options are given as usual and filter options with a ``safety_`` prefix,
``safe:nominal-nmpc:horizon=10,safety_gamma=1,safety_margin=0.1`` (see :func:`wrap`).

The barrier functions
---------------------
Each robot i is represented by its look-ahead point ``p_i = (x + l cos theta, y + l sin theta)``,
whose velocity ``dp_i/dt = v e(theta) + l omega e_perp(theta)`` is affine in (v, omega) (and
invertible for l > 0, so both inputs steer it). A disc of radius ``r_i + l`` around p_i covers the
robot, so the barriers are, per robot i:

* obstacle k (centre c_k, radius R_k): ``h = |p_i - c_k| - (R_k + r_i + l + margin)``;
* robot j: ``h = |p_i - p_j| - (r_i + r_j + 2 l + margin)``;
* workspace wall, e.g. the left one: ``h = x(p_i) - (x_min + l + margin)``, which keeps the
  robot's centre inside the box as the env requires (its body may overhang, as in the env).

The filter keeps ``dh/dt >= -gamma h`` for each of them (gamma: the class-K gain). Robot pairs are
split decentrally: each robot of a pair takes half, ``n_ij . dp_i/dt >= -gamma h_ij / 2``, which
adds up to the pair's condition. We chose the split over one joint QP for the team because (1)
each robot's problem then has two variables and is solved exactly in closed form
(:mod:`controllers.solvers.two_variable_qp`, compiled), in microseconds per robot (a joint QP
through CasADi's ``conic`` costs ~0.3 ms per call even for 2 variables and 1.3-6 ms for 32
variables with daqp / qpOASES); (2) each robot's problem stays feasible on its own (see below),
so one robot in trouble does not make the whole team's problem infeasible; (3) it is what robots
running the filter on board, knowing only positions, could do. Its price is conservatism: a robot
never yields more than half a pair's barrier, even when its partner could not yield at all.

From continuous to sampled time (why the guarantee is exact for the nominal robots)
------------------------------------------------------------------------------------
The command is held for a period ``dt``. Every barrier is convex in the look-ahead points (a norm
minus a constant, or affine), so ``h(t + dt) >= h(t) + n . delta_p`` with n its gradient at t.
Holding (v, omega), ``f(t) = n . dp/dt`` drifts from its initial value as the heading turns:
``|f'| <= |omega| (|v| k_s + l |omega| k_c)`` with ``k_s = min(1, |n . e_perp| + omega_max dt)``,
``k_c = min(1, |n . e| + omega_max dt)``, so ``n . delta_p >= dt f(0) - dt^2/2 sup |f'|``. With
``|v||omega| <= lam omega_max |v| + (1 - lam) v_max |omega|`` (true for every lam in [0, 1]; lam is
taken from the inner command, for which it is tightest) and ``omega^2 <= omega_max |omega|``,
each barrier becomes four linear rows (one per sign of v and of omega) of::

    n . dp/dt - c_v |v| - c_omega |omega| >= -gamma h,
    c_v = dt/2 k_s lam omega_max,   c_omega = dt/2 (k_s (1 - lam) v_max + l omega_max k_c),

which gives ``h(t + dt) >= (1 - gamma dt) h(t)``: with ``0 < gamma dt <= 1`` the safe set
``h >= 0`` is invariant for the nominal (slip-free) kinematics, not only in the limit dt -> 0.
The command (0, 0) satisfies every row whenever every h >= 0, so each robot's QP is feasible
until a barrier is already negative.

Only barriers that can bind are built: the rows can be violated inside the command box only if
``gamma h < (|a_v| + c_v) v_max + (|a_omega| + c_omega) omega_max`` (``dh/dt = a_v v + a_omega omega``;
the "sensing radius": with the defaults at most 0.34 m of clearance to obstacles and walls and
0.69 m between robots), so each QP grows with the number of nearby objects only; the distance
check itself visits every obstacle and pair, a few floating-point operations each.

Deadlocks
---------
A filter only removes the unsafe part of a command; it does not plan. A controller that drives
straight at an obstacle (``consensus-free``) is stopped in front of it, and one that plans with
smaller clearances than the filter keeps (the NMPCs' 0.015 m against the filter's
``l + margin``) can push two robots into a corner of the safe set where the only safe motion is
backwards, which the QP, staying near the command, does not choose. For a controller that takes
margins, widening them to the filter's (``nominal-nmpc:obstacle_offset=0.08,robot_offset=0.13``) is
the better cure (``bench/safety_filter.py``); the filter is for controllers that cannot.
``omega_weight`` is small by default so that the filter steers away from a barrier rather than
brakes in front of it.

Slip and infeasibility
----------------------
The filter sees the nominal kinematics only (the scenario carries no slip), so under slip it is a
filter, not a guarantee: ``margin`` [m] is extra clearance for the unmodelled drift; since slip
scales with the commanded speed, which the filter lowers near obstacles, a few centimetres go a
long way. When slip has already pushed a robot inside a barrier (h < 0) its rows ask for a
positive rate of recovery, which may be out of reach within the limits. Then the fallback is the
least-violating command: the recovery rates asked by the violated rows are scaled by the largest
factor s in [0, 1] that is feasible (bisection; s = 0, which (0, 0) satisfies, means no violated
barrier may shrink), and the QP is solved at that s. Such periods are counted
(``SafetyStats.infeasible``).
"""

from controllers.safety.barriers import BarrierFilter, FilterStep
from controllers.safety.filter import SafetyFilter, SafetyStats, wrap
from controllers.safety.options import FILTER_OPTION_PREFIX, SafetyOptions

__all__ = [
    "FILTER_OPTION_PREFIX",
    "BarrierFilter",
    "FilterStep",
    "SafetyFilter",
    "SafetyOptions",
    "SafetyStats",
    "wrap",
]
