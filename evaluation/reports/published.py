"""Published data: the episode logs behind every results page, in the repository as
``data/NAME.tar.xz`` (each run's ``episodes.jsonl`` and, for a sweep, its ``sweep.json``;
``bash data/publish.sh pack`` writes them), read back checked so that a page's generator rebuilds
the page from them byte for byte.

xz (LZMA, Python's standard ``lzma``: no extra dependency, read by ``tar -xJf`` and pandas alike)
holds the same logs in a third of gzip's size (57.8 MB of ``.tar.gz`` became 26.4 MB). What is
left is the records' full-precision floats (poses, distances, timings: about 40 per episode at
8 bytes of entropy each), which stay unrounded because resumed runs and the bit-identity checks
compare them exactly.

An episode log is JSON lines: a header ``{"kind": "koopnav-run", "config": {...}}`` with the
run's settings, then one record per episode (the fields of ``docs/results.schema.json``). In
pandas::

    import json, tarfile
    import pandas as pd

    with tarfile.open("data/paper_realistic.tar.xz") as archive:
        member = archive.extractfile("paper_realistic/sweep/uncertainty-realistic/episodes.jsonl")
        lines = member.read().decode().splitlines()
    episodes = pd.DataFrame([json.loads(line) for line in lines[1:]])
    episodes.groupby("controller")["success"].mean()

Reading an archive back trusts nothing in it (:func:`extract_archive`): the file must be a regular
file of bounded size; its members are streamed, each checked before a byte of it is written (a
directory or an episode log or sweep manifest, at a relative path inside the extraction directory:
no absolute path, ``..``, link or device; one top directory, the run's), with their number, each
one's size, the total unpacked and the compression ratio bounded as the bytes come (the ``MAX_*``
limits below, in the policy loader's style, :mod:`baselines.safe_load`), so a decompression bomb
is stopped within its first megabytes; :func:`evaluation.reports.publications.extracted_archive` unpacks into a
temporary directory removed after use, a single archive or a publication split per controller
(:mod:`evaluation.reports.publications`, whose parts are each read back by :func:`extract_archive`).
"""

from __future__ import annotations

import functools
import importlib
import io
import json
import lzma
import os
import shutil
import tarfile
import warnings
from collections.abc import Iterable
from pathlib import Path, PurePosixPath
from typing import IO, Any

from evaluation.episodes.distinct import read_once
from evaluation.episodes.records import record_problem
from evaluation.reports.results import Results
from koopman_envs.checks import parse_json
from koopman_envs.deprecation import REMOVAL
from koopman_envs.files import MAX_LOG_BYTES, read_bounded, read_text, write_atomic

__all__ = [
    "ARCHIVE_SUFFIX",
    "MAX_ARCHIVE_BYTES",
    "MAX_MEMBERS",
    "MAX_MEMBER_BYTES",
    "MAX_RATIO",
    "MAX_TOTAL_BYTES",
    "PACKED_OUT",
    "RATIO_FLOOR",
    "extract_archive",
    "is_archive",
    "pack_run",
    "packed_log",
    "packed_member",
    "results_from_log",
    "run_files",
    "tar_xz",
]

_MIB = 2**20
#: Largest published archive [bytes], read whole before it is unpacked: the largest committed one
#: (robustness) is 5.8 MB.
MAX_ARCHIVE_BYTES = 64 * _MIB
#: Largest number of members: a sweep's manifest and one log per level (the largest holds 14).
MAX_MEMBERS = 256
#: Largest unpacked member [bytes]: an episode log, which is then read whole
#: (:data:`koopman_envs.files.MAX_LOG_BYTES`; the largest committed one is 9.8 MB).
MAX_MEMBER_BYTES = MAX_LOG_BYTES
#: Largest total unpacked [bytes], tar headers included: ten times the largest committed archive (51 MB).
MAX_TOTAL_BYTES = 512 * _MIB
#: Largest ratio of the bytes unpacked to the compressed bytes read so far, beyond
#: :data:`RATIO_FLOOR`: the committed archives unpack at 5-10:1; beyond 100:1 the payload is runs
#: of one byte, a decompression bomb's (229 KB of xz once unpacked to 1.5 GB).
MAX_RATIO = 100
#: Bytes unpacked before the ratio is checked: a small archive's fixed costs (tar headers and
#: padding, xz's blocks) may compress beyond :data:`MAX_RATIO` and cost nothing.
RATIO_FLOOR = _MIB
#: the member files a published archive holds (directories aside)
_MEMBER_NAMES = ("episodes.jsonl", "sweep.json")
#: the magic bytes an xz stream starts with
_XZ_MAGIC = b"\xfd7zXZ\x00"
#: bytes unpacked at a time
_CHUNK = _MIB

