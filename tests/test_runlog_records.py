"""The resume log (evaluation/episodes/runlog.py) and the record schema (evaluation/episodes/records.py) called
directly, every expectation written out (issue 41, mutation testing): the header's bytes, what a
resume reads back, each refusal with its file, line and field, the repairs and their notes, the
lock, and every field rule of the schema at its boundary.

tests/test_runlog.py and tests/test_records.py drive the same code through real runs and the
committed baseline; these use hand-made logs and records, so each case runs in milliseconds.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

import evaluation.episodes.runlog as runlog
from evaluation.episodes.records import (
    DEGRADED_FAILURE_SHARE,
    RAN,
    STATUSES,
    finished_status,
    is_degraded,
    json_safe,
    ran,
    record_problem,
)
from evaluation.episodes.runlog import (
    RESUME_KEYS,
    LogError,
    OutputNotWritable,
    RunLocked,
    ensure_output_dir,
    open_log,
    read_log,
    run_signature,
)

CONFIG = {"env_ids": ["KoopNav-TargetReaching-v0"], "seed": 5, "episodes": 2, "workers": 4}
HEADER = (
    b'{"kind": "koopnav-run", "config": {"env_ids": ["KoopNav-TargetReaching-v0"], "controller_configs": null, '
    b'"maps": null, "map_files": null, "slips": null, "episodes": 2, "random_maps": null, "seed": 5, '
    b'"env_settings": null, "calibration": null, "gifs": null}}\n'
)


def _rec(key: str = "k0", **changes) -> dict:
    record = {
        "key": key,
        "status": "ok",
        "env_id": "KoopNav-TargetReaching-v0",
        "controller": "consensus",
        "map": "map1",
        "slip": "nominal",
        "trial": 0,
        "seed": 0,
        "success": False,
        "collision": None,
        "steps": 20,
        "final_distance": [0.5, 0.25, 0.0],
        "solver_failures": 0,
    }
    record.update(changes)
    return record


def _line(record) -> bytes:
    return (json.dumps(record) + "\n").encode()


def _log(tmp_path: Path, *lines: bytes, header: bytes = HEADER) -> Path:
    path = tmp_path / "episodes.jsonl"
    path.write_bytes(header + b"".join(lines))
    return path


# ============================================================================ the resume log
def test_the_signature_is_the_resume_keys_in_plain_json() -> None:
    assert RESUME_KEYS == (
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
    config = {**CONFIG, "env_settings": {"tol": math.nan, "size": (1, 2)}, "maps": ("a", "b")}
    assert run_signature(config) == {
        "env_ids": ["KoopNav-TargetReaching-v0"],
        "controller_configs": None,
        "maps": ["a", "b"],
        "map_files": None,
        "slips": None,
        "episodes": 2,
        "random_maps": None,
        "seed": 5,
        "env_settings": {"tol": None, "size": [1, 2]},
        "calibration": None,
        "gifs": None,
    }


def test_a_new_log_starts_with_its_header_line(tmp_path) -> None:
    out = tmp_path / "a" / "b"
    handle, done = open_log(out, CONFIG, resume=False)
    try:
        assert done == {} and handle.mode == "a"
        assert (out / "episodes.jsonl").read_bytes() == HEADER
    finally:
        handle.close()
    # resuming a log with a header and nothing else: nothing done, the header kept as it was
    handle, done = open_log(out, CONFIG, resume=True)
    handle.close()
    assert done == {} and (out / "episodes.jsonl").read_bytes() == HEADER


def test_an_existing_log_needs_resume_and_a_resume_reads_its_episodes(tmp_path, capsys) -> None:
    log = _log(tmp_path, _line(_rec("k0")), _line(_rec("k1", seed=1)), b'{"key": "k2", "sta')
    with pytest.raises(ValueError) as caught:
        open_log(tmp_path, CONFIG, resume=False)
    assert str(caught.value) == f"{log} exists: pass --resume to continue that run, or choose another --out"
    handle, done = open_log(tmp_path, CONFIG, resume=True)  # the refusal released the lock
    handle.write(json.dumps(_rec("k2", seed=2)) + "\n")
    handle.close()
    assert done == {"k0": _rec("k0"), "k1": _rec("k1", seed=1)}
    assert capsys.readouterr().err == (
        f"note: {log}: dropped 1 incomplete record (line 4, 18 bytes cut by the interruption); it will "
        "be run again\n"
    )
    assert log.read_bytes() == HEADER + _line(_rec("k0")) + _line(_rec("k1", seed=1)) + _line(
        _rec("k2", seed=2)
    )


def test_a_log_of_one_torn_byte_is_resumed_with_its_header_written_again(tmp_path, capsys) -> None:
    (tmp_path / "episodes.jsonl").write_bytes(HEADER[:1])  # killed after the header's first byte
    handle, done = open_log(tmp_path, CONFIG, resume=True)
    handle.close()
    assert done == {} and (tmp_path / "episodes.jsonl").read_bytes() == HEADER
    assert "the header line was cut by the interruption" in capsys.readouterr().err


def test_a_resume_checks_the_records_against_the_plan(tmp_path) -> None:
    _log(tmp_path, _line(_rec("k9")))
    with pytest.raises(LogError, match="line 2: episode 'k9' is not one of this run's episodes"):
        open_log(tmp_path, CONFIG, resume=True, expected={"k0": {"seed": 0}})
    handle, done = open_log(tmp_path, CONFIG, resume=True, expected={"k9": {"seed": 0}})
    handle.close()
    assert done == {"k9": _rec("k9")}


class _Msvcrt:
    """A stand-in for Windows' msvcrt: records the lock asked for, or refuses it."""

    LK_NBLCK = 2

    def __init__(self, held: bool) -> None:
        self.held, self.calls = held, []

    def locking(self, fd, mode, nbytes):
        self.calls.append((fd, mode, nbytes))
        if self.held:
            raise PermissionError(13, "Permission denied")


