"""A run's publication in ``data/``, in one of two forms, read back alike (issue 61):

- **one archive**, ``data/NAME.tar.xz`` (:mod:`evaluation.reports.published`): every log of the
  run in one file. Every run published before issue 61 is one; they are read, never repacked
  (repacking would add their whole size to the history again).
- **split per controller**, the directory ``data/NAME/`` (what ``bash data/publish.sh pack``
  writes now): ``run.tar.xz``, the run's frame (each episode log's header line, and the sweep
  manifest), and ``controllers/LABEL.tar.xz``, one per controller, each holding every log of the
  run with a part header ``{"kind": "koopnav-part", "controller": LABEL}`` as line 1 and that
  controller's records after it. Packing is reproducible (:func:`evaluation.reports.published.tar_xz`),
  so republishing after a rerun of one controller rewrites its file only (and the frame, a few
  kilobytes, when the run's settings changed: a controller added, its options changed).

Reading either back trusts nothing: each archive is unpacked by
:func:`evaluation.reports.published.extract_archive` (its limits and refusals), and a split
publication is refused, named, when it holds anything else than the frame and the parts, a part
of a controller that is not the run's or a part missing, a part of another run, a log the frame
does not hold or a log missing from a part, a frame log that is more than a run header, or a
record of another controller than its part's (a file renamed or copied from elsewhere). The logs
are put back together as the run's directory: each log's header, then each controller's records
in the header's order (a page's readers sort records in the run's planned order, so the page is
the same from either form).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from evaluation.reports.published import (
    ARCHIVE_SUFFIX,
    MAX_MEMBER_BYTES,
    extract_archive,
    is_archive,
    packed_member,
    run_files,
    tar_xz,
)
from koopman_envs.checks import parse_json
from koopman_envs.files import MAX_LOG_BYTES, read_bounded, read_text, write_atomic

__all__ = [
    "FRAME",
    "MAX_PARTS",
    "PARTS",
    "PART_KIND",
    "extract_split",
    "extracted_archive",
    "is_published",
    "is_split",
    "pack_split",
    "unpack_hint",
    "unpack_run",
]

#: the frame's file in a split publication: each log's header line and the sweep manifest
FRAME = "run" + ARCHIVE_SUFFIX
#: the folder of a split publication's parts, one ``LABEL.tar.xz`` per controller
PARTS = "controllers"
#: the ``kind`` of a part's line 1
PART_KIND = "koopnav-part"
#: Most parts (controllers) of one split publication: the largest run (robustness) has 26.
MAX_PARTS = 256
#: what a controller label must look like to name its part's file (every published label does);
#: no path separator, no leading dot, the same file on every file system. A space (the ablation's
#: labels, ``model=learned margins=paper constraints=soft``) is written ``%20`` in the file's name
#: (:data:`_SPACE`): a label holds no ``%``, so the name reads back to the label unambiguously.
#: ``@`` names a training seed (``rl-ppo-set@seed0``, :mod:`evaluation.experiments.seeds`).
_LABEL_FILE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+=@ -]{0,99}")
#: a label's space in its part's file name
_SPACE = "%20"


def is_split(path: str | Path) -> bool:
    """Whether ``path`` is a directory holding a split publication's frame (:data:`FRAME`)."""
    return Path(path).is_dir() and (Path(path) / FRAME).exists()


def is_published(path: str | Path) -> bool:
    """Whether ``path`` names a publication: an archive (``*.tar.xz``) or a split one."""
    return is_archive(path) or is_split(path)


def unpack_hint(path: str | Path) -> str:
    """The command that unpacks the publication ``path`` into a directory ``DIR`` (for messages)."""
    if is_split(path):
        return f"python -m evaluation.archive unpack {path} DIR"
    return f"tar -xJf {path} -C DIR"


def _part_header(label: str) -> bytes:
    """Line 1 of every log in ``label``'s part, with its newline."""
    return (json.dumps({"kind": PART_KIND, "controller": label}) + "\n").encode()