#: how a published archive's name ends
ARCHIVE_SUFFIX = ".tar.xz"

#: record fields a published log leaves out: every step's decision time (the per-episode median
#: and 95th percentile stay; a cell's p95 then comes from them), a third of the packed size
PACKED_OUT = ("solve_ms",)


#: names that moved to :mod:`evaluation.reports.publications` (issue 61, with the split form),
#: read here for one release with a DeprecationWarning (CHANGELOG.md)
_MOVED = ("extracted_archive", "unpack_run")


def __getattr__(name: str) -> Any:
    """:data:`_MOVED`'s names at their old path, with a warning naming the new one."""
    if name in _MOVED:
        warnings.warn(
            f"evaluation.reports.published.{name} is deprecated and will be removed in KoopNav {REMOVAL}; "
            f"import it from evaluation.reports.publications (it reads split publications too)",
            DeprecationWarning,
            stacklevel=2,
        )
        # by name, not an import statement: publications imports this module
        return getattr(importlib.import_module("evaluation.reports.publications"), name)
    raise AttributeError(f"module 'evaluation.reports.published' has no attribute {name!r}")


def _plan_order(config: dict[str, Any]) -> Any:
    """Sort key of a record in the order the run planned its episodes (env, controller, map,
    slip, trial), so that a page does not depend on the order workers finished in."""
    envs = list(config.get("env_ids") or [])
    labels = [c.get("label") for c in config.get("controller_configs") or []]
    maps = config.get("maps") or {}
    slips = list(config.get("slips") or [])

    def key(record: dict[str, Any]) -> tuple:
        env = record["env_id"]
        env_maps = list(maps.get(env, []))
        return (
            envs.index(env) if env in envs else len(envs),
            labels.index(record["controller"]) if record["controller"] in labels else len(labels),
            env_maps.index(record["map"]) if record["map"] in env_maps else len(env_maps),
            slips.index(record["slip"]) if record["slip"] in slips else len(slips),
            record["trial"],
        )

    return key


def results_from_log(path: str | Path) -> Results:
    """A run's results from its episode log: the header's settings and every record, each
    checked (:func:`evaluation.episodes.records.record_problem`; a torn or foreign line is refused by
    its number), in the run's planned order; an episode logged twice is read once, and refused
    (:class:`~evaluation.episodes.distinct.ConflictingRecords`, a ``ValueError``) when its two records
    disagree (:func:`evaluation.episodes.distinct.read_once`). The log is read as
    :func:`koopman_envs.files.read_text` reads (a regular file of at most
    :data:`koopman_envs.files.MAX_LOG_BYTES`)."""
    path = Path(path)
    text = read_text(path, MAX_LOG_BYTES, what="episode log", expected="a KoopNav episode log (JSON lines)")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    try:
        header = parse_json(lines[0], f"{path}, line 1") if lines else None
    except ValueError:  # not JSON (a JSONDecodeError) or nested past the bound: not a header
        header = None
    if not isinstance(header, dict) or header.get("kind") != "koopnav-run":
        raise ValueError(f"{path} is not a KoopNav episode log (line 1 is not a run header)")
    config = dict(header["config"])
    config["controllers"] = [c["label"] for c in config.get("controller_configs") or []]
    records: list[dict[str, Any]] = []
    for number, line in enumerate(lines[1:], start=2):
        try:
            record = parse_json(line, f"{path}, line {number}")
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}, line {number}: not JSON ({exc.msg})") from None
        problem = record_problem(record)
        if problem is not None:
            raise ValueError(f"{path}, line {number}: {problem}")
        records.append(record)
    once = read_once(records, str(path), [f"line {number}" for number in range(2, len(records) + 2)])
    return Results(sorted(once, key=_plan_order(config)), config)