@pytest.mark.parametrize("held", [False, True])
def test_on_windows_the_log_is_locked_with_msvcrt_without_waiting(tmp_path, monkeypatch, held) -> None:
    import sys
    import types

    msvcrt = _Msvcrt(held)
    monkeypatch.setitem(sys.modules, "msvcrt", msvcrt)
    monkeypatch.setattr(runlog, "sys", types.SimpleNamespace(platform="win32"))
    log = tmp_path / "episodes.jsonl"
    handle = open(log, "a", encoding="utf-8")
    fd = handle.fileno()
    try:
        if held:
            with pytest.raises(RunLocked, match="is being written by another run"):
                runlog._lock(handle, log)
            assert handle.closed
        else:
            runlog._lock(handle, log)
            assert not handle.closed
        assert msvcrt.calls == [(fd, _Msvcrt.LK_NBLCK, 1)]  # one byte, non-blocking
    finally:
        handle.close()


def test_a_second_run_on_the_same_log_is_refused_while_the_first_holds_it(tmp_path) -> None:
    first, _ = open_log(tmp_path, CONFIG, resume=False)
    try:
        with pytest.raises(RunLocked) as caught:
            open_log(tmp_path, CONFIG, resume=True)
        assert str(caught.value) == (
            f"{tmp_path / 'episodes.jsonl'} is being written by another run (it holds the log's lock); wait "
            "for it to finish or stop it, or choose another --out; nothing was changed"
        )
    finally:
        first.close()
    second, _ = open_log(tmp_path, CONFIG, resume=True)
    second.close()


def test_a_bad_log_is_refused_and_its_lock_released(tmp_path) -> None:
    _log(tmp_path, b"not json\n")
    for _ in range(2):  # the second attempt is refused for the same reason, not for a held lock
        with pytest.raises(LogError, match="line 2: not JSON"):
            open_log(tmp_path, CONFIG, resume=True)


def test_read_back_reads_an_episode_logged_twice_alike_once_and_notes_it(tmp_path) -> None:
    b = _rec("b", trial=1, seed=1, steps=8)
    log = _log(tmp_path, _line(_rec("a")), _line(b), _line(_rec("a", wall_seconds=9.0)), _line(b))
    before = log.read_bytes()
    done, notes = read_log(log, CONFIG)
    assert done == {"a": _rec("a"), "b": b}  # the first of each (a wall time is no outcome)
    assert notes == [
        f"{log}: 2 record(s) repeat an episode logged before, outcome for outcome; each episode is read once"
    ]
    assert log.read_bytes() == before  # nothing to repair


