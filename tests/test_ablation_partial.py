"""docs/make_ablation_md.py on a publication packed while the ablation runs (a checkpoint carried
to the next session): the page says how far each configuration is and estimates no effect until
every configuration has the episodes its run plans; on a complete run it is the evaluator's
report as before. On a small real run (tests/data/ablation_trial0.tar.xz: 8 configurations, 4
maps, 1 episode each)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import pack_run

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_ablation_md import page, shortfalls  # noqa: E402  (docs/ is no package)

FIXTURE = ROOT / "tests" / "data" / "ablation_trial0.tar.xz"
HARD = "model=learned margins=paper constraints=hard"
SOFT = "model=learned margins=paper constraints=soft"


def _partial(tmp_path: Path, keep: int) -> Path:
    """The fixture with ``HARD``'s records cut to its first ``keep`` and every record of the
    configurations after it in the header's order gone, packed as the run would be mid-way."""
    with extracted_archive(FIXTURE) as run:
        lines = (run / "episodes.jsonl").read_text().splitlines()
    header = json.loads(lines[0])
    labels = [c["label"] for c in header["config"]["controller_configs"]]
    later = set(labels[labels.index(HARD) + 1 :])
    kept, hard = [lines[0]], 0
    for line in lines[1:]:
        label = json.loads(line)["controller"]
        if label == HARD:
            hard += 1
            if hard > keep:
                continue
        if label not in later:
            kept.append(line)
    made = tmp_path / "ablation"
    made.mkdir()
    (made / "episodes.jsonl").write_text("\n".join(kept) + "\n")
    return pack_run(made, tmp_path / "ablation.tar.xz")


def test_a_partial_run_names_each_unfinished_configuration_and_states_no_effect(tmp_path: Path) -> None:
    text = page(_partial(tmp_path, keep=1))
    assert "**In progress: the ablation run is published partial**" in text
    assert f"| {HARD} | 1 of 4 |" in text
    assert f"| {SOFT} |" not in text  # complete: not listed
    assert "complete configurations (every episode their run plans) 1 of 8" in text
    assert "main effect" in text and "Holm" not in text and "%" not in text


def test_shortfalls_come_from_the_runs_header(tmp_path: Path) -> None:
    with extracted_archive(_partial(tmp_path, keep=3)) as run:
        lines = (run / "episodes.jsonl").read_text().splitlines()
    config = json.loads(lines[0])["config"]
    short = shortfalls(config, [json.loads(line) for line in lines[1:]])
    assert short[HARD] == (3, 4) and SOFT not in short and len(short) == 7
    assert all(planned == 4 for _, planned in short.values())


def test_a_complete_run_is_the_evaluators_report() -> None:
    text = page(FIXTURE)
    assert "In progress" not in text and "Holm" in text
