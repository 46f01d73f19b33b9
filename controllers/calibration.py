"""Calibration: what a controller may learn about the robots before it is evaluated.

Every controller gets the same offer: a :class:`koopman_envs.CalibrationPlant` (the deployment
env's robots in an open field, slip included, slip means hidden) with the same budget of
team-transitions and the same seed. A controller that wants data implements
``calibrate(plant, *, seed)``; the Koopman-NMPC fits its model there, the NMPCs with an
``uncertainty_margin`` measure their own prediction error there.

This module holds the pieces they share: the identification data set (the paper's random
inputs and random initial states, one fixed function of plant, budget and seed, so two
controllers calibrated on the same plant see the same data), the RMS one-step position
residual, and an on-disk cache keyed by plant signature, budget and seed. The cache is optional:
a write that fails warns once (:class:`~controllers.disk_cache.CacheWriteWarning`) and the
calibration goes on with its in-memory result; a bad entry is refused on reading
(:class:`CacheWarning`) and recomputed.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.base import Calibratable, calibratable
from controllers.disk_cache import CacheWriteWarning, cache_root, write_atomic
from koopman_envs import CalibrationPlant, make_plant
from koopman_envs.checks import check_flag, check_int
from koopman_envs.params import PARAMS

__all__ = [
    "MAX_CALIBRATION_BUDGET",
    "MAX_HOLD",
    "MAX_POSITION_RESIDUAL",
    "CacheWarning",
    "CacheWriteWarning",
    "Calibratable",
    "DataSpec",
    "TrajectoryData",
    "cache_dir",
    "cache_path",
    "calibrate_controller",
    "check_hold",
    "check_position_residual",
    "check_random_hold",
    "collect_data",
    "data_spec_for",
    "position_residual",
    "poses_before",
    "previous_commands",
    "write_atomic",
]

#: Largest RMS one-step position residual a calibration may report [m]: ten times the longest
#: step the identification inputs can make (speed up to ``koopman_input_bound`` for one period). A cached
#: value beyond it cannot come from a fit of these robots and is measured again.
MAX_POSITION_RESIDUAL = 10.0 * PARAMS.koopman_input_bound * PARAMS.dt


class CacheWarning(UserWarning):
    """A cache entry failed its check on reading and is recomputed (the warning names the file).

    A cache that cannot be written warns with :class:`~controllers.disk_cache.CacheWriteWarning`
    instead (once per process).
    """


def check_position_residual(value: Any, n_robots: int, source: str = "") -> NDArray[np.float64]:
    """A per-robot position residual read back from a file, checked.

    Parameters
    ----------
    value : any
        What the file holds: must be a list of ``n_robots`` finite numbers in
        [0, :data:`MAX_POSITION_RESIDUAL`].
    n_robots : int
        Team size of the plant it belongs to.
    source : str, optional
        The file, for the message (its first words).

    Returns
    -------
    ndarray, shape (n_robots,)

    Raises
    ------
    ValueError
        Naming ``source``, the bad value and what is allowed.
    """
    where = f"{source}: " if source else ""
    try:
        residual = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{where}position_residual={value!r} is not a list of numbers") from None
    if residual.shape != (n_robots,):
        raise ValueError(
            f"{where}position_residual has shape {residual.shape}; expected one value per robot ({n_robots},)"
        )
    if not np.all(np.isfinite(residual)) or np.any(residual < 0) or np.any(residual > MAX_POSITION_RESIDUAL):
        raise ValueError(
            f"{where}position_residual={residual.tolist()} is not within [0, {MAX_POSITION_RESIDUAL:g}] m "
            "(finite, one value per robot)"
        )
    return residual


# the identification inputs come from their own stream of the seed (the plant draws its slip from another)
_INPUT_STREAM = 0x494E5055  # "INPU"

#: the longest hold of an identification input [periods]: 10 s, a tenth of a paper trajectory
#: (1000 periods), so that a trajectory still sees 100 different commands per robot
MAX_HOLD = 100


def check_hold(hold: object) -> int:
    """``hold`` (periods each identification input is held) as an int in [1, :data:`MAX_HOLD`],
    else ``ValueError`` naming it."""
    return check_int(
        "hold",
        hold,
        1,
        maximum=MAX_HOLD,
        note="periods each random input is held; 1: drawn anew every period",
    )


def check_random_hold(random_hold: object, hold: int) -> bool:
    """``random_hold`` (each segment's hold drawn from 1..``hold``) as a bool, else ``ValueError``
    naming it; True needs ``hold`` >= 2 (with ``hold=1`` every segment is one period: the paper's
    inputs, which ``random_hold=False`` already names)."""
    random_hold = check_flag("random_hold", random_hold)
    if random_hold and hold < 2:
        raise ValueError(
            f"random_hold=True with hold={hold!r}: the holds are drawn from 1..hold, so hold must be >= 2"
        )
    return random_hold


@dataclass(frozen=True)
class DataSpec:
    """How an identification data set is drawn (the paper's protocol, SPEC section 2).

    Attributes
    ----------
    trajectories, steps : int
        Teams and periods per team; ``trajectories * steps`` team-transitions.
    input_bound : float
        Commands uniform on [-b, b]^2 per robot and period (beyond the actuation limits, as the paper).
    state_bound : float
        Initial poses uniform on [-b, b]^3 per robot.
    seed : int
        Seed of the inputs and initial states.
    hold : int
        Periods each robot's random command is held (piecewise constant, changing at periods 0,
        hold, 2 hold, ...; the last hold cut at the trajectory's end). 1, the default, is the
        paper's protocol: a command drawn anew every period. Longer holds let robots with inertia
        and motor lag (the physics plant) reach steady speeds within the data.
    random_hold : bool
        False (the default): every hold is ``hold`` periods. True: every robot's command is held
        for a number of periods drawn uniformly from 1..``hold`` anew for each command, so the
        data mix fast changes with steady speeds (a multi-level pseudo-random input; ``hold`` >= 2).
    """

    trajectories: int
    steps: int
    input_bound: float = PARAMS.koopman_input_bound
    state_bound: float = PARAMS.koopman_state_bound
    seed: int = 0
    hold: int = 1
    random_hold: bool = False

    def __post_init__(self) -> None:
        # frozen: the checked values replace what was given (e.g. numpy's int64)
        object.__setattr__(self, "hold", check_hold(self.hold))
        object.__setattr__(self, "random_hold", check_random_hold(self.random_hold, self.hold))

    @property
    def transitions(self) -> int:
        """Team-transitions in the set."""
        return self.trajectories * self.steps

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (``hold`` only when it is not 1 and ``random_hold`` only when True, so
        that the data sets drawn before either existed keep their cache keys and model files)."""
        out = asdict(self)
        if self.hold == 1:
            del out["hold"]
        if not self.random_hold:
            del out["random_hold"]
        return out


#: the largest calibration budget [team-transitions]: 10x the paper's 1,000,000. The identification
#: data are held in memory (poses and commands, about 40 bytes per robot and transition: 1.2 GB
#: for 3 robots at this bound), so a larger budget is refused before it fills the memory.
MAX_CALIBRATION_BUDGET = 10_000_000


def data_spec_for(budget: int, seed: int = 0, hold: int = 1, random_hold: bool = False) -> DataSpec:
    """The identification set a budget buys: trajectories of the paper's length (1000 periods),
    as many as fit (one shorter trajectory when the budget is below one paper trajectory), each
    random input held for ``hold`` periods, or with ``random_hold`` for 1..``hold`` periods drawn
    per input (:class:`DataSpec`)."""
    check_int(
        "calibration budget",
        budget,
        1,
        maximum=MAX_CALIBRATION_BUDGET,
        note="team-transitions; the data take about 40 bytes per robot and transition",
    )
    steps = min(PARAMS.koopman_steps, int(budget))
    return DataSpec(
        trajectories=int(budget) // steps, steps=steps, seed=seed, hold=hold, random_hold=random_hold
    )


@dataclass(frozen=True)
class TrajectoryData:
    """Identification trajectories.

    Attributes
    ----------
    states : ndarray, shape (T + 1, B, N, 3)
        Poses; ``states[t, b]`` is team b at period t.
    commands : ndarray, shape (T, B, N, 2)
        Commands applied between periods t and t + 1.
    spec : DataSpec
        How they were drawn.
    """

    states: NDArray[np.float64]
    commands: NDArray[np.float64]
    spec: DataSpec


def collect_data(plant: CalibrationPlant, spec: DataSpec) -> TrajectoryData:
    """Drive the plant's teams with the random inputs of ``spec`` (spends ``spec.transitions``).

    With ``spec.hold`` = K > 1 every robot's command is drawn once per K periods and held: the
    draws are those of ``ceil(steps / K)`` periods of ``hold=1`` data (the same stream), each
    repeated K times, so ``hold=1`` draws exactly the paper's inputs. With ``spec.random_hold``
    the k-th command of a robot is the ``hold=1`` stream's period k, held for a number of periods
    drawn from 1..K (after the commands, from the same stream), independently per robot."""
    if spec.trajectories < 1 or spec.steps < 1:
        raise ValueError(f"trajectories={spec.trajectories} and steps={spec.steps} must be >= 1")
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(_INPUT_STREAM,)))
    n, b = plant.n_robots, spec.state_bound
    start = rng.uniform(-b, b, size=(spec.trajectories, n, 3))
    # a robot's holds are at least one period each, so it needs at most `steps` draws
    draws = spec.steps if spec.random_hold else -(-spec.steps // spec.hold)
    commands = rng.uniform(-spec.input_bound, spec.input_bound, size=(draws, spec.trajectories, n, 2))
    if spec.random_hold:
        commands = _held_randomly(commands, rng, spec.hold)
    elif spec.hold > 1:
        commands = np.repeat(commands, spec.hold, axis=0)[: spec.steps]
    return TrajectoryData(plant.rollout(start, commands), commands, spec)


def _held_randomly(draws: NDArray[np.float64], rng: np.random.Generator, hold: int) -> NDArray[np.float64]:
    """Commands (T, B, N, 2) whose robot-wise k-th segment is ``draws[k]``, held for a number of
    periods drawn uniformly from 1..``hold`` per segment and robot (the last one cut at T)."""
    steps = draws.shape[0]
    lengths = rng.integers(1, hold, endpoint=True, size=draws.shape[:-1])  # (T, B, N)
    ends = np.cumsum(lengths, axis=0)  # the period each segment's successor starts at
    switch = np.zeros(draws.shape[:-1], dtype=np.int64)
    period, team, robot = np.nonzero(ends < steps)
    switch[ends[period, team, robot], team, robot] = 1
    segment = np.cumsum(switch, axis=0)  # (T, B, N): the segment each period belongs to
    return np.take_along_axis(draws, segment[..., None], axis=0)


def previous_commands(commands: NDArray, memory: int) -> NDArray[np.float64]:
    """The ``memory`` commands before every period of trajectories that start at rest.

    Parameters
    ----------
    commands : ndarray, shape (T, ..., N, 2)
        Commands of periods 0..T-1.
    memory : int
        How many to remember.

    Returns
    -------
    ndarray, shape (T + 1, ..., memory, N, 2)
        Entry [t, ..., l] is the command of period t - 1 - l, zero before period 0 (a team at rest
        has the same lag state as one commanded to stand still).
    """
    commands = np.asarray(commands, dtype=np.float64)
    steps = commands.shape[0]
    padded = np.concatenate([np.zeros((memory,) + commands.shape[1:]), commands])
    # padded[t + memory - 1 - l] is the command of period t - 1 - l
    return np.stack([padded[memory - 1 - lag : memory + steps - lag] for lag in range(memory)], axis=-3)


def poses_before(states: NDArray, start: int = 0, stop: int | None = None) -> NDArray[np.float64]:
    """The poses one period before periods ``start`` to ``stop`` - 1 (default: every period) of
    trajectories (T + 1, ..., N, 3) that start at rest: entry t is pose t - 1, and the entry of
    period 0 the start itself (a standing robot has not moved). A chunk of periods reads only
    the poses from ``start`` - 1 on."""
    stop = len(states) if stop is None else stop
    states = np.asarray(states[max(0, start - 1) : stop], dtype=np.float64)
    return np.concatenate([states[:1], states[:-1]])[len(states) - (stop - start) :]


def position_residual(
    predict: Callable[..., NDArray],
    data: TrajectoryData,
    chunk: int = 100,
    memory: int = 0,
    velocity: bool = False,
) -> NDArray[np.float64]:
    """RMS one-step position error of a prediction model on a data set, per robot [m].

    Parameters
    ----------
    predict : callable
        ``predict(poses (..., N, 3), commands (..., N, 2)) -> poses (..., N, 3)``, with
        ``memory`` > 0 ``predict(poses, commands, previous (..., memory, N, 2))``, with
        ``velocity`` also ``before=`` the poses one period earlier (..., N, 3).
    data : TrajectoryData
    chunk : int
        Periods evaluated at once (bounds memory).
    memory : int
        Previous commands the model takes (:func:`previous_commands`; 0: none).
    velocity : bool
        The model takes the poses one period before (:func:`poses_before`).
    """
    total = np.zeros(data.states.shape[2])
    steps = data.commands.shape[0]
    for t0 in range(0, steps, chunk):
        t1 = min(steps, t0 + chunk)
        lifted: dict[str, NDArray] = {}
        if memory:
            # the commands before period t0 are those of the periods before it
            previous = previous_commands(data.commands[max(0, t0 - memory) : t1], memory)[-(t1 - t0 + 1) : -1]
            lifted["previous"] = previous
        if velocity:  # the pose before period t0 is that of period t0 - 1 (the start's own at 0)
            lifted["before"] = poses_before(data.states, t0, t1)
        predicted = predict(data.states[t0:t1], data.commands[t0:t1], **lifted)
        err = predicted[..., :2] - data.states[t0 + 1 : t1 + 1, ..., :2]
        total += (err**2).sum(axis=-1).sum(axis=(0, 1))
    return np.sqrt(total / (steps * data.states.shape[1]))


def cache_dir() -> Path:
    """User cache directory of calibrations (``<cache root>/calibration``, see :mod:`controllers.disk_cache`)."""
    return cache_root() / "calibration"


def cache_key(kind: str, plant: CalibrationPlant, spec: DataSpec, **extra: Any) -> str:
    """Hash of what determines a calibration: its kind, the plant, the data set, and ``extra``."""
    blob = {
        "kind": kind,
        "plant": plant.signature,
        "plant_seed": plant.seed,
        "budget": plant.budget,
        "data": spec.to_dict(),
        **extra,
    }
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:20]


