"""A power statement under every published table of paired tests (issue 60: "a power statement
per table: the smallest paired difference it detects with 80% power after the correction, from
the measured discordance").

evaluation.stats.designs.table_power states it for a table of paired success tests on units
that are their own clusters (the paper protocol's (map, slip, seed) episodes, a sweep's episode
units, the sim-to-sim pages' units), in the bench page's wording; every generator calls it
(docs/make_results_md.py through evaluation.reports.sections.paired_power_note, the sweep pages
through evaluation.reports.sections.profiles, docs/make_compute_md.py, docs/make_sim2sim_md.py).
The published pages are checked here as committed: each paired table has its statement right
below it, and where the table shows its discordant pairs, the statement's numbers are the table's.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from evaluation.stats.aggregate import paired_comparisons
from evaluation.stats.designs import table_power
from evaluation.stats.families import detectable_difference, paired_power
from evaluation.stats.robustness import level_costs, profiles
from evaluation.stats.run_data import RunData

from helpers.records import episode_record

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

SENTENCE = re.compile(
    r"^Power: m = (?P<m>\d+) tests?, Holm at alpha = 0\.05 \(first step alpha/m = (?P<step>[\d.e-]+)\)\. "
    r"With (?P<pairs>\d+) pairs per comparison(?: \(the fewest of the table's\))?, a pair being (?P<unit>[^,]+(?:, [^,]+)*?), "
    r"and discordance (?P<psi>[\d.]+) pooled over the table's (?P<k>\d+) comparisons? "
    r"\((?P<disc>[\d,]+) discordant of (?P<total>[\d,]+) pairs\), (?P<found>.+) is found with 80% power\.$"
)


# --------------------------------------------------------------------------- the helper
def test_the_statement_is_the_layout_test_with_one_pair_per_cluster() -> None:
    power = table_power([60, 60, 40], [12, 30, 8], 5, "one seed")
    psi = 50 / 160  # pooled: discordant pairs over all pairs, not the median of the shares
    assert power.discordance == pytest.approx(psi)
    assert (power.pairs, power.most_pairs, power.total_pairs, power.discordant) == (40, 60, 160, 50)
    expected = detectable_difference(40, 1, discordance=psi, family_size=5, alpha=0.05, power=0.8)
    assert power.difference == pytest.approx(expected)
    # and that difference has 80% power at Holm's first step, a smaller one less
    assert paired_power(expected, 40, 1, discordance=psi, family_size=5) == pytest.approx(0.8, abs=1e-6)
    assert paired_power(0.9 * expected, 40, 1, discordance=psi, family_size=5) < 0.8
    text = power.sentence()
    assert text.startswith("Power: m = 5 tests, Holm at alpha = 0.05 (first step alpha/m = 0.01). ")
    assert "With 40 pairs per comparison (the fewest of the table's), a pair being one seed," in text
    assert "discordance 0.31 pooled over the table's 3 comparisons (50 discordant of 160 pairs)" in text
    assert f"a paired difference of {100 * expected:.1f} points is found with 80% power." in text
    assert SENTENCE.match(text)


def test_pooling_weighs_a_comparison_by_its_pairs() -> None:
    # the median of the shares (0.1, 0.5, 0.5) would be 0.5; pooled it is 65/190
    power = table_power([100, 50, 40], [10, 25, 20], 3, "one seed")
    assert power.discordance == pytest.approx(55 / 190)
    assert power.discordance != pytest.approx(0.5)


def test_more_tests_in_the_family_need_a_larger_difference() -> None:
    one = table_power([80], [24], 1, "one seed").difference
    many = table_power([80], [24], 240, "one seed").difference
    assert 0 < one < many < 0.3


def test_what_cannot_be_detected_is_said_why() -> None:
    few = table_power([4], [3], 1, "one seed")
    assert math.isnan(few.difference)
    assert "the exact test's smallest p-value over 4 pairs, 2/2^4 = 0.125, is above alpha/m" in few.sentence()
    assert "m = 1 test," in few.sentence()
    none = table_power([40, 40], [0, 0], 2, "one seed")
    assert math.isnan(none.difference)
    assert "no discordant pair to compute a power from" in none.sentence()
    small = table_power([20] * 19, [3] * 19, 19, "one seed")
    assert math.isnan(small.difference)
    assert "not even the largest the discordance allows" in small.sentence()
    assert "With 20 pairs per comparison, a pair" in small.sentence()  # all alike: no "fewest"


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (([], [], 1, "u"), "pairs is empty"),
        (([10, 10], [1], 1, "u"), "pairs has 2 comparison(s) and discordant 1"),
        (([10], [11], 1, "u"), "discordant[0]=11 is more than pairs[0]=10"),
        (([0], [0], 1, "u"), "pairs[0]"),
        (([10], [-1], 1, "u"), "discordant[0]"),
        (([10], [1], 0, "u"), "family_size"),
        (([10], [1], 1, ""), "unit=''"),
    ],
)
def test_bad_input_is_named(args: tuple, named: str) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        table_power(*args)


# --------------------------------------------------------------------------- the family's m


def _team() -> list[dict]:
    records = []
    for name, rate in (("a", 0.9), ("b", 0.5), ("c", 0.2)):
        records += [episode_record(name, s, s < rate * 20, s + ord(name)) for s in range(20)]
    return records


def test_the_paired_tables_family_counts_a_twins_test_once() -> None:
    records = _team()
    assert {r["family_size"] for r in paired_comparisons(records)} == {3}
    twin = records + [{**r, "controller": "c-twin"} for r in records if r["controller"] == "c"]
    rows = paired_comparisons(twin)
    # 6 rows; a-c-twin and b-c-twin are a-c's and b-c's tests: m = 4
    assert len(rows) == 6 and {r["family_size"] for r in rows} == {4}


def test_the_run_pages_statement_is_its_rows() -> None:
    from evaluation.reports.sections import paired_power_note

    results = RunData(_team(), {"controllers": ["a", "b", "c"]})
    rows = results.paired()
    note = paired_power_note(results)
    expected = table_power(
        [r["n"] for r in rows], [r["only_a"] + r["only_b"] for r in rows], 3, "x"
    ).sentence()
    assert note is not None and note.split(", a pair being")[0] == expected.split(", a pair being")[0]
    # 20 seeds, a-b 8 discordant, a-c 14, b-c 6: 28 of 60
    assert "(28 discordant of 60 pairs)" in note


def _sweep() -> dict:
    """A sweep of one axis, two levels, two controllers: ref always succeeds; x fails more at level 1."""
    levels = []
    for level, cut in ((0, 15), (1, 8)):
        records = []
        for name in ("ref", "x"):
            for s in range(20):
                success = True if name == "ref" else s < cut
                records.append(
                    {
                        **episode_record(name, s, success, s + ord(name[0]) + level),
                        "key": f"{name}-{level}-{s}",
                    }
                )
        levels.append((level, RunData(records, {"controllers": ["ref", "x"]})))
    return {"noise": levels}


def test_a_sweeps_profiles_and_level_costs_carry_their_family_and_discordance() -> None:
    from evaluation.reports.sections.profiles import level_cost_power_note, level_power_note

    (profile,) = profiles(_sweep(), "ref")
    assert profile.family_size == 2  # x against ref at each level
    assert [row.paired["discordant"] for row in profile.rows if row.paired] == [5, 12]
    note = level_power_note(profile)
    assert note is not None and "m = 2 tests" in note and "(17 discordant of 40 pairs)" in note
    costs = level_costs(_sweep())
    # ref: no change (0 discordant); x: 7 fewer successes at level 1
    assert [(c.controller, c.discordant, c.family_size) for c in costs] == [("ref", 0, 2), ("x", 7, 2)]
    cost_note = level_cost_power_note(costs)
    assert cost_note is not None and "(7 discordant of 40 pairs)" in cost_note


# --------------------------------------------------------------------------- the published pages
def _statements(text: str) -> list[re.Match]:
    return [m for m in (SENTENCE.match(line) for line in text.splitlines()) if m]


def _table_ends(text: str, header: str) -> list[int]:
    """Line numbers of the last row of every table whose header line contains ``header``."""
    lines, ends = text.splitlines(), []
    for i, line in enumerate(lines):
        if line.startswith("|") and header in line:
            j = i
            while j + 1 < len(lines) and lines[j + 1].startswith("|"):
                j += 1
            ends.append(j)
    return ends


def _next_statement(text: str, end: int) -> re.Match | None:
    """The power statement among the paragraphs right after the table ending at line ``end``
    (before the next table or heading)."""
    for line in text.splitlines()[end + 1 :]:
        if line.startswith(("|", "#")):
            return None
        found = SENTENCE.match(line)
        if found:
            return found
    return None


@pytest.mark.parametrize(
    ("page", "header"),
    [
        ("results.md", "| only a / only b |"),
        ("compute.md", "| Only A succeeds |"),
        ("sim2sim_results.md", "| physics - kinematic [points] |"),
        ("sim2sim_results.md", "| fine-tuned from |"),
        ("robustness_results.md", "| McNemar p | Holm p |"),
        ("lidar_results.md", "| McNemar p | Holm p |"),
        ("crowd_results.md", "| McNemar p | Holm p |"),
        ("realistic_results.md", "| McNemar p | Holm p |"),
    ],
)
def test_every_paired_table_of_a_page_has_its_statement(page: str, header: str) -> None:
    text = (DOCS / page).read_text(encoding="utf-8")
    ends = _table_ends(text, header)
    assert ends, f"docs/{page} has no table with {header!r}"
    missing = [end + 1 for end in ends if _next_statement(text, end) is None]
    assert missing == [], f"docs/{page}: the tables ending at lines {missing} have no power statement"


def _counted_tables(text: str, header: str, discordant) -> list[tuple[list[tuple[int, int]], re.Match]]:
    """Each table with ``header``: its rows' (pairs, discordant) and the statement below it."""
    lines, out = text.splitlines(), []
    for end in _table_ends(text, header):
        start = end
        while lines[start - 1].startswith("|"):
            start -= 1
        head = [c.strip() for c in lines[start].strip("|").split("|")]
        rows = [[c.strip() for c in line.strip("|").split("|")] for line in lines[start + 2 : end + 1]]
        statement = _next_statement(text, end)
        assert statement is not None
        out.append(([discordant(dict(zip(head, row))) for row in rows], statement))
    return out


