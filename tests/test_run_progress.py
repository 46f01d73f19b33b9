"""How far a run is, defined once (:mod:`evaluation.stats.progress`): the benchmark page's
(task, controller) progress and the sim-to-sim page's per-controller progress read the same plan
from a run's header, so a header without ``slips`` (one slip, the default) is read alike by both."""

from __future__ import annotations

import json
from pathlib import Path

from evaluation.reports.bench import BenchProgress, load_mode
from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import pack_run
from evaluation.stats.progress import Progress, planned_episodes
from evaluation.stats.transfer import run_progress

ROOT = Path(__file__).resolve().parents[1]
CHARGED = ROOT / "tests" / "data" / "bench_test_realtime_layouts0-2.tar.xz"


def _without_slips(tmp_path: Path) -> Path:
    """The charged fixture with ``slips`` taken out of its header, packed again."""
    with extracted_archive(CHARGED) as run:
        log = run / "episodes.jsonl"
        lines = log.read_text(encoding="utf-8").splitlines()
        header = json.loads(lines[0])
        assert header["config"].pop("slips") == ["high"]
        log.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n", encoding="utf-8")
        return pack_run(run, tmp_path / "bench_test_realtime.tar.xz")


def test_the_bench_progress_is_the_shared_plan() -> None:
    """Each (task, controller) of the fixture plans its suite's layouts x episodes per layout x
    slips (3 x 1 x 1), the count :func:`planned_episodes` gives, and says so on the page."""
    mode = load_mode("charged", CHARGED)
    assert mode.results is not None
    config = mode.results.config
    assert {(state.done, state.planned) for state in mode.progress.values()} == {(3, 3)}
    for (env_id, _), state in mode.progress.items():
        assert isinstance(state, Progress)
        assert state.planned == planned_episodes(config, env_id)
    assert BenchProgress(1, 3).text() == "pending: 1 of 3 episodes"
    assert not BenchProgress(2, 3).complete and BenchProgress(3, 3).complete


def test_a_header_without_slips_plans_one_slip_on_both_pages(tmp_path: Path) -> None:
    """The header without ``slips`` plans the same 3 episodes per (task, controller) (the bench's
    own count raised KeyError here) and 6 per controller over both tasks for sim-to-sim."""
    mode = load_mode("charged", _without_slips(tmp_path))
    assert mode.results is not None
    assert "slips" not in mode.results.config
    assert {(state.done, state.planned) for state in mode.progress.values()} == {(3, 3)}
    assert mode.pending("KoopNav-Formation-v0", "consensus") is None
    assert run_progress(mode.results) == {"orca": Progress(6, 6), "consensus": Progress(6, 6)}