def cache_path(kind: str, key: str, suffix: str) -> Path:
    """Where a cached calibration of ``kind`` with ``key`` lives."""
    return cache_dir() / f"{kind}-{key}{suffix}"


def calibrate_controller(
    controller: Any, env: Any, *, budget: int = PARAMS.calibration_budget, seed: int = 0
) -> dict[str, Any] | None:
    """Offer ``controller`` the calibration plant of ``env``, as the evaluator does.

    Parameters
    ----------
    controller : Controller
        Any controller; one that is not :class:`~controllers.base.Calibratable` (itself or down
        its wrappers' ``inner`` chain, see :func:`~controllers.base.calibratable`) is left alone.
    env : env, env id or CalibrationPlant
        The deployment env (any front, wrapped or not), or a ready plant.
    budget : int
        Team-transitions the controller may use (ignored for a ready plant).
    seed : int
        Calibration seed.

    Returns
    -------
    dict or None
        The controller's calibration summary plus ``budget``, or None when it does not calibrate.
    """
    learner = calibratable(controller)
    if learner is None:
        return None
    plant = env if isinstance(env, CalibrationPlant) else make_plant(env, budget=budget, seed=seed)
    summary = dict(learner.calibrate(plant, seed=seed) or {})
    summary.setdefault("transitions", plant.used)
    summary["budget"] = plant.budget
    return summary
