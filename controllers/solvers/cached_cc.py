"""A C compiler command that caches object files by content (run as a script by CasADi's JIT).

CasADi's ``shell`` JIT compiler calls ``<compiler> <flags> -c SOURCE.c -o OUT.o``. This script
stands in for ``<compiler>``::

    python cached_cc.py --cache DIR --cc gcc --tag TAG [--background] <flags> -c SOURCE.c -o OUT.o

The object of a source is stored as ``DIR/<key>.o`` with its SHA-256 in ``DIR/<key>.o.sha256``,
where the key hashes the tag (CasADi version, compiler identity), the flags and the source text.
A hit copies the object (no compiler call); an entry whose checksum does not match is compiled
again and replaced. Entries are written to a temporary file and renamed, so concurrent
processes never read half an object; one process compiles a given source while the others wait.
With ``--background`` a miss does not compile in the caller's time: the source is handed to a
detached compile into the cache and the script exits with :data:`MISS_COMPILING_IN_BACKGROUND`,
so that the caller builds its solver uncompiled this once. Standalone on purpose: it runs once per compile in a fresh
interpreter and must not import the package (and CasADi) to do so.

The cache is optional (:mod:`controllers.disk_cache`): when it cannot be written, a compile step
still compiles (the object is only not kept) and a background miss still exits with
:data:`MISS_COMPILING_IN_BACKGROUND`; the caller's process warns about the cache.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time


def _digest(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def _store(directory: str, src: str, dst: str, text: str | None = None) -> None:
    """Copy ``src`` (or write ``text``) to ``dst`` atomically (temporary file + rename)."""
    fd, tmp = tempfile.mkstemp(dir=directory, suffix=".part")
    os.close(fd)
    try:
        if text is None:
            shutil.copyfile(src, tmp)
        else:
            with open(tmp, "w", encoding="ascii") as fh:
                fh.write(text)
        os.replace(tmp, dst)
    finally:
        if os.path.exists(tmp):
            try:
                os.remove(tmp)
            except OSError:
                pass  # the error that brought us here is the one to report


#: exit code of a miss in background mode: the caller builds its solver uncompiled this time
MISS_COMPILING_IN_BACKGROUND = 75


def main(argv: list[str]) -> int:
    settings = {}
    while argv and argv[0] in ("--cache", "--cc", "--tag", "--background", "--into-cache"):
        if argv[0] in ("--background", "--into-cache"):
            settings[argv[0][2:]] = "1"
            argv = argv[1:]
            continue
        settings[argv[0][2:]] = argv[1]
        argv = argv[2:]
    args = argv
    source = next((a for a in args if a.endswith(".c")), None)
    out = args[args.index("-o") + 1] if "-o" in args and args.index("-o") + 1 < len(args) else None
    compile_cmd = [*settings["cc"].split(), *args]
    if source is None or out is None or "-c" not in args:
        return subprocess.call(compile_cmd)  # not a compile step we know: just run the compiler
    flags = [a for a in args if a not in (source, out)]
    key = hashlib.sha256()
    for part in (settings.get("tag", ""), "\0".join(flags)):
        key.update(part.encode() + b"\0")
    with open(source, "rb") as fh:
        key.update(fh.read())
    directory = settings["cache"]
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError:
        # no cache (a path through a file, a read-only file system): compile here, uncached; in
        # background mode the caller goes on uncompiled, as on any miss
        return MISS_COMPILING_IN_BACKGROUND if settings.get("background") else subprocess.call(compile_cmd)
    entry = os.path.join(directory, key.hexdigest()[:32] + ".o")
    checksum = entry + ".sha256"
    if _copy_if_valid(entry, checksum, out):
        return 0
    if settings.get("background"):
        return _start_background_compile(settings, args, source, out, entry)
    # one compiler per source at a time: worker processes that build the same problem together
    # wait for the first one's object instead of compiling it again (minutes for a large NLP)
    try:
        lock = open(entry + ".lock", "a")  # noqa: SIM115 - closed by the with below
    except OSError:
        return subprocess.call(compile_cmd)  # a read-only cache: compile, keep nothing
    with lock:
        _lock(lock)
        if _copy_if_valid(entry, checksum, out):
            return 0
        code = subprocess.call(compile_cmd)
        if code == 0 and os.path.exists(out):
            # the object first, then its checksum: a reader that sees the object without a
            # matching checksum compiles again instead of trusting it
            try:
                _store(directory, out, entry)
                if settings.get("into-cache"):
                    # before the checksum, which completes the entry: whoever sees the entry
                    # complete sees no scratch left of its background compile
                    _remove_scratch(source, out)
                _store(directory, "", checksum, text=_digest(entry))
            except OSError:
                pass  # a full disk: the object is compiled, only not kept
    if settings.get("into-cache"):  # a background compile: its source and output were scratch
        _remove_scratch(source, out)
    return code


def _remove_scratch(*paths: str) -> None:
    """Remove a background compile's scratch files (its pending source and its output)."""
    for scratch in paths:
        if os.path.exists(scratch):
            os.remove(scratch)


def _start_background_compile(
    settings: dict[str, str], args: list[str], source: str, out: str, entry: str
) -> int:
    """A miss in background mode: compile into the cache in a detached process (minutes for a large
    NLP) and tell the caller to go on uncompiled; the next process that builds the problem hits."""
    directory = settings["cache"]
    pending = entry[: -len(".o")] + ".c"
    # a pending source older than an hour belongs to a compile that died: start it again
    if not os.path.exists(pending) or time.time() - os.path.getmtime(pending) > 3600:
        try:
            _store(directory, source, pending)
        except OSError:
            return MISS_COMPILING_IN_BACKGROUND  # the cache cannot take it: nothing to compile into
        # the same arguments with the pending source and a scratch output: the same key
        same = [pending if a == source else (entry + ".build" if a == out else a) for a in args]
        detached = [
            sys.executable,
            "-S",
            os.path.abspath(__file__),
            "--cache",
            directory,
            "--cc",
            settings["cc"],
            "--tag",
            settings.get("tag", ""),
            "--into-cache",
            *same,
        ]
        subprocess.Popen(
            detached,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            cwd=directory,
        )
    return MISS_COMPILING_IN_BACKGROUND


def _copy_if_valid(entry: str, checksum: str, out: str) -> bool:
    """Copy a cached object whose checksum matches to ``out``; False if there is none."""
    try:
        with open(checksum, encoding="ascii") as fh:
            expected = fh.read().strip()
        if _digest(entry) == expected:
            shutil.copyfile(entry, out)
            return True
    except OSError:
        pass  # no entry (or half of one)
    return False


def _lock(handle) -> None:
    """Exclusive advisory lock, released when the file closes (no-op where fcntl is missing)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: concurrent builds compile twice, still correct
        return
    fcntl.flock(handle.fileno(), fcntl.LOCK_EX)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
