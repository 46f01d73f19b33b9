"""The episode log read back: a torn tail is repaired, an unreadable or foreign line refuses the
resume by its line number, and a resume after any kill point gives the uninterrupted results."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.episodes.runlog import LogError, read_log

ROOT = Path(ev.__file__).parent
TESTS = Path(__file__).parent

#: a fast run: consensus, short episodes (trial 2 is the log's last line and carries no trajectory)
FAST = ev.RunSpec(
    envs=["KoopNav-TargetReaching-v0"],
    controllers=["consensus"],
    maps=["map1"],
    slips=["high"],
    episodes=3,
    seed=5,
    env_kwargs={"max_episode_steps": 20},
)
#: the same with a second controller whose episodes wait for a gate file (tests/plugin_controllers.py)
GATED = FAST.replace(controllers=["consensus", "plugin_controllers:GatedConsensus"], episodes=2)
GATED_ARGS = [
    "--env",
    "KoopNav-TargetReaching-v0",
    "--controllers",
    "consensus",
    "plugin_controllers:GatedConsensus",
    "--maps",
    "map1",
    "--slips",
    "high",
    "--episodes",
    "2",
    "--seed",
    "5",
    "--max-episode-steps",
    "20",
    "--start-noise",
    "0",
]

#: record fields that hold wall times (they differ between any two runs)
_TIMING = {"wall_seconds", "solve_ms", "solve_ms_median", "solve_ms_p95", "controller_extra", "calibration"}


def outcomes(records: list[dict]) -> list[dict]:
    """Records without their wall times, in order."""
    return [{k: v for k, v in r.items() if k not in _TIMING} for r in records]


def _config(spec: ev.RunSpec) -> dict:
    return spec.resolved().config(1, "process")


def _expected(spec: ev.RunSpec) -> dict:
    return {e.key: e.record_fields() for e in spec.resolved().episodes_plan()}


@pytest.fixture(scope="module")
def fast_run(tmp_path_factory) -> tuple[Path, ev.Results]:
    out = tmp_path_factory.mktemp("fast")
    return out / "episodes.jsonl", ev.evaluate(FAST, workers=1, out=out)


def test_a_torn_last_line_is_cut_off_at_every_byte_offset(tmp_path, fast_run) -> None:
    log, _ = fast_run
    data = log.read_bytes()
    lines = data.split(b"\n")[:-1]
    head = b"\n".join(lines[:-1]) + b"\n"
    last = lines[-1]
    keys = [json.loads(line)["key"] for line in lines[1:-1]]
    copy = tmp_path / "episodes.jsonl"
    # every proper prefix of the last line, and the whole line without its newline: all torn
    for cut in range(1, len(last) + 1):
        copy.write_bytes(head + last[:cut])
        done, notes = read_log(copy, _config(FAST), _expected(FAST))
        assert sorted(done) == sorted(keys), cut
        assert len(notes) == 1 and "dropped 1 incomplete record" in notes[0] and "run again" in notes[0]
        assert f"line {len(lines)}" in notes[0]
        assert copy.read_bytes() == head, cut  # repaired: the next record starts on its own line
    copy.write_bytes(data)  # an intact log: nothing to say, nothing changed
    done, notes = read_log(copy, _config(FAST), _expected(FAST))
    assert len(done) == 3 and notes == [] and copy.read_bytes() == data


@pytest.mark.parametrize("cut", [1, 40, -1, 0])
def test_resume_after_a_torn_line_equals_the_uninterrupted_run(tmp_path, fast_run, cut, capsys) -> None:
    log, reference = fast_run
    out = tmp_path / "run"
    out.mkdir()
    data = log.read_bytes()
    last_start = data.rstrip(b"\n").rfind(b"\n") + 1
    end = len(data) - 1 if cut == 0 else last_start + cut if cut > 0 else len(data) + cut - 1
    (out / "episodes.jsonl").write_bytes(data[:end])
    resumed = ev.evaluate(FAST, workers=1, out=out, resume=True)
    assert "dropped 1 incomplete record" in capsys.readouterr().err
    assert outcomes(resumed.records) == outcomes(reference.records)
    written = (out / "episodes.jsonl").read_text().splitlines()
    assert len(written) == 4 and all(json.loads(line) for line in written)
    again = ev.evaluate(FAST, workers=1, out=out, resume=True)  # nothing left to run, nothing to repair
    assert outcomes(again.records) == outcomes(reference.records)
    assert "dropped" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("line", "problem"),
    [
        (b"{}", "an object without the episode fields"),
        (b"123", "a JSON int, not an episode record"),
        (b"[]", "a JSON list, not an episode record"),
        (b"not json at all", "not JSON"),
        (b'{"key": "x", "status": "ok"}', "an object without the episode fields"),
    ],
)
def test_an_unreadable_or_foreign_line_refuses_the_resume_by_number(
    tmp_path, fast_run, line, problem
) -> None:
    log, _ = fast_run
    lines = log.read_bytes().split(b"\n")
    lines.insert(2, line)  # between the first and the second record: line 3
    copy = tmp_path / "episodes.jsonl"
    copy.write_bytes(b"\n".join(lines))
    before = copy.read_bytes()
    with pytest.raises(LogError, match=f"line 3: {problem}"):
        read_log(copy, _config(FAST), _expected(FAST))
    assert copy.read_bytes() == before  # refused: nothing changed


def test_a_record_of_another_run_is_refused(tmp_path, fast_run) -> None:
    log, _ = fast_run
    lines = log.read_bytes().split(b"\n")
    record = json.loads(lines[1])
    other_seed = {**record, "seed": 999}
    other_key = {**record, "key": record["key"].replace("|0", "|7")}
    bad_status = {**record, "status": "fine"}
    no_outcome = {k: v for k, v in record.items() if k != "final_distance"}
    for rec, problem in [
        (other_seed, "was run with other settings \\(seed\\)"),
        (other_key, "is not one of this run's episodes"),
        (bad_status, "field 'status' is 'fine'; allowed: one of"),
        (no_outcome, "record without \\['final_distance'\\]"),
    ]:
        copy = tmp_path / "episodes.jsonl"
        copy.write_bytes(b"\n".join([lines[0], json.dumps(rec).encode(), *lines[2:]]))
        with pytest.raises(LogError, match=f"line 2: .*{problem}"):
            read_log(copy, _config(FAST), _expected(FAST))


@pytest.mark.parametrize(
    "change, problem",
    [
        ({"success": "maybe"}, "field 'success' is 'maybe'; allowed: true or false"),
        ({"success": None}, "field 'success' is None; allowed: true or false"),
        ({"steps": -5}, "field 'steps' is -5; allowed: an integer >= 0"),
        ({"steps": 1.5}, "field 'steps' is 1.5; allowed: an integer >= 0"),
        ({"collision": "x"}, "field 'collision' is 'x'; allowed: null or the collision's kinds"),
        ({"final_distance": [0.1, "far", 0.2]}, "field 'final_distance' is \\[0.1, 'far', 0.2\\]"),
        ({"solver_failures": -1}, "field 'solver_failures' is -1"),
        ({"trial": "0"}, "field 'trial' is '0'"),
        ({"time_to_goal": -3.0}, "field 'time_to_goal' is -3.0"),
        ({"final_poses": [[0.0, 0.0]]}, "field 'final_poses' is \\[\\[0.0, 0.0\\]\\]"),
    ],
)
def test_a_record_with_a_bad_value_is_refused_naming_file_line_and_field(
    tmp_path, fast_run, change, problem
) -> None:
    log, _ = fast_run
    lines = log.read_bytes().split(b"\n")
    record = {**json.loads(lines[2]), **change}
    copy = tmp_path / "episodes.jsonl"
    copy.write_bytes(b"\n".join([lines[0], lines[1], json.dumps(record).encode(), *lines[3:]]))
    with pytest.raises(LogError, match=f"{copy}.*line 3: {problem}"):
        read_log(copy, _config(FAST), _expected(FAST))


def test_the_cli_refuses_a_foreign_log_with_exit_2(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    args = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
    args += ["--slips", "high", "--episodes", "2", "--max-episode-steps", "20", "--workers", "1", "--quiet"]
    assert ev.main([*args, "--out", str(out)]) == 0
    log = out / "episodes.jsonl"
    lines = log.read_bytes().split(b"\n")
    log.write_bytes(b"\n".join([lines[0], b"{}", *lines[1:]]))
    capsys.readouterr()
    code = ev.main([*args, "--out", str(out), "--resume"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "line 2: an object without the episode fields" in err and "Traceback" not in err


def test_a_torn_header_is_written_again(tmp_path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    ev.evaluate(FAST.replace(episodes=1), workers=1, out=tmp_path / "whole")
    header = (tmp_path / "whole" / "episodes.jsonl").read_bytes().split(b"\n")[0]
    (out / "episodes.jsonl").write_bytes(header[:25])
    results = ev.evaluate(FAST.replace(episodes=1), workers=1, out=out, resume=True)
    assert len(results.records) == 1
    assert (out / "episodes.jsonl").read_bytes().split(b"\n")[0] == header
    (out / "episodes.jsonl").write_bytes(b'{"not": "a header')  # not a prefix of ours: refused
    with pytest.raises(LogError, match="not a KoopNav episode log"):
        ev.evaluate(FAST.replace(episodes=1), workers=1, out=out, resume=True)


def test_out_pointing_at_a_file_is_refused_before_any_episode(tmp_path, capsys) -> None:
    target = tmp_path / "results.txt"
    target.write_text("mine")
    args = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
    code = ev.main([*args, "--episodes", "1", "--workers", "1", "--quiet", "--out", str(target)])
    err = capsys.readouterr().err
    assert (
        code == ev.UNWRITABLE_OUT_EXIT
        and "is a file; it must be a directory" in err
        and "Traceback" not in err
    )
    assert target.read_text() == "mine"
    code = ev.main([*args, "--episodes", "1", "--workers", "1", "--quiet", "--out", str(target / "sub")])
    assert code == ev.UNWRITABLE_OUT_EXIT and "cannot be made a directory" in capsys.readouterr().err


# ------------------------------------------------------------------ kills and signals, gated
def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_gated_run(
    tmp_path: Path, extra: list[str], lines: int, waiting: int = 0
) -> tuple[subprocess.Popen, Path, Path]:
    """Start the CLI on :data:`GATED` in its own session with the gate closed; return once its log
    has ``lines`` lines (the consensus episodes: the gated ones cannot start until the gate opens)
    and ``waiting`` gated episodes wait at the gate (every worker past its start-up)."""
    out, gate = tmp_path / "run", tmp_path / "gate"
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(TESTS), str(ROOT)]),
        "KOOPNAV_TEST_GATE": str(gate),
    }
    proc = subprocess.Popen(
        [sys.executable, "evaluate.py", *GATED_ARGS, "--out", str(out), *extra],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # Ctrl-C as a terminal user has it: a suite started in the background of a
        # non-interactive shell (`bash .ci/run &`) inherits SIGINT ignored, and Python then
        # installs no KeyboardInterrupt handler in the evaluator
        preexec_fn=_default_sigint,
    )
    log = out / "episodes.jsonl"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and (
        not log.exists()
        or len(log.read_text().splitlines()) < lines
        or len(list(tmp_path.glob("gate.waiting-*"))) < waiting
    ):
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    return proc, out, gate


@pytest.fixture(scope="module")
def gated_reference(tmp_path_factory) -> ev.Results:
    return ev.evaluate(GATED, workers=1, out=tmp_path_factory.mktemp("gated"))  # no gate set: no wait


@pytest.mark.parametrize(
    # slow: a second killed run, a fresh interpreter and its episodes (issue 61); one kill by default
    "finished",
    [1, pytest.param(2, marks=pytest.mark.slow)],
)
def test_sigkill_at_any_point_then_resume_equals_the_uninterrupted_run(
    tmp_path, gated_reference, finished
) -> None:
    proc, out, gate = start_gated_run(tmp_path, ["--workers", "1", "--quiet"], lines=1 + finished)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    logged = len((out / "episodes.jsonl").read_text().splitlines()) - 1
    assert finished <= logged <= 2  # the gated episodes cannot have finished
    gate.touch()
    resumed = ev.evaluate(GATED, workers=1, out=out, resume=True)
    assert outcomes(resumed.records) == outcomes(gated_reference.records)


# slow: a fresh evaluator with 2 worker processes, about 4 CPU-s (issue 61); the SIGKILL test keeps
# a killed and resumed run in the default run
@pytest.mark.slow
def test_ctrl_c_exits_130_and_resume_finishes_identically(tmp_path, gated_reference) -> None:
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) stops the workers cleanly."""
    proc, out, gate = start_gated_run(tmp_path, ["--workers", "2"], lines=3, waiting=2)
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert "interrupted after 2/4" in stderr and "--resume" in stderr
    gate.touch()
    resumed = ev.evaluate(GATED, workers=1, out=out, resume=True)
    assert outcomes(resumed.records) == outcomes(gated_reference.records)