@pytest.mark.parametrize("repair", [True, False])
def test_a_torn_last_line_is_noted_and_cut_off_when_repairing(tmp_path, repair) -> None:
    log = _log(tmp_path, _line(_rec("a")), b"{}\n", b'{"key"')
    with pytest.raises(LogError):  # a complete line that is no record refuses before any repair
        read_log(log, CONFIG, repair=repair)
    log = _log(tmp_path, _line(_rec("a")), b'{"key"')
    done, notes = read_log(log, CONFIG, repair=repair)
    assert done == {"a": _rec("a")}
    assert notes == [
        f"{log}: dropped 1 incomplete record (line 3, 6 bytes cut by the interruption); it will be run again"
    ]
    assert log.read_bytes() == HEADER + _line(_rec("a")) + (b"" if repair else b'{"key"')


@pytest.mark.parametrize("cut", [0, 1, 30, len(HEADER) - 1])
def test_a_torn_header_is_written_again(tmp_path, cut) -> None:
    log = tmp_path / "episodes.jsonl"
    log.write_bytes(HEADER[:cut])
    assert read_log(log, CONFIG, repair=False) == (
        {},
        [f"{log}: the header line was cut by the interruption; it was written again"],
    )
    assert log.read_bytes() == HEADER[:cut]
    assert read_log(log, CONFIG)[0] == {}
    assert log.read_bytes() == HEADER


def test_a_lone_line_that_is_no_header_is_refused(tmp_path) -> None:
    log = tmp_path / "episodes.jsonl"
    log.write_bytes(b'{"kind": "other"}')
    with pytest.raises(LogError) as caught:
        read_log(log, CONFIG)
    assert str(caught.value) == f"{log} is not a KoopNav episode log (its only line is not a run header)"
    assert log.read_bytes() == b'{"kind": "other"}'


@pytest.mark.parametrize(
    ("header", "why"),
    [
        (b"not json\n", "is not a KoopNav episode log (line 1 is not JSON); nothing was overwritten"),
        (b"\xff\xfe\n", "is not a KoopNav episode log (line 1 is not JSON); nothing was overwritten"),
        (
            b'{"kind": "other", "config": {}}\n',
            "belongs to a run with other settings (line 1 is not a KoopNav run header); use the same options "
            "to resume, or another --out directory; nothing was overwritten",
        ),
        (
            b"[1]\n",
            "belongs to a run with other settings (line 1 is not a KoopNav run header); use the same options "
            "to resume, or another --out directory; nothing was overwritten",
        ),
        (
            HEADER.replace(b'"seed": 5', b'"seed": 6').replace(b'"episodes": 2', b'"episodes": 3'),
            "belongs to a run with other settings (episodes: logged 3, now 2; seed: logged 6, now 5); use the "
            "same options to resume, or another --out directory; nothing was overwritten",
        ),
        (
            b'{"kind": "koopnav-run", "config": {"seed": 5, "extra": 1}}\n',
            "belongs to a run with other settings (env_ids: logged None, now ['KoopNav-TargetReaching-v0']; "
            "episodes: logged None, now 2; extra: logged 1, now None); use the same options to resume, or "
            "another --out directory; nothing was overwritten",
        ),
    ],
)
def test_a_header_of_another_run_is_refused_naming_what_differs(tmp_path, header, why) -> None:
    log = _log(tmp_path, _line(_rec()), header=header)
    before = log.read_bytes()
    with pytest.raises(LogError) as caught:
        read_log(log, CONFIG)
    assert str(caught.value) == f"{log} {why}"
    assert log.read_bytes() == before


def test_bad_lines_are_refused_by_number_the_first_ten_listed(tmp_path) -> None:
    lines = [_line(_rec("ok"))] + [b"{oops\n"] * 11 + [_line({"key": "x"}), b"\xff\n"]
    log = _log(tmp_path, *lines, b'{"torn')
    before = log.read_bytes()
    with pytest.raises(LogError) as caught:
        read_log(log, CONFIG)
    listed = "; ".join(
        f"line {n}: not JSON (Expecting property name enclosed in double quotes)" for n in range(3, 13)
    )
    assert str(caught.value) == (
        f"{log} cannot be resumed: {listed}; and 3 more. It is not this run's log as KoopNav wrote it; "
        "resume into another --out, or move the file aside to start afresh (nothing was changed)"
    )
    assert log.read_bytes() == before  # not even the torn line is cut


