"""The episode log of a run (``OUT/episodes.jsonl``): a header naming the run's settings, then one
JSON line per finished episode, flushed at once, so that an interrupted run can be resumed.

Reading a log back trusts nothing in it: a line cut by a kill is repaired (cut off, reported, its
episode run again), and a line that cannot be read, or a record that is not an episode of this run,
refuses the resume with its line number, so that no result is lost or taken on faith. An episode
logged twice is read once, and refused with both line numbers when its two records disagree
(:func:`evaluation.episodes.distinct.read_once`).
"""

from __future__ import annotations

import itertools
import json
import os
import sys
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from evaluation.episodes.distinct import ConflictingRecords, read_once
from evaluation.episodes.log_weights import check_weights, signed_weights, without_weights
from evaluation.episodes.records import json_safe, record_problem
from koopman_envs.checks import differing_settings, parse_json
from koopman_envs.files import MAX_LOG_BYTES, check_regular, read_bounded, write_atomic

__all__ = [
    "DEFAULT_OUT",
    "RESUME_KEYS",
    "LogError",
    "OutputNotWritable",
    "RunLocked",
    "cut_torn",
    "ensure_output_dir",
    "forget_controllers",
    "open_append_locked",
    "open_log",
    "output_directory",
    "parse_lines",
    "read_log",
    "run_signature",
    "split_lines",
]

#: settings that must match for a resume (everything that changes what an episode does)
RESUME_KEYS = (
    "env_ids",
    "controller_configs",
    "maps",
    "map_files",
    "slips",
    "episodes",
    "random_maps",
    "seed",
    "env_settings",
    "calibration",
    "gifs",
)


class LogError(ValueError):
    """An episode log that cannot be resumed as it is (named by file and line)."""


class RunLocked(ValueError):
    """Another run is writing the same episode log (two runs on one ``--out``)."""


class OutputNotWritable(OSError):
    """The output directory cannot be made or written (refused before any episode runs)."""


#: ``--out`` when none is given (:func:`output_directory`), relative to the working directory
DEFAULT_OUT = "results"


def output_directory(out: str | None, resume: bool) -> str:
    """The run's directory: ``out`` when given (one that holds a run is refused by
    :func:`open_log` unless ``resume``); else :data:`DEFAULT_OUT`, or, when that holds
    something and the run does not resume it, the first of ``results-2``, ``results-3``, ...
    that holds nothing, so that the same command run twice runs twice and keeps the first run."""
    if out is not None:
        return out
    if resume:
        return DEFAULT_OUT
    names = itertools.chain([DEFAULT_OUT], (f"{DEFAULT_OUT}-{n}" for n in itertools.count(2)))
    return next(name for name in names if _holds_nothing(Path(name)))


def _holds_nothing(path: Path) -> bool:
    """Nothing at ``path``, or an empty directory (a symlink, even to one, holds something)."""
    if path.is_symlink():
        return False
    return not path.exists() or (path.is_dir() and not any(path.iterdir()))


def ensure_output_dir(out: str | os.PathLike[str]) -> Path:
    """``out`` as a directory this process can write, made if missing.

    Raises
    ------
    OutputNotWritable
        ``out`` is a file, cannot be made, or a file cannot be created in it (read-only, no
        permission, no space), with the reason.
    """
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputNotWritable(f"--out {os.fspath(out)!r} is a file; it must be a directory (or a new path)")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        # a real write: permission bits alone do not tell (root, read-only mounts, full disks)
        with tempfile.TemporaryFile(dir=out_dir):
            pass
    except OSError as exc:
        raise OutputNotWritable(
            f"--out {os.fspath(out)!r} cannot be made a directory this run can write: "
            f"{exc.strerror or exc}; choose another --out"
        ) from None
    return out_dir


def _lock(handle: IO[str], log: Path) -> None:
    """Hold an exclusive lock on the open log until ``handle`` closes (or the process ends), so
    that a second run on the same ``--out`` is refused instead of running the same episodes."""
    try:
        if sys.platform == "win32":
            import msvcrt

            msvcrt.locking(handle.fileno(), msvcrt.LK_NBLCK, 1)
        else:
            import fcntl

            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        raise RunLocked(
            f"{log} is being written by another run (it holds the log's lock); wait for it to "
            "finish or stop it, or choose another --out; nothing was changed"
        ) from None