def _labels(header: bytes, where: str) -> list[str]:
    """The controller labels of a run header line, in its order; ``ValueError`` naming ``where``
    when the line is not a run header."""
    try:
        parsed = parse_json(header, where)
    except ValueError:
        parsed = None
    config = (
        parsed.get("config") if isinstance(parsed, dict) and parsed.get("kind") == "koopnav-run" else None
    )
    configs = config.get("controller_configs") if isinstance(config, dict) else None
    if not isinstance(configs, list) or not all(
        isinstance(c, dict) and isinstance(c.get("label"), str) for c in configs
    ):
        raise ValueError(f"{where}: line 1 is not a KoopNav run header naming its controllers")
    return [c["label"] for c in configs]


def _part_name(label: str, dest: Path) -> str:
    """The file name of ``label``'s part; ``ValueError`` for a label that cannot name a file."""
    if not _LABEL_FILE.fullmatch(label):
        raise ValueError(
            f"controller label {label!r} cannot name its part's file (letters, digits and . _ + = -, "
            f"at most 100, not starting with a dot or a sign); {dest} was not written"
        )
    return label.replace(" ", _SPACE) + ARCHIVE_SUFFIX


def pack_split(run_dir: str | Path, dest: str | Path) -> Path:
    """Publish a run split per controller into the directory ``dest`` (``data/NAME``): the frame
    :data:`FRAME` and one part per controller under :data:`PARTS`, each packed reproducibly
    (records without :data:`~evaluation.reports.published.PACKED_OUT`); a file whose bytes are
    unchanged is left as it is, and the part of a controller the run no longer has is removed.

    Raises
    ------
    ValueError
        ``dest`` is a file or has a suffix (``.tar.xz``: one archive); ``run_dir`` holds no episode log; a log's
        line 1 is not a run header, or a record is of a controller its header does not name; a
        label cannot name a file. Nothing is written then.
    """
    run_dir, dest = Path(run_dir), Path(dest)
    if dest.suffix or (os.path.lexists(dest) and not dest.is_dir()):
        raise ValueError(
            f"{dest}: a split publication is a directory named as its run, without a suffix (data/NAME); "
            f"one archive is packed by evaluation.reports.published.pack_run (NAME{ARCHIVE_SUFFIX})"
        )
    frame: list[tuple[str, bytes]] = []
    logs: list[tuple[str, dict[str, list[bytes]]]] = []
    labels: dict[str, None] = {}  # every log's labels, in order
    for path in run_files(run_dir, dest):
        name = str(path.relative_to(run_dir.parent))
        data = packed_member(path, MAX_MEMBER_BYTES)
        if path.name != "episodes.jsonl":
            frame.append((name, data))
            continue
        header, _, body = data.partition(b"\n")
        frame.append((name, header + b"\n"))
        ours = _labels(header, str(path))
        labels.update(dict.fromkeys(ours))
        by_label: dict[str, list[bytes]] = {label: [] for label in ours}
        for number, line in enumerate(body.split(b"\n"), start=2):
            if line:
                label = json.loads(line).get("controller")
                if label not in by_label:
                    raise ValueError(
                        f"{path}, line {number}: a record of controller {label!r}, not one of the run's "
                        f"{ours}; {dest} was not written"
                    )
                by_label[label].append(line + b"\n")
        logs.append((name, by_label))
    parts = {
        _part_name(label, dest): tar_xz(
            (name, _part_header(label) + b"".join(by_label.get(label, []))) for name, by_label in logs
        )
        for label in labels
    }
    (dest / PARTS).mkdir(parents=True, exist_ok=True)
    for path, data in [(dest / FRAME, tar_xz(frame))] + [(dest / PARTS / n, d) for n, d in parts.items()]:
        if not path.is_file() or path.read_bytes() != data:  # unchanged: not even touched
            write_atomic(path, data)
    for stale in sorted((dest / PARTS).iterdir()):
        if stale.name not in parts:
            stale.unlink()
    return dest


def _files(run: Path) -> dict[str, Path]:
    """The files below an unpacked run's directory, by their path relative to it."""
    return {str(p.relative_to(run)): p for p in sorted(run.rglob("*")) if p.is_file()}