@pytest.mark.parametrize(("count", "tail"), [(10, ""), (11, "; and 1 more")])
def test_ten_bad_lines_are_all_listed_and_an_eleventh_is_counted(tmp_path, count, tail) -> None:
    log = _log(tmp_path, *[b"[]\n"] * count)
    with pytest.raises(LogError) as caught:
        read_log(log, CONFIG)
    listed = "; ".join(f"line {n}: a JSON list, not an episode record" for n in range(2, 12))
    assert str(caught.value).startswith(f"{log} cannot be resumed: {listed}{tail}. It is not this run's log")


def test_each_bad_record_is_named_with_its_line_and_problem(tmp_path) -> None:
    log = _log(
        tmp_path, _line(_rec("a")), b"\xff\n", _line([1]), _line(_rec("b", steps=-5)), _line(_rec("c"))
    )
    with pytest.raises(LogError) as caught:
        read_log(log, CONFIG)
    message = str(caught.value)
    assert message.startswith(
        f"{log} cannot be resumed: line 3: not JSON ('utf-8' codec can't decode byte 0xff in position 0: "
        "invalid start byte); line 4: a JSON list, not an episode record; line 5: field 'steps' is -5; "
        "allowed: an integer >= 0. It is not"
    )


def test_records_of_other_episodes_or_settings_are_refused_when_the_plan_is_known(tmp_path) -> None:
    expected = {"k0": {"seed": 0, "map": "map1"}, "k1": {"seed": 1, "map": "map1"}}
    log = _log(tmp_path, _line(_rec("k0")), _line(_rec("k1", seed=0, map="map2")), _line(_rec("k9")))
    with pytest.raises(LogError) as caught:
        read_log(log, CONFIG, expected)
    assert (
        "line 3: episode 'k1' was run with other settings (map, seed); line 4: episode 'k9' is not one of "
        "this run's episodes. It is not"
    ) in str(caught.value)
    log = _log(tmp_path, _line(_rec("k0")), _line(_rec("k1", seed=1)))
    assert read_log(log, CONFIG, expected) == ({"k0": _rec("k0"), "k1": _rec("k1", seed=1)}, [])
    # without a plan any valid record is taken
    log = _log(tmp_path, _line(_rec("k9", seed=3)))
    assert read_log(log, CONFIG) == ({"k9": _rec("k9", seed=3)}, [])


def test_the_output_directory_is_made_and_tried_with_a_real_write(tmp_path, monkeypatch) -> None:
    out = tmp_path / "x" / "y"
    assert ensure_output_dir(out) == out and out.is_dir() and list(out.iterdir()) == []
    assert ensure_output_dir(str(out)) == out  # an existing directory is fine
    (tmp_path / "file").write_text("")
    with pytest.raises(OutputNotWritable) as caught:
        ensure_output_dir(tmp_path / "file")
    assert (
        str(caught.value)
        == f"--out {str(tmp_path / 'file')!r} is a file; it must be a directory (or a new path)"
    )

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    # a read-only --out (a mount, say) beside a writable temporary directory: the write is tried in --out
    real = runlog.tempfile.TemporaryFile

    def read_only_out(*args, dir=None, **kwargs):
        if dir is not None and Path(dir) == out:
            raise OSError(30, "Read-only file system")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(runlog.tempfile, "TemporaryFile", read_only_out)
    with pytest.raises(OutputNotWritable, match="Read-only file system; choose another --out"):
        ensure_output_dir(out)
    monkeypatch.setattr(runlog.tempfile, "TemporaryFile", refuse)
    with pytest.raises(OutputNotWritable) as caught:
        ensure_output_dir(out)
    assert str(caught.value) == (
        f"--out {str(out)!r} cannot be made a directory this run can write: Permission denied; choose another --out"
    )
    with pytest.raises(OutputNotWritable):
        open_log(out, CONFIG, resume=False)
    assert not (out / "episodes.jsonl").exists()


def test_a_log_that_cannot_be_opened_is_refused_as_not_writable(tmp_path, monkeypatch) -> None:
    real_open = os.open  # the log is opened by os.open (O_NONBLOCK: a FIFO cannot block it)

    def refuse(path, *args, **kwargs):
        if str(path).endswith("episodes.jsonl"):
            raise PermissionError(13, "Permission denied")
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", refuse)
    with pytest.raises(OutputNotWritable) as caught:
        open_log(tmp_path, CONFIG, resume=False)
    assert (
        str(caught.value) == f"{tmp_path / 'episodes.jsonl'} cannot be opened for writing: Permission denied"
    )


