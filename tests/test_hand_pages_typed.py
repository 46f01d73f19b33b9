"""A number typed into any audited page (tests/helpers/hand_audit.py) is named with its page, its
line and its token: one test for every page of tests/test_hand_pages*.py, and a check that no
audited page is left without a case; and a prose number is a repeat of a table only where its
sentence names the row that holds it."""

from __future__ import annotations

import pytest
import test_hand_pages
import test_hand_pages_controllers
import test_hand_pages_ops
import test_hand_pages_rl

from helpers.hand_audit import Audit, named_rows, page_problems, sentence, table_rows, typed_into

#: every audited page -> its audit, from the four files that hold the pages' claims
AUDITS: dict[str, Audit] = {
    **test_hand_pages.AUDITS,
    **test_hand_pages_ops.AUDITS,
    test_hand_pages_controllers.PAGE: test_hand_pages_controllers.AUDIT,
    test_hand_pages_rl.PAGE: test_hand_pages_rl.AUDIT,
}

#: (page, the line it is typed after, the typed line, the token the audit must name)
TYPED = [
    ("benchmark.md", "## Versioning\n", "A check takes 12 s on this machine.\n", "12 s"),
    ("benchmark.md", "## Metrics\n", "Of the layouts, 7 of 9 are hard.\n", "7 of 9"),
    ("benchmark.md", "## Statistics\n", "It rejects in 41% of the cases.\n", "41%"),
    ("physics.md", "## Speed\n", "| a new row | 1,234 | 2.5 |\n", "1,234"),
    ("physics.md", "## The robot\n", "It drives at 0.45 m/s.\n", "0.45 m/s"),
    ("physics.md", "## Speed\n", "It steps 2.5x faster.\n", "2.5x"),
    ("physics.md", "## What the model learns\n", "Its error is 9.99 cm.\n", "9.99 cm"),
    ("performance.md", "## Rendering\n", "A frame takes 12 ms.\n", "12 ms"),
    ("movers.md", "## Speed\n", "It runs at 9,999 env-steps/s.\n", "9,999 env-steps/s"),
    ("ci.md", "## Exit codes\n", "The suite took 99 CPU-s.\n", "99 CPU-s"),
    ("layout.md", "## What a clone weighs\n", "A clone is 300 MB.\n", "300 MB"),
    ("environments.md", "## Maps\n", "Of the seeds, 7 of 9 fit.\n", "7 of 9"),
    ("robustness.md", "# Robustness profiles\n", "It keeps 41% of them.\n", "41%"),
    ("uncertainty.md", "## Presets\n", "A preset costs 3.5 ms.\n", "3.5 ms"),
    ("evaluator.md", "## Equal terms\n", "A run takes 42 CPU-hours.\n", "42 CPU-hours"),
    ("hard_constraints.md", "## What remains inherent\n", "It fails 17 of 80.\n", "17 of 80"),
    ("perception.md", "## Accuracy\n", "Its error is 2.2 cm.\n", "2.2 cm"),
    ("getting_started.md", "## Install\n", "It installs in 95 s.\n", "95 s"),
    ("controllers.md", "## Consensus\n", "It takes 0.4 ms per step.\n", "0.4 ms"),
    ("controllers.md", "## Safety filter\n", "| a new row | 3/20 [1-23%] |\n", "3/20"),
    ("rl.md", "## Results\n", "It settles 41% of them.\n", "41%"),
    ("rl.md", "### BenchMARL\n", "It runs at 1,234 frames/s.\n", "1,234 frames/s"),
]


@pytest.mark.parametrize(("page", "after", "typed", "token"), TYPED)
def test_a_new_number_typed_into_a_page_is_named_with_its_line(
    page: str, after: str, typed: str, token: str
) -> None:
    edited, line = typed_into(AUDITS[page], after, typed)
    assert f"docs/{page} line {line}: {token!r} is checked by nothing" in page_problems(edited, AUDITS[page])


def test_every_audited_page_has_a_typed_number() -> None:
    assert sorted({case[0] for case in TYPED}) == sorted(AUDITS)


#: docs/physics.md's first region of model-error tables (up to "### A lift with memory"), the
#: figures typed into it, and whether the audit takes each as a repeat: the same figure counts
#: only where the sentence names its row
MODEL = "## What the model learns\n"


@pytest.mark.parametrize(
    ("typed", "token", "repeat"),
    [
        # the section's first table: its ice row holds 8.31 (the circle's ratio)
        ("On ice the model errs 8.31 times the unicycle's.\n", "8.31 times", True),
        # 36.89 is the carpet row's ratio: a table figure, but not of a row the sentence names
        ("On ice the model errs 36.89 times the unicycle's.\n", "36.89 times", False),
        # a sentence that names no row repeats nothing, whatever the tables hold
        ("The model errs 8.31 times the unicycle's.\n", "8.31 times", False),
    ],
)
def test_a_repeat_names_its_row(typed: str, token: str, repeat: bool) -> None:
    audit = AUDITS["physics.md"]
    edited, line = typed_into(audit, MODEL, typed)
    named = f"docs/physics.md line {line}: {token!r} is checked by nothing" in page_problems(edited, audit)
    assert named is not repeat


def test_the_rows_a_sentence_names() -> None:
    table = (
        "| floor | lift | error |\n|---|---|---|\n| high (ice) | pose only | 8.39 |\n"
        "| | `memory 3` | 4.1 |\n| nominal (carpet) | pose only | 36.89 |\n| consensus | time limit, 600: 1, 202 | 2 |\n"
    )
    rows = table_rows(table)
    assert [row.labels for row in rows[1:3]] == [
        (("high (ice)", "high", "ice"), ("pose only",)),
        (("high (ice)", "high", "ice"), ("memory 3",)),
    ]
    assert rows[4].labels == (("consensus",),)  # a cell that describes names nothing
    text = "Intro. On ice, memory 3 errs 4.1 cm. On carpet the pose only lift errs more.\n"
    at = text.index("4.1")
    assert sentence(text, at, at + 3) == "on ice, memory 3 errs 4.1 cm"
    assert [r.numbers for r in named_rows(rows, sentence(text, at, at + 3))] == [("4.1",)]  # code kept out
    at = text.index("more")
    assert [r.numbers for r in named_rows(rows, sentence(text, at, at + 4))] == [("36.89",)]
