"""The tuning studies' curves as the docs show them (issue 60, "the docs show each controller's
expected best validation score against the number of configurations tried"): docs/tuning.md's
table rebuilt from the committed studies (data/tuning/*/study.jsonl) by code of its own, and the
figure docs/_static/tuning.png against what its generator draws.

The figure: docs/make_tuning_md.py draws it through docs/make_pages.py's registry (data/pages.json)
with matplotlib's Agg backend, which writes the same bytes for the same data and matplotlib; the
PNG records the matplotlib that drew it (its ``Software`` text chunk), so the bytes are compared
when that is the installed one, and otherwise the image's size and the generator's run.
"""

from __future__ import annotations

import json
import re
import struct
import sys
from pathlib import Path

import matplotlib
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
import make_tuning_md  # noqa: E402

from controllers.tuning import STUDIES_DIR  # noqa: E402
from evaluation.tune.report import CURVE_POINTS, expected_best_markdown, load_summary  # noqa: E402

PAGE = ROOT / "docs" / "tuning.md"
FIGURE = ROOT / "docs" / "_static" / "tuning.png"


def _entry() -> dict:
    (entry,) = [
        e for e in json.loads((ROOT / "data" / "pages.json").read_text()) if e["page"] == "docs/tuning.md"
    ]
    return entry


def _folders() -> list[Path]:
    """The studies the page shows: its registry entry's controllers, each data/tuning/NAME."""
    return [STUDIES_DIR / name for name in _entry()["args"]]


def _scores(folder: Path) -> list[float]:
    """The trials' scores of a study log, read as plain JSON lines (the header first)."""
    lines = (folder / "study.jsonl").read_text(encoding="utf-8").splitlines()
    assert json.loads(lines[0])["kind"] == "koopnav-study"
    return [float(json.loads(line)["score"]) for line in lines[1:] if line.strip()]


def _expected_best(scores: list[float], n: int) -> float:
    """Dodge et al. (2019): the expected best of n draws with replacement from the scores,
    sum_i v_(i) ((i/N)^n - ((i-1)/N)^n), the scores sorted."""
    ordered = sorted(scores)
    size = len(ordered)
    return sum(v * ((i / size) ** n - ((i - 1) / size) ** n) for i, v in enumerate(ordered, start=1))


def _page_rows(text: str) -> dict[str, list[str]]:
    """The curves table of docs/tuning.md: controller -> its cells after the task."""
    section = text.split("## The curves as a table", 1)[1]
    rows = {}
    for line in section.splitlines():
        found = re.match(r"^\| `([\w-]+)` \| \w+ \| (.*) \|$", line)
        if found:
            rows[found[1]] = [cell.strip() for cell in found[2].split("|")]
    return rows


def curve_problems(text: str) -> list[str]:
    """Every cell of ``text``'s curves table that the committed studies do not give, and every
    study of the page's registry entry the table leaves out."""
    rows = _page_rows(text)
    problems = []
    for folder in _folders():
        scores = _scores(folder)
        name = json.loads((folder / "study.jsonl").read_text(encoding="utf-8").splitlines()[0])["controller"]
        if name not in rows:
            problems.append(f"{name}: no row")
            continue
        *cells, last = rows[name]
        expected = [f"{_expected_best(scores, n):.3f}" if n <= len(scores) else "-" for n in CURVE_POINTS]
        expected_last = f"{_expected_best(scores, len(scores)):.3f} (N = {len(scores)})"
        if cells != expected or last != expected_last:
            problems.append(
                f"{name}: the page states {rows[name]}; the study gives {[*expected, expected_last]}"
            )
    return problems


def test_the_pages_curves_are_the_studies() -> None:
    text = PAGE.read_text(encoding="utf-8")
    assert len(_page_rows(text)) == len(_entry()["args"]) == 6
    assert curve_problems(text) == []