def is_archive(path: str | Path) -> bool:
    """Whether ``path`` names a published archive (``*.tar.xz``, :data:`ARCHIVE_SUFFIX`)."""
    return str(path).endswith(ARCHIVE_SUFFIX)


def _check_name(archive: Path) -> None:
    if not is_archive(archive):
        raise ValueError(f"{archive}: a published archive's name ends in {ARCHIVE_SUFFIX!r}")


class _Counted:
    """A binary stream that counts the bytes read from it."""

    def __init__(self, stream: io.BufferedIOBase) -> None:
        self.stream, self.count = stream, 0

    def read(self, size: int = -1) -> bytes:
        data = self.stream.read(size)
        self.count += len(data)
        return data


class _Bounded:
    """The unpacked tar stream of an xz archive, refused as soon as what it has unpacked exceeds
    :data:`MAX_TOTAL_BYTES`, or :data:`MAX_RATIO` times the compressed bytes read (beyond
    :data:`RATIO_FLOOR`): every byte tarfile reads (headers included) comes through here."""

    def __init__(self, blob: bytes, archive: Path) -> None:
        self.packed = _Counted(io.BytesIO(blob))
        self.xz = lzma.LZMAFile(self.packed)  # type: ignore[arg-type]  # reads like a file
        self.archive, self.count = archive, 0

    def read(self, size: int = -1) -> bytes:
        data = self.xz.read(min(size, _CHUNK) if size >= 0 else _CHUNK)
        self.count += len(data)
        if self.count > MAX_TOTAL_BYTES:
            raise ValueError(
                f"{self.archive}: unpacks to more than {MAX_TOTAL_BYTES} bytes, the most allowed "
                "(evaluation.reports.published.MAX_TOTAL_BYTES); nothing more was unpacked"
            )
        if self.count > RATIO_FLOOR and self.count > MAX_RATIO * self.packed.count:
            raise ValueError(
                f"{self.archive}: {self.packed.count} compressed bytes unpack to {self.count} and more, "
                f"beyond {MAX_RATIO}:1 (evaluation.reports.published.MAX_RATIO): the mark of a decompression "
                "bomb; nothing more was unpacked"
            )
        return data


def _member_parts(archive: Path, member: tarfile.TarInfo) -> tuple[str, ...]:
    """The path of ``member`` below the extraction directory, as parts; refused by name when it
    is not a directory or a regular file, would land outside (absolute, ``..``), or is a file
    outside a run's directory."""
    name = PurePosixPath(member.name)
    parts = name.parts  # pathlib has dropped the empty and "." parts ("a//./b" is ("a", "b"))
    if name.is_absolute() or ".." in parts or not parts or "\\" in member.name:
        raise ValueError(
            f"{archive}: member {member.name!r} would land outside the extraction directory (an absolute "
            "path or '..'); a published archive holds relative paths only"
        )
    if member.isdir():
        return parts
    kinds = ((member.issym, "a symbolic link"), (member.islnk, "a hard link"), (member.isdev, "a device"))
    kind = next((what for test, what in kinds if test()), None)
    if kind is not None or not member.isfile():
        raise ValueError(
            f"{archive}: member {member.name!r} is {kind or 'not a regular file'}; a published archive "
            "holds regular files only"
        )
    if parts[-1] not in _MEMBER_NAMES:
        raise ValueError(f"{archive}: member {member.name!r} is not an episode log or a sweep manifest")
    if len(parts) < 2:  # the run's directory would be this file: unpack_run then restored nothing
        raise ValueError(
            f"{archive}: member {member.name!r} is not inside a run's directory; a published archive "
            "holds one run's directory (RUN/episodes.jsonl, RUN/sweep.json, RUN/sweep/LEVEL/...)"
        )
    if member.size > MAX_MEMBER_BYTES:
        raise ValueError(
            f"{archive}: member {member.name!r} unpacks to {member.size} bytes; at most "
            f"{MAX_MEMBER_BYTES} per member are allowed (evaluation.reports.published.MAX_MEMBER_BYTES)"
        )
    return parts


