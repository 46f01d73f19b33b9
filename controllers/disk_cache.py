"""The package's on-disk cache: one root for calibrations and compiled solvers, and atomic writes into it."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["cache_root", "write_atomic"]


def cache_root() -> Path:
    """``$KOOPNAV_CACHE``, default ``~/.cache/koopnav``."""
    return Path(os.environ.get("KOOPNAV_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "koopnav"))


def write_atomic(path: Path, write: Callable[[str], object], suffix: str) -> None:
    """Write through a temporary file and rename, so that concurrent workers never read half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=suffix)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