# slow: a fresh evaluator with 2 worker processes, about 4 CPU-s (issue 61)
@pytest.mark.slow
def test_sigterm_stops_the_workers_and_leaves_a_resumable_log(tmp_path, gated_reference) -> None:
    """``kill`` (SIGTERM to the main process alone) must not leave orphan workers computing."""
    proc, out, gate = start_gated_run(tmp_path, ["--workers", "2", "--quiet"], lines=3, waiting=2)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "--resume" in stderr
    deadline = time.monotonic() + 30
    left = ["?"]
    while time.monotonic() < deadline and left:
        ps = subprocess.run(["ps", "-o", "pid=", "-s", str(proc.pid)], capture_output=True, text=True)
        left = ps.stdout.split()
        time.sleep(0.2)
    assert not left, f"worker processes still running: {left}"
    gate.touch()
    resumed = ev.evaluate(GATED, workers=1, out=out, resume=True)
    assert outcomes(resumed.records) == outcomes(gated_reference.records)
    shutil.rmtree(out)


def test_forgetting_a_controller_reruns_only_its_episodes_on_resume(tmp_path) -> None:
    """The republishing path for a changed controller: its records leave the log (every other
    line kept byte for byte), and the resume runs exactly its episodes again, with the
    uninterrupted run's results."""
    from evaluation.episodes.runlog import forget_controllers
    from evaluation.forget import main as forget_main

    spec = FAST.replace(controllers=["consensus", "consensus-free"], episodes=2)
    first = ev.evaluate(spec, workers=1, out=tmp_path)
    log = tmp_path / "episodes.jsonl"
    before = log.read_bytes().splitlines(keepends=True)
    assert forget_controllers(tmp_path, ["consensus-free"]) == 2
    after = log.read_bytes().splitlines(keepends=True)
    assert after == [line for line in before if b'"controller": "consensus-free"' not in line]
    assert len(after) == len(before) - 2
    again = ev.evaluate(spec, workers=1, out=tmp_path, resume=True)
    assert outcomes(again.records) == outcomes(first.records)
    assert len(log.read_bytes().splitlines()) == len(before)
    assert forget_main(["consensus", "--", str(tmp_path)]) == 0
    assert all(b'"controller": "consensus"' not in line for line in log.read_bytes().splitlines()[1:])