def run_signature(config: dict[str, Any]) -> dict[str, Any]:
    """The parts of a run configuration that must match for a resume (plain JSON); a
    compute-aware run's scale and machine too (decision times of two machines do not mix; absent
    from a free-compute run's, as in logs written before the mode existed), and a suite run's
    suite."""
    signature = {k: config.get(k) for k in RESUME_KEYS}
    if config.get("compute"):
        signature["compute"] = config["compute"]
    # a suite run's suite (name, version, split, selection, each task's split hash): a log of
    # another suite version is another run (absent from other runs', as in logs written before)
    if config.get("suite"):
        signature["suite"] = config["suite"]
    signature.update(signed_weights(config))  # the learned controllers' (evaluation.episodes.log_weights)
    return json.loads(json.dumps(json_safe(signature)))


def _header_line(config: dict[str, Any]) -> bytes:
    """The first line of a run's log, as written (with its newline)."""
    return (json.dumps({"kind": "koopnav-run", "config": run_signature(config)}) + "\n").encode()


def _adds_controllers(theirs: Any, ours: dict[str, Any]) -> list[str] | None:
    """The labels a run with signature ``ours`` adds to the logged run ``theirs`` when it is the
    same run with more controllers (every other setting equal, every logged controller kept with
    its options); None otherwise."""
    if not isinstance(theirs, dict) or set(theirs) != set(ours):
        return None
    if any(theirs[k] != ours[k] for k in ours if k != "controller_configs"):
        return None
    logged, now = theirs.get("controller_configs"), ours.get("controller_configs") or []
    if not isinstance(logged, list) or any(c not in now for c in logged):
        return None
    return [c["label"] for c in now if c not in logged]


def _check_header(log: Path, first: bytes, config: dict[str, Any]) -> tuple[list[str], dict[str, Any]]:
    """Refuse a log whose first line is not this run's header; the labels this run adds to the
    logged one (an empty list for the same run) and the logged signature (weights apart)."""
    try:
        header = parse_json(first, f"{log} line 1")
    except ValueError:  # not JSON, not UTF-8, or nested beyond any header
        raise LogError(
            f"{log} is not a KoopNav episode log (line 1 is not JSON); nothing was overwritten"
        ) from None
    ours = without_weights(run_signature(config))
    logged = isinstance(header, dict) and header.get("kind") == "koopnav-run" and header.get("config") or None
    theirs = without_weights(logged)
    if theirs == ours:
        return [], logged  # type: ignore[return-value]
    added = _adds_controllers(theirs, ours)
    if added:
        return added, logged  # type: ignore[return-value]
    if isinstance(theirs, dict):
        what = differing_settings(theirs, ours)
    else:
        what = "line 1 is not a KoopNav run header"
    raise LogError(
        f"{log} belongs to a run with other settings ({what}); use the same options to resume, "
        "or another --out directory; nothing was overwritten"
    )


def _read(log: Path) -> bytes:
    """The log's bytes: a regular file of at most :data:`koopman_envs.files.MAX_LOG_BYTES`, refused
    unread otherwise (a FIFO given as the log hung ``--resume`` forever)."""
    return read_bounded(log, MAX_LOG_BYTES, what="episode log")


def _replace_log(path: Path, data: bytes) -> None:
    """Replace the log's bytes through a temporary file beside it (a kill leaves the old log or
    the new one, never a mix: :func:`koopman_envs.files.write_atomic`)."""
    write_atomic(path, data)


def _rewrite_header(path: Path, config: dict[str, Any]) -> None:
    """Give the log this run's header, every record byte for byte."""
    data = _read(path)
    _replace_log(path, _header_line(config) + data[data.index(b"\n") + 1 :])


def _record_problem(rec: Any, expected: Mapping[str, Mapping[str, Any]] | None) -> str | None:
    """Why ``rec`` is not an episode record of this run (None when it is one)."""
    problem = record_problem(rec)
    if problem is not None or expected is None:
        return problem
    fields = expected.get(rec["key"])
    if fields is None:
        return f"episode {rec['key']!r} is not one of this run's episodes"
    differ = sorted(k for k, v in fields.items() if rec.get(k) != v)
    if differ:
        return f"episode {rec['key']!r} was run with other settings ({', '.join(differ)})"
    return None


def split_lines(data: bytes) -> tuple[list[bytes], bytes]:
    """The complete lines of a JSON-lines file and its torn last piece (``b""`` when none).

    A log ends with a newline after every complete line, so the last piece after the final
    newline is empty unless a kill cut the final write short: that piece is torn, whatever it
    looks like (it may even parse as JSON).
    """
    lines = data.split(b"\n")
    return lines, lines.pop()


