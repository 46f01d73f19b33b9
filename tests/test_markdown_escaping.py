"""Markdown reports escape user text as the HTML page does (issue 41, item 11): a controller label
such as ``<img src=x onerror=alert(1)>`` shows as text in results.md and the baseline comparison,
never as a tag a Markdown viewer would render."""

from __future__ import annotations

import evaluate as ev
from evaluation.reports.sections import Items, Note, Section, TableBlock, markdown, markdown_text

HOSTILE = "<img src=x onerror=alert(1)>"


def test_markdown_text_escapes_what_opens_a_tag_and_keeps_comparisons() -> None:
    assert markdown_text(HOSTILE) == "&lt;img src=x onerror=alert(1)>"
    assert markdown_text("</script><!-- x --><?php") == "&lt;/script>&lt;!-- x -->&lt;?php"
    assert markdown_text("p <0.001, a < b, 3<4") == "p <0.001, a < b, 3<4"  # no tag: unchanged


def test_tables_items_titles_and_notes_are_escaped() -> None:
    text = markdown(
        [
            Section(
                "s",
                f"Title {HOSTILE}",
                (
                    Note(f"note {HOSTILE}"),
                    TableBlock((["Controller", "x"], [[HOSTILE, "a|b"]]), caption=HOSTILE),
                    Items((("key`with`ticks", f"error {HOSTILE}"),)),
                ),
            )
        ]
    )
    assert "<img" not in text
    assert "| &lt;img src=x onerror=alert(1)> | a\\|b |" in text  # the pipe no longer splits the row
    assert "- `` key`with`ticks ``: error &lt;img" in text  # the code span outlasts the backticks


def test_a_hostile_label_is_text_in_every_report_file(tmp_path) -> None:
    out = tmp_path / "run"
    code = ev.main(
        [
            "--env",
            "KoopNav-TargetReaching-v0",
            "--maps",
            "map1",
            "--episodes",
            "1",
            "--max-episode-steps",
            "5",
            "--workers",
            "1",
            "--quiet",
            "--controllers",
            f"consensus:label={HOSTILE}",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    report = (out / "results.md").read_text()
    assert "<img" not in report and "&lt;img src=x onerror=alert(1)>" in report
    assert HOSTILE not in (out / "index.html").read_text()
