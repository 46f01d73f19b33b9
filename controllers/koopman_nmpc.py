"""Koopman-NMPC: the NMPC of SPEC section 3 predicting with the learned bilinear Koopman model."""

from __future__ import annotations

import os
from typing import Any, Sequence

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
    config, **options
        NMPC options, see :class:`controllers.nmpc.NMPCConfig`.
    """

    name = "koopman-nmpc"

    def __init__(
        self,
        slip: str | Sequence[float] = "nominal",
        model: KoopmanModel | str | os.PathLike | None = None,
        dictionary: str = "minimal",
        config: NMPCConfig | None = None,
        **options: Any,
    ) -> None:
        if model is not None and not isinstance(model, KoopmanModel):
            model = KoopmanModel.load(model)
        super().__init__(model, config, **options)
        self.slip = slip
        self.dictionary = dictionary
        self._fixed_model = model is not None

    def _model_for(self, scenario: Scenario) -> KoopmanModel:
        if self.model is None or (not self._fixed_model and self.model.n_robots != scenario.n_robots):
            self.model = get_model(self.slip, scenario.n_robots, self.dictionary)
        return self.model
