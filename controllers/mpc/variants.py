"""The NMPCs by prediction model: nominal (the slip-free unicycle), Koopman (the learned bilinear
model, SPEC section 3) and adaptive Koopman (the learned model updated online).

Koopman-NMPC predicts with the model learned from data of the robots it drives. Nominal NMPC
predicts with the slip-free unicycle; with ``uncertainty_margin > 0`` its :meth:`calibrate`
measures the unicycle's RMS one-step position residual on the same calibration data and widens
the margins by it, as Koopman-NMPC does with its own residual.

Adaptive Koopman-NMPC is the Koopman-NMPC whose bilinear model learns online from its episode.
The controller starts every episode from its calibrated model (so episodes stay independent and
reproducible in any order or process) and, after every period, folds the observed transition
into the model by recursive least squares (:class:`controllers.koopman.online.RecursiveBilinearFit`).
It is told nothing about slip: a slip zone or a changing slip level shows up only as prediction
error, which the update then absorbs. The coefficients enter the NMPC as NLP parameters, so an
update costs no rebuild or recompilation.

Its safety margins follow its own recent prediction error: ``uncertainty_margin`` (k) times the
RMS one-step position residual of the last ``residual_window`` periods (per robot), never below
the offsets, and the calibrated residual until the window has filled a little. With k = 0 the
margins are the paper's offsets, as for koopman-nmpc.
"""

from __future__ import annotations

import json
import os
import time
import warnings
from collections import deque
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from controllers.calibration import (
    MAX_HOLD,
    CacheWarning,
    cache_key,
    cache_path,
    check_hold,
    check_position_residual,
    check_random_hold,
    collect_data,
    data_spec_for,
    position_residual,
    write_atomic,
)
from controllers.disk_cache import entry_exists
from controllers.estimation import PoseFrontEnd
from controllers.koopman import KoopmanModel, calibrated_model
from controllers.koopman.dictionary import DICTIONARIES, MAX_MEMORY
from controllers.koopman.fit import STRUCTURES
from controllers.koopman.online import (
    ADAPTED_TERMS,
    RecursiveBilinearFit,
    check_adapted,
    check_forgetting,
    check_prior_weight,
)
from controllers.koopman.refit import MAX_ROLLOUT_REFITS
from controllers.koopman.store import check_lift, check_refits, check_structure, default_structure
from controllers.mpc.config import ROBUST_UNCERTAINTY_MARGIN, NMPCConfig
from controllers.mpc.controller import NMPCController
from controllers.mpc.models import UnicycleModel
from koopman_envs import CalibrationPlant, Observed
from koopman_envs.checks import Range, parse_json
from koopman_envs.files import MAX_TEXT_BYTES, read_text
from koopman_envs.scenario import Scenario

__all__ = ["AdaptiveKoopmanNMPC", "KoopmanNMPC", "NominalNMPC"]


#: periods of a-priori residuals before the recent residual replaces the calibrated one
_MIN_RESIDUALS = 5


class NominalNMPC(NMPCController):
    """NMPC that predicts with the slip-free unicycle (no slip knowledge, no learning).

    With ``uncertainty_margin > 0`` its :meth:`calibrate` measures the unicycle's RMS one-step
    position residual on the same calibration data the Koopman-NMPC fits its model to, and
    widens the margins by it, exactly as the Koopman-NMPC does with its own residual.
    """

    name = "nominal-nmpc"
    episode_cost = 1  # an optimizer: after the Koopman-NMPC, before the cheap controllers

    def __init__(self, config: NMPCConfig | None = None, **options: Any) -> None:
        super().__init__(None, config, **options)
        self._models: dict[tuple[int, float], UnicycleModel] = {}

    def calibrate(self, plant: CalibrationPlant, *, seed: int = 0) -> dict[str, Any]:
        """Measure the unicycle's residual on ``plant`` when the margins need it (else use no data)."""
        if self.config.uncertainty_margin == 0:
            self.position_residual = None
            return {"transitions": 0, "source": "not needed"}
        start = time.perf_counter()
        spec = data_spec_for(plant.budget, seed)
        key = cache_key("unicycle-residual", plant, spec, dt=plant.dt)
        path = cache_path("unicycle-residual", key, ".json")
        summary = {"transitions": spec.transitions, "key": key}
        try:
            residual = check_position_residual(
                parse_json(read_text(path, MAX_TEXT_BYTES, what="calibration cache entry"), str(path))[
                    "position_residual"
                ],
                plant.n_robots,
            ).tolist()
            source = "cache"
        except (OSError, ValueError, KeyError, TypeError) as exc:  # missing or bad entry: measure again
            if entry_exists(path):
                warnings.warn(
                    f"calibration cache entry {path}: {type(exc).__name__}: {exc}; measuring it again",
                    CacheWarning,
                    stacklevel=2,
                )
            model = UnicycleModel(plant.n_robots, plant.dt)
            residual = position_residual(model.step, collect_data(plant, spec)).tolist()
            blob = json.dumps({"position_residual": residual})
            write_atomic(path, lambda tmp: Path(tmp).write_text(blob, encoding="utf-8"), ".json")
            source = "measured"
        self.position_residual = np.asarray(residual, dtype=float)
        return {**summary, "source": source, "seconds": time.perf_counter() - start}

    def _model_for(self, scenario: Scenario) -> UnicycleModel:
        key = (scenario.n_robots, scenario.dt)
        if key not in self._models:
            self._models[key] = UnicycleModel(scenario.n_robots, scenario.dt)
        return self._models[key]


