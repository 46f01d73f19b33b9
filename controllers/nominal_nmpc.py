"""Nominal NMPC: the NMPC of SPEC section 3 with the slip-free unicycle as prediction model."""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from controllers.calibration import (
    CacheWarning,
    cache_key,
    cache_path,
    check_position_residual,
    collect_data,
    data_spec_for,
    position_residual,
    write_atomic,
)
from controllers.nmpc import NMPCConfig, NMPCController
from controllers.unicycle import UnicycleModel
from koopman_envs.plant import CalibrationPlant
from koopman_envs.scenario import Scenario

__all__ = ["NominalNMPC"]


class NominalNMPC(NMPCController):
    """NMPC that predicts with the slip-free unicycle (no slip knowledge, no learning).

    With ``uncertainty_margin > 0`` its :meth:`calibrate` measures the unicycle's RMS one-step
    position residual on the same calibration data the Koopman-NMPC fits its model to, and
    widens the margins by it, exactly as the Koopman-NMPC does with its own residual.
    """

    name = "nominal-nmpc"

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
                json.loads(path.read_text(encoding="utf-8"))["position_residual"], plant.n_robots
            ).tolist()
            source = "cache"
        except (OSError, ValueError, KeyError, TypeError) as exc:  # missing or bad entry: measure again
            if path.exists():
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
