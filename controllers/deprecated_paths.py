"""The controller modules' paths of the previous release, kept importable for one release.

``import controllers.nmpc`` (and the other paths of :data:`MOVED`) still works and gives a
module whose names are read from where they live now, with a ``DeprecationWarning`` naming the new
module. Nothing in the package imports these paths; they exist for users' code and notebooks.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from collections.abc import Sequence
from typing import Any

__all__ = ["MOVED", "install_moved_paths"]

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


class MovedModule(types.ModuleType):
    """A module that reads every name from the modules that hold it now."""

    def __init__(self, name: str, targets: Sequence[str]) -> None:
        super().__init__(name, f"Moved: {name} now lives in {', '.join(targets)}.")
        self._targets = tuple(targets)

    def __getattr__(self, attribute: str) -> Any:
        if attribute.startswith("__"):
            raise AttributeError(attribute)
        for target in self._targets:
            module = importlib.import_module(target)
            if hasattr(module, attribute):
                return getattr(module, attribute)
        raise AttributeError(
            f"module {self.__name__!r} (moved to {list(self._targets)}) has no attribute {attribute!r}"
        )

    def __dir__(self) -> list[str]:
        names: set[str] = set()
        for target in self._targets:
            names.update(getattr(importlib.import_module(target), "__all__", ()))
        return sorted(names)


class _MovedLoader(importlib.abc.Loader):
    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        return MovedModule(spec.name, MOVED[spec.name])

    def exec_module(self, module: types.ModuleType) -> None:
        targets = MOVED[module.__name__]
        warnings.warn(
            f"{module.__name__} is deprecated and will be removed in the next release; import from "
            f"{' / '.join(targets)} instead",
            DeprecationWarning,
            stacklevel=2,
        )


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(
        self, fullname: str, path: Any = None, target: Any = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname in MOVED:
            return importlib.machinery.ModuleSpec(fullname, _MovedLoader())
        return None


def install_moved_paths() -> None:
    """Make the paths of :data:`MOVED` importable (idempotent)."""
    if not any(isinstance(finder, _MovedFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _MovedFinder())
