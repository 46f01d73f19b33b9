"""Koopman-NMPC: the NMPC of SPEC section 3 predicting with the learned bilinear Koopman model."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from controllers.koopman import KoopmanModel, calibrated_model
from controllers.koopman.store import check_structure, default_structure
from controllers.nmpc import NMPCConfig, NMPCController
from koopman_envs.plant import CalibrationPlant
from koopman_envs.scenario import Scenario

__all__ = ["KoopmanNMPC"]


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
        paper's 3 robots, per-robot beyond).
    config, **options
        NMPC options, see :class:`controllers.nmpc.NMPCConfig` (``uncertainty_margin`` uses the
        model's RMS one-step position residual on its calibration data).
    """

    name = "koopman-nmpc"
    model: KoopmanModel | None  # only ever a KoopmanModel here (__init__, _use)

    def __init__(
        self,
        model: KoopmanModel | str | os.PathLike | None = None,
        dictionary: str = "minimal",
        config: NMPCConfig | None = None,
        structure: str = "auto",
        **options: Any,
    ) -> None:
        if structure != "auto":
            check_structure(structure)
        self.structure = structure
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
        if structure == "auto":
            structure = default_structure(plant.n_robots)
        model, summary = calibrated_model(plant, seed, self.dictionary, structure=structure)
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