# ========================================================================= the record schema
def test_statuses_and_which_of_them_ran() -> None:
    assert STATUSES == ("ok", "degraded", "error") and RAN == ("ok", "degraded")
    assert [ran({"status": s}) for s in ("ok", "degraded", "error", "OK", None)] == [
        True,
        True,
        False,
        False,
        False,
    ]
    assert ran({}) is False
    assert [is_degraded({"status": s}) for s in ("ok", "degraded", "error")] == [False, True, False]
    assert is_degraded({}) is False


@pytest.mark.parametrize(
    ("failures", "decisions", "status"),
    [
        (0, 0, "ok"),
        (5, 0, "ok"),  # no decisions: nothing to judge
        (0, 10, "ok"),
        (25, 100, "ok"),  # exactly a quarter is not more than a quarter
        (26, 100, "degraded"),
        (1, 4, "ok"),
        (2, 4, "degraded"),
        (1, 3, "degraded"),
        (1, 1, "degraded"),
    ],
)
def test_an_episode_is_degraded_when_more_than_a_quarter_of_its_decisions_failed(
    failures, decisions, status
) -> None:
    assert DEGRADED_FAILURE_SHARE == 0.25
    assert finished_status(failures, decisions) == status


def test_json_safe_turns_what_json_cannot_hold_into_null() -> None:
    value = {
        "a": math.nan,
        "b": [math.inf, -math.inf, 1.5, (2, math.nan)],
        "c": {"d": (math.nan,), "e": "text", "f": None, "g": True, "h": 3},
        "i": np.float64("nan"),
        "j": np.float64(2.5),
    }
    assert json_safe(value) == {
        "a": None,
        "b": [None, None, 1.5, [2, None]],
        "c": {"d": [None], "e": "text", "f": None, "g": True, "h": 3},
        "i": None,
        "j": 2.5,
    }
    assert json_safe((1, 2)) == [1, 2] and json_safe(math.inf) is None and json_safe(0.0) == 0.0
    assert json.dumps(json_safe(value), allow_nan=False)


def _error(**changes) -> dict:
    record = {
        k: v
        for k, v in _rec().items()
        if k in ("key", "status", "env_id", "controller", "map", "slip", "trial", "seed")
    }
    return {**record, "status": "error", "error": "RuntimeError: boom", **changes}


@pytest.mark.parametrize(
    "record",
    [
        _rec(),
        _rec(status="degraded"),
        _rec(success=True, collision=None, steps=0, final_distance=[0.0], solver_failures=0, trial=0, seed=0),
        _rec(collision="obstacle+robot+workspace+mover", final_distance=[1, 2, 3]),
        _rec(collision="mover"),
        _rec(final_distance=[0.1, 0.2, 0.3], final_poses=[[1.0, -2.0, -3.1], [0, 0, 0], [-5, 5, 3.1]]),
        _rec(truncated=True, time_to_goal=None, formation_rms=None, solve_ms_median=None, solve_ms_p95=None),
        _rec(time_to_goal=0.0, formation_rms=0, solve_ms_median=1.5, solve_ms_p95=2, wall_seconds=0),
        _rec(path_length=[], control_effort=[0.0, 2]),
        _rec(error=""),
        _error(),
        _error(success="anything", steps=-1),  # outcome fields of an error record are not read
        _error(error=""),
    ],
)
def test_records_as_koopnav_writes_them_pass(record) -> None:
    assert record_problem(record) is None


