"""Controller registry: ``make(name, **options)`` and ``available()``.

Built-in names are registered in :mod:`controllers`. Other packages add controllers through the
entry-point group ``koopnav.controllers`` (name = controller name, value = ``module:factory``),
for example in their ``pyproject.toml``::

    [project.entry-points."koopnav.controllers"]
    my-controller = "my_package.control:MyController"

so that ``controllers.make("my-controller")`` and the evaluator find them without code changes.
"""

from __future__ import annotations

import importlib
from importlib import metadata
from typing import Any, Callable

from controllers.base import Controller

__all__ = ["ENTRY_POINT_GROUP", "available", "factory", "make", "register"]

ENTRY_POINT_GROUP = "koopnav.controllers"

_REGISTRY: dict[str, Callable[..., Controller] | str] = {}


def register(name: str, factory: Callable[..., Controller] | str, *, overwrite: bool = False) -> None:
    """Register a controller factory (a callable or a ``"module:attribute"`` string)."""
    if not overwrite and name in _REGISTRY:
        raise ValueError(f"controller {name!r} is already registered")
    _REGISTRY[name] = factory


def _entry_points() -> dict[str, metadata.EntryPoint]:
    return {ep.name: ep for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def available() -> list[str]:
    """Names of every controller: built-in ones and those of installed entry points."""
    return sorted(set(_REGISTRY) | set(_entry_points()))


def _resolve(factory: Callable[..., Controller] | str) -> Callable[..., Controller]:
    if callable(factory):
        return factory
    module, _, attribute = factory.partition(":")
    return getattr(importlib.import_module(module), attribute)


def factory(name: str) -> Callable[..., Controller]:
    """The callable that builds controller ``name`` (raises ``ValueError`` for unknown names)."""
    if name in _REGISTRY:
        return _resolve(_REGISTRY[name])
    points = _entry_points()
    if name not in points:
        raise ValueError(f"controller {name!r} is not one of {available()}")
    return points[name].load()


def make(name: str, **options: Any) -> Controller:
    """Build a controller by name.

    Raises
    ------
    ValueError
        Unknown name (the message lists the available ones).
    """
    return factory(name)(**options)
