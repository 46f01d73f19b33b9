"""The output directory (issue 41, items 7 and 12): an unwritable ``--out`` is refused before any
episode with its own exit code, and two runs on one ``--out`` cannot both run its episodes (the
episode log is locked while a run writes it)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.episodes.runlog import OutputNotWritable, RunLocked, ensure_output_dir, open_log

ARGS = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
ARGS += ["--episodes", "1", "--max-episode-steps", "5", "--workers", "1", "--quiet"]


def _unwritable(tmp_path: Path, monkeypatch) -> Path:
    """A directory no file can be created in, also for root (whom permission bits do not stop)."""
    out = tmp_path / "read-only"
    out.mkdir()
    real = __import__("tempfile").TemporaryFile

    def refuse(*args, dir=None, **kwargs):  # noqa: A002 - tempfile's own keyword
        if dir is not None and Path(dir) == out:
            raise PermissionError(13, "Permission denied", str(out))
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr("evaluation.episodes.runlog.tempfile.TemporaryFile", refuse)
    return out


def test_an_unwritable_out_is_refused_up_front_with_its_own_exit_code(tmp_path, monkeypatch, capsys) -> None:
    out = _unwritable(tmp_path, monkeypatch)
    code = ev.main([*ARGS, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == ev.UNWRITABLE_OUT_EXIT == 103, err
    assert f"--out {str(out)!r} cannot be made a directory this run can write: Permission denied" in err
    assert "Traceback" not in err and list(out.iterdir()) == []


def test_a_sweep_into_an_unwritable_out_is_refused_up_front(tmp_path, monkeypatch, capsys) -> None:
    out = _unwritable(tmp_path, monkeypatch)
    code = ev.main([*ARGS, "--sweep", "comm.drop=0,0.5", "--out", str(out)])
    assert code == ev.UNWRITABLE_OUT_EXIT, capsys.readouterr().err
    assert list(out.iterdir()) == []  # not even the manifest


@pytest.mark.skipif(sys.platform == "win32", reason="no POSIX permission bits")
@pytest.mark.usefixtures("permission_bits_bind")  # root (CI) too
def test_a_read_only_directory_is_refused_for_real(tmp_path) -> None:
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o500)
    try:
        with pytest.raises(OutputNotWritable, match="cannot be made a directory this run can write"):
            ensure_output_dir(out)
    finally:
        out.chmod(0o700)


def test_a_second_run_on_the_same_out_is_refused_while_the_first_writes(tmp_path) -> None:
    config = {"seed": 0}
    handle, done = open_log(tmp_path, config, resume=False)
    try:
        assert done == {}
        with pytest.raises(RunLocked, match="is being written by another run"):
            open_log(tmp_path, config, resume=True)
        # from another process too (a second evaluator on the same --out): refused, exit 2
        code = subprocess.run(
            [
                sys.executable,
                "-c",
                "import sys, evaluate as ev; sys.exit(ev.main(sys.argv[1:]))",
                *ARGS,
                "--out",
                str(tmp_path),
                "--resume",
            ],
            capture_output=True,
            text=True,
            cwd=Path(ev.__file__).parent,
        )
        assert code.returncode == 2, code.stderr
        assert "is being written by another run" in code.stderr
    finally:
        handle.close()
    # the first run gone, the log is free again (and, being another run's, refused by its header)
    with pytest.raises(ValueError, match="belongs to a run with other settings"):
        open_log(tmp_path, {"seed": 1}, resume=True)