@pytest.mark.parametrize(
    ("record", "problem"),
    [
        ([], "a JSON list, not an episode record"),
        (None, "a JSON NoneType, not an episode record"),
        ("x", "a JSON str, not an episode record"),
        (
            {},
            "an object without the episode fields ['key', 'status', 'env_id', 'controller', 'map', 'slip', 'trial', 'seed']",
        ),
        (
            {k: v for k, v in _rec().items() if k not in ("slip", "env_id")},
            "an object without the episode fields ['env_id', 'slip']",
        ),
        (
            {k: v for k, v in _rec().items() if k not in ("steps", "success")},
            "a 'ok' record without ['success', 'steps']",
        ),
        (
            {k: v for k, v in _rec(status="degraded").items() if k != "solver_failures"},
            "a 'degraded' record without ['solver_failures']",
        ),
        ({**_error(), "error": None} | {"status": "error"}, "field 'error' is None; allowed: a string"),
        ({k: v for k, v in _error().items() if k != "error"}, "an 'error' record without its 'error' text"),
        (_rec(key=""), "field 'key' is ''; allowed: a non-empty string"),
        (_rec(key=1), "field 'key' is 1; allowed: a non-empty string"),
        (_rec(status="OK"), "field 'status' is 'OK'; allowed: one of ['ok', 'degraded', 'error']"),
        (_rec(env_id=None), "field 'env_id' is None; allowed: a non-empty string"),
        (_rec(controller=""), "field 'controller' is ''; allowed: a non-empty string"),
        (_rec(slip=[]), "field 'slip' is []; allowed: a non-empty string"),
        (_rec(trial=-1), "field 'trial' is -1; allowed: an integer >= 0"),
        (_rec(trial=1.0), "field 'trial' is 1.0; allowed: an integer >= 0"),
        (_rec(seed=False), "field 'seed' is False; allowed: an integer >= 0"),
        (_rec(success=1), "field 'success' is 1; allowed: true or false"),
        (
            _rec(collision=""),
            "field 'collision' is ''; allowed: null or the collision's kinds joined with '+', of ['obstacle', 'robot', 'workspace', 'mover']",
        ),
        (_rec(collision="robot+"), "field 'collision' is 'robot+'"),
        (_rec(collision="robot+robot"), "field 'collision' is 'robot+robot'"),
        (_rec(collision="Robot"), "field 'collision' is 'Robot'"),
        (_rec(collision=["robot"]), "field 'collision' is ['robot']"),
        (_rec(steps=True), "field 'steps' is True; allowed: an integer >= 0"),
        (
            _rec(final_distance=[]),
            "field 'final_distance' is []; allowed: a non-empty list of finite numbers >= 0 (one per robot, metres)",
        ),
        (_rec(final_distance=[0.1, -1e-12]), "field 'final_distance' is [0.1, -1e-12]"),
        (_rec(final_distance=[0.1, math.nan]), "field 'final_distance' is [0.1, nan]"),
        (_rec(final_distance=[True]), "field 'final_distance' is [True]"),
        (_rec(final_distance=0.5), "field 'final_distance' is 0.5"),
        (
            _rec(final_distance=(0.5,)),
            "field 'final_distance' is (0.5,); allowed: a non-empty list of finite numbers >= 0 (one per robot, metres)",
        ),
        (_rec(solver_failures=-1), "field 'solver_failures' is -1; allowed: an integer >= 0"),
        (_rec(truncated="no"), "field 'truncated' is 'no'; allowed: true or false"),
        (
            _rec(time_to_goal=-0.5),
            "field 'time_to_goal' is -0.5; allowed: null or a finite number >= 0 (seconds)",
        ),
        (_rec(time_to_goal=math.inf), "field 'time_to_goal' is inf"),
        (
            _rec(final_poses=[[0, 0]]),
            "field 'final_poses' is [[0, 0]]; allowed: a list of [x, y, heading] triples of finite numbers",
        ),
        (_rec(final_poses=[[0, 0, math.nan]]), "field 'final_poses' is [[0, 0, nan]]"),
        (_rec(final_poses=[[0, 0, 0, 0]]), "field 'final_poses' is [[0, 0, 0, 0]]"),
        (_rec(final_poses=[0, 0, 0]), "field 'final_poses' is [0, 0, 0]"),
        (_rec(final_poses={"a": 1}), "field 'final_poses' is {'a': 1}"),
        (_rec(path_length=[-1.0]), "field 'path_length' is [-1.0]; allowed: a list of finite numbers >= 0"),
        (
            _rec(control_effort=[math.inf]),
            "field 'control_effort' is [inf]; allowed: a list of finite numbers >= 0",
        ),
        (_rec(formation_rms=-1), "field 'formation_rms' is -1; allowed: null or a finite number >= 0"),
        (_rec(solve_ms_median="1"), "field 'solve_ms_median' is '1'; allowed: null or a finite number >= 0"),
        (_rec(solve_ms_p95=-0.1), "field 'solve_ms_p95' is -0.1; allowed: null or a finite number >= 0"),
        (_rec(wall_seconds=None), "field 'wall_seconds' is None; allowed: a finite number >= 0"),
        (_rec(error=5), "field 'error' is 5; allowed: a string"),
        (
            _rec(success=True, collision="obstacle+robot"),
            "field 'success' is true with collision 'obstacle+robot' (a success has no collision)",
        ),
        (
            _rec(final_poses=[[0, 0, 0], [1, 1, 1]]),
            "field 'final_poses' holds 2 robots and 'final_distance' 3 (one of each per robot)",
        ),
        # the first problem in the schema's order is the one named
        (_rec(seed=-1, steps=-1, key=""), "field 'key' is ''; allowed: a non-empty string"),
        (_rec(steps=-1, seed=-1), "field 'seed' is -1; allowed: an integer >= 0"),
    ],
)
def test_each_problem_is_named_exactly(record, problem) -> None:
    assert record_problem(record) is not None
    assert record_problem(record).startswith(problem)
    if "allowed" in problem or "(" in problem:
        assert record_problem(record) == problem