@pytest.mark.parametrize(
    ("page", "header", "discordant"),
    [
        (
            "results.md",
            "| only a / only b |",
            lambda r: (int(r["Pairs"]), sum(int(x) for x in r["only a / only b"].split("/"))),
        ),
        (
            "compute.md",
            "| Only A succeeds |",
            lambda r: (int(r["Pairs"]), int(r["Only A succeeds"]) + int(r["Only B succeeds"])),
        ),
    ],
)
def test_a_statement_is_its_tables_pairs_and_discordance(page: str, header: str, discordant) -> None:
    """Recomputed from the table's own columns: the pairs, the pooled discordance and the
    detectable difference; the family's m is at most the table's rows (twins count once)."""
    text = (DOCS / page).read_text(encoding="utf-8")
    tables = _counted_tables(text, header, discordant)
    assert tables
    for counts, statement in tables:
        pairs = [n for n, _ in counts]
        total, disc = sum(pairs), sum(d for _, d in counts)
        m = int(statement["m"])
        assert 1 <= m <= len(counts) and int(statement["k"]) == len(counts)
        assert int(statement["pairs"]) == min(pairs)
        assert int(statement["total"].replace(",", "")) == total
        assert int(statement["disc"].replace(",", "")) == disc
        assert float(statement["psi"]) == pytest.approx(disc / total, abs=0.005)
        expected = detectable_difference(min(pairs), 1, discordance=disc / total, family_size=m)
        if math.isnan(expected):
            assert statement["found"].startswith("no paired difference")
        else:
            assert statement["found"] == f"a paired difference of {100 * expected:.1f} points"
