"""The controller modules' paths of the previous release, kept importable for one release.

``import controllers.nmpc`` (and the other paths of :data:`MOVED`) still works: each old path is
a plain stub module (``controllers/nmpc.py`` ...) whose names are read from where they live now,
with one ``DeprecationWarning`` naming the new module and the removal release (no import hook,
as Stable-Baselines3 keeps its moved paths). Nothing in the package imports these paths; they
exist for users' code and notebooks.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Sequence
from typing import Any

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


#: the release that removes the paths of :data:`MOVED`
REMOVAL = "0.2.0"


def moved_module(name: str, targets: Sequence[str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a deprecated stub module ``name`` (PEP 562): every
    name is read from the modules in ``targets``, in order. Called from the stub's body, it warns
    once (a ``DeprecationWarning`` naming the new modules and the removal release)."""
    warnings.warn(
        f"{name} is deprecated and will be removed in KoopNav {REMOVAL}; import from "
        f"{' / '.join(targets)} instead",
        DeprecationWarning,
        stacklevel=3,
    )

    def __getattr__(attribute: str) -> Any:
        if attribute.startswith("__"):
            raise AttributeError(attribute)
        for target in targets:
            module = importlib.import_module(target)
            if hasattr(module, attribute):
                return getattr(module, attribute)
        raise AttributeError(f"module {name!r} (moved to {list(targets)}) has no attribute {attribute!r}")

    def __dir__() -> list[str]:
        names: set[str] = set()
        for target in targets:
            names.update(getattr(importlib.import_module(target), "__all__", ()))
        return sorted(names)

    return __getattr__, __dir__
