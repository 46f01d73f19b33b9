"""The seeds' per-seed table says which seed was chosen on validation, not that it was shipped:
the table (seeds.md, and docs/seeds_results.md, which is the command's own tables) is written
before ``--ship`` copies anything, and the published run (``bash data/publish.sh seeds``) runs
without ``--ship``; it said "shipped: yes" of a seed whose policy is not the shipped one."""

from __future__ import annotations

from pathlib import Path

from evaluation.experiments.seeds import SeedRun, aggregate, report_markdown


def test_the_per_seed_table_names_the_chosen_seed_without_claiming_it_shipped() -> None:
    runs = [
        SeedRun("ippo", "formation", seed, Path("."), {"success_rate": rate, "step": 10})
        for seed, rate in ((0, 0.4), (1, 0.6), (2, 0.5))
    ]
    result = aggregate({0: {0: [1], 1: [0]}, 1: {0: [1], 1: [1]}, 2: {0: [0], 1: [0]}}, n_boot=50)
    table = report_markdown(
        [
            {
                "policy": "ippo",
                "task": "formation",
                "suite": "s",
                "runs": runs,
                "aggregate": result,
                "chosen": runs[1],
            }
        ],
        "validation",
    )
    per_seed = table.split("\n\n")[0].splitlines()
    assert per_seed[0].endswith("| validation success [95% CI over layouts] | chosen (what --ship ships) |")
    assert [line.rsplit("|", 2)[1].strip() for line in per_seed[2:]] == ["", "chosen on validation", ""]
    assert "shipped" not in table.replace("--ship ships", "")