class KoopmanNMPC(NMPCController):
    """NMPC whose prediction model f_b is learned from data of the robots it drives.

    The model comes from :meth:`calibrate` (the evaluator calls it with the deployment env's
    calibration plant: the paper's 1000 x 1000 random-input transitions by default, fitted once
    and cached on disk) or is given directly. The controller is never told the slip setting.

    Parameters
    ----------
    model : KoopmanModel or path, optional
        Use this model (then :meth:`calibrate` keeps it and only its recorded residual counts).
        ``controllers.koopman.fit_for_env(env_id, **env_kwargs)`` fits one for any env.
    dictionary : str
        Dictionary of the model that :meth:`calibrate` fits (``"minimal"``: the paper's).
    structure : str
        How the fitted model couples the robots: ``"stacked"`` (the paper's one team
        regression), ``"per-robot"`` (each robot's own block; the fit and the NMPC problem grow
        linearly with N instead of quadratically) or ``"auto"`` (default: stacked up to the
        paper's 3 robots, per-robot beyond; stacked with ``memory``, ``velocity`` or
        ``rollout_refits``).
    memory : int
        Previous commands in the lift of the model that :meth:`calibrate` fits (0: the paper's
        pose-only lift). With L > 0 the model can carry the robots' lag (inertia, motor ramps:
        the physics plant, docs/physics.md); the NMPC's state then holds each robot's last L
        commands, the measured state the ones it sent. Stacked models only.
    velocity : bool
        The robots' measured velocity in the lift of the model that :meth:`calibrate` fits: the
        last period's move in the body frame (forward, lateral, turn) and its products with the
        heading's cos and sin, so that the model can carry the robots' inertia without a window
        of commands. The NMPC's state then holds each robot's pose one period before, the
        measured state the pose it measured a period ago. Stacked models only.
    hold : int
        Periods each random input of the identification data that :meth:`calibrate` draws is held
        (piecewise constant; 1, the default: the paper's inputs, drawn anew every period, which
        keeps the kinematic plant's results bit for bit). A robot with inertia and motor lag (the
        physics plant) reaches steady speeds only under held inputs (docs/physics.md). Part of
        the calibration's cache key.
    random_hold : bool
        False (default): every input held ``hold`` periods. True: each input held for a number of
        periods drawn uniformly from 1..``hold`` (``hold`` >= 2), so the data mix fast changes
        with steady speeds. Part of the calibration's cache key.
    rollout_refits : int
        Refits of the model that :meth:`calibrate` fits on its own open-loop rollouts of the
        identification data over the NMPC's horizon (0, the default: the paper's one-step least
        squares; :func:`controllers.koopman.refit.refit_on_rollouts`), so that it is fitted on
        the predicted states it is fed in the horizon too. Stacked models only; part of the
        calibration's cache key.
    config, **options
        NMPC options, see :class:`controllers.mpc.config.NMPCConfig` (``uncertainty_margin`` uses the
        model's RMS one-step position residual on its calibration data).
    """

    name = "koopman-nmpc"
    episode_cost = 2  # the longest episodes: an optimizer over the learned model (its lifted state)
    #: allowed values of the text options (controllers.option_spec)
    OPTION_CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {
        "dictionary": tuple(DICTIONARIES),
        "structure": ("auto", *STRUCTURES),
    }
    #: the allowed range of its own numeric options (:mod:`controllers.option_spec`)
    OPTION_RANGES: ClassVar[dict[str, Range]] = {
        "memory": Range(0, MAX_MEMORY, integer=True, note="previous commands in the lift"),
        "hold": Range(1, MAX_HOLD, integer=True, note="periods per identification input"),
        "rollout_refits": Range(0, MAX_ROLLOUT_REFITS, integer=True, note="refits on the model's rollouts"),
    }
    model: KoopmanModel | None  # only ever a KoopmanModel here (__init__, _use)

    def __init__(
        self,
        model: KoopmanModel | str | os.PathLike | None = None,
        dictionary: str = "minimal",
        config: NMPCConfig | None = None,
        structure: str = "auto",
        memory: int = 0,
        velocity: bool = False,
        hold: int = 1,
        random_hold: bool = False,
        rollout_refits: int = 0,
        **options: Any,
    ) -> None:
        self.hold = check_hold(hold)
        self.random_hold = check_random_hold(random_hold, self.hold)
        if structure != "auto":
            check_structure(structure)
        self.memory, self.velocity = check_lift(
            memory, velocity, "stacked" if structure == "auto" else structure
        )
        self.structure = structure
        self.rollout_refits = check_refits(rollout_refits, "stacked" if structure == "auto" else structure)
        if model is not None and not isinstance(model, KoopmanModel):
            model = KoopmanModel.load(model)
        super().__init__(model, config, **options)
        self.dictionary = dictionary
        self._fixed_model = model is not None
        if model is not None:
            self._use(model)

    def _use(self, model: KoopmanModel) -> None:
        self.model = model
        residual = model.metadata.get("position_residual")
        self.position_residual = None if residual is None else np.asarray(residual, dtype=float)

    def calibrate(self, plant: CalibrationPlant, *, seed: int = 0) -> dict[str, Any]:
        """Fit the model of ``plant``'s robots (or load it from the cache); see the class docstring."""
        if self._fixed_model:
            assert self.model is not None  # _fixed_model: __init__ was given a model
            return {"transitions": int(self.model.metadata.get("transitions", 0)), "source": "given model"}
        structure = self.structure
        if structure == "auto":  # a lift with memory or velocity is a stacked model's
            structure = (
                "stacked"
                if self.memory or self.velocity or self.rollout_refits
                else default_structure(plant.n_robots)
            )
        model, summary = calibrated_model(
            plant,
            seed,
            self.dictionary,
            structure=structure,
            memory=self.memory,
            velocity=self.velocity,
            hold=self.hold,
            random_hold=self.random_hold,
            rollout_refits=self.rollout_refits,
        )
        summary["structure"] = structure
        self._use(model)
        return summary

    def _model_for(self, scenario: Scenario) -> KoopmanModel:
        if self.model is None:
            raise ValueError(
                "koopman-nmpc has no model: call calibrate(plant) first (the evaluator does), or pass "
                "model=controllers.koopman.fit_for_env(env_id, **env_kwargs)"
            )
        return self.model


