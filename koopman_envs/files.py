"""The one reader and the one writer of every file KoopNav reads back or writes out.

Reading: :func:`read_bounded` reads a file only if it is a regular file of at most a given size,
checked before it is opened (a FIFO would block the open, ``/dev/zero`` would fill the memory) and
again on the open handle (the path may have been swapped meanwhile), then counted while it is
read in chunks (a file may grow while it is read). Baselines, thresholds, sweep manifests, episode
logs, results documents, published archives, map files and policy files all come through it; a
file that fails is refused with :class:`FileRefused` (a ``ValueError``), naming the file, what it
is, and the cap.

Writing: :func:`write_atomic` writes a report, a manifest, a figure or a cache entry into a
temporary file beside it, flushes it to the disk and renames it over the old one, so that an
interruption or a full disk leaves the old file whole (or none), never half a file; the error
names the file. The append-only episode log (:mod:`evaluation.episodes.runlog`) keeps its own rules.

This module is in the environments' base layer so that every package above (the controllers,
the baselines, the evaluator) reads and writes through it.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
from collections.abc import Callable
from pathlib import Path

__all__ = [
    "MAX_LOG_BYTES",
    "MAX_TEXT_BYTES",
    "FileRefused",
    "check_regular",
    "read_bounded",
    "read_text",
    "write_atomic",
]

_MIB = 2**20
#: Largest episode log or results document [bytes] (``episodes.jsonl``, ``results.json``, a
#: baseline): the largest published level's log is 10 MB; 256 MiB holds some 100,000 episodes with
#: every step's decision time, and bounds what the JSON parser (several times the text) builds.
MAX_LOG_BYTES = 256 * _MIB
#: Largest settings file [bytes] (a thresholds TOML, ``sweep.json``, ``pages.json``, a policy's
#: ``metadata.json``): the shipped ones are under 1 MB.
MAX_TEXT_BYTES = 16 * _MIB
#: Bytes read at a time: never one buffer of the whole cap.
_CHUNK = _MIB

#: what a path that is not a regular file is, by its mode
_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class FileRefused(ValueError):
    """A file KoopNav reads back is missing, unreadable, not a regular file, or over its cap.

    The message names the file (as what it was read for: a baseline, a thresholds file...), what
    it is, and the cap. A ``ValueError``: the command line answers it with exit 2, bad input.
    """


def _size(n: int) -> str:
    """``n`` bytes, with MiB for the reader."""
    return f"{n} bytes ({n / _MIB:.1f} MiB)" if n >= _MIB else f"{n} bytes"


def _refuse(path: str | os.PathLike[str], what: str, reason: str) -> FileRefused:
    return FileRefused(f"{what} {os.fspath(path)!r} cannot be read: {reason}")


def _unreadable(path: str | os.PathLike[str], what: str, exc: OSError) -> FileRefused:
    return FileRefused(f"{what} {os.fspath(path)!r} cannot be read ({exc.strerror or exc})")


def _check_status(path: str | os.PathLike[str], status: os.stat_result, limit: int, what: str) -> None:
    """Refuse a status that is not a regular file's, or one of more than ``limit`` bytes."""
    if not stat.S_ISREG(status.st_mode):
        kind = next((name for test, name in _KINDS if test(status.st_mode)), "not a file")
        raise _refuse(path, what, f"it is {kind}, not a regular file (only regular files are read)")
    if status.st_size > limit:
        raise _refuse(path, what, f"it is {_size(status.st_size)}; at most {_size(limit)} are allowed")


def check_regular(path: str | os.PathLike[str], limit: int, *, what: str = "file") -> os.stat_result:
    """The status of ``path``, a regular file of at most ``limit`` bytes; looked at, never opened.

    For a caller that opens the file itself in a mode that would block on a FIFO (an append-mode
    open waits for a reader forever).

    Parameters
    ----------
    path : str or path-like
        The file.
    limit : int
        Its largest allowed size [bytes].
    what : str
        What the file is read as, for the message (``"baseline"``, ``"episode log"``...).

    Raises
    ------
    FileRefused
        ``path`` is missing or cannot be looked at, is not a regular file, or is larger than
        ``limit``; the message names it, what it is and the cap.
    """
    try:
        status = os.stat(path)
    except OSError as exc:
        raise _unreadable(path, what, exc) from None
    _check_status(path, status, limit, what)
    return status


def read_bounded(path: str | os.PathLike[str], limit: int, *, what: str = "file") -> bytes:
    """The bytes of ``path``, a regular file of at most ``limit`` bytes.

    The file is looked at before it is opened (:func:`check_regular`), opened without blocking
    (``O_NONBLOCK``: a FIFO swapped in meanwhile cannot hang the open), looked at again on the open
    handle, and read in chunks counted against ``limit``.

    Parameters
    ----------
    path : str or path-like
        The file.
    limit : int
        Its largest allowed size [bytes].
    what : str
        What the file is read as, for the message.

    Raises
    ------
    FileRefused
        As :func:`check_regular`, or the file cannot be read, or grew beyond ``limit`` while read.
    """
    check_regular(path, limit, what=what)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    parts, total = [], 0
    try:
        fd = os.open(path, flags)
        with os.fdopen(fd, "rb", buffering=0) as handle:
            _check_status(path, os.fstat(handle.fileno()), limit, what)
            while chunk := handle.read(_CHUNK):
                total += len(chunk)
                if total > limit:
                    raise _refuse(path, what, f"it grew beyond {_size(limit)} while read, the most allowed")
                parts.append(chunk)
    except OSError as exc:
        raise _unreadable(path, what, exc) from None
    return b"".join(parts)


