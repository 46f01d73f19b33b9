"""What KoopNav deprecates, in one place: the release that removes it (:data:`REMOVAL`) and the
module paths that moved, kept for one release by an import hook instead of stub files.

A package registers its moved paths as data when it is imported
(``register_moved_paths({"evaluation.statistics": "evaluation.stats.statistics"})`` in
``evaluation/__init__.py``); Python imports a package before it looks for a module inside it, so
the registration is always in place when an old path is imported. :class:`MovedPathFinder`, on
``sys.meta_path``, then answers for the registered paths:

- ``import OLD`` (or ``from OLD import name``) warns with a ``DeprecationWarning`` at the importing
  line, "OLD is deprecated and will be removed in KoopNav 0.2.0; import from NEW", and gives the
  new module itself: ``sys.modules[OLD] is NEW``, so its names, classes and patches are the new
  module's. A registered path that is a package carries its submodules (``OLD.sub`` is
  ``NEW.sub``).
- ``python -m OLD`` of a path registered as a command warns and runs ``NEW``'s ``main()`` with the
  same arguments and exit code; the finder's spec for ``OLD`` is runnable for ``runpy``.

Nothing is a file at an old path, so a package's root holds only its modules; a path goes when its
registration is removed (the release named by :data:`REMOVAL`).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import CodeType, FrameType, ModuleType
from typing import NoReturn

from koopman_envs.checks import choice_message

__all__ = ["REMOVAL", "MovedPath", "MovedPathFinder", "moved_paths", "register_moved_paths"]

#: the release that removes what is deprecated now (the moved module paths, the observed view's
#: dict API), named in CHANGELOG.md
REMOVAL = "0.2.0"


@dataclass(frozen=True)
class MovedPath:
    """One module path that moved.

    Attributes
    ----------
    old : str
        The previous dotted module path, imported with a ``DeprecationWarning`` until
        :data:`REMOVAL`.
    new : str
        The module it names now.
    command : bool
        ``python -m old`` runs ``new``'s ``main()`` (the paths the docs told users to run).
    """

    old: str
    new: str
    command: bool = False


#: every registered path, old -> what it moved to
_REGISTRY: dict[str, MovedPath] = {}


def moved_paths() -> dict[str, MovedPath]:
    """The registered moved paths (a copy), old path -> :class:`MovedPath`: those of every package
    imported so far."""
    return dict(_REGISTRY)


def _check_path(value: object, role: str) -> str:
    if not isinstance(value, str) or not all(part.isidentifier() for part in value.split(".")):
        raise ValueError(f"{role}={value!r} is not a dotted module path such as 'package.module'")
    return value


def register_moved_paths(moved: Mapping[str, str], *, commands: Collection[str] = ()) -> None:
    """Keep the module paths ``moved`` (old -> new) importable for one release, with a warning.

    Called by a package's ``__init__.py`` with its own moved paths. Registering the same path to
    the same module again does nothing.

    Parameters
    ----------
    moved : mapping of str to str
        Old dotted module path -> the module it moved to (the module itself, not a package face,
        so that ``OLD`` keeps every name it had).
    commands : collection of str
        The old paths of ``moved`` that users ran (``python -m OLD``); each new module must have
        a ``main(argv=None) -> int``.

    Raises
    ------
    ValueError
        For a path that is not a dotted module path, a new path inside its old one (importing it
        would import the old path first), a chain (an old path registered as another's new one, or
        the reverse: point each at the final module), an old path already registered to another
        module, or a command that is not among ``moved``.
    """
    unknown = sorted(set(commands) - set(moved))
    if unknown:
        raise ValueError(f"commands {unknown} are not among the moved paths {sorted(moved)}")
    targets = {entry.new for entry in _REGISTRY.values()} | set(moved.values())
    for old, new in moved.items():
        _check_path(old, "old")
        _check_path(new, "new")
        if new == old or new.startswith(f"{old}."):
            raise ValueError(f"{old!r} cannot move to {new!r}, a module at or inside the old path")
        if new in _REGISTRY or new in moved or old in targets:
            raise ValueError(
                f"{old!r} -> {new!r} makes a chain of moved paths; point every old path at the final module"
            )
        known = _REGISTRY.get(old)
        if known is not None and known.new != new:
            raise ValueError(f"{old!r} is already registered as moved to {known.new!r}, not {new!r}")
    for old, new in moved.items():
        _REGISTRY[old] = MovedPath(old, new, old in commands)
    if _FINDER not in sys.meta_path:
        # first, before the path finder: a moved package's old name would otherwise let it load a
        # submodule a second time, under the old name, from the folder the two names share
        sys.meta_path.insert(0, _FINDER)


def _resolve(fullname: str) -> MovedPath | None:
    """The move of ``fullname``: registered itself, or inside a registered package."""
    moved = _REGISTRY.get(fullname)
    if moved is not None:
        return moved
    head = fullname
    while "." in head:
        head = head.rpartition(".")[0]
        package = _REGISTRY.get(head)
        if package is not None:
            return MovedPath(fullname, package.new + fullname[len(head) :])
    return None


class MovedPathFinder(importlib.abc.MetaPathFinder):
    """The ``sys.meta_path`` finder of the registered moved paths (one, installed by the first
    :func:`register_moved_paths`); it answers None for every other name."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        """A spec whose loader gives the new module, or None when ``fullname`` did not move (or its
        new module does not exist). Its origin is the new module's file (``python -m`` sets
        ``sys.argv[0]`` to it, as running the new module would)."""
        moved = _resolve(fullname)
        if moved is None:
            return None
        new_spec = importlib.util.find_spec(moved.new)
        if new_spec is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _MovedPathLoader(moved), origin=new_spec.origin)


_FINDER = MovedPathFinder()

#: what ``python -m OLD`` runs; under another name (multiprocessing's spawned workers run the main
#: module again as ``__mp_main__``) it runs nothing, as a command's ``if __name__ == "__main__"``
_COMMAND_SOURCE = (
    'if __name__ == "__main__":\n'
    "    from koopman_envs.deprecation import _run_moved_command\n"
    "    _run_moved_command({old!r})\n"
)


class _MovedPathLoader(importlib.abc.Loader):
    """Loads a moved path as its new module (and runs it, for ``runpy``, when it is a command)."""

    def __init__(self, moved: MovedPath) -> None:
        self.moved = moved

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None  # a plain module, replaced by the new one in exec_module

    def exec_module(self, module: ModuleType) -> None:
        warnings.warn(
            f"{self.moved.old} is deprecated and will be removed in KoopNav {REMOVAL}; "
            f"import from {self.moved.new}",
            DeprecationWarning,
            stacklevel=_importer_stacklevel(),
        )
        # the import system returns what sys.modules holds under the name once this returns
        sys.modules[self.moved.old] = importlib.import_module(self.moved.new)

    def get_code(self, fullname: str) -> CodeType:
        """The code ``python -m`` runs for a command; a moved module that is not one is refused by
        name (runpy reports the ImportError's message)."""
        if not self.moved.command:
            raise ImportError(
                f"{fullname} moved to {self.moved.new} (deprecated, removed in KoopNav {REMOVAL}) and "
                "is not a command: import it from its new path"
            )
        source = _COMMAND_SOURCE.format(old=self.moved.old)
        return compile(source, f"<{self.moved.old}: moved to {self.moved.new}>", "exec")


def _run_moved_command(old: str) -> NoReturn:
    """``python -m old``: warn (at the main module, whose warnings Python shows by default) and run
    ``main()`` of the new module with the same arguments, exiting with its code."""
    moved = _REGISTRY.get(old)
    if moved is None or not moved.command:
        commands = sorted(name for name, entry in _REGISTRY.items() if entry.command)
        raise ValueError(choice_message("old", old, commands, among="the moved commands"))
    warnings.warn(
        f"python -m {old} is deprecated and will be removed in KoopNav {REMOVAL}; run python -m {moved.new}",
        DeprecationWarning,
        stacklevel=2,
    )
    raise SystemExit(importlib.import_module(moved.new).main())


#: importlib's own folder: ``importlib.import_module`` is a frame there between the import system
#: and the code that asked for the module
_IMPORTLIB = str(Path(importlib.__file__).parent)


def _is_import_system(frame: FrameType) -> bool:
    """The frames ``warnings`` itself skips when it counts a stacklevel (CPython's rule)."""
    filename = frame.f_code.co_filename
    return "importlib" in filename and "_bootstrap" in filename


def _importer_stacklevel() -> int:
    """The ``stacklevel`` of a warning raised in ``exec_module`` that names the code importing the
    module: ``warnings`` skips the import system's frames, but not ``importlib.import_module``'s
    (without this, an import through it would be reported as importlib's, which the default
    filters hide)."""
    frame: FrameType | None = sys._getframe(1)  # exec_module: stacklevel 1
    level = 1
    while frame is not None:
        frame = frame.f_back
        while frame is not None and _is_import_system(frame):
            frame = frame.f_back
        level += 1
        if frame is None or not frame.f_code.co_filename.startswith(_IMPORTLIB):
            break
    return level
