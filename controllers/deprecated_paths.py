"""The controller modules' paths of the previous release, kept importable for one release.

``import controllers.nmpc`` (and the other paths of :data:`MOVED`) still works: each old path is
a plain stub module (``controllers/nmpc.py`` ...) whose names are read from where they live now,
with one ``DeprecationWarning`` naming the new module and the removal release (no import hook,
as Stable-Baselines3 keeps its moved paths). Nothing in the package imports these paths; they
exist for users' code and notebooks.
"""

from __future__ import annotations

from koopman_envs.deprecated import REMOVAL, moved_module

__all__ = ["MOVED", "REMOVAL", "moved_module"]

#: old module -> the modules its names live in now (searched in order)
MOVED: dict[str, tuple[str, ...]] = {
    "controllers.nmpc": (
        "controllers.mpc.config",
        "controllers.mpc.models",
        "controllers.mpc.controller",
        "controllers.mpc.problem",
    ),
    "controllers.rti": ("controllers.mpc.rti",),
    "controllers.distributed": ("controllers.mpc.distributed",),
    "controllers.koopman_nmpc": ("controllers.mpc.variants",),
    "controllers.nominal_nmpc": ("controllers.mpc.variants",),
    "controllers.adaptive_koopman_nmpc": ("controllers.mpc.variants",),
    "controllers.unicycle": ("controllers.mpc.models",),
    "controllers.qp2": ("controllers.solvers.two_variable_qp",),
    "controllers.solver_cache": ("controllers.solvers.compiled",),
    "controllers.cache": ("controllers.disk_cache",),
}
