"""Controllers for the KoopNav environments.

>>> import controllers
>>> controllers.available()
['consensus', 'consensus-free', 'koopman-nmpc', 'nominal-nmpc']
>>> ctrl = controllers.make("koopman-nmpc", slip="high")
>>> ctrl.reset(env.unwrapped.scenario, seed=0)
>>> action = ctrl.act(obs, info)

Every controller follows :class:`controllers.base.Controller`; other packages register their
own through the ``koopnav.controllers`` entry-point group (see :mod:`controllers.registry`).
"""

from controllers.base import BaseController, Controller, ControllerStats
from controllers.registry import ENTRY_POINT_GROUP, accepts_option, available, make, register

register("koopman-nmpc", "controllers.koopman_nmpc:KoopmanNMPC")
register("nominal-nmpc", "controllers.nominal_nmpc:NominalNMPC")
register("consensus", "controllers.consensus:ConsensusController")
register("consensus-free", "controllers:_consensus_without_avoidance")


def _consensus_without_avoidance(**options):
    """The consensus law with collision avoidance off (the paper's validation variant)."""
    from controllers.consensus import ConsensusController

    options.setdefault("collision_avoidance", False)
    return ConsensusController(**options)


__all__ = [
    "BaseController",
    "Controller",
    "ControllerStats",
    "ENTRY_POINT_GROUP",
    "accepts_option",
    "available",
    "make",
    "register",
]