class AdaptiveKoopmanNMPC(KoopmanNMPC):
    """Koopman-NMPC with an online RLS update of its model and residual-driven margins.

    Parameters
    ----------
    model, dictionary, structure
        As :class:`KoopmanNMPC` (the starting model).
    forgetting : float
        RLS forgetting factor in (0, 1] (0.98: ~5 s of memory at the paper's 0.1 s period).
    prior_weight : float
        Calibration-like transitions the starting model is worth (> 0).
    residual_window : int
        Periods of recent one-step residuals behind the margins (>= 1).
    adapt : bool
        False freezes the model (margins still follow the residuals): an ablation switch.
    adapted : {"all", "input"}
        Which coefficients the update changes: every free one (default), or only those of the
        command terms (A, the motion without commands, stays calibrated); see
        :class:`controllers.koopman.online.RecursiveBilinearFit`.
    config, **options
        NMPC options (:class:`controllers.mpc.config.NMPCConfig`); ``uncertainty_margin`` defaults
        to :data:`controllers.mpc.config.ROBUST_UNCERTAINTY_MARGIN` here (3 recent RMS residuals).

    Notes
    -----
    Its :meth:`stats` add the online update's cost per step (``online_update_ms_median`` / ``_p95``:
    RLS, new NLP parameters, margins) and ``online_updates_rejected`` (transitions the guards refused).
    """

    name = "adaptive-koopman-nmpc"
    #: NMPC options whose default differs from NMPCConfig's (controllers.options reads them too)
    NMPC_DEFAULTS: ClassVar[dict[str, Any]] = {"uncertainty_margin": ROBUST_UNCERTAINTY_MARGIN}
    OPTION_CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {
        **KoopmanNMPC.OPTION_CHOICES,
        "adapted": ADAPTED_TERMS,
    }
    #: the allowed range of its own numeric options (:mod:`controllers.option_spec`; ours)
    OPTION_RANGES: ClassVar[dict[str, Range]] = {
        "forgetting": Range(0, 1, low_open=True, note="1: no forgetting"),
        "prior_weight": Range(0, 1e9, low_open=True, note="calibration transitions"),
        # the residuals kept: 10,000 periods are 1,000 s, longer than any episode
        "residual_window": Range(1, 10_000, integer=True, note="periods"),
    }

    def __init__(
        self,
        model: KoopmanModel | str | os.PathLike | None = None,
        dictionary: str = "minimal",
        forgetting: float = 0.98,
        prior_weight: float = 200.0,
        residual_window: int = 20,
        adapt: bool = True,
        adapted: str = "all",
        config: NMPCConfig | None = None,
        structure: str = "auto",
        **options: Any,
    ) -> None:
        for key, value in self.NMPC_DEFAULTS.items():
            options.setdefault(key, value)
        check_forgetting(forgetting)  # the online fit's own checks, then the upper bounds declared here
        check_prior_weight(prior_weight)
        for key, value in (("prior_weight", prior_weight), ("residual_window", residual_window)):
            self.OPTION_RANGES[key].check(key, value)
        self.forgetting = float(forgetting)
        self.prior_weight = float(prior_weight)
        self.residual_window = residual_window
        self.adapt = bool(adapt)
        self.adapted = check_adapted(adapted)
        self._estimator: RecursiveBilinearFit | None = None
        super().__init__(model, dictionary, config, structure, **options)

    def _use(self, model: KoopmanModel) -> None:
        if model.memory or model.velocity:
            raise ValueError(
                f"{self.name} updates a pose-only model online; this model has memory={model.memory}, "
                f"velocity={model.velocity}"
            )
        super()._use(model)
        self._estimator = None  # rebuilt for the new model at the next reset

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        super()._reset(scenario, seed)
        assert self.model is not None  # else super()._reset raised (_model_for)
        if self._estimator is None or self._estimator.model is not self.model:
            self._estimator = RecursiveBilinearFit(
                self.model, self.forgetting, self.prior_weight, self.adapted
            )
        self._estimator.reset()
        self._residuals: deque[NDArray] = deque(maxlen=self.residual_window)
        self._previous: tuple[NDArray, NDArray | None] | None = None
        self._limits = np.array([scenario.v_max, scenario.omega_max])

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        front_end = self.front_end
        if isinstance(front_end, PoseFrontEnd):
            # learn what happened, not what is planned from: the estimate of now (before the
            # delay compensation carries it forward) and the command that acted to reach it
            poses = np.array(front_end.filtered, dtype=np.float64)
            if self._previous is not None:
                self._timed_learn(self._previous[0], front_end.acting(), poses)
            command = super()._act(observation, observed)
            self._previous = (poses, None)
            return command
        poses = observed.observed_poses
        if self._previous is not None:
            assert self._previous[1] is not None
            self._timed_learn(self._previous[0], self._previous[1], poses)
        command = super()._act(observation, observed)
        n = poses.shape[0]
        # the env saturates commands to the limits; learn from what the robots actually received
        applied = np.clip(command.reshape(n, 2), -self._limits, self._limits)
        self._previous = (poses, applied)
        return command

    def _timed_learn(self, poses: NDArray, commands: NDArray, next_poses: NDArray) -> None:
        start = time.perf_counter()
        self._learn(poses, commands, next_poses)
        self._stats.extra_times.setdefault("online_update", []).append(time.perf_counter() - start)

    def _learn(self, poses: NDArray, commands: NDArray, next_poses: NDArray) -> None:
        estimator = self._estimator
        assert estimator is not None  # built by _reset; _learn runs from the episode's second step
        if self.adapt:
            rejected = estimator.rejected
            error = estimator.update(poses, commands, next_poses)
            self._stats.counts["online_updates_rejected"] += estimator.rejected - rejected
            self.set_model_parameters(estimator.nlp_parameters())
        else:
            error = estimator.model.lift(next_poses[None])[0][estimator.outputs] - estimator.predict(
                poses, commands
            )
        # a-priori position error per robot: rows 4i, 4i + 1 of C are robot i's x, y
        xy = error.reshape(-1, 4)[:, :2]
        self._residuals.append(np.einsum("ij,ij->i", xy, xy))
        if self.config.uncertainty_margin > 0 and len(self._residuals) >= _MIN_RESIDUALS:
            recent = np.sqrt(np.mean(np.asarray(self._residuals), axis=0))
            self.set_margins(*self.margins_for(poses.shape[0], recent))