def _part_files(directory: Path) -> dict[str, Path]:
    """A split publication's parts by label, each a regular file; ``ValueError`` naming anything
    else in the publication."""
    foreign = sorted(p.name for p in directory.iterdir() if p.name not in (FRAME, PARTS))
    if foreign:
        raise ValueError(f"{directory}: holds {foreign}; a split publication holds {FRAME} and {PARTS}/ only")
    folder = directory / PARTS
    if folder.is_symlink() or not folder.is_dir():
        raise ValueError(
            f"{directory}: no {PARTS}/ folder of parts beside {FRAME}; the publication is incomplete"
        )
    parts: dict[str, Path] = {}
    for path in sorted(folder.iterdir()):
        label = path.name.removesuffix(ARCHIVE_SUFFIX).replace(_SPACE, " ")
        if (
            " " in path.name
            or path.is_symlink()
            or not path.is_file()
            or not is_archive(path)
            or not _LABEL_FILE.fullmatch(label)
        ):
            raise ValueError(f"{path}: not a controller's part (a regular file LABEL{ARCHIVE_SUFFIX})")
        parts[label] = path
    if len(parts) > MAX_PARTS:
        raise ValueError(
            f"{directory}: holds {len(parts)} parts, more than {MAX_PARTS}, the most allowed "
            "(evaluation.reports.publications.MAX_PARTS)"
        )
    return parts


def _read_part(part: Path, label: str, logs: dict[str, list[str]], run: Path) -> dict[str, bytes]:
    """The records of ``label``'s part, unpacked into ``run``'s parent, by log; ``ValueError``
    naming the part for another run's part, a log missing or foreign, a torn or wrong line 1, or a
    record that is not ``label``'s or whose log's header does not name it."""
    files = _files(run)
    if set(files) != set(logs):
        raise ValueError(
            f"{part}: holds the logs {sorted(files)}, the run's frame {sorted(logs)}; a part holds every "
            "log of its run"
        )
    records: dict[str, bytes] = {}
    for name, path in files.items():
        head, _, body = read_bounded(path, MAX_LOG_BYTES, what="episode log").partition(b"\n")
        if head + b"\n" != _part_header(label):
            raise ValueError(f"{part}: {name}, line 1 is not the part header of controller {label!r}")
        for number, line in enumerate(body.split(b"\n"), start=2):
            if not line:
                continue
            try:
                record = parse_json(line, f"{part}: {name}, line {number}")
            except json.JSONDecodeError:
                # a syntax error is a torn line; parse_json's own refusal of a line past its size
                # or nesting bound names the line itself and goes out as it is
                raise ValueError(f"{part}: {name}, line {number} is not a JSON record (torn?)") from None
            owner = record.get("controller") if isinstance(record, dict) else None
            if owner != label or label not in logs[name]:
                raise ValueError(
                    f"{part}: {name}, line {number} is a record of {owner!r}, not of its part's controller "
                    f"{label!r} among the log's {logs[name]}"
                )
        records[name] = body if body.endswith(b"\n") or not body else body + b"\n"  # lines stay lines
    return records


