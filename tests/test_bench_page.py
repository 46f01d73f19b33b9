"""docs/bench_results.md and README's headline (docs/make_bench_md.py, issue 60) on small real
runs of the test split, and the page's tolerance of runs published progressively.

The fixtures are two real runs of the evaluator on layouts 0-2 of each task's test split, orca and
consensus, packed as data/publish.sh packs (12 episodes each)::

    python evaluate.py --suite koopnav-bench-v1 --split test --layouts 0:3 --controllers orca consensus \\
        --reference orca [--realtime] --out RUN
    python -m evaluation.archive RUN tests/data/bench_test[_realtime]_layouts0-2.tar.xz
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from controllers.tuning import study_budget
from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import pack_run
from evaluation.reports.sections.blocks import rate_cell

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_bench_md import HEADLINE, load_mode, main, page  # noqa: E402  (docs/ is no package)
from make_pages import block_of, with_block  # noqa: E402

FREE = ROOT / "tests" / "data" / "bench_test_layouts0-2.tar.xz"
CHARGED = ROOT / "tests" / "data" / "bench_test_realtime_layouts0-2.tar.xz"


@pytest.fixture(scope="module")
def modes() -> list:
    return [load_mode("charged", CHARGED), load_mode("free", FREE)]


def test_the_page_lays_out_the_evaluators_numbers(modes) -> None:
    text = page(modes, None)
    block = block_of(text, HEADLINE)
    assert block is not None and text.count(block) == 1
    charged, free = modes
    # every headline cell is the evaluator's layout_summary, charged and free side by side
    for row in charged.results.layout_summary:
        other = next(
            r
            for r in free.results.layout_summary
            if (r["env_id"], r["controller"]) == (row["env_id"], row["controller"])
        )
        cells = [rate_cell(r["success"]["value"], r["success"]["ci"]) for r in (row, other)]
        line = next(
            line for line in block.splitlines() if line.startswith(f"| {row['controller']} | {cells[0]} |")
        )
        assert line.endswith(f" | {cells[1]} |")
    # the suite's label with its hash, the tested tables with their families and power
    assert "koopnav-bench-v1/target_reaching/test@7f6471b2138e" in block
    assert "**Paired: Success**" in text and "**Paired: Strict success" in text
    assert "**Paired: Success excusing unavoidable collisions**" in text
    assert text.count("is found with 80% power") == 2 * 8  # 8 tables per mode
    assert "## Tuning budget" in text and "| orca | validation | 24 of 24 | 50 | 1,200 |" in text
    assert "pending" not in text.split("## The runs")[1].split("## Leaderboard")[0]


def test_a_partial_run_names_its_pending_rows(tmp_path) -> None:
    """An interrupted run (formation consensus has 1 of its 3 episodes) and a run not published
    yet: their rows are pending, the complete ones shown, nothing fails."""
    with extracted_archive(CHARGED) as run:
        log = run / "episodes.jsonl"
        lines = log.read_text(encoding="utf-8").splitlines(keepends=True)
        assert json.loads(lines[-1])["controller"] == "consensus"
        log.write_text("".join(lines[:-2]), encoding="utf-8")
        partial = pack_run(run, tmp_path / "bench_test_realtime.tar.xz")
    out = tmp_path / "page.md"
    assert main(["--charged", str(partial), "--free", str(tmp_path / "bench_test"), "--out", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    block = block_of(text, HEADLINE)
    assert block is not None
    assert "| consensus | pending: 1 of 3 episodes |" in block
    assert "pending: not published yet" in block
    assert "pending: formation consensus (1 of 3 episodes)" in text
    assert "**The paper track**: pending" in block
    # the pending row is in no tested table
    tested = text.split("## Compute charged: outcomes")[1]
    assert "| formation | orca | consensus |" not in tested
    assert "| target reaching | orca | consensus |" in tested


def test_nothing_published_gives_a_pending_headline(tmp_path) -> None:
    out = tmp_path / "page.md"
    assert main(["--charged", str(tmp_path / "a"), "--free", str(tmp_path / "b"), "--out", str(out)]) == 0
    block = block_of(out.read_text(encoding="utf-8"), HEADLINE)
    assert block is not None and ": pending, " in block and "|" not in block


def test_the_modes_are_refused_swapped(tmp_path, capsys) -> None:
    out = tmp_path / "page.md"
    assert main(["--charged", str(FREE), "--free", str(CHARGED), "--out", str(out)]) == 2
    assert "its decision time is not charged; --charged needs compute charged" in capsys.readouterr().err
    assert not out.exists()


def test_readmes_block_is_replaced_in_place() -> None:
    readme = "intro\n<!-- begin x: note -->\nold\n<!-- end x -->\ntail\n"
    block = "<!-- begin x: new -->\n| 1 |\n<!-- end x -->\n"
    assert with_block(readme, "x", block) == "intro\n" + block + "tail\n"
    assert block_of(with_block(readme, "x", block), "x") == block
    with pytest.raises(ValueError, match="no block 'y'"):
        with_block(readme, "y", block)


def test_a_study_gives_its_budget_finished_or_not(tmp_path) -> None:
    budget = study_budget("orca")
    assert budget is not None and budget.finished and budget.episodes_run == 1200
    assert budget.verdict == "defaults kept (a tie)"
    assert study_budget("no-such-controller") is None
    # a study cut short is reported unfinished, not refused
    (tmp_path / "orca").mkdir()
    log = (
        (ROOT / "data" / "tuning" / "orca" / "study.jsonl")
        .read_text(encoding="utf-8")
        .splitlines(keepends=True)
    )
    (tmp_path / "orca" / "study.jsonl").write_text("".join(log[:6]), encoding="utf-8")
    cut = study_budget("orca", tmp_path)
    assert cut is not None and not cut.finished
    assert (cut.configurations_run, cut.configurations, cut.verdict) == (5, 24, "unfinished")


def test_runs_of_different_suites_are_refused(tmp_path, capsys) -> None:
    """Side by side, the two modes must have run the same units: a run of other layouts is named."""
    with extracted_archive(FREE) as run:
        log = run / "episodes.jsonl"
        lines = log.read_text(encoding="utf-8").splitlines(keepends=True)
        header = json.loads(lines[0])
        header["config"]["suite"]["layouts"] = [0, 2]
        kept = [line for line in lines[1:] if json.loads(line)["layout"] < 2]
        log.write_text(json.dumps(header) + "\n" + "".join(kept), encoding="utf-8")
        other = pack_run(run, tmp_path / "bench_test.tar.xz")
    out = tmp_path / "page.md"
    assert main(["--charged", str(CHARGED), "--free", str(other), "--out", str(out)]) == 2
    assert "the publications ran different suites" in capsys.readouterr().err
