"""Issue 59, item 2, where a user meets it: a FIFO given to ``--check`` and ``/dev/zero`` given to
``--baseline`` are refused by ``evaluate.py`` itself, exit 2 with the file named, before any
episode runs (tests/test_bounded_reads.py holds the readers to the same rule in-process).

The command runs in a subprocess with a timeout (tests/test_bounded_reads.py's ``_cli``): only a
guard against the hang a FIFO used to be, never a measure of speed. A file of its own, which
names no module that .ci/mutation.sh mutates, so that the committed mutation stores stay decided
against the test files they name."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from test_bounded_reads import ARGS, _cli  # the same command line and hang guard


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
