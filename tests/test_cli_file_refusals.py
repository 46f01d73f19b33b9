"""Issue 59, item 2, where a user meets it: a FIFO given to ``--check`` and ``/dev/zero`` given to
``--baseline`` are refused by ``evaluate.py`` itself, exit 2 with the file named, before any
episode runs (tests/test_bounded_reads.py holds the readers to the same rule in-process).

The command runs in a subprocess with a timeout: only a guard against the hang a FIFO used to be,
never a measure of speed. This file imports no module that .ci/mutation.sh mutates, so the
mutation stores' verdicts stay decided against the test files they name."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: a command that used to hang on a FIFO is stopped after this [s] (a hang guard, not a timing)
HANG_GUARD = 120
ARGS = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
ARGS += ["--episodes", "1", "--max-episode-steps", "5", "--workers", "1", "--quiet"]


def _cli(*argv: str) -> subprocess.CompletedProcess[str]:
    """``python evaluate.py ARGV`` from the repository root; a hang fails the test."""
    try:
        return subprocess.run(
            [sys.executable, str(ROOT / "evaluate.py"), *argv],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=HANG_GUARD,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"evaluate.py {' '.join(argv)} hung (killed after {HANG_GUARD} s)")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_given_to_check_exits_2_before_any_episode(tmp_path: Path) -> None:
    fifo = tmp_path / "floors.toml"
    os.mkfifo(fifo)
    out = tmp_path / "out"
    done = _cli(*ARGS, "--out", str(out), "--check", str(fifo))
    assert done.returncode == 2, done.stderr
    assert f"thresholds file {str(fifo)!r} cannot be read: it is a FIFO" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert not (out / "episodes.jsonl").exists(), "an episode ran before the thresholds were read"


def test_dev_zero_given_to_baseline_exits_2_before_any_episode(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = _cli(*ARGS, "--out", str(out), "--baseline", "/dev/zero")
    assert done.returncode == 2, done.stderr
    assert "baseline '/dev/zero' cannot be read: it is a character device, not a regular file" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (out / "episodes.jsonl").exists(), "an episode ran before the baseline was read"
