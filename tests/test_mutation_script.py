""".ci/mutation.sh with WORKDIR (issue 59): a mutation run that continues in a later session.

The script is run for real (mutmut 3 and all) on a repository of one tiny module in ``tmp_path``
that stands in for ``evaluation/episodes/records.py``: a run, then what an interruption or a
kill can leave (verdicts missing or interrupted, a torn meta or score file), then a rerun, which
must test again exactly the mutants without a trusted verdict and reach the same score. Killing
the script at a chosen moment is left to a measurement (docs/ci.md), as it would depend on timing.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from helpers.mutation_repo import MUTMUT_MISSING, git, run_script, score_line, tiny_source

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(MUTMUT_MISSING is not None, reason=str(MUTMUT_MISSING)),
]


def _run(source: Path, workdir: Path, **extra: str) -> subprocess.CompletedProcess[str]:
    # the committed store beside the clone, tests/test_mutation_store.py
    return run_script(source, workdir.parent / "store", workdir, **extra)


def _meta(workdir: Path) -> Path:
    return workdir / "records/koopnav/mutants/evaluation/episodes/records.py.meta"


def test_a_rerun_tests_only_the_mutants_without_a_trusted_verdict_and_refuses_another_clone(
    tmp_path: Path,
) -> None:
    source, workdir = tiny_source(tmp_path / "source"), tmp_path / "work"
    first = _run(source, workdir)
    assert first.returncode == 0, first.stdout + first.stderr
    score = score_line(first)
    assert score.startswith("records: 5/6 killed (83.3%)"), score
    assert "survived: evaluation.episodes.records.x_grade__mutmut_" in first.stdout
    meta = json.loads(_meta(workdir).read_text())
    durations = meta["durations_by_key"]
    assert len(durations) == 6

    # finished: the kept score is printed again and mutmut is not started
    log = (workdir / "records/run.log").read_text()
    again = _run(source, workdir)
    assert again.returncode == 0, again.stdout + again.stderr
    assert score_line(again) == f"{score} (finished in an earlier session)"
    assert (workdir / "records/run.log").read_text() == log

    # what an interruption leaves: two mutants without a verdict, one interrupted (pytest's 2),
    # and a score file cut short
    names = sorted(durations)
    meta["exit_code_by_key"][names[0]] = None
    meta["exit_code_by_key"][names[1]] = None
    meta["exit_code_by_key"][names[2]] = 2
    _meta(workdir).write_text(json.dumps(meta))
    score_file = workdir / "records/score"
    score_file.write_text(score_file.read_text()[:-20])
    (tmp_path / "store/records.json").unlink()  # the clone's verdicts alone
    resumed = _run(source, workdir)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert "torn score file" in resumed.stdout
    assert "3 of 6 mutants have a verdict, 1 interrupted or doubtful verdicts to test again" in (
        resumed.stdout
    )
    assert score_line(resumed).split(" in ")[0] == score.split(" in ")[0]
    after = json.loads(_meta(workdir).read_text())["durations_by_key"]
    assert [after[n] == durations[n] for n in names] == [False, False, False, True, True, True]

    # a torn meta file: no verdict of it is trusted, every mutant is made and tested afresh
    _meta(workdir).write_text(_meta(workdir).read_text()[:40])
    score_file.unlink()
    (tmp_path / "store/records.json").unlink()
    afresh = _run(source, workdir)
    assert afresh.returncode == 0, afresh.stdout + afresh.stderr
    assert "records.py.meta is torn: every mutant is made and tested afresh" in afresh.stdout
    assert score_line(afresh).split(" in ")[0] == score.split(" in ")[0]
    renewed = json.loads(_meta(workdir).read_text())["durations_by_key"]
    assert not any(renewed[n] == after[n] for n in names)

    # another test selection, then another commit: refused by name, nothing run
    other = _run(source, workdir, WITHOUT="tests/test_records.py")
    assert other.returncode == 2
    assert f"{workdir}/records/koopnav was set up with another test selection" in other.stderr
    cloned = git(source, "rev-parse", "HEAD")
    (source / "README.md").write_text("moved on\n")
    git(source, "add", ".")
    git(source, "commit", "-qm", "later")
    later = _run(source, workdir)
    assert later.returncode == 2
    head = git(source, "rev-parse", "HEAD")
    assert f"{workdir}/records was cloned from commit {cloned}, not from" in later.stderr
    assert head in later.stderr and f"remove {workdir}/records" in later.stderr
