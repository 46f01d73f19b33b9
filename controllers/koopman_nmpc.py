"""Koopman-NMPC: the NMPC of SPEC section 3 predicting with the learned bilinear Koopman model."""

from __future__ import annotations

import os
from typing import Any, Sequence

import numpy as np

from controllers.koopman import KoopmanModel, get_model
from controllers.nmpc import NMPCConfig, NMPCController
from koopman_envs.scenario import Scenario

__all__ = ["KoopmanNMPC"]


class KoopmanNMPC(NMPCController):
    """NMPC whose prediction model f_b is learned from simulator data of the deployment setting.

    Parameters
    ----------
    slip : str or sequence of float
        Which setting the robots are deployed in, i.e. which simulator the training data come
        from: the shipped models for ``"nominal"``, ``"low"``, ``"high"``, a cached fit otherwise.
        The controller never sees lambda itself, only the model learned from that data.
    model : KoopmanModel or path, optional
        Use this model instead (overrides ``slip``).
    dictionary : str
        Dictionary of the model to fit or load (``"minimal"``: the paper's).
    uncertainty_margin : float
        (ours) Safety margins grow to ``uncertainty_margin`` times each robot's RMS one-step
        position residual on the model's training data (recorded in the model file) when that
        exceeds the paper's 0.015 m: a model learned on slipping robots knows that their motion
        strays from its mean prediction, and hugging obstacles at 1.5 cm then ends in contact.
        With the nominal model the margins stay at the paper's value. 0 disables it.
    config, **options
        NMPC options, see :class:`controllers.nmpc.NMPCConfig`.
    """

    name = "koopman-nmpc"

    def __init__(
        self,
        slip: str | Sequence[float] = "nominal",
        model: KoopmanModel | str | os.PathLike | None = None,
        dictionary: str = "minimal",
        uncertainty_margin: float = 3.0,
        config: NMPCConfig | None = None,
        **options: Any,
    ) -> None:
        if not np.isfinite(uncertainty_margin) or uncertainty_margin < 0:
            raise ValueError(f"uncertainty_margin={uncertainty_margin!r} must be a finite number >= 0")
        self.uncertainty_margin = float(uncertainty_margin)
        if model is not None and not isinstance(model, KoopmanModel):
            model = KoopmanModel.load(model)
        super().__init__(model, config, **options)
        self.slip = slip
        self.dictionary = dictionary
        self._fixed_model = model is not None

    def safety_margins(self, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
        """Paper margins, widened by the model's own one-step residual per robot."""
        obstacle, pair = super().safety_margins(scenario)
        residual = np.asarray(self.model.metadata.get("position_residual", np.zeros(scenario.n_robots)), float)
        spread = self.uncertainty_margin * residual
        obstacle = np.maximum(obstacle, spread)
        pairs = [(i, j) for i in range(scenario.n_robots) for j in range(i + 1, scenario.n_robots)]
        pair = np.maximum(pair, np.array([spread[i] + spread[j] for i, j in pairs]))
        return obstacle, pair

    def _model_for(self, scenario: Scenario) -> KoopmanModel:
        if self.model is None or (not self._fixed_model and self.model.n_robots != scenario.n_robots):
            self.model = get_model(self.slip, scenario.n_robots, self.dictionary)
        return self.model
