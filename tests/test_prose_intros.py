"""The intros of the generated results pages (docs/_intros/*.md) are templates whose numbers are
filled from the archives the page's generator reads (docs/make_prose_md.py, issue 60): checked
here on one small committed sweep (data/realistic_classic.tar.xz, two levels, 960 episodes)
against counts made directly from its records, with a datum changed in a copy of it, and with
placeholders that name nothing the page reads."""

from __future__ import annotations

import json
import re
import runpy
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np
import pytest

from evaluation.exit_codes import BAD_INPUT_EXIT
from evaluation.reports.published import extract_archive

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_prose_md import expand, expand_template, runs_by_file  # noqa: E402  (docs/ is no package)

ARCHIVE = ROOT / "data" / "realistic_classic.tar.xz"
LEVEL = "realistic_classic@uncertainty=realistic"


@pytest.fixture(scope="module")
def records() -> dict[str, list[dict]]:
    """The archive's records per level (``nominal``, ``realistic``), read without the evaluator."""
    out: dict[str, list[dict]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        run = extract_archive(ARCHIVE, scratch)
        for level in ("nominal", "realistic"):
            lines = (run / "sweep" / f"uncertainty-{level}" / "episodes.jsonl").read_text().splitlines()
            out[level] = [json.loads(line) for line in lines[1:] if line]
    return out


@pytest.fixture(scope="module")
def runs():
    return runs_by_file([ARCHIVE])


def _of(records: list[dict], controller: str, **where: object) -> list[dict]:
    return [
        r
        for r in records
        if r["controller"] == controller and r["status"] == "ok" and all(r[k] == v for k, v in where.items())
    ]


def test_the_numbers_are_the_records_counts(records, runs) -> None:
    orca = _of(records["realistic"], "orca")
    k = sum(r["success"] for r in orca)
    assert expand(f"{{{{ kn {LEVEL} orca }}}}", runs) == f"{k}/{len(orca)}"
    assert expand(f"{{{{ count {LEVEL} orca }}}}", runs) == str(k)
    assert expand(f"{{{{ rate {LEVEL} orca }}}}", runs) == f"{100 * k / len(orca):.0f}%"
    assert expand(f"{{{{ episodes {LEVEL} orca trial=0,1,2 }}}}", runs) == str(
        sum(r["trial"] in (0, 1, 2) for r in orca)
    )
    times = [r["solve_ms_median"] for r in _of(records["realistic"], "dwa")]
    assert expand(f"{{{{ median {LEVEL} dwa solve_ms_median }}}}", runs) == f"{np.median(times):.2g}"
    dwa = _of(records["nominal"], "dwa")
    missed, decided = sum(r["deadline_misses"] for r in dwa), sum(r["decisions"] for r in dwa)
    at_nominal = "realistic_classic@uncertainty=nominal"
    assert expand(f"{{{{ misses {at_nominal} dwa }}}}", runs) == f"{missed:,} of {decided:,}"
    obstacle = sum("obstacle" in (r["collision"] or "") for r in dwa)
    assert expand(f"{{{{ collisions {at_nominal} dwa obstacle }}}}", runs) == str(obstacle)
    # the family of part 5 of the realistic page: four controllers against the reference, two levels
    assert expand("{{ sweep_tests realistic_classic }}", runs) == "8"


def test_span_is_the_range_over_its_alternatives(records, runs) -> None:
    rates = [
        round(100 * np.mean([r["success"] for r in _of(records["realistic"], c)])) for c in ("orca", "dwa")
    ]
    low, high = min(rates), max(rates)
    expected = f"{low}%" if low == high else f"{low}-{high}%"
    assert expand(f"{{{{ span rate {LEVEL} orca|dwa }}}}", runs) == expected
    every = [
        round(100 * np.mean([r["success"] for r in _of(records[level], "orca")]))
        for level in ("nominal", "realistic")
    ]
    assert expand("{{ span rate realistic_classic@* orca }}", runs) in (
        f"{min(every)}-{max(every)}%",
        f"{min(every)}%",
    )
    worst = expand("{{ span max vsref_holm realistic_classic orca|dwa uncertainty=realistic }}", runs)
    both = [
        expand(f"{{{{ vsref_holm realistic_classic {c} uncertainty=realistic }}}}", runs)
        for c in ("orca", "dwa")
    ]
    assert worst in both and worst.startswith("Holm p")
    with pytest.raises(ValueError, match=re.escape("are not one number with one unit")):
        expand("{{ span vsref realistic_classic orca|dwa uncertainty=realistic }}", runs)


def _page(intro: Path, archive: Path, out: Path, capfd: pytest.CaptureFixture[str]) -> tuple[object, str]:
    """docs/make_robustness_md.py on one archive with ``intro``: (exit code, stderr)."""
    argv = [str(archive), "--intro", str(intro), "--out", str(out), "--figures", str(out.parent / "fig")]
    saved = sys.argv
    sys.argv = ["make_robustness_md.py", *argv]
    code: object = 0
    try:
        runpy.run_path(str(ROOT / "docs" / "make_robustness_md.py"), run_name="__main__")
    except SystemExit as exc:
        code = exc.code
    finally:
        sys.argv = saved
    return code, capfd.readouterr().err


def test_a_changed_datum_changes_the_page(records, tmp_path: Path) -> None:
    """One Koopman-NMPC success turned into a collision in a copy of the archive: the intro
    expanded from the copy states one success less (the generator's own use of the template is
    checked below and, page by page, by tests/test_published_pages.py)."""
    intro = tmp_path / "intro.md"
    intro.write_text(f"Koopman-NMPC {{{{ kn {LEVEL} koopman-nmpc }}}} under `realistic`.\n")
    mine = _of(records["realistic"], "koopman-nmpc")
    k, n = sum(r["success"] for r in mine), len(mine)
    assert expand_template(intro, [ARCHIVE]) == f"Koopman-NMPC {k}/{n} under `realistic`.\n"

    run = extract_archive(ARCHIVE, tmp_path / "copy")
    log = run / "sweep" / "uncertainty-realistic" / "episodes.jsonl"
    lines = log.read_text().splitlines()
    for i, line in enumerate(lines[1:], start=1):
        record = json.loads(line)
        if record["controller"] == "koopman-nmpc" and record["success"]:
            record.update(success=False, collision="obstacle")
            for key in ("strict_success", "success_excusing_unavoidable"):
                if key in record:
                    record[key] = False
            lines[i] = json.dumps(record)
            break
    log.write_text("\n".join(lines) + "\n")
    changed = tmp_path / "changed" / ARCHIVE.name  # named as the original: the same run name
    changed.parent.mkdir()
    with tarfile.open(changed, "w:xz", preset=0) as tar:  # preset 0: pack_run's 9 takes 30 s here
        tar.add(run, arcname=run.name)
    assert expand_template(intro, [changed]) == f"Koopman-NMPC {k - 1}/{n} under `realistic`.\n"


@pytest.mark.parametrize(
    ("placeholder", "message"),
    [
        ("{{ rate nowhere@uncertainty=realistic orca }}", "run 'nowhere' is not one of the page's runs"),
        ("{{ rates realistic_classic orca }}", "'rates' is not one of the functions"),
        (f"{{{{ rate {LEVEL} ppo }}}}", "controller 'ppo' is not in the run"),
        ("{{ rate realistic_classic@uncertainty=lab orca }}", "name one of its levels"),
        ("{{ vsref_points realistic_classic orca uncertainty=lab }}", "no paired row of 'orca'"),
        (f"{{{{ median {LEVEL} orca nothing }}}}", "field 'nothing' is in neither"),
        (f"{{{{ misses {LEVEL} orca all }}}}", "misses takes RUN CONTROLLER [count]"),
        ("{{ span rate realistic_classic@level=* orca }}", "sweep 'realistic_classic' has the axes"),
        ("{{ span nope x }}", "span takes a number function"),
    ],
)
def test_a_placeholder_with_no_source_fails_the_build_naming_it(runs, placeholder: str, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)) as raised:
        expand(f"Text before.\n\nSo {placeholder} here.\n", runs)
    assert placeholder in str(raised.value)


def test_the_generator_refuses_a_page_with_a_bad_placeholder(tmp_path: Path, capfd) -> None:
    """The message names the template and the placeholder; no page is written."""
    intro = tmp_path / "intro.md"
    intro.write_text("ORCA {{ rate nowhere@uncertainty=realistic orca }}.\n")
    code, err = _page(intro, ARCHIVE, tmp_path / "page.md", capfd)
    assert code == BAD_INPUT_EXIT
    assert "placeholder '{{ rate nowhere@uncertainty=realistic orca }}'" in err and str(intro) in err
    assert not (tmp_path / "page.md").exists()


def test_two_archives_of_one_name_are_refused_when_named() -> None:
    """A page may read one archive twice (two parts of one sweep); two archives of one name are
    refused when a placeholder names that run."""
    assert expand("{{ kn realistic_classic@uncertainty=realistic orca }}", runs_by_file([ARCHIVE, ARCHIVE]))
    twice = runs_by_file(["data/paper.tar.xz", "elsewhere/paper.tar.xz"])
    assert expand("no placeholder", twice) == "no placeholder"
    with pytest.raises(ValueError, match=re.escape("run 'paper' names several archives")):
        expand("{{ kn paper orca }}", twice)
