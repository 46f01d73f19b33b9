"""The built-in controllers and their named presets, as one table.

A *controller* is a class registered under a name. A *preset* is a registered controller with
some options set by default (``koopman-nmpc-robust`` is ``koopman-nmpc`` with
``uncertainty_margin=3``); it is built by :func:`build_preset`, which gives the controller the
preset's name, so reports and statistics name what was asked for. Options given to
``controllers.make`` override a preset's defaults.
"""

from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass, field
from typing import Any

__all__ = ["CONTROLLERS", "PRESETS", "Preset", "build_preset", "builtin_names", "register_builtins"]

#: the robust presets' ``uncertainty_margin`` (kept equal to controllers.mpc.config's, tested):
#: written here so that listing the presets imports no solver
_ROBUST = 3.0
#: the ``mpc-cbf`` preset's barrier decay rate gamma (controllers.mpc.config.NMPCConfig.cbf_gamma):
#: chosen on a slalom map of our own that no protocol uses (tests/test_mpc_cbf.py), and ablated on the protocols in
#: docs/controllers.md
_CBF_GAMMA = 0.1

#: the built-in controllers: name -> "module:Class"
CONTROLLERS = {
    "koopman-nmpc": "controllers.mpc.variants:KoopmanNMPC",
    "adaptive-koopman-nmpc": "controllers.mpc.variants:AdaptiveKoopmanNMPC",
    "nominal-nmpc": "controllers.mpc.variants:NominalNMPC",
    # distributed: every robot its own small NMPC, neighbours' plans as moving obstacles (16-32 robots)
    "dmpc-nominal": "controllers.mpc.distributed:DistributedNMPC",
    "consensus": "controllers.consensus:ConsensusController",
    # the classic baselines (issue 45): ORCA through pyrvo (the [crowd] extra) and DWA (numpy)
    "orca": "controllers.classic.orca:ORCAController",
    "dwa": "controllers.classic.dwa:DWAController",
}


@dataclass(frozen=True)
class Preset:
    """A registered controller with some options set by default.

    Attributes
    ----------
    name : str
        The preset's registered name (and the built controller's ``name``).
    base : str
        The controller it builds (a name of :data:`CONTROLLERS`).
    defaults : dict
        Options set unless the caller sets them.
    doc : str
        One line for listings and docs.
    """

    name: str
    base: str
    defaults: dict[str, Any] = field(default_factory=dict)
    doc: str = ""


PRESETS = (
    Preset(
        "koopman-nmpc-robust",
        "koopman-nmpc",
        {"uncertainty_margin": _ROBUST},
        "Koopman-NMPC with margins widened by its calibrated residual",
    ),
    Preset(
        "nominal-nmpc-robust",
        "nominal-nmpc",
        {"uncertainty_margin": _ROBUST},
        "nominal NMPC with margins widened by the unicycle's calibrated residual",
    ),
    Preset(
        "dmpc-nominal-robust",
        "dmpc-nominal",
        {"uncertainty_margin": _ROBUST},
        "distributed nominal NMPC with margins widened by each robot's calibrated residual",
    ),
    Preset(
        "dmpc-koopman",
        "dmpc-nominal",
        {"model": "koopman"},
        "distributed NMPC predicting with each robot's block of the per-robot Koopman model",
    ),
    Preset(
        "dmpc-koopman-robust",
        "dmpc-nominal",
        {"model": "koopman", "uncertainty_margin": _ROBUST},
        "distributed Koopman NMPC with margins widened by each robot's calibrated residual",
    ),
    Preset(
        "mpc-cbf",
        "nominal-nmpc",
        {"cbf_gamma": _CBF_GAMMA},
        "nominal NMPC with discrete-time control barrier constraints (Zeng et al. 2021) in the problem",
    ),
    Preset(
        "consensus-free",
        "consensus",
        {"collision_avoidance": False},
        "the consensus law with collision avoidance off (the paper's validation variant)",
    ),
)


def _resolve(path: str) -> Any:
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module), attribute)


def build_preset(preset: Preset, **options: Any) -> Any:
    """The preset's controller: its base built with the preset's defaults under ``options``,
    named after the preset."""
    controller = _resolve(CONTROLLERS[preset.base])(**{**preset.defaults, **options})
    controller.name = preset.name
    return controller


def register_builtins(register: Any) -> None:
    """Register every built-in controller and preset with ``register(name, factory)``."""
    for name, path in CONTROLLERS.items():
        register(name, path)
    for preset in PRESETS:
        register(preset.name, functools.partial(build_preset, preset))


def builtin_names() -> list[str]:
    """The names of the built-in controllers and presets (not those registered at run time)."""
    return sorted({*CONTROLLERS, *(preset.name for preset in PRESETS)})