def test_a_long_value_is_cut_to_60_characters_in_the_message() -> None:
    value = "x" * 58  # repr: 60 characters, shown whole
    assert (
        record_problem(_rec(status=value))
        == f"field 'status' is {value!r}; allowed: one of ['ok', 'degraded', 'error']"
    )
    value = "x" * 59  # repr: 61 characters, cut to 57 and '...'
    assert record_problem(_rec(status=value)) == (
        f"field 'status' is '{'x' * 56}...; allowed: one of ['ok', 'degraded', 'error']"
    )


def _controllers(*labels: str, options: dict | None = None) -> dict:
    configs = [{"label": label, "name": label, "options": dict(options or {})} for label in labels]
    return {**CONFIG, "controller_configs": configs}


def test_a_run_with_more_controllers_extends_the_log_and_keeps_its_records(tmp_path) -> None:
    """Adding controllers to a finished run (everything else equal): the logged records stay
    valid, the header becomes this run's, and only the new controllers' episodes are missing."""
    logged = _controllers("consensus")
    b = _rec("b", trial=1, seed=1)
    log = _log(tmp_path, _line(_rec("a")), _line(b), header=runlog._header_line(logged))
    records = log.read_bytes().split(b"\n", 1)[1]
    wider = _controllers("orca", "consensus")
    assert read_log(log, wider, repair=False) == (
        {"a": _rec("a"), "b": b},
        [
            f"{log}: this run adds orca to the logged run's controllers; their episodes run now, the logged ones are kept"
        ],
    )
    assert log.read_bytes() == runlog._header_line(logged) + records  # not repaired: untouched
    done, _ = read_log(log, wider)
    assert set(done) == {"a", "b"}
    assert log.read_bytes() == runlog._header_line(wider) + records
    assert read_log(log, wider) == ({"a": _rec("a"), "b": b}, [])  # now the same run
    # fewer controllers, or a logged controller with other options, is another run
    for other in (logged, _controllers("orca", "consensus", options={"x": 1})):
        with pytest.raises(LogError, match="controller_configs: logged"):
            read_log(log, other)
    assert log.read_bytes() == runlog._header_line(wider) + records


def test_open_log_appends_to_the_extended_log_under_its_lock(tmp_path) -> None:
    logged, wider = _controllers("consensus"), _controllers("consensus", "dwa")
    _log(tmp_path, _line(_rec("a")), header=runlog._header_line(logged))
    handle, done = open_log(tmp_path, wider, resume=True)
    try:
        assert set(done) == {"a"}
        with pytest.raises(RunLocked):  # the new file is locked too
            open_log(tmp_path, wider, resume=True)
        handle.write(json.dumps(_rec("b", trial=1, seed=1)) + "\n")
        handle.flush()
    finally:
        handle.close()
    assert set(read_log(tmp_path / "episodes.jsonl", wider)[0]) == {"a", "b"}


# ============================================================================ issue 59: mutation survivors
def test_the_signature_carries_a_compute_aware_runs_compute_and_a_suite_runs_suite() -> None:
    compute = {"scale": 2.0, "machine": "m1"}
    suite = {"name": "s", "version": 3, "split": "test"}
    plain = run_signature(CONFIG)
    assert "compute" not in plain and "suite" not in plain
    assert run_signature({**CONFIG, "compute": compute, "suite": suite}) == {
        **plain,
        "compute": compute,
        "suite": suite,
    }
    assert run_signature({**CONFIG, "compute": None, "suite": {}}) == plain  # free compute, no suite