def parse_lines(
    lines: Sequence[bytes], problem: Callable[[Any], str | None], first: int = 2
) -> tuple[list[Any], list[str], list[str]]:
    """Parse the record lines of a JSON-lines log (the one parser of every KoopNav log).

    Parameters
    ----------
    lines : sequence of bytes
        Complete lines (:func:`split_lines`), the header excluded.
    problem : callable
        Why a parsed record is not one of this log's (None when it is one).
    first : int
        The line number of ``lines[0]`` in the file (2: after the header).

    Returns
    -------
    records : list
        The good records, in order.
    places : list of str
        ``"line N"`` of each good record.
    bad : list of str
        ``"line N: why"`` of each line that is not JSON or not a record of this log.
    """
    records: list[Any] = []
    places: list[str] = []
    bad: list[str] = []
    for number, raw in enumerate(lines, start=first):
        try:
            rec = parse_json(raw, "the record")
        except ValueError as exc:  # not JSON (or not UTF-8), or nested beyond any record
            bad.append(f"line {number}: not JSON ({getattr(exc, 'msg', exc)})")
            continue
        why = problem(rec)
        if why is not None:
            bad.append(f"line {number}: {why}")
            continue
        records.append(rec)
        places.append(f"line {number}")
    return records, places, bad


def cut_torn(path: str | os.PathLike[str], data: bytes, torn: bytes) -> None:
    """Cut the torn last piece ``torn`` off the log ``path`` whose bytes were ``data``, so that
    the next record starts on a line of its own."""
    with open(path, "r+b") as handle:
        handle.truncate(len(data) - len(torn))


def read_log(
    log: str | os.PathLike[str],
    config: dict[str, Any],
    expected: Mapping[str, Mapping[str, Any]] | None = None,
    *,
    repair: bool = True,
) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """Finished episodes of a previous run with the same settings, and notes on what was repaired.

    Parameters
    ----------
    log : path
        The run's ``episodes.jsonl``.
    config : dict
        The run's configuration; its resume signature must equal the log header's.
    expected : mapping, optional
        Episode key -> the fields its record must carry (:meth:`EpisodeSpec.record_fields`); a
        record of another key or other fields is refused.
    repair : bool
        Cut a torn last line (one a kill left without its newline) off the file.

    Returns
    -------
    done : dict
        Episode key -> its record (an episode logged twice alike is read once,
        :func:`evaluation.episodes.distinct.read_once`).
    notes : list of str
        What was repaired, for the user (e.g. the dropped incomplete record).

    Raises
    ------
    LogError
        The header is not this run's, a complete line is not JSON, a record is not an episode
        of this run, or two records of one episode disagree in their outcome: each named by its
        line number. Nothing is changed in the file then.
    """
    path = Path(log)
    data = _read(path)
    notes: list[str] = []
    lines, torn = split_lines(data)
    if not lines:  # the kill came while the header was written: nothing was finished
        if not _header_line(config).startswith(torn):
            raise LogError(f"{path} is not a KoopNav episode log (its only line is not a run header)")
        if repair:
            _replace_log(path, _header_line(config))
        return {}, [f"{path}: the header line was cut by the interruption; it was written again"]
    added, logged = _check_header(path, lines[0], config)
    records, places, bad = parse_lines(lines[1:], lambda rec: _record_problem(rec, expected))
    if not bad:
        try:
            once = read_once(records, str(path), places)
        except ConflictingRecords as exc:
            bad.append(str(exc).removeprefix(f"{path}: "))
    if bad:
        raise LogError(
            f"{path} cannot be resumed: "
            + "; ".join(bad[:10])
            + (f"; and {len(bad) - 10} more" if len(bad) > 10 else "")
            + ". It is not this run's log as KoopNav wrote it; resume into another --out, or move "
            "the file aside to start afresh (nothing was changed)"
        )
    kept = check_weights(path, logged, config, once, LogError, notes)  # other weights: refused
    # an episode logged twice alike is one episode (evaluation.episodes.distinct.read_once)
    done = {rec["key"]: rec for rec in once}
    if len(once) < len(records):
        notes.append(
            f"{path}: {len(records) - len(once)} record(s) repeat an episode logged before, outcome for "
            "outcome; each episode is read once"
        )
    if torn:
        if repair:
            cut_torn(path, data, torn)
        notes.append(
            f"{path}: dropped 1 incomplete record (line {len(lines) + 1}, {len(torn)} bytes cut by "
            "the interruption); it will be run again"
        )
    if (added or run_signature(kept) != logged) and repair:  # added, or a new digest of one unplayed
        _rewrite_header(path, kept)
    if added:
        notes.append(
            f"{path}: this run adds {', '.join(added)} to the logged run's controllers; their episodes "
            "run now, the logged ones are kept"
        )
    return done, notes


