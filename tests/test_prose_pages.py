"""docs/paper.md is written from a template whose numbers are placeholders filled from the
committed data (docs/make_prose_md.py, issue 60): one section expanded here against the committed
page (the whole page is rebuilt byte for byte by tests/test_published_pages.py, slow), and a bad
placeholder refused by name."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_pages import PAGES  # noqa: E402  (docs/ is no package)
from make_prose_md import expand  # noqa: E402
from prose_numbers import Runs, parse_runs  # noqa: E402

PAPER = next(entry for entry in PAGES if entry["page"] == "docs/paper.md")
TEMPLATE = (ROOT / PAPER["args"][0]).read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def paper_runs() -> Runs:
    """The runs docs/paper.md reads (data/pages.json), each loaded when a placeholder names it."""
    return Runs(parse_runs(PAPER["args"][PAPER["args"].index("--runs") + 1 :]))


def test_a_part_of_the_paper_page_is_rebuilt_from_the_data(paper_runs) -> None:
    """The team-size section (four small archives) expands to the committed page's text; the
    whole page is rebuilt byte for byte by tests/test_published_pages.py (slow)."""
    heading = "## Results with larger teams"
    section = heading + TEMPLATE.split(heading)[1].split("\n## ")[0]
    text = expand(section, paper_runs)
    assert "{{" not in text and "| 16 (3) | 3/3 [44-100%]" in text
    assert text in (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("placeholder", "message"),
    [
        ("{{ nope scale_n3 }}", "'nope' is not one of the functions"),
        ("{{ kn scale_n99 koopman-nmpc }}", "run 'scale_n99' is not one of the page's runs"),
        ("{{ kn scale_n3 koopman }}", "controller 'koopman' is not in the run"),
        ("{{ kn scale_n3 koopman-nmpc slip=high }}", "no episode of koopman-nmpc with {'slip': 'high'}"),
        ("{{ kn scale_n3@movers.count=4 koopman-nmpc }}", "run 'scale_n3' is not a sweep"),
        ("{{ kn scale_n3 }}", "kn takes 2 argument(s) besides the filters"),
        ("{{ scale_table koopman-nmpc runs=scale_n3 slip=high }}", "scale_table takes no filter"),
        ("{{ scale_table koopman-nmpc }}", "scale_table needs runs=NAME,NAME"),
        ("{{ kn scale_n3 koopman-nmpc", "an unpaired '{{' is left in the page at line 1"),
    ],
)
def test_a_bad_placeholder_is_refused_by_name(paper_runs, placeholder, message) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        expand(placeholder, paper_runs)


def test_a_run_list_that_is_not_name_equals_path_is_refused() -> None:
    with pytest.raises(ValueError, match=re.escape("run 'data/paper.tar.xz' is not NAME=PATH")):
        parse_runs(["data/paper.tar.xz"])
    with pytest.raises(ValueError, match=re.escape("run 'a' is given twice")):
        parse_runs(["a=x.tar.xz", "a=y.tar.xz"])


def test_the_ablation_placeholders_read_the_evaluators_main_effects() -> None:
    """``effect``, ``effect_p`` and ``factor_table`` on the small real ablation run
    (tests/test_ablation_units.py's fixture): what the published ablation will feed the page."""
    from evaluation.experiments.ablation import main_effects
    from evaluation.reports.publications import extracted_archive
    from evaluation.reports.published import results_from_log

    archive = "tests/data/ablation_trial0.tar.xz"
    runs = Runs(parse_runs([f"ablation={archive}"]))
    with extracted_archive(ROOT / archive) as run:
        margins = next(
            e for e in main_effects(results_from_log(run / "episodes.jsonl")) if e["factor"] == "margins"
        )
    low, high = round(100 * margins["low"]), round(100 * margins["high"])
    expected = f"{round(100 * margins['difference']):+d} [{low:+d}, {high:+d}]"
    assert expand("{{ effect ablation margins }}", runs) == expected
    assert expand("{{ effect_p ablation margins }}", runs).startswith("Holm p = ")
    table = expand("{{ factor_table ablation }}", runs).splitlines()
    assert table[0] == "| Configuration | learned model | nominal model |"
    assert len(table) == 2 + 4 and table[2].startswith("| paper margins, soft constraints | 75% [30-95] |")
