"""Controller registry: ``make(name, **options)`` and ``available()``.

Built-in names are registered in :mod:`controllers`. Other packages add controllers through the
entry-point group ``koopnav.controllers`` (name = controller name, value = ``module:factory``),
for example in their ``pyproject.toml``::

    [project.entry-points."koopnav.controllers"]
    my-controller = "my_package.control:MyController"

so that ``controllers.make("my-controller")`` and the evaluator find them without code changes.
Without an entry point, a controller can be named by its import path:
``make("my_package.control:MyController")`` (a name that is not registered and reads
``module:Attribute``). The attribute is checked before anything is called: it must be a class
with the controller's methods (``reset``, ``act``, ``stats``; e.g. derived from
:class:`~controllers.base.BaseController`) or a function annotated to return one, so that a
command line such as ``--controllers os:system:command=...`` is refused, not run (importing the
module does run its top level, as ``python -c "import module"`` would).

A *wrapper prefix* builds a controller around any other: ``make("safe:consensus")`` is the
``consensus`` controller behind the wrapper registered as ``safe`` (:func:`register_wrapper`);
the wrapper receives the inner controller's factory and every option, and passes on those that
are not its own.
"""

from __future__ import annotations

import functools
import importlib
import sys
import typing
from collections.abc import Callable
from importlib import metadata
from typing import Any

from controllers.base import Controller
from controllers.tuning.presets import is_comparison_variant
from koopman_envs.checks import choice_message

__all__ = [
    "ENTRY_POINT_GROUP",
    "available",
    "controller_class",
    "declared_class",
    "factory",
    "is_import_path",
    "make",
    "register",
    "register_wrapper",
    "split_name",
]

ENTRY_POINT_GROUP = "koopnav.controllers"

_REGISTRY: dict[str, Callable[..., Controller] | str] = {}
#: name -> the controller class its factory builds, for a factory that does not say so itself
#: (a preset's ``functools.partial``): a class or ``"module:Class"``
_BUILDS: dict[str, type | str] = {}
_WRAPPERS: dict[str, Callable[..., Controller] | str] = {}
#: wrapper prefix -> (its option dataclass as "module:Class", the prefix of its options, what it does)
_WRAPPER_OPTIONS: dict[str, tuple[str, str, str]] = {}


def register(
    name: str,
    factory: Callable[..., Controller] | str,
    *,
    overwrite: bool = False,
    builds: type | str | None = None,
) -> None:
    """Register a controller factory (a callable or a ``"module:attribute"`` string).

    ``builds``: the controller class the factory builds (or its ``"module:Class"``), for a factory
    that is neither that class nor a function annotated to return it (a ``functools.partial``),
    so that what the class declares (``acts_in_batch``, ``episode_cost``) can be read without
    building a controller (:func:`controller_class`).
    """
    if not overwrite and name in _REGISTRY:
        raise ValueError(f"controller {name!r} is already registered")
    _REGISTRY[name] = factory
    if builds is not None:
        _BUILDS[name] = builds
    else:
        _BUILDS.pop(name, None)


def register_wrapper(
    prefix: str,
    wrapper: Callable[..., Controller] | str,
    *,
    overwrite: bool = False,
    options: tuple[str, str, str] | None = None,
) -> None:
    """Register a wrapper prefix: ``make(f"{prefix}:{name}", **options)`` calls
    ``wrapper(factory(name), **options)`` (a callable or a ``"module:attribute"`` string).
    ``options``: the wrapper's option dataclass (``"module:Class"``), the prefix its options
    carry and what the wrapper does, for :func:`controllers.options` (None: it takes none)."""
    if not prefix or ":" in prefix:
        raise ValueError(f"wrapper prefix {prefix!r} must be non-empty and contain no ':'")
    if not overwrite and prefix in _WRAPPERS:
        raise ValueError(f"wrapper prefix {prefix!r} is already registered")
    _WRAPPERS[prefix] = wrapper
    if options is not None:
        _WRAPPER_OPTIONS[prefix] = options
    else:
        _WRAPPER_OPTIONS.pop(prefix, None)


def wrapper_options(prefix: str) -> tuple[type, str, str] | None:
    """A registered wrapper's option dataclass, the prefix of its options and what it does (None
    for a wrapper registered without options)."""
    if prefix not in _WRAPPER_OPTIONS:
        return None
    path, option_prefix, role = _WRAPPER_OPTIONS[prefix]
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module), attribute), option_prefix, role


def split_name(name: str) -> tuple[tuple[str, ...], str]:
    """``"safe:consensus"`` -> ``(("safe",), "consensus")``: the leading wrapper prefixes and the
    rest (which is not checked)."""
    prefixes = []
    head, sep, tail = name.partition(":")
    while sep and head in _WRAPPERS:
        prefixes.append(head)
        name = tail
        head, sep, tail = name.partition(":")
    return tuple(prefixes), name


def is_import_path(name: str) -> bool:
    """True for ``"package.module:Attribute"``: a controller factory given by where it is defined
    (the module part dotted Python identifiers, the attribute one identifier)."""
    module, sep, attribute = name.partition(":")
    return bool(sep) and all(part.isidentifier() for part in module.split(".")) and attribute.isidentifier()


def _entry_points(refresh: bool = False) -> dict[str, metadata.EntryPoint]:
    """The installed ``koopnav.controllers`` entry points, read once per process and path (reading
    them scans every installed distribution, about 15 ms, which a batched evaluation building a
    controller per batch would pay each time); ``refresh`` reads them again (a name not found
    does: a plugin installed into the running process is found)."""
    if refresh:
        _read_entry_points.cache_clear()
    return _read_entry_points(tuple(sys.path))


