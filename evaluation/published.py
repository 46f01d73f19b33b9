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
"""

from __future__ import annotations

import json
import lzma
import tarfile
import tempfile
from pathlib import Path
from typing import Any

from evaluation.distinct import read_once
from evaluation.records import record_problem
from evaluation.results import Results

__all__ = ["ARCHIVE_SUFFIX", "PACKED_OUT", "extract_archive", "is_archive", "pack_run", "results_from_log"]

#: how a published archive's name ends
ARCHIVE_SUFFIX = ".tar.xz"

#: record fields a published log leaves out: every step's decision time (the per-episode median
#: and 95th percentile stay; a cell's p95 then comes from them), a third of the packed size
PACKED_OUT = ("solve_ms",)


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
    checked (:func:`evaluation.records.record_problem`; a torn or foreign line is refused by
    its number), in the run's planned order; an episode logged twice is read once, and refused
    (:class:`~evaluation.distinct.ConflictingRecords`, a ``ValueError``) when its two records
    disagree (:func:`evaluation.distinct.read_once`)."""
    path = Path(path)
    lines = path.read_text(encoding="utf-8").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    try:
        header = json.loads(lines[0]) if lines else None
    except json.JSONDecodeError:
        header = None
    if not isinstance(header, dict) or header.get("kind") != "koopnav-run":
        raise ValueError(f"{path} is not a KoopNav episode log (line 1 is not a run header)")
    config = dict(header["config"])
    config["controllers"] = [c["label"] for c in config.get("controller_configs") or []]
    records: list[dict[str, Any]] = []
    for number, line in enumerate(lines[1:], start=2):
        try:
            record = json.loads(line)
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


def extract_archive(archive: str | Path, into: str | Path | None = None) -> Path:
    """Unpack a published archive (its episode logs and manifests only: any other member, or
    one that would land outside ``into``, is refused by name) and return the run's directory.
    ``into``: where (default: a new temporary directory)."""
    archive = Path(archive)
    _check_name(archive)
    target = Path(into) if into is not None else Path(tempfile.mkdtemp(prefix="koopnav-published-"))
    try:
        tar = tarfile.open(archive, "r:xz")
    except (tarfile.ReadError, lzma.LZMAError) as exc:
        raise ValueError(f"{archive}: not an xz-compressed tar archive ({exc})") from None
    with tar:
        members = tar.getmembers()
        for member in members:
            name = Path(member.name)
            if not member.isfile() or name.name not in ("episodes.jsonl", "sweep.json"):
                if member.isdir():
                    continue
                raise ValueError(
                    f"{archive}: member {member.name!r} is not an episode log or a sweep manifest"
                )
        tar.extractall(target, filter="data")
    tops = {Path(m.name).parts[0] for m in members if m.isfile()}
    if len(tops) != 1:
        raise ValueError(f"{archive}: holds {sorted(tops)}, not one run's directory")
    return target / tops.pop()


def pack_run(run_dir: str | Path, archive: str | Path) -> Path:
    """Pack a run's episode logs and sweep manifest into ``archive`` (a .tar.xz), reproducibly
    (sorted members, fixed times and owners, xz preset 9), each log's records without
    :data:`PACKED_OUT`."""
    import io

    run_dir, archive = Path(run_dir), Path(archive)
    _check_name(archive)
    members = sorted(
        p for p in run_dir.rglob("*") if p.is_file() and p.name in ("episodes.jsonl", "sweep.json")
    )
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for path in members:
            data = path.read_bytes()
            if path.name == "episodes.jsonl":
                lines = data.decode("utf-8").split("\n")
                kept = [lines[0]]
                for line in lines[1:]:
                    if line:
                        record = json.loads(line)
                        kept.append(json.dumps({k: v for k, v in record.items() if k not in PACKED_OUT}))
                data = ("\n".join(kept) + "\n").encode("utf-8")
            info = tarfile.TarInfo(str(path.relative_to(run_dir.parent)))
            info.size, info.mtime, info.mode = len(data), 0, 0o644
            tar.addfile(info, io.BytesIO(data))
    archive.write_bytes(lzma.compress(buffer.getvalue(), format=lzma.FORMAT_XZ, preset=9))
    return archive


if __name__ == "__main__":  # python -m evaluation.published RUN_DIR ARCHIVE
    import sys

    print(pack_run(sys.argv[1], sys.argv[2]))
