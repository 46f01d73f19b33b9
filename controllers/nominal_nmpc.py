"""Nominal NMPC: the NMPC of SPEC section 3 with the slip-free unicycle as prediction model."""

from __future__ import annotations

from typing import Any

from controllers.nmpc import NMPCConfig, NMPCController
from controllers.unicycle import UnicycleModel
from koopman_envs.scenario import Scenario

__all__ = ["NominalNMPC"]


class NominalNMPC(NMPCController):
    """NMPC that predicts with the slip-free unicycle (no slip knowledge, no learning)."""

    name = "nominal-nmpc"

    def __init__(self, config: NMPCConfig | None = None, **options: Any) -> None:
        super().__init__(None, config, **options)
        self._models: dict[tuple[int, float], UnicycleModel] = {}

    def _model_for(self, scenario: Scenario) -> UnicycleModel:
        key = (scenario.n_robots, scenario.dt)
        if key not in self._models:
            self._models[key] = UnicycleModel(scenario.n_robots, scenario.dt)
        return self._models[key]
