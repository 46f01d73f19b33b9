"""The episode log of a run (``OUT/episodes.jsonl``): a header naming the run's settings, then one
JSON line per finished episode, flushed at once, so that an interrupted run can be resumed."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import IO, Any

from evaluation.results import json_safe

__all__ = ["RESUME_KEYS", "open_log", "run_signature"]

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


def run_signature(config: dict[str, Any]) -> dict[str, Any]:
    """The parts of a run configuration that must match for a resume (plain JSON)."""
    return json.loads(json.dumps(json_safe({k: config.get(k) for k in RESUME_KEYS})))


def _read(log: Path, config: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Finished episodes of a previous run with the same settings (key -> record)."""
    lines = log.read_text(encoding="utf-8").splitlines()
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError:
        raise ValueError(
            f"{log} is not a KoopNav episode log (bad first line); nothing was overwritten"
        ) from None
    ours = run_signature(config)
    theirs = header.get("config") if header.get("kind") == "koopnav-run" else None
    if theirs != ours:
        if isinstance(theirs, dict):
            differ = sorted(k for k in set(ours) | set(theirs) if ours.get(k) != theirs.get(k))
            what = "; ".join(f"{k}: logged {theirs.get(k)!r}, now {ours.get(k)!r}" for k in differ)
        else:
            what = "not a KoopNav run header"
        raise ValueError(
            f"{log} belongs to a run with other settings ({what}); use the same options to resume, "
            "or another --out directory; nothing was overwritten"
        )
    done = {}
    for line in lines[1:]:
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by the interruption: that episode simply runs again
        done[rec["key"]] = rec
    return done


def open_log(
    out: str | os.PathLike[str], config: dict[str, Any], resume: bool
) -> tuple[IO[str], dict[str, dict[str, Any]]]:
    """Open the run's log for appending; return it with the episodes a previous run finished.

    Raises
    ------
    ValueError
        A log exists and ``resume`` is false, or it belongs to other settings.
    """
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    log = out_dir / "episodes.jsonl"
    if log.exists() and log.stat().st_size > 0:
        if not resume:
            raise ValueError(f"{log} exists: pass --resume to continue that run, or choose another --out")
        done = _read(log, config)
        return open(log, "a", encoding="utf-8"), done  # noqa: SIM115 - the caller closes it
    handle = open(log, "w", encoding="utf-8")  # noqa: SIM115
    handle.write(json.dumps({"kind": "koopnav-run", "config": run_signature(config)}) + "\n")
    handle.flush()
    return handle, {}