def test_an_edited_curve_fails() -> None:
    text = PAGE.read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith("| `dwa` | both | 0."))
    cells = row.split(" | ")
    cells[3] = f"{float(cells[3]) + 0.001:.3f}"  # dwa's expected best of 2, one thousandth up
    edited = text.replace(row, " | ".join(cells))
    assert edited != text and curve_problems(edited) != []
    # a study left out of the table
    dropped = "\n".join(line for line in text.splitlines() if not line.startswith("| `orca` | both | 0.3"))
    assert curve_problems(dropped) == ["orca: no row"]


def test_the_table_is_the_reports_own() -> None:
    """The page's table is evaluation.tune.report's own (:func:`expected_best_markdown`)."""
    studies = [load_summary(folder) for folder in _folders()]
    table = expected_best_markdown(studies)
    assert table.rstrip("\n") in PAGE.read_text(encoding="utf-8")
    # the curve at n = 1 is the mean score, and it never falls with n
    for study in studies:
        assert _expected_best(study.scores, 1) == pytest.approx(sum(study.scores) / len(study.scores))
        curve = [_expected_best(study.scores, n) for n in range(1, len(study.scores) + 1)]
        assert all(b >= a - 1e-12 for a, b in zip(curve, curve[1:]))
        assert curve[-1] <= max(study.scores)


@pytest.mark.parametrize(
    ("points", "named"),
    [((), "points is empty"), ((0, 2), "holds 0"), ((2, 2), "names a count twice"), ((1.5,), "holds 1.5")],
)
def test_the_table_refuses_bad_counts(points: tuple, named: str) -> None:
    study = load_summary(_folders()[0])
    with pytest.raises(ValueError, match=re.escape(named)):
        expected_best_markdown([study], points)


def test_a_study_shorter_than_a_column_shows_a_dash() -> None:
    study = load_summary(_folders()[0])
    short = type(study)(study.controller, study.task, study.budget, study.scores[:3])
    (row,) = [line for line in expected_best_markdown([short]).splitlines() if line.startswith("| `")]
    assert row.split(" | ")[2:] == [
        f"{_expected_best(short.scores, 1):.3f}",
        f"{_expected_best(short.scores, 2):.3f}",
        "-",
        "-",
        "-",
        f"{_expected_best(short.scores, 3):.3f} (N = 3) |",
    ]


def _png_facts(data: bytes) -> tuple[tuple[int, int], str | None]:
    """A PNG's (width, height) and its ``Software`` text, read chunk by chunk."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    size, software, at = None, None, 8
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kind, body = data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
        elif kind == b"tEXt" and body.startswith(b"Software\x00"):
            software = body.split(b"\x00", 1)[1].decode("latin-1")
        at += 12 + length
    assert size is not None
    return size, software


def test_the_figure_is_what_its_generator_draws(tmp_path: Path) -> None:
    """docs/make_tuning_md.py, as docs/make_pages.py runs it, draws the committed figure: the same
    bytes when the committed one was drawn by the installed matplotlib, else the same size."""
    out, figures = tmp_path / "tuning.md", tmp_path / "_static"
    assert make_tuning_md.main([*_entry()["args"], "--out", str(out), "--figures", str(figures)]) == 0
    drawn, committed = (figures / make_tuning_md.FIGURE).read_bytes(), FIGURE.read_bytes()
    (size, _), (committed_size, software) = _png_facts(drawn), _png_facts(committed)
    assert size == committed_size
    assert software is not None and "Matplotlib version" in software
    if software.split("version", 1)[1].split(",", 1)[0] == matplotlib.__version__:
        assert drawn == committed, "docs/_static/tuning.png is not what docs/make_tuning_md.py draws"
    assert out.read_text(encoding="utf-8") == PAGE.read_text(encoding="utf-8")


def test_the_generator_refuses_a_controller_without_a_study(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    code = make_tuning_md.main(["orca", "no-such-controller", "--out", str(tmp_path / "t.md")])
    err = capsys.readouterr().err
    assert code == 2 and "data/tuning/no-such-controller" in err and "data/tuning/orca'" not in err
    assert not (tmp_path / "t.md").exists()