def extract_split(directory: str | Path, into: str | Path) -> Path:
    """Unpack the split publication ``directory`` into ``into`` as the run's directory (each log
    whole again: its header, then every controller's records in the header's order) and return it.

    Raises
    ------
    ValueError
        Naming the file: any refusal of :func:`evaluation.reports.published.extract_archive`, and
        those of a split publication (module docstring); nothing is left in ``into`` then.
    """
    directory, into = Path(directory), Path(into)
    if not directory.is_dir():
        raise ValueError(f"{directory}: not a directory, so not a split publication (data/NAME/{FRAME}, ...)")
    parts = _part_files(directory)
    with tempfile.TemporaryDirectory(prefix="koopnav-split-") as scratch:
        run = extract_archive(directory / FRAME, Path(scratch) / "frame")
        frame = _files(run)
        logs: dict[str, list[str]] = {}
        for name, path in frame.items():
            if path.name == "episodes.jsonl":
                text = read_text(path, MAX_LOG_BYTES, what="episode log", expected="a run header line")
                if text.count("\n") != 1 or not text.endswith("\n"):
                    raise ValueError(f"{directory / FRAME}: {name} is not one run header line")
                logs[name] = _labels(text.encode(), f"{directory / FRAME}: {name}")
        wanted = list(dict.fromkeys(label for labels in logs.values() for label in labels))
        if sorted(parts) != sorted(wanted):
            raise ValueError(
                f"{directory}: parts {sorted(parts)}, the run's controllers {sorted(wanted)}: "
                f"missing {sorted(set(wanted) - set(parts))}, foreign {sorted(set(parts) - set(wanted))}"
            )
        records: dict[str, dict[str, bytes]] = {}
        for label in wanted:
            unpacked = extract_archive(parts[label], Path(scratch) / "parts" / label)
            if unpacked.name != run.name:
                raise ValueError(f"{parts[label]}: a part of run {unpacked.name!r}, not of {run.name!r}")
            records[label] = _read_part(parts[label], label, logs, unpacked)
        target = into / run.name
        if os.path.lexists(target):
            raise ValueError(f"{target} exists; a publication is unpacked into a directory without its run")
        try:
            for name, path in frame.items():
                data = read_bounded(path, MAX_MEMBER_BYTES, what="unpacked member")
                if name in logs:
                    data += b"".join(records[label][name] for label in logs[name])
                    if len(data) > MAX_LOG_BYTES:
                        raise ValueError(
                            f"{directory}: {name} is {len(data)} bytes put together, beyond {MAX_LOG_BYTES}"
                        )
                write_atomic(target / name, data)
        except BaseException:
            shutil.rmtree(target, ignore_errors=True)
            raise
    return target


@contextlib.contextmanager
def extracted_archive(publication: str | Path) -> Iterator[Path]:
    """A publication unpacked into a new temporary directory, removed when the ``with`` block
    ends, normally or by an exception: a split one (a directory, :func:`extract_split`) or one
    archive (:func:`evaluation.reports.published.extract_archive`)::

        with extracted_archive("data/paper.tar.xz") as run:
            results = results_from_log(run / "episodes.jsonl")

    Yields
    ------
    pathlib.Path
        The run's directory.
    """
    scratch = Path(tempfile.mkdtemp(prefix="koopnav-published-"))
    try:
        if Path(publication).is_dir():
            yield extract_split(publication, scratch)
        else:
            yield extract_archive(publication, scratch)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _records(log: Path) -> int:
    """The number of records of an episode log (its lines after the header)."""
    text = read_text(log, MAX_LOG_BYTES, what="episode log", expected="a KoopNav episode log (JSON lines)")
    return max(0, sum(1 for line in text.split("\n") if line) - 1)


def unpack_run(archive: str | Path, into: str | Path, *, force: bool = False) -> Path:
    """Restore a publication's logs (one archive or a split one) under ``into`` (``data/publish.sh
    unpack``: a new machine's ``data/runs/``), and return the run's directory there.

    A local episode log that holds more records than the publication's (a run continued since it
    was packed) is kept: the publication is refused, naming the log and both counts, before any
    file is written, unless ``force``. Every file is replaced whole
    (:func:`koopman_envs.files.write_atomic`).

    Raises
    ------
    ValueError
        The publication is refused (:func:`extracted_archive`), or a local log holds more records.
    """
    into = Path(into)
    with extracted_archive(archive) as run:
        unpacked = sorted(p for p in run.rglob("*") if p.is_file())
        targets = {path: into / path.relative_to(run.parent) for path in unpacked}
        if not force:
            for path, target in targets.items():
                if path.name == "episodes.jsonl" and os.path.lexists(target):
                    ours, theirs = _records(target), _records(path)
                    if ours > theirs:
                        raise ValueError(
                            f"{target} holds {ours} records, the archive {archive} {theirs}: unpacking would "
                            "lose the records added since it was packed; pack them first (bash "
                            "data/publish.sh pack), or unpack with --force to replace the log"
                        )
        for path, target in targets.items():
            write_atomic(target, read_bounded(path, MAX_MEMBER_BYTES, what="unpacked member"))
        return into / run.name
