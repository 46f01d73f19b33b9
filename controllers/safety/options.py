"""The safety filter's options: :class:`SafetyOptions`, their ranges and checks, and the prefix that
routes ``safety_*`` options of a ``safe:<name>`` configuration to the filter."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from koopman_envs.checks import Range, checked_options
from koopman_envs.params import PARAMS

__all__ = ["FILTER_OPTION_PREFIX", "SafetyOptions"]

#: in ``safe:<name>`` configurations, options with this prefix go to the filter, the others to ``<name>``
FILTER_OPTION_PREFIX = "safety_"


@dataclass(frozen=True)
class SafetyOptions:
    """Options of the CBF safety filter (all ours; ranges checked on construction).

    The defaults keep the narrowest passage of the paper maps open (0.56 m between two obstacles
    of Map 1 and Map 3; a robot needs ``2 (r + lookahead + margin)`` = 0.54 m), so that the
    filter does not close a way the inner controller may take.

    Attributes
    ----------
    gamma : float
        Class-K gain [1/s], ``0 < gamma <= 1 / dt`` (10 for the paper's dt): each barrier may
        shrink by at most the fraction ``gamma dt`` per period. Small: brake early and gently;
        large: late and hard.
    margin : float
        Extra clearance [m] beyond the robot and obstacle radii (and between robots), in
        ``[0, 1]``: room for the slip the filter does not model.
    lookahead : float
        Distance of the controlled point ahead of the axle [m], in ``(0, 0.5]``. Larger lets a
        turn move the point more (more steering authority) but inflates every radius by as much.
    omega_weight : float
        Weight of a change of omega relative to a change of v in the cost [m^2/rad^2], in
        ``(0, 100]``: small prefers turning away, large prefers braking.
    mover_velocity : float
        Share of a mover's observed velocity its barrier accounts for, in ``[0, 1]``: 1
        (default) a moving barrier (constant-velocity prediction: the robot recedes as fast as
        the mover approaches, on top of the class-K rate); 0 the mover as a disc standing where
        it is seen (prediction off).
    chance_risk : float
        Risk level in ``(0, 0.5)`` of the chance-constrained widening: with an estimator's pose
        covariance (the inner controller's ``estimator``), every barrier widens by z sigma as
        the NMPCs' margins do (:func:`controllers.mpc.margins.chance_tightening`); without
        one, never.
    """

    gamma: float = 2.0
    margin: float = 0.02
    lookahead: float = 0.05
    omega_weight: float = 0.01
    mover_velocity: float = 1.0
    chance_risk: float = 0.05

    #: allowed range per option (:mod:`controllers.option_spec` reads it for the option table)
    RANGES: ClassVar[dict[str, Range]] = {
        "gamma": Range(0.0, 1.0 / PARAMS.dt, low_open=True, note="1/s (gamma * dt <= 1)"),
        "margin": Range(0.0, 1.0, note="m"),
        "lookahead": Range(0.0, 0.5, low_open=True, note="m"),
        "omega_weight": Range(0.0, 100.0, low_open=True, note="m^2/rad^2"),
        "mover_velocity": Range(0.0, 1.0),
        # (0, 0.5): 0.5 itself would add no margin (z = 0)
        "chance_risk": Range(0.0, 0.5, low_open=True, high_open=True),
    }

    def __post_init__(self) -> None:
        for name in self.RANGES:
            self.check(name, getattr(self, name))

    @classmethod
    def check(cls, name: str, value: Any, prefix: str = "") -> None:
        """Raise ``ValueError`` naming option ``prefix + name``, its value and its allowed range."""
        try:
            cls.RANGES[name].check(prefix + name, value)
        except ValueError:
            raise ValueError(
                f"safety filter option {prefix}{name}={value!r} is out of range; allowed: {cls.RANGES[name]}"
            ) from None

    @classmethod
    def from_options(cls, prefix: str = "", **options: Any) -> SafetyOptions:
        """Build from keyword options; errors name the option as given (with ``prefix``), its value
        and what is allowed."""
        return checked_options(cls, "safety filter", prefix, options, cls.check)
