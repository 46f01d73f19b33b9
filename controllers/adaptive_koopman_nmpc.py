"""Adaptive Koopman-NMPC: the Koopman-NMPC whose bilinear model learns online from its episode.

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

import os
import time
from collections import deque
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.koopman import KoopmanModel
from controllers.koopman.online import (
    RecursiveBilinearFit,
    check_adapted,
    check_forgetting,
    check_prior_weight,
)
from controllers.koopman_nmpc import KoopmanNMPC
from controllers.nmpc import ROBUST_UNCERTAINTY_MARGIN, NMPCConfig
from koopman_envs.checks import check_int
from koopman_envs.scenario import Scenario

__all__ = ["AdaptiveKoopmanNMPC"]

#: periods of a-priori residuals before the recent residual replaces the calibrated one
_MIN_RESIDUALS = 5


class AdaptiveKoopmanNMPC(KoopmanNMPC):
    """Koopman-NMPC with an online RLS update of its model and residual-driven margins.

    Parameters
    ----------
    model, dictionary, structure
        As :class:`controllers.koopman_nmpc.KoopmanNMPC` (the starting model).
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
        NMPC options (:class:`controllers.nmpc.NMPCConfig`); ``uncertainty_margin`` defaults
        to :data:`controllers.nmpc.ROBUST_UNCERTAINTY_MARGIN` here (3 recent RMS residuals).

    Notes
    -----
    Its :meth:`stats` add the online update's cost per step (``online_update_ms_median`` / ``_p95``:
    RLS, new NLP parameters, margins) and ``online_updates_rejected`` (transitions the guards refused).
    """

    name = "adaptive-koopman-nmpc"

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
        options.setdefault("uncertainty_margin", ROBUST_UNCERTAINTY_MARGIN)
        check_forgetting(forgetting)
        check_prior_weight(prior_weight)
        check_int("residual_window", residual_window, 1, note="periods")
        self.forgetting = float(forgetting)
        self.prior_weight = float(prior_weight)
        self.residual_window = residual_window
        self.adapt = bool(adapt)
        self.adapted = check_adapted(adapted)
        self._estimator: RecursiveBilinearFit | None = None
        super().__init__(model, dictionary, config, structure, **options)

    def _use(self, model: KoopmanModel) -> None:
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
        self._previous: tuple[NDArray, NDArray] | None = None
        self._limits = np.array([scenario.v_max, scenario.omega_max])

    def _act(self, observation: NDArray, info: dict[str, Any]) -> NDArray[np.float64]:
        poses = np.asarray(info["poses"], dtype=np.float64)
        if self._previous is not None:
            start = time.perf_counter()
            self._learn(*self._previous, poses)
            self._stats.extra_times.setdefault("online_update", []).append(time.perf_counter() - start)
        command = super()._act(observation, info)
        n = poses.shape[0]
        # the env saturates commands to the limits; learn from what the robots actually received
        applied = np.clip(command.reshape(n, 2), -self._limits, self._limits)
        self._previous = (poses, applied)
        return command

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