def test_a_record_nested_too_deep_is_refused_naming_the_record(tmp_path) -> None:
    deep = b"[" * 65 + b"]" * 65 + b"\n"
    with pytest.raises(LogError) as caught:
        read_log(_log(tmp_path, deep), CONFIG)
    assert "line 2: not JSON (the record: JSON nested 65 levels deep; allowed: at most 64)" in str(
        caught.value
    )


def test_a_run_adding_two_controllers_names_both(tmp_path) -> None:
    log = _log(tmp_path, _line(_rec("a")), header=runlog._header_line(_controllers("consensus")))
    _, notes = read_log(log, _controllers("consensus", "orca", "dwa"), repair=False)
    assert notes == [
        f"{log}: this run adds orca, dwa to the logged run's controllers; their episodes run now, the "
        "logged ones are kept"
    ]


def test_an_episode_log_that_is_a_fifo_is_refused_as_an_episode_log(tmp_path) -> None:
    log = tmp_path / "episodes.jsonl"
    os.mkfifo(log)
    with pytest.raises(ValueError) as caught:
        open_log(tmp_path, CONFIG, resume=True)
    assert str(caught.value) == (
        f"episode log {str(log)!r} cannot be read: it is a FIFO (named pipe), not a regular file "
        "(only regular files are read)"
    )


def test_a_locked_log_that_is_a_fifo_is_refused_as_what_it_is(tmp_path) -> None:
    log = tmp_path / "study.jsonl"
    os.mkfifo(log)
    with pytest.raises(ValueError, match=r"^study log '.*study\.jsonl' cannot be read: it is a FIFO"):
        runlog.open_append_locked(log, "study log")


def test_a_locked_log_is_opened_for_appending_without_blocking_and_not_executable(tmp_path) -> None:
    """O_NONBLOCK stays on the handle (a FIFO swapped in cannot hang the open); the file is made
    with the usual 0o666 less the umask."""
    import fcntl
    import stat

    log = tmp_path / "study.jsonl"
    with runlog.open_append_locked(log, "study log") as handle:
        flags = fcntl.fcntl(handle.fileno(), fcntl.F_GETFL)
        assert flags & os.O_NONBLOCK and flags & os.O_APPEND
        handle.write("é\n")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(log.stat().st_mode) == 0o666 & ~umask
    assert log.read_bytes() == "é\n".encode()


def test_a_second_writer_of_a_locked_log_is_refused_naming_it(tmp_path) -> None:
    log = tmp_path / "study.jsonl"
    with runlog.open_append_locked(log, "study log"):
        with pytest.raises(RunLocked) as caught:
            runlog.open_append_locked(str(log), "study log")
    assert str(caught.value).startswith(f"{log} is being written by another run")


def test_a_run_that_takes_the_extended_log_first_is_refused_naming_it(tmp_path, monkeypatch) -> None:
    """Another run that locks the log rewritten with this run's header before this one reopens
    it: this one is refused, naming the log."""
    logged, wider = _controllers("consensus"), _controllers("consensus", "dwa")
    log = _log(tmp_path, _line(_rec("a")), header=runlog._header_line(logged))
    held = []
    real_read_log = runlog.read_log

    def read_then_taken(*args, **kwargs):
        result = real_read_log(*args, **kwargs)
        held.append(runlog.open_append_locked(log, "episode log"))
        return result

    monkeypatch.setattr(runlog, "read_log", read_then_taken)
    try:
        with pytest.raises(RunLocked) as caught:
            open_log(tmp_path, wider, resume=True)
    finally:
        for handle in held:
            handle.close()
    assert str(caught.value).startswith(f"{log} is being written by another run")


def test_forgetting_controllers_of_a_log_another_run_holds_is_refused_naming_it(tmp_path) -> None:
    log = _log(tmp_path, _line(_rec("a")))
    with runlog.open_append_locked(log, "episode log"):
        with pytest.raises(RunLocked) as caught:
            runlog.forget_controllers(tmp_path, ["consensus"])
    assert str(caught.value).startswith(f"{log} is being written by another run")
    assert log.read_bytes() == HEADER + _line(_rec("a"))
