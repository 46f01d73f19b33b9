"""Compiled NMPC solvers, compiled once per machine.

CasADi's JIT turns an NLP's functions into C and compiles them in every process (30-60 s per
problem structure), which made compiled solvers impractical. :func:`jit_options` gives ``nlpsol``
options whose compiler command is :mod:`controllers.solvers.cached_cc`: the object file of each
generated source is kept under ``<cache root>/solvers/`` keyed by the source text, the compiler
flags, the compiler's identity and CasADi's version, so the second process (or worker) that
builds the same problem copies it instead of compiling. Without a C compiler the solver stays
uncompiled, with one warning. The cache is optional: when it cannot be written (one
:class:`~controllers.disk_cache.CacheWriteWarning` per process), a foreground build compiles
without keeping the object and a background build stays uncompiled.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import casadi as ca
from threadpoolctl import ThreadpoolController

from controllers.disk_cache import cache_root, writable

__all__ = ["COMPILER_FLAGS", "blas_threads", "compiler", "jit_options", "nlpsol", "solver_cache_dir"]

#: flags of the compiled NLP functions (-O2: -O3 compiles far longer for no measurable gain here)
COMPILER_FLAGS = ("-O2",)
_WRAPPER = Path(__file__).with_name("cached_cc.py")
_BUILD_DIRS: list[str] = []


def solver_cache_dir() -> Path:
    """Where compiled solver objects are kept (``<cache root>/solvers``)."""
    return cache_root() / "solvers"


def compiler() -> str | None:
    """The C compiler (``$CC``, default ``gcc``) as an absolute path, or None if there is none."""
    return shutil.which(os.environ.get("CC", "gcc"))


@functools.cache
def _identity(cc: str) -> str:
    """The compiler's own version text (part of every cache key)."""
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        out = ""
    return f"{cc}|{out.strip()}"


@functools.lru_cache(maxsize=1)
def _warn_no_compiler() -> None:
    warnings.warn(
        f"no C compiler found (CC={os.environ.get('CC', 'gcc')!r}): NMPC solvers run uncompiled, several times "
        "slower; install gcc for compiled solvers",
        RuntimeWarning,
        stacklevel=3,
    )


def _cleanup() -> None:
    for directory in _BUILD_DIRS:
        shutil.rmtree(directory, ignore_errors=True)


atexit.register(_cleanup)


def jit_options(flags: tuple[str, ...] = COMPILER_FLAGS, background: bool = False) -> dict[str, Any]:
    """``nlpsol`` options for a compiled solver with the on-disk cache ({} without a compiler).

    Each call gets its own build directory (fixed file names inside it, so that the generated
    source is the same text in every process and the cache can match it). ``background=True``:
    a cache miss compiles in a detached process and the build raises, so that :func:`nlpsol`
    returns the uncompiled solver at once (the NMPC default: a first run on a machine is never
    held up for minutes; the next process gets the compiled solver).

    A cache directory that cannot be written warns once per process
    (:func:`controllers.disk_cache.writable`); a foreground build then compiles in this process
    without keeping the object, and ``background=True`` returns {} (uncompiled): a detached
    compile would have nowhere to put its object.
    """
    cc = compiler()
    if cc is None:
        _warn_no_compiler()
        return {}
    # probed in both modes, for the one warning; only a background build cannot do without it
    if not writable(solver_cache_dir()) and background:
        return {}
    build = tempfile.mkdtemp(prefix="koopnav-jit-")
    _BUILD_DIRS.append(build)
    # casadi's bundled stubs omit the module's __version__, which it has at runtime
    version: str = ca.__version__  # type: ignore[attr-defined]
    tag = hashlib.sha256(f"casadi {version}|{_identity(cc)}".encode()).hexdigest()[:16]
    command = f'"{sys.executable}" -S "{_WRAPPER}" --cache "{solver_cache_dir()}" --cc "{cc}" --tag {tag}' + (
        " --background" if background else ""
    )
    return {
        "jit": True,
        "compiler": "shell",
        # fixed names keep the generated text the same in every process (a temporary suffix also
        # renames symbols inside it, which defeats the cache); :func:`nlpsol` writes the source
        # into the build directory, not the working directory that worker processes share
        "jit_temp_suffix": False,
        # the build directory is removed as a whole at exit (CasADi's own cleanup would run after
        # it, during interpreter teardown, and warn about every file already gone)
        "jit_cleanup": False,
        "jit_options": {
            "compiler": command,
            "flags": list(flags),
            "directory": build + os.sep,
            "temp_suffix": False,
            "name": "nlp",
            "verbose": False,
            "cleanup": False,
        },
    }


@contextlib.contextmanager
def _working_directory(path: str) -> Iterator[None]:
    previous = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(previous)


#: Threads of the solvers' BLAS/OpenMP (CasADi's MUMPS and OpenBLAS), unless the user set
#: ``OMP_NUM_THREADS``. The NMPC problems are small and sparse: extra threads only contend, with
#: each other and with the evaluator's worker processes (N = 8 on the 2-core machine: 0.42 s of
#: system time in a 1.1 s IPOPT solve with two threads, 0.01 s with one), and one thread keeps the
#: floating-point order fixed. It takes effect only before the solver libraries load, i.e. before
#: the process's first ``nlpsol``.
SOLVER_THREADS = "1"


@functools.cache
def _thread_pools() -> ThreadpoolController:
    """The numerical libraries' thread pools loaded in this process (found once: a scan costs ms)."""
    return ThreadpoolController()


def blas_threads() -> contextlib.AbstractContextManager[Any]:
    """A context in which numpy's BLAS and LAPACK (OpenBLAS, MKL) run :data:`SOLVER_THREADS`
    threads, the others' count restored on leaving.

    Environment variables cannot do this for numpy: its BLAS has read them when numpy loaded,
    before KoopNav. The real-time iteration's dense stage blocks need it: from about 24 rows on
    OpenBLAS splits an eigendecomposition over its threads, which on the loaded 2-core machine
    made 20 blocks of 33 rows (a Koopman lift with memory or velocity) take 2.5 s instead of 73
    ms (0.22 s of CPU instead of 4 ms); the result is the same bits with one thread.
    """
    return _thread_pools().limit(limits=int(SOLVER_THREADS), user_api="blas")


def nlpsol(label: str, plugin: str, nlp: dict[str, Any], options: dict[str, Any]) -> ca.Function:
    """``casadi.nlpsol``; with :func:`jit_options` the generated source is written into the
    build's own directory (CasADi writes it to the working directory, under a fixed name)."""
    os.environ.setdefault("OMP_NUM_THREADS", SOLVER_THREADS)
    directory = options.get("jit_options", {}).get("directory") if options.get("jit") else None
    if not directory:
        return ca.nlpsol(label, plugin, nlp, options)
    try:
        with _working_directory(directory):
            return ca.nlpsol(label, plugin, nlp, options)
    except RuntimeError:
        if "--background" not in options["jit_options"].get("compiler", ""):
            raise
    # not in the cache yet: compiling in the background; this solver runs uncompiled
    _note_background_compile()
    plain = {k: v for k, v in options.items() if k not in _JIT_KEYS}
    return ca.nlpsol(label, plugin, nlp, plain)


_JIT_KEYS = ("jit", "compiler", "jit_options", "jit_temp_suffix", "jit_cleanup")


@functools.lru_cache(maxsize=1)
def _note_background_compile() -> None:
    warnings.warn(
        f"compiling an NMPC solver into {solver_cache_dir()} in the background (minutes, once per machine and "
        "problem structure); until it is there, solvers run uncompiled",
        RuntimeWarning,
        stacklevel=3,
    )