def _unpack(archive: Path, tar: tarfile.TarFile, target: Path) -> set[str]:
    """Stream the members of ``tar`` into ``target``, each checked before any of its bytes are
    written (:func:`_member_parts`) and counted while written; the top directories of the members
    (an empty directory beside the run's counts too: it would be left behind)."""
    tops: set[str] = set()
    members = 0
    for member in tar:
        members += 1
        if members > MAX_MEMBERS:
            raise ValueError(
                f"{archive}: holds more than {MAX_MEMBERS} members, the most allowed "
                "(evaluation.reports.published.MAX_MEMBERS)"
            )
        parts = _member_parts(archive, member)
        dest = target.joinpath(*parts)
        tops.add(parts[0])
        if member.isdir():
            dest.mkdir(parents=True, exist_ok=True)
            continue
        dest.parent.mkdir(parents=True, exist_ok=True)
        source = tar.extractfile(member)
        assert source is not None  # a regular file's  # noqa: S101
        if os.path.lexists(dest):
            raise ValueError(f"{archive}: member {member.name!r} appears twice")
        # whole or not at all: a kill mid-member leaves no shortened log that reads as a shorter run
        write_atomic(dest, functools.partial(_copy_member, archive, member, source))
    return tops


def _copy_member(archive: Path, member: tarfile.TarInfo, source: IO[bytes], path: str) -> None:
    """Copy the bytes of ``member`` from ``source`` to ``path``, counted against its declared size."""
    written = 0
    with open(path, "wb") as handle:
        while chunk := source.read(_CHUNK):
            written += len(chunk)
            if written > member.size:  # tarfile stops at the declared size; counted anyway
                raise ValueError(f"{archive}: member {member.name!r} holds more than it declares")
            handle.write(chunk)


def _remove(paths: list[Path]) -> None:
    """Remove ``paths`` (files or directory trees), whatever is already gone."""
    for path in paths:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


def extract_archive(archive: str | Path, into: str | Path) -> Path:
    """Unpack a published archive into the directory ``into`` and return the run's directory.

    The archive is read as :func:`koopman_envs.files.read_bounded` reads (a regular file of at most
    :data:`MAX_ARCHIVE_BYTES`), then streamed: every member is checked before its bytes are
    written (a directory or a regular file named ``episodes.jsonl`` or ``sweep.json`` within the
    run's directory, a relative path inside ``into``, at most :data:`MAX_MEMBER_BYTES`), their
    number is bounded (:data:`MAX_MEMBERS`), and the unpacked bytes are counted as they come
    (:data:`MAX_TOTAL_BYTES`, :data:`MAX_RATIO`), so a bomb is stopped within its first megabytes;
    the archive must hold one top directory, the run's. What was unpacked of a refused archive is
    removed. Use :func:`evaluation.reports.publications.extracted_archive` for a directory that is removed after use.

    Raises
    ------
    ValueError
        Naming the archive: its name, what it is (not a regular file, too large, not xz, truncated,
        damaged), the member that is refused and why, or a limit exceeded.
    """
    archive, target = Path(archive), Path(into)
    _check_name(archive)
    blob = read_bounded(archive, MAX_ARCHIVE_BYTES, what="published archive")
    if not blob.startswith(_XZ_MAGIC):
        raise ValueError(f"{archive}: not an xz-compressed tar archive (it does not start as an xz stream)")
    made = not target.exists()
    target.mkdir(parents=True, exist_ok=True)
    before = set(target.iterdir())
    try:
        with tarfile.open(fileobj=_Bounded(blob, archive), mode="r|") as tar:  # type: ignore[call-overload]
            tops = _unpack(archive, tar, target)
        if len(tops) != 1:
            raise ValueError(f"{archive}: holds {sorted(tops)}, not one run's directory")
    except BaseException as exc:
        _remove([target] if made else sorted(set(target.iterdir()) - before))  # nothing of it stays
        if isinstance(exc, EOFError):
            raise ValueError(f"{archive}: is truncated (the xz stream ends before its end marker)") from None
        if isinstance(exc, (tarfile.TarError, lzma.LZMAError)):
            raise ValueError(
                f"{archive}: is damaged or not a tar archive ({type(exc).__name__}: {exc})"
            ) from None
        raise
    return target / tops.pop()