def read_text(
    path: str | os.PathLike[str], limit: int, *, what: str = "file", expected: str = "UTF-8 text"
) -> str:
    """The text of ``path`` (UTF-8), read by :func:`read_bounded`.

    Parameters
    ----------
    path, limit, what
        As :func:`read_bounded`.
    expected : str
        What the file should hold, for the message of a file that is not text (``"a results.json
        (UTF-8 JSON)"``).

    Raises
    ------
    FileRefused
        As :func:`read_bounded`, or the bytes are not UTF-8 text: the message names the file,
        where the first bad byte is, and what was expected.
    """
    data = read_bounded(path, limit, what=what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        bad = data[exc.start : exc.start + 1]
        raise FileRefused(
            f"{what} {os.fspath(path)!r} is not UTF-8 text (byte {exc.start} is {bad!r}); expected {expected}"
        ) from None


#: the flags of a temporary file: made here or not at all (``O_EXCL``), never through a symbolic
#: link, not inherited by child processes, binary on Windows (as :func:`tempfile.mkstemp`'s)
_TEMP_FLAGS = (
    os.O_RDWR
    | os.O_CREAT
    | os.O_EXCL
    | getattr(os, "O_NOFOLLOW", 0)
    | getattr(os, "O_CLOEXEC", 0)
    | getattr(os, "O_NOINHERIT", 0)
    | getattr(os, "O_BINARY", 0)
)
#: names tried for a temporary file before giving up (as :func:`tempfile.mkstemp`)
_TEMP_TRIES = 100


def _make_temporary(folder: Path, prefix: str, suffix: str) -> tuple[int, str]:
    """A new file ``folder/prefix<random>suffix``, opened for writing: (its descriptor, its path).

    Made with mode 0o666 for the kernel to take the umask off (and apply a folder's default
    ACL), the mode a plain ``open(path, "w")`` gives. The umask is never read: the only way is to
    set it (``os.umask``) and set it back, and a thread that makes a file in between would make
    it with the wrong mode (:func:`tempfile.mkstemp` makes 0o600 files, which were then chmod'ed
    to ``0o666 & ~umask`` read that way).
    """
    for _ in range(_TEMP_TRIES):
        name = os.path.join(folder, f"{prefix}{secrets.token_hex(6)}{suffix}")
        try:
            return os.open(name, _TEMP_FLAGS, 0o666), name
        except FileExistsError:
            continue
    raise FileExistsError(
        errno.EEXIST, f"no free temporary file name in {_TEMP_TRIES} tries", os.fspath(folder)
    )


def write_atomic(
    path: str | os.PathLike[str],
    content: str | bytes | Callable[[str], object],
    *,
    encoding: str = "utf-8",
    suffix: str | None = None,
) -> Path:
    """Write ``path`` whole or not at all: a temporary file beside it, flushed to the disk, renamed over it.

    Parameters
    ----------
    path : str or path-like
        The file; its folder is made if missing.
    content : str, bytes or callable
        The text (encoded with ``encoding``), the bytes, or ``write(temporary_path)``, a writer of
        its own (a figure's ``savefig``); the temporary file keeps ``path``'s suffix (or
        ``suffix``), by which such writers pick the format.
    encoding : str
        The encoding of a text ``content``.
    suffix : str, optional
        The temporary file's suffix (default: ``path``'s).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OSError
        The folder cannot be made, or the write, flush or rename failed (no space left, no
        permission, read-only file system): of the same errno, naming ``path``, which is left as
        it was (the temporary file removed).
    """
    path = Path(path)
    tmp: str | None = None
    fd: int | None = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # the mode a plain open would give it (0o666 less the umask, applied by the kernel)
        fd, tmp = _make_temporary(path.parent, f".{path.name}.", path.suffix if suffix is None else suffix)
        if callable(content):
            os.close(fd)
            fd = None
            content(tmp)
            fd = os.open(tmp, os.O_RDONLY)  # the writer closed its own handle: flush through a new one
        else:
            view = memoryview(content.encode(encoding) if isinstance(content, str) else content)
            while view:  # os.write may write less than asked
                view = view[os.write(fd, view) :]
        os.fsync(fd)  # on the disk before the rename: a crash then leaves the old file or the new one
        os.close(fd)
        fd = None
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        raise OSError(
            exc.errno, f"{exc.strerror or exc}; {path} was left as it was", os.fspath(path)
        ) from exc
    finally:
        if fd is not None:
            os.close(fd)
        if tmp is not None:
            with contextlib.suppress(OSError):  # a torn temporary file must not stay
                os.remove(tmp)
    return path