def test_forgetting_refuses_a_log_with_an_unreadable_line(tmp_path) -> None:
    (tmp_path / "episodes.jsonl").write_text('{"kind": "koopnav-run"}\n{"controller": "x"}\nnot json\n')
    with pytest.raises(LogError, match=r"episodes.jsonl: line 3 is not a JSON record"):
        forget_controllers_of(tmp_path)
    assert (tmp_path / "episodes.jsonl").read_text().endswith("not json\n")  # unchanged
    with pytest.raises(LogError, match="no episode log"):
        forget_controllers_of(tmp_path / "nothing")
    from evaluation.forget import main as forget_main

    assert forget_main(["x", "--", str(tmp_path / "nothing")]) == 2


def forget_controllers_of(path: Path) -> int:
    from evaluation.episodes.runlog import forget_controllers

    return forget_controllers(path, ["x"])


def test_adding_a_controller_to_a_finished_run_runs_only_its_episodes(tmp_path) -> None:
    """The publishing path for a new controller: the same run with one more controller resumes
    the log, keeps every logged record byte for byte, and runs only the new controller's
    episodes, with the results of a run that had it from the start."""
    both = FAST.replace(controllers=["consensus", "consensus-free"], episodes=2)
    reference = ev.evaluate(both, workers=1, out=tmp_path / "both")
    ev.evaluate(both.replace(controllers=["consensus"]), workers=1, out=tmp_path)
    log = tmp_path / "episodes.jsonl"
    logged = log.read_bytes().splitlines(keepends=True)[1:]
    extended = ev.evaluate(both, workers=1, out=tmp_path, resume=True)
    lines = log.read_bytes().splitlines(keepends=True)
    assert lines[0] == (tmp_path / "both" / "episodes.jsonl").read_bytes().splitlines(keepends=True)[0]
    assert lines[1 : 1 + len(logged)] == logged  # the logged records, untouched
    assert len(lines) == 1 + 2 * len(logged)
    assert all(b'"controller": "consensus-free"' in line for line in lines[1 + len(logged) :])
    key = lambda r: r["key"]  # noqa: E731
    assert sorted(outcomes(extended.records), key=key) == sorted(outcomes(reference.records), key=key)
    # one controller fewer is another run: refused by name
    with pytest.raises(ValueError, match="controller_configs: logged"):
        ev.evaluate(both.replace(controllers=["consensus"]), workers=1, out=tmp_path, resume=True)


def test_main_puts_the_callers_sigterm_handler_back(tmp_path) -> None:
    # evaluate.main turns SIGTERM into a resumable stop only while it runs: a program (or test
    # session) that calls it keeps its own handler afterwards, whether the run ends well or not
    def own_handler(signum, frame) -> None:  # pragma: no cover - never delivered
        raise AssertionError("not called")

    before = signal.signal(signal.SIGTERM, own_handler)
    try:
        bad = ["--env", "KoopNav-TargetReaching-v0", "--maps", "map9", "--out", str(tmp_path / "o")]
        assert ev.main(bad) == 2
        assert signal.getsignal(signal.SIGTERM) is own_handler
        tiny = ["--env", "KoopNav-TargetReaching-v0", "--maps", "map1", "--episodes", "1"]
        tiny += [
            "--max-episode-steps",
            "3",
            "--controllers",
            "consensus",
            "--quiet",
            "--out",
            str(tmp_path / "r"),
        ]
        assert ev.main(tiny) == 0
        assert signal.getsignal(signal.SIGTERM) is own_handler
    finally:
        signal.signal(signal.SIGTERM, before)
