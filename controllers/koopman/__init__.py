"""Bilinear Koopman models of a robot team, learned from simulator data (SPEC section 2).

>>> from controllers.koopman import fit_for_env
>>> model = fit_for_env("KoopNav-Formation-v0", slip="high")   # the shipped model of that setting
>>> model.step(poses, commands)          # f_b(x, u), batched numpy
>>> f = model.casadi_step()              # the same map as a CasADi function for the NMPC
"""

from controllers.koopman.accuracy import circle_test
from controllers.koopman.dictionary import DICTIONARIES, get_dictionary
from controllers.koopman.fit import fit_bilinear
from controllers.koopman.model import KoopmanModel, ModelFileError
from controllers.koopman.store import calibrated_model, fit_for_env, fit_on_plant

__all__ = [
    "DICTIONARIES",
    "KoopmanModel",
    "ModelFileError",
    "circle_test",
    "calibrated_model",
    "fit_bilinear",
    "fit_for_env",
    "fit_on_plant",
    "get_dictionary",
]
