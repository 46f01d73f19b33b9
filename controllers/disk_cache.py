"""The package's on-disk cache: one root for calibrations and compiled solvers, and atomic writes into it.

The cache is optional. Everything in it can be computed again, so a cache that cannot be written
(a read-only directory or file system, a full disk, a ``KOOPNAV_CACHE`` below a regular file) must
never fail a run: :func:`write_atomic` and :func:`writable` warn once per process
(:class:`CacheWriteWarning`, naming the directory and the reason) and the caller goes on with what
it computed in memory. Reading stays the caller's job, and it checks what it reads (a torn or
foreign entry is refused by name and recomputed, see :mod:`controllers.calibration`).
"""

from __future__ import annotations

import os
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

from koopman_envs import files

__all__ = ["CacheWriteWarning", "cache_root", "entry_exists", "writable", "write_atomic"]


class CacheWriteWarning(UserWarning):
    """The cache cannot be written; the run goes on without caching (warned once per process)."""


# one warning per process: a run that cannot cache would otherwise warn on every calibration,
# solver build and worker episode, and bury whatever else it has to say
_unwritable_warned = False


def cache_root() -> Path:
    """``$KOOPNAV_CACHE``, default ``~/.cache/koopnav``."""
    return Path(os.environ.get("KOOPNAV_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "koopnav"))


def _warn_unwritable(directory: Path, exc: OSError) -> None:
    """Warn (once per process) that ``directory`` cannot be written, and why."""
    global _unwritable_warned
    if _unwritable_warned:
        return
    _unwritable_warned = True
    warnings.warn(
        f"the KoopNav cache directory {directory} cannot be written ({type(exc).__name__}: {exc}); the run "
        "goes on without caching: calibrations and compiled solvers are recomputed in every process. Set "
        "KOOPNAV_CACHE to a writable directory to keep them",
        CacheWriteWarning,
        stacklevel=3,
    )


def writable(directory: Path) -> bool:
    """Whether a cache entry can be created in ``directory`` (made if missing), tried with a real file.

    A probe for writers that cannot warn themselves (the compiler wrapper of
    :mod:`controllers.solvers.compiled` runs in a child process). False warns as :func:`write_atomic`
    does.
    """
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=directory, suffix=".probe")
        os.close(fd)
        os.remove(probe)
    except OSError as exc:
        _warn_unwritable(directory, exc)
        return False
    return True


def write_atomic(path: Path, write: Callable[[str], object], suffix: str) -> bool:
    """Write a cache entry through a temporary file and rename, so that concurrent workers never
    read half a file (:func:`koopman_envs.files.write_atomic`, the one atomic writer). Best effort:
    the cache is optional.

    Parameters
    ----------
    path : Path
        The entry.
    write : callable
        ``write(temporary_path)`` writes the entry's content.
    suffix : str
        Suffix of the temporary file (some writers pick the format by it).

    Returns
    -------
    bool
        True if the entry is in place; False if the write failed with an ``OSError`` (permission,
        read-only or full file system, a path through a regular file): then nothing is left
        behind, and the first failure of the process warns with :class:`CacheWriteWarning`.
    """
    try:
        files.write_atomic(path, write, suffix=suffix)
    except OSError as exc:
        _warn_unwritable(path.parent, exc)
        return False
    return True


def entry_exists(path: Path) -> bool:
    """``path.exists()``, False when it cannot even be looked at (a cache directory without
    search permission raises ``PermissionError`` there): the entry is then computed again."""
    try:
        return path.exists()
    except OSError:
        return False