@functools.lru_cache(maxsize=4)
def _read_entry_points(path: tuple[str, ...]) -> dict[str, metadata.EntryPoint]:
    return {ep.name: ep for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def available(*, variants: bool = True) -> list[str]:
    """Names of every controller: built-in ones and those of installed entry points.

    Parameters
    ----------
    variants : bool
        Include the ``<name>-v0`` variants of the tuned presets (the defaults before tuning,
        :func:`controllers.tuning.presets.is_comparison_variant`). Default runs pass ``False``: a variant
        runs only when asked for by name (``--controllers mpc-cbf-v0``), and is always buildable.
    """
    names = set(_REGISTRY) | set(_entry_points())
    return sorted(n for n in names if variants or not is_comparison_variant(n))


def _resolve(factory: Callable[..., Controller] | str) -> Callable[..., Controller]:
    if callable(factory):
        return factory
    module, _, attribute = factory.partition(":")
    resolved: Callable[..., Controller] = getattr(importlib.import_module(module), attribute)
    return resolved


#: the methods a controller class has (:class:`~controllers.base.Controller`)
_CONTROLLER_METHODS = ("reset", "act", "stats")


def _is_controller_class(target: Any) -> bool:
    return isinstance(target, type) and all(callable(getattr(target, m, None)) for m in _CONTROLLER_METHODS)


def _return_annotation(target: Any) -> Any:
    """What a callable's return annotation names (None without one, or when it cannot be resolved)."""
    if isinstance(target, type) or not callable(target):
        return None
    try:
        return typing.get_type_hints(target).get("return")
    except Exception:  # noqa: BLE001 - an unresolvable annotation declares nothing
        return None


def declared_class(target: Any) -> type | None:
    """The controller class a factory declares it builds, found without calling it: the
    factory itself when it is a controller class, the class its return annotation names when it
    is a function; None otherwise (a ``functools.partial``, a function annotated with the
    :class:`Controller` protocol only, anything that is not a factory)."""
    if isinstance(target, type):
        return target if _is_controller_class(target) else None
    returns = _return_annotation(target)
    return returns if _is_controller_class(returns) else None


def _declares_controller(target: Any) -> bool:
    """Whether ``target`` declares the controller contract without being called: a controller
    class, or a function whose return annotation is one (or the :class:`Controller` protocol)."""
    return declared_class(target) is not None or _return_annotation(target) is Controller


def _checked_import(name: str) -> Callable[..., Controller]:
    """The factory an import path names, refused before any call unless it declares the contract."""
    try:
        target = _resolve(name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"controller {name!r} cannot be imported: {type(exc).__name__}: {exc}") from None
    if not _declares_controller(target):
        if isinstance(target, type):
            missing = [m for m in _CONTROLLER_METHODS if not callable(getattr(target, m, None))]
            what = f"class {target.__qualname__!r}, which lacks {missing}"
        else:
            what = f"{type(target).__name__} {getattr(target, '__qualname__', target)!r}, which declares no controller"
        raise ValueError(
            f"controller {name!r} names {what}: it does not declare the controller contract, and nothing "
            "was called. An import path must name "
            f"a class with the methods {list(_CONTROLLER_METHODS)} (derive from controllers.BaseController) "
            "or a function annotated to return one (-> controllers.base.Controller)"
        )
    return target


def factory(name: str) -> Callable[..., Controller]:
    """The callable that builds controller ``name``, wrapper prefixes included (raises
    ``ValueError`` for unknown names, naming the unknown controller without its prefixes)."""
    prefixes, base = split_name(name)
    if prefixes:
        build = factory(base)
        for prefix in reversed(prefixes):
            build = functools.partial(_resolve(_WRAPPERS[prefix]), build)
        return build
    if name in _REGISTRY:
        return _resolve(_REGISTRY[name])
    if is_import_path(name):
        return _checked_import(name)
    points = _entry_points()
    if name not in points:
        points = _entry_points(refresh=True)
    if name not in points:
        raise ValueError(choice_message("controller", name, available(), sep=" "))
    loaded: Callable[..., Controller] = points[name].load()
    return loaded


def controller_class(name: str) -> type | None:
    """The class controller ``name`` builds, found without building it: its factory's
    :func:`declared_class`, or the class it was registered as building (``register(...,
    builds=...)``: the presets). Behind wrapper prefixes, the outermost wrapper's class
    (``safe:rl-ppo`` builds a safety filter); :func:`split_name` gives the wrapped name.

    Returns None when only a call would tell (a factory function without a class annotation).
    Raises ``ValueError`` for an unknown name, as :func:`factory` does.
    """
    prefixes, _ = split_name(name)
    if prefixes:
        return declared_class(_resolve(_WRAPPERS[prefixes[0]]))
    if name in _BUILDS:
        return declared_class(_resolve(_BUILDS[name]))
    return declared_class(factory(name))


def make(name: str, **options: Any) -> Controller:
    """Build a controller by name (``"name"`` or ``"prefix:name"`` for a wrapped one).

    Raises
    ------
    ValueError
        Unknown name (the message lists the available ones), or a factory (an import path, an
        entry point) that builds something without the :class:`~controllers.base.Controller`
        members (the message names the missing ones).
    """
    controller = factory(name)(**options)
    missing = [
        member
        for member in ("name", "reset", "act", "stats")
        if not hasattr(controller, member) or (member != "name" and not callable(getattr(controller, member)))
    ]
    if missing:
        raise ValueError(
            f"controller {name!r} built a {type(controller).__module__}.{type(controller).__qualname__}, "
            f"which is not a controller: it lacks {missing} (a controller has a name and the methods "
            "reset(scenario, seed=...), act(observation, info) and stats(); derive from "
            "controllers.BaseController to get them)"
        )
    return controller