def pack_run(run_dir: str | Path, archive: str | Path) -> Path:
    """Pack a run's episode logs and sweep manifest into ``archive`` (a .tar.xz), reproducibly
    (sorted members, fixed times and owners, xz preset 9), each log's records without
    :data:`PACKED_OUT`.

    Raises
    ------
    ValueError
        ``archive`` does not end in :data:`ARCHIVE_SUFFIX`, or ``run_dir`` holds no episode log
        (``archive`` is then left as it was), or a log is not a regular file of at most
        :data:`MAX_MEMBER_BYTES`.
    """
    run_dir, archive = Path(run_dir), Path(archive)
    _check_name(archive)
    members = run_files(run_dir, archive)
    return write_atomic(
        archive,
        tar_xz(
            (str(path.relative_to(run_dir.parent)), packed_member(path, MAX_MEMBER_BYTES)) for path in members
        ),
    )


def run_files(run_dir: Path, dest: Path) -> list[Path]:
    """The files of ``run_dir`` a publication holds (its episode logs and sweep manifest), sorted;
    ``ValueError`` when it holds no episode log (a missing directory too), naming ``dest``, which
    is then not written."""
    members = sorted(p for p in run_dir.rglob("*") if p.is_file() and p.name in _MEMBER_NAMES)
    if not any(p.name == "episodes.jsonl" for p in members):
        raise ValueError(
            f"{run_dir}: no episode log (episodes.jsonl) in it or below it, so not a run's directory; "
            f"{dest} was not written"
        )
    return members


def packed_log(data: bytes, where: str) -> bytes:
    """An episode log's bytes as published: its header line, then each record without
    :data:`PACKED_OUT`, one per line; a line that is not a JSON object (or is nested past
    :func:`koopman_envs.checks.parse_json`'s bound) is a ``ValueError`` naming ``where`` and its number."""
    lines = data.decode("utf-8").split("\n")
    kept = [lines[0]]
    for number, line in enumerate(lines[1:], start=2):
        if line:
            record = parse_json(line, f"{where}, line {number}")
            if not isinstance(record, dict):
                raise ValueError(
                    f"{where}, line {number}: a JSON {type(record).__name__}, not an episode record"
                )
            kept.append(json.dumps({k: v for k, v in record.items() if k not in PACKED_OUT}))
    return ("\n".join(kept) + "\n").encode("utf-8")


def packed_member(path: Path, limit: int) -> bytes:
    """The bytes a run's file ``path`` is published as (an episode log by :func:`packed_log`, a
    sweep manifest as it is), read as :func:`koopman_envs.files.read_bounded` reads (a regular
    file of at most ``limit`` bytes)."""
    data = read_bounded(path, limit, what="episode log or sweep manifest")
    return packed_log(data, str(path)) if path.name == "episodes.jsonl" else data


def tar_xz(members: Iterable[tuple[str, bytes]]) -> bytes:
    """The members ``(path, bytes)`` as an xz-compressed tar archive, reproducibly: the same
    members give the same bytes (PAX format, in the order given, times 0, mode 0644, no owner;
    xz preset 9), so a file republished unchanged is unchanged in git."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for name, data in members:
            info = tarfile.TarInfo(name)
            info.size, info.mtime, info.mode = len(data), 0, 0o644
            tar.addfile(info, io.BytesIO(data))
    return lzma.compress(buffer.getvalue(), format=lzma.FORMAT_XZ, preset=9)
