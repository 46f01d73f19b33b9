"""Moved module paths kept importable for one release: each old path is a plain stub module
whose names are read from where they live now, with one ``DeprecationWarning`` naming the new
module and the removal release (no import hook, as Stable-Baselines3 keeps its moved paths).
:mod:`controllers.deprecated_paths` uses the same helper."""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["MOVED", "REMOVAL", "moved_module", "moved_names"]

#: the release that removes the moved paths
REMOVAL = "0.2.0"

#: the environment package's old module paths -> where their names live now (issue 44: one layer
#: per folder: the builders in builder/, the fronts and what draws and runs them in fronts/)
MOVED: dict[str, tuple[str, ...]] = {
    "koopman_envs.keywords": ("koopman_envs.builder.keywords",),
    "koopman_envs.config": ("koopman_envs.builder.config",),
    "koopman_envs.engine": ("koopman_envs.builder.engine",),
    "koopman_envs.engine_memory": ("koopman_envs.builder.engine_memory",),
    "koopman_envs.episode_layout": ("koopman_envs.builder.episode_layout",),
    "koopman_envs.plant": ("koopman_envs.builder.plant",),
    "koopman_envs.rendering": ("koopman_envs.fronts.rendering",),
    "koopman_envs.rendering_layers": ("koopman_envs.fronts.rendering_layers",),
    "koopman_envs.animation": ("koopman_envs.fronts.animation",),
    "koopman_envs.demo": ("koopman_envs.fronts.demo",),
    "koopman_envs.episode": ("koopman_envs.fronts.episode",),
    "koopman_envs.tasks.layout": ("koopman_envs.layout",),
}


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


def moved_names(name: str, moved: Sequence[str], target: str) -> Callable[[str], Any]:
    """The ``__getattr__`` (PEP 562) of a module ``name`` some of whose names moved to ``target``:
    a moved name is read from ``target`` with a ``DeprecationWarning`` naming the new module and
    the removal release; any other name is an ``AttributeError``."""

    def __getattr__(attribute: str) -> Any:
        if attribute in moved:
            warnings.warn(
                f"{name}.{attribute} is deprecated and will be removed in KoopNav {REMOVAL}; "
                f"import it from {target}",
                DeprecationWarning,
                stacklevel=2,
            )
            return getattr(importlib.import_module(target), attribute)
        raise AttributeError(f"module {name!r} has no attribute {attribute!r}")

    return __getattr__
