"""What the classic baselines share: each robot's view of its team-mates, its goal, option checks.

Both baselines are decentralized: robot i plans from what it knows, its own pose estimate and the
last message of each team-mate (``known_poses[i]``, ``message_age[i]``; a team-mate it has not
heard of yet is left out). A message carries a pose, not a velocity, so :class:`TeamView` estimates
each team-mate's velocity from its messages: the displacement between the newest message and one
at least ``window`` periods older, divided by the time between them (a finite difference over a
window, which averages the localization noise down by the window's length), and carries a late
message forward to now along that velocity. A robot's own velocity is the command it sent last.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Mapping
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController
from controllers.estimation import FRONT_END_LEVERS, check_estimator, estimator_choices, front_end_option
from controllers.movers import MOVER_PREDICTIONS, check_mover_prediction
from koopman_envs.checks import Range, checked_options
from koopman_envs.scenario import Scenario

__all__ = [
    "CLASSIC_CHOICES",
    "CLASSIC_LEVERS",
    "ClassicController",
    "ClassicSettings",
    "TeamView",
    "goals",
    "in_range",
    "settings_from",
]

_Settings = TypeVar("_Settings")

#: the levers of the estimator front-end the classic baselines can switch off (``ablate``)
CLASSIC_LEVERS = FRONT_END_LEVERS
#: periods of messages kept beyond the velocity window (late and lost messages)
_SLACK = 20


def in_range(ranges: Mapping[str, Range], key: str, value: Any) -> Any:
    """``value`` checked against option ``key``'s declared range in ``ranges`` (a controller's
    ``OPTION_RANGES``, which :mod:`controllers.option_spec` also reads): the one bound of each
    option, ``ValueError`` naming the option, the value and the range otherwise."""
    return ranges[key].check(key, value)


def checked_fields(settings: Any, ranges: Mapping[str, Range]) -> None:
    """Check every field of a frozen settings dataclass that has a declared range in ``ranges``
    (:func:`in_range`: ``ValueError`` naming it), keeping the checked value (an integer option
    given as a whole float is stored as the integer); for its ``__post_init__``."""
    for key in ranges:
        object.__setattr__(settings, key, in_range(ranges, key, getattr(settings, key)))


#: the allowed values of DWA's and ORCA's text options (:mod:`controllers.option_spec`): the
#: movers' prediction and the estimator front-end's choices
CLASSIC_CHOICES: dict[str, tuple[str, ...]] = {"mover_prediction": MOVER_PREDICTIONS, **estimator_choices()}


class ClassicSettings:
    """What the classic baselines' frozen settings dataclasses share: on construction every field
    with a range in the class's ``RANGES`` is checked (:func:`checked_fields`), and the options
    every classic baseline has, ``mover_prediction``, ``estimator`` and ``ablate`` (its levers:
    :data:`CLASSIC_LEVERS`), against their choices; ``ValueError`` naming the bad one."""

    #: the allowed range of every numeric field (the controller's ``OPTION_RANGES``)
    RANGES: ClassVar[dict[str, Range]] = {}
    velocity_window: int
    mover_prediction: str
    estimator: str
    ablate: str

    def __post_init__(self) -> None:
        checked_fields(self, self.RANGES)
        check_mover_prediction(self.mover_prediction)
        check_estimator(self.estimator, self.ablate, levers=CLASSIC_LEVERS)


def settings_from(
    kind: type[_Settings], config: _Settings | None, options: dict[str, Any], owner: str
) -> _Settings:
    """A controller's settings: ``config`` (default: ``kind()``) with ``options`` (field name ->
    value) in place of its fields, each checked by the dataclass itself.

    Raises
    ------
    TypeError
        ``config`` is not a ``kind``.
    ValueError
        An option ``kind`` has no field for (with a did-you-mean and the allowed names), or a
        value outside its field's range or choices.
    """
    if config is not None and not isinstance(config, kind):
        raise TypeError(f"{owner}: config={config!r} is not a {kind.__name__}")
    built: _Settings = checked_options(kind, owner, "", options, lambda *_: None)
    return built if config is None else dataclasses.replace(config, **options)  # type: ignore[type-var]


class ClassicController(BaseController):
    """What DWA and ORCA share: their option tables read off their settings dataclass
    (``SETTINGS``; ``OPTION_RANGES`` is its ``RANGES``, set per subclass), the settings built from
    ``config`` and ``**options``, the estimator front-end, the team view and the last command sent
    (a robot's own velocity)."""

    #: the allowed values of the text options (:mod:`controllers.option_spec`)
    OPTION_CHOICES: ClassVar[dict[str, tuple[str, ...]]] = CLASSIC_CHOICES
    #: the options' names, types, defaults and docs (:mod:`controllers.option_spec`): a frozen
    #: :class:`ClassicSettings` dataclass, set by every subclass
    SETTINGS: ClassVar[type[ClassicSettings]] = ClassicSettings
    #: the allowed range of every numeric option (:mod:`controllers.option_spec`): ``SETTINGS.RANGES``,
    #: declared with the settings
    OPTION_RANGES: ClassVar[dict[str, Range]] = {}
    #: the settings (frozen), ``config`` with ``options`` in place
    config: ClassicSettings

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.OPTION_RANGES = cls.SETTINGS.RANGES

    def __init__(self, config: ClassicSettings | None, options: dict[str, Any]) -> None:
        super().__init__()
        self.config = settings_from(self.SETTINGS, config, options, self.name)
        self.front_end = front_end_option(self.config.estimator, self.config.ablate)
        self._team = TeamView(self.config.velocity_window)
        self._last = np.zeros((0, 2))  # the command each robot sent last (v, omega)

    def _reset_team(self, scenario: Scenario) -> None:
        """A new episode: no messages kept, every robot at rest."""
        self._team.reset(scenario.n_robots, scenario.dt)
        self._last = np.zeros((scenario.n_robots, 2))


class TeamView:
    """Every robot's view of the team: positions carried to now and velocities, from messages.

    Parameters
    ----------
    window : int
        Periods between the two messages whose difference is a team-mate's velocity.
    """

    def __init__(self, window: int) -> None:
        self.window = window
        self._dt = 0.1
        self._step = 0
        self._history: deque[tuple[NDArray[np.float64], NDArray[np.float64]]] = deque()
        self._velocity = np.zeros((0, 0, 2))
        self._newest = np.zeros((0, 0))

    def reset(self, n_robots: int, dt: float) -> None:
        """Start an episode of ``n_robots`` robots and period ``dt`` [s]."""
        self._dt = dt
        self._step = 0
        self._history = deque(maxlen=self.window + _SLACK)
        self._velocity = np.zeros((n_robots, n_robots, 2))
        self._newest = np.full((n_robots, n_robots), -np.inf)

    def update(
        self, known: NDArray[np.float64], ages: NDArray[np.int64], commands: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """One period: ``known`` (N, N, 3) and ``ages`` (N, N) as in the observed info, ``commands``
        (N, 2) the commands sent last. Returns, as robot i sees robot j at [i, j]: positions now
        (N, N, 2), velocities (N, N, 2) and whether i has heard of j (N, N; the diagonal True)."""
        n = known.shape[0]
        heard = ages >= 0
        sent = np.where(heard, self._step - ages, np.nan).astype(np.float64)  # when each pose was measured
        position = known[..., :2].copy()
        fresh = heard & (sent > self._newest)
        if fresh.any():
            estimate = self._finite_difference(sent, position)
            self._velocity = np.where(fresh[..., None], estimate, self._velocity)
            self._newest = np.where(fresh, sent, self._newest)
        self._history.append((sent, position.copy()))
        self._step += 1
        velocity = self._velocity.copy()
        late = (np.where(heard, ages, 0) * self._dt)[..., None]
        position = position + late * velocity  # a late message carried forward to now
        own = np.arange(n)
        theta = known[own, own, 2]
        position[own, own] = known[own, own, :2]
        velocity[own, own] = commands[:, :1] * np.column_stack([np.cos(theta), np.sin(theta)])
        heard = heard.copy()
        heard[own, own] = True
        return position, velocity, heard

    def _finite_difference(
        self, sent: NDArray[np.float64], position: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Per pair, the velocity between the message now and the newest one at least ``window``
        periods older (else the oldest older one kept; zero without any)."""
        if not self._history:
            return np.zeros_like(position)
        past_sent = np.stack([h[0] for h in self._history])  # (H, N, N), oldest first
        past_position = np.stack([h[1] for h in self._history])  # (H, N, N, 2)
        with np.errstate(invalid="ignore"):
            far = past_sent <= sent - self.window
            older = past_sent < sent
        last_far = far.shape[0] - 1 - np.argmax(far[::-1], axis=0)
        first_older = np.argmax(older, axis=0)
        pick = np.where(far.any(axis=0), last_far, first_older)
        found = np.asarray(older.any(axis=0))
        then = np.take_along_axis(past_sent, pick[None], axis=0)[0]
        where = np.take_along_axis(past_position, pick[None, ..., None], axis=0)[0]
        span = np.where(found, (sent - then) * self._dt, 1.0)
        return np.where(found[..., None], (position - where) / np.maximum(span, 1e-9)[..., None], 0.0)


def goals(
    scenario: Scenario, position: NDArray[np.float64], velocity: NDArray[np.float64], heard: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each robot's goal and its velocity (both (N, 2)) from its own view ((N, N, 2) arrays of
    :meth:`TeamView.update`): its target, or on the formation task a follower's slot, the
    leader's position as the follower knows it plus the follower's formation offset (moving with
    the leader's velocity). A follower aims at its own target while it has not heard of the
    leader and once the leader is within the goal tolerance of its target (where the slot is the
    follower's target, without the noise of the leader's pose)."""
    goal = np.array(scenario.targets[:, :2], dtype=np.float64)
    moving = np.zeros_like(goal)
    if scenario.is_formation:
        lead = scenario.leader
        offsets = scenario.formation_offsets - scenario.formation_offsets[lead]
        for i in range(scenario.n_robots):
            if i == lead or not heard[i, lead]:
                continue
            if np.hypot(*(position[i, lead] - goal[lead])) <= scenario.goal_tolerance:
                continue  # a leader on its target: the slot is the follower's own target
            goal[i] = position[i, lead] + offsets[i]
            moving[i] = velocity[i, lead]
    return goal, moving
