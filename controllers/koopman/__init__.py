"""Bilinear Koopman models of a robot team, learned from simulator data (SPEC section 2).

>>> from controllers.koopman import get_model
>>> model = get_model("high")            # shipped model of the high-slip setting
>>> model.step(poses, commands)          # f_b(x, u), batched numpy
>>> f = model.casadi_step()              # the same map as a CasADi function for the NMPC
"""

from controllers.koopman.accuracy import circle_test
from controllers.koopman.data import DataSpec, collect_data
from controllers.koopman.dictionary import DICTIONARIES, get_dictionary
from controllers.koopman.fit import fit_bilinear
from controllers.koopman.model import KoopmanModel, ModelFileError
from controllers.koopman.store import fit_model, get_model

__all__ = [
    "DICTIONARIES",
    "DataSpec",
    "KoopmanModel",
    "ModelFileError",
    "circle_test",
    "collect_data",
    "fit_bilinear",
    "fit_model",
    "get_dictionary",
    "get_model",
]