def _open_append(log: Path, what: str = "episode log") -> IO[str]:
    """The log opened for appending (never truncated: another run may be writing it). An existing
    log must be a regular file within the cap before it is opened (an append-mode open of a FIFO
    waits for a reader forever), and the open does not block either (``O_NONBLOCK``: a FIFO put
    there meanwhile fails the open instead)."""
    if os.path.lexists(log):
        check_regular(log, MAX_LOG_BYTES, what=what)
    flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NONBLOCK", 0)
    try:
        return os.fdopen(os.open(log, flags, 0o666), "a", encoding="utf-8")
    except OSError as exc:
        raise OutputNotWritable(f"{log} cannot be opened for writing: {exc.strerror or exc}") from None


def open_append_locked(log: str | os.PathLike[str], what: str) -> IO[str]:
    """A JSON-lines log (``what``, e.g. ``"study log"``) opened for appending and locked while
    open, as the episode log is (:func:`open_log`): a regular file within
    :data:`~koopman_envs.files.MAX_LOG_BYTES`, never truncated, and a second writer refused with
    :class:`RunLocked`.

    Raises
    ------
    OutputNotWritable, RunLocked, koopman_envs.files.FileRefused
        As :func:`open_log`.
    """
    handle = _open_append(Path(log), what)
    _lock(handle, Path(log))
    return handle


def open_log(
    out: str | os.PathLike[str],
    config: dict[str, Any],
    resume: bool,
    expected: Mapping[str, Mapping[str, Any]] | None = None,
) -> tuple[IO[str], dict[str, dict[str, Any]]]:
    """Open the run's log for appending; return it with the episodes a previous run finished.

    A torn last line is cut off first (reported on stderr), so that the next record starts on a
    line of its own.

    The log stays locked while it is open: a second run on the same ``out`` is refused
    (:class:`RunLocked`) instead of running the same episodes.

    Raises
    ------
    OutputNotWritable
        ``out`` is not a directory this process can make and write.
    ValueError
        A log exists and ``resume`` is false, another run holds it (:class:`RunLocked`), or it
        cannot be resumed (:class:`LogError`).
    """
    log = ensure_output_dir(out) / "episodes.jsonl"
    handle = _open_append(log)
    _lock(handle, log)
    try:
        if log.stat().st_size > 0:
            if not resume:
                raise ValueError(f"{log} exists: pass --resume to continue that run, or choose another --out")
            inode = os.fstat(handle.fileno()).st_ino
            done, notes = read_log(log, config, expected)
            for note in notes:
                print(f"note: {note}", file=sys.stderr)
            if os.stat(log).st_ino != inode:  # the header was rewritten into a new file
                handle.close()
                handle = _open_append(log)
                _lock(handle, log)
            return handle, done
        handle.write(_header_line(config).decode())
        handle.flush()
    except BaseException:
        handle.close()
        raise
    return handle, {}


def forget_controllers(out: str | os.PathLike[str], labels: Sequence[str]) -> int:
    """Drop the records of the controllers ``labels`` from every episode log under ``out`` (a
    run's or a sweep's directory), so that ``--resume`` runs their episodes again: after a change
    of those controllers that changes what they do, their rows are republished without rerunning
    anyone else's. Each log keeps its header and every other line byte for byte; it is rewritten
    through a temporary file (a kill leaves the old log or the new one, never a mix) while holding
    the log's lock (a run writing it is refused, :class:`RunLocked`).

    Returns
    -------
    int
        Records dropped.

    Raises
    ------
    LogError
        A log under ``out`` with a line that is not a JSON record (named by file and line).
    """
    dropped = 0
    wanted = set(labels)
    logs = sorted(Path(out).rglob("episodes.jsonl"))
    if not logs:
        raise LogError(f"no episode log (episodes.jsonl) under {out}")
    for log in logs:
        with _open_append(log) as handle:
            _lock(handle, log)
            lines = _read(log).splitlines(keepends=True)
            kept = lines[:1]
            for number, line in enumerate(lines[1:], start=2):
                try:
                    rec = parse_json(line, f"{log} line {number}")
                except ValueError:  # not JSON (or not UTF-8), or nested beyond any record
                    raise LogError(
                        f"{log}: line {number} is not a JSON record; nothing was changed"
                    ) from None
                if isinstance(rec, dict) and rec.get("controller") in wanted:
                    dropped += 1
                else:
                    kept.append(line)
            if len(kept) != len(lines):
                _replace_log(log, b"".join(kept))
    return dropped
