"""Controllers for the KoopNav environments.

>>> import controllers
>>> controllers.available()
['adaptive-koopman-nmpc', 'consensus', 'consensus-free', 'koopman-nmpc', 'koopman-nmpc-robust', 'nominal-nmpc', 'nominal-nmpc-robust']
>>> ctrl = controllers.make("koopman-nmpc")
>>> ctrl.calibrate(koopman_envs.make_plant(env), seed=0)   # learns from the env's robots (cached)
>>> ctrl.reset(env.unwrapped.scenario, seed=0)
>>> action = ctrl.act(obs, info)

Every controller follows :class:`controllers.base.Controller`; other packages register their
own through the ``koopnav.controllers`` entry-point group (see :mod:`controllers.registry`).
Any of them runs behind the CBF safety filter of :mod:`controllers.safety` as ``safe:<name>``.
"""

from controllers.base import BaseController, Controller, ControllerStats
from controllers.registry import ENTRY_POINT_GROUP, available, make, register, register_wrapper, split_name

register("koopman-nmpc", "controllers.koopman_nmpc:KoopmanNMPC")
register("koopman-nmpc-robust", "controllers:_koopman_nmpc_robust")
register("adaptive-koopman-nmpc", "controllers.adaptive_koopman_nmpc:AdaptiveKoopmanNMPC")
register("nominal-nmpc", "controllers.nominal_nmpc:NominalNMPC")
register("nominal-nmpc-robust", "controllers:_nominal_nmpc_robust")
# distributed: every robot its own small NMPC, neighbours' plans as moving obstacles (16-32 robots)
register("dmpc-nominal", "controllers.distributed:DistributedNMPC")
register("dmpc-nominal-robust", "controllers:_dmpc_nominal_robust")
register("dmpc-koopman", "controllers:_dmpc_koopman")
register("dmpc-koopman-robust", "controllers:_dmpc_koopman_robust")
register("consensus", "controllers.consensus:ConsensusController")
register("consensus-free", "controllers:_consensus_without_avoidance")
# any controller behind the CBF safety filter: "safe:<name>", filter options prefixed "safety_"
register_wrapper("safe", "controllers.safety:wrap")


def _dmpc_koopman(**options):
    """The distributed NMPC predicting with each robot's block of the per-robot Koopman model."""
    from controllers.distributed import DistributedNMPC

    return DistributedNMPC(model="koopman", **options)


def _dmpc_nominal_robust(**options):
    """The distributed nominal NMPC with margins widened by the unicycle's calibrated residual."""
    from controllers.distributed import DistributedNMPC
    from controllers.nmpc import ROBUST_UNCERTAINTY_MARGIN

    options.setdefault("uncertainty_margin", ROBUST_UNCERTAINTY_MARGIN)
    ctrl = DistributedNMPC(**options)
    ctrl.name = "dmpc-nominal-robust"
    return ctrl


def _dmpc_koopman_robust(**options):
    """The distributed Koopman NMPC with margins widened by each robot's calibrated residual."""
    from controllers.nmpc import ROBUST_UNCERTAINTY_MARGIN

    options.setdefault("uncertainty_margin", ROBUST_UNCERTAINTY_MARGIN)
    ctrl = _dmpc_koopman(**options)
    ctrl.name = "dmpc-koopman-robust"
    return ctrl


def _consensus_without_avoidance(**options):
    """The consensus law with collision avoidance off (the paper's validation variant)."""
    from controllers.consensus import ConsensusController

    options.setdefault("collision_avoidance", False)
    ctrl = ConsensusController(**options)
    ctrl.name = "consensus-free"
    return ctrl


def _koopman_nmpc_robust(**options):
    """Koopman-NMPC with margins widened by its calibrated residual (``uncertainty_margin``)."""
    from controllers.koopman_nmpc import KoopmanNMPC
    from controllers.nmpc import ROBUST_UNCERTAINTY_MARGIN

    options.setdefault("uncertainty_margin", ROBUST_UNCERTAINTY_MARGIN)
    ctrl = KoopmanNMPC(**options)
    ctrl.name = "koopman-nmpc-robust"
    return ctrl


def _nominal_nmpc_robust(**options):
    """Nominal NMPC with margins widened by its calibrated residual, like koopman-nmpc-robust."""
    from controllers.nmpc import ROBUST_UNCERTAINTY_MARGIN
    from controllers.nominal_nmpc import NominalNMPC

    options.setdefault("uncertainty_margin", ROBUST_UNCERTAINTY_MARGIN)
    ctrl = NominalNMPC(**options)
    ctrl.name = "nominal-nmpc-robust"
    return ctrl


__all__ = [
    "BaseController",
    "Controller",
    "ControllerStats",
    "ENTRY_POINT_GROUP",
    "available",
    "make",
    "register",
    "register_wrapper",
    "split_name",
]
