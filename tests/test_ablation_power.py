"""docs/ablation.md's full-data path states its power (issue 60: a power statement per table):
on a synthetic complete publication, the page docs/make_ablation_md.py writes has the main-effects
table's family (m = 3 factors, Holm) and the smallest main effect found with 80% power, and that
number is the one recomputed here from the units' differences. The published page is a progress
page while the ablation run is partial (tests/test_ablation_partial.py)."""

from __future__ import annotations

import json
import re
import statistics
import sys
from pathlib import Path

import pytest

from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import pack_run
from evaluation.stats.families import detectable_difference

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_ablation_md import page  # noqa: E402  (docs/ is no package)

FIXTURE = ROOT / "tests" / "data" / "ablation_trial0.tar.xz"
SEEDS = 12
FACTORS = ("model", "margins", "constraints")
#: what makes a record its configuration's (kept when its outcome is taken from another's)
IDENTITY = ("key", "env_id", "controller", "map", "slip", "controller_name", "controller_options")


def _wins(label: str, unit: int) -> bool:
    """A synthetic outcome: soft constraints win more, widened margins a little more, the model
    nothing; varied by unit so the units' differences spread."""
    levels = dict(part.split("=") for part in label.split())
    score = (unit * 7) % 10
    return score < (6 if levels["constraints"] == "soft" else 3) + (
        1 if levels["margins"] == "widened" else 0
    )


def _complete(tmp_path: Path) -> tuple[Path, list[dict]]:
    """The fixture's run grown to ``SEEDS`` episodes per map (its header says so), every episode
    distinct (its final poses moved by its seed), packed as a complete publication."""
    with extracted_archive(FIXTURE) as run:
        lines = (run / "episodes.jsonl").read_text().splitlines()
    header = json.loads(lines[0])
    header["config"]["episodes"] = SEEDS
    fixture = [json.loads(line) for line in lines[1:]]
    records = []
    maps: dict[str, int] = {}
    for base in fixture:
        for seed in range(SEEDS):
            unit = maps.setdefault(base["map"], len(maps)) * SEEDS + seed
            won = _wins(base["controller"], unit)
            # the outcome of an episode of the fixture on the same map that ended so (the same
            # configuration's first): a whole, consistent record; the base's where none did
            same_map = [r for r in fixture if r["map"] == base["map"] and r["success"] == won]
            same_map.sort(key=lambda r: r["controller"] != base["controller"])
            outcome = same_map[0] if same_map else base
            records.append(
                {
                    **outcome,
                    **{k: base[k] for k in IDENTITY},
                    "key": base["key"].rsplit("|", 1)[0] + f"|{seed}",
                    "trial": seed,
                    "seed": seed,
                    "final_poses": [[x + 1e-3 * seed, y, t] for x, y, t in outcome["final_poses"]],
                }
            )
    made = tmp_path / "ablation"
    made.mkdir()
    text = "\n".join([json.dumps(header), *(json.dumps(r) for r in records)]) + "\n"
    (made / "episodes.jsonl").write_text(text)
    return pack_run(made, tmp_path / "ablation.tar.xz"), records


def _expected_power(records: list[dict]) -> tuple[int, float, float]:
    """Units, the median over factors of the SD of the units' differences, and the detectable main
    effect at Holm's first step over the 3 factors: recomputed from the records."""
    outcomes: dict[tuple, dict[str, bool]] = {}
    for r in records:
        outcomes.setdefault((r["env_id"], r["map"], r["slip"], r["seed"]), {})[r["controller"]] = r["success"]
    sds = []
    for factor in FACTORS:
        diffs = []
        for won in outcomes.values():
            pairs = []
            for label, a in won.items():
                levels = dict(part.split("=") for part in label.split())
                first = {"model": "learned", "margins": "paper", "constraints": "soft"}[factor]
                second = {"model": "nominal", "margins": "widened", "constraints": "hard"}[factor]
                if levels[factor] != first:
                    continue
                other = " ".join(f"{f}={second if f == factor else levels[f]}" for f in FACTORS)
                pairs.append(a - won[other])
            diffs.append(sum(pairs) / len(pairs))
        sds.append(statistics.stdev(diffs))
    sd = statistics.median(sds)
    units = len(outcomes)
    return units, sd, detectable_difference(units, 1, sd=sd, family_size=3)


def test_a_complete_publication_states_the_tables_power(tmp_path: Path) -> None:
    archive, records = _complete(tmp_path)
    text = page(archive)
    assert "In progress" not in text and "Pending" not in text
    units, sd, difference = _expected_power(records)
    assert units == 4 * SEEDS
    statement = re.search(
        r"Family 'ablation: main effects on success, one per factor': m = 3 tests, Holm at alpha = 0\.05 "
        r"\(first step alpha/m = 0\.0167\)\. With (\d+) episode units \(each its own cluster\) and an SD of "
        r"the units' differences of ([\d.]+), a main effect of ([\d.]+) points is found with 80% power\.",
        text,
    )
    assert statement is not None, "the main-effects table has no power statement"
    assert int(statement[1]) == units
    assert float(statement[2]) == pytest.approx(sd, rel=1e-2)
    assert statement[3] == f"{100 * difference:.1f}"
    # the statement sits right below the main-effects table
    table_end = text.index("| constraints | soft vs hard |")
    assert text.index("Family 'ablation:") > table_end
    assert "|" not in text[text.index("\n", table_end) : text.index("Family 'ablation:")].strip()
