"""Prose that cannot drift (issue 60): every number README.md states is checked against its
source, and no published page differs from what its generator wrote.

- README's numbers: the quick leaderboard's episode counts from the evaluator's quick plan and
  the controllers each install can build; its two commands' times from the table of measured
  times in docs/performance.md; the tasks, maps and episodes per cell from the code. Every digit
  in README's text must belong to one of these checks (a new number needs a check).
- The published pages (data/pages.json): each one's bytes against the SHA-256 its generator's
  output had (data/pages.sha256, written by docs/make_pages.py), so a page edited by hand fails
  here in a second; tests/test_published_pages.py (slow) rebuilds them from the data.

Each check reads the text it is given, so the tests below also show that editing a README number
by hand, or a number of a generated page, makes them fail.
"""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

import controllers as registry
from controllers.tuning import BEST_FILE, STUDIES_DIR, study_adoption
from evaluation.execution.runner import usable_controllers
from evaluation.experiments.protocols import QUICK_SLIPS, TASK_MAPS, quick_protocol

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_pages import (  # noqa: E402  (docs/ is no package)
    PAGES,
    block_of,
    edited_pages,
    main,
    page_digest,
    read_digests,
    stale_readme_blocks,
)

README = (ROOT / "README.md").read_text(encoding="utf-8")

#: the modules of the extras that add controllers to the quick leaderboard
EXTRA_MODULES = {"rl": "stable_baselines3", "crowd": "pyrvo"}


# --------------------------------------------------------------------------- the sources
def quick_counts(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """The quick leaderboard's episodes with the core install, and what each extra adds: the
    controllers the evaluator can build with every extra's module missing
    (:func:`evaluation.execution.runner.usable_controllers`), the others by the extra their refusal names,
    each times the episodes the quick plan gives one controller."""
    for module in EXTRA_MODULES.values():
        monkeypatch.setitem(sys.modules, module, None)  # an import of it now raises ImportError
    core = usable_controllers(verbose=False)
    needs: dict[str, list[str]] = {}
    for name in registry.available(variants=False):  # a -v0 variant runs only when named
        if name in core:
            continue
        try:
            registry.make(name)
        except (ImportError, ValueError) as exc:
            extra = re.search(r"\.\[(\w+)\]", str(exc))
            needs.setdefault(extra[1] if extra else "?", []).append(name)
    per_controller = len(quick_protocol().resolved(["consensus"]).episodes_plan(""))
    return {
        "core": per_controller * len(core),
        **{extra: per_controller * len(names) for extra, names in needs.items()},
    }


#: a row of docs/performance.md's table of README's commands
ROW = re.compile(r"^\| `(?P<command>[^`]+)` \| (?P<time>[^|]+?) \| (?P<episodes>[^|]+?) \|", re.MULTILINE)


def _seconds(text: str) -> float:
    minutes = re.fullmatch(r"(\d+) min (\d+) s", text)
    if minutes:
        return 60 * int(minutes[1]) + int(minutes[2])
    seconds = re.fullmatch(r"([\d.]+) s", text)
    if not seconds:
        raise ValueError(f"wall time {text!r} is not 'S s' or 'M min S s'")
    return float(seconds[1])


def measured_times() -> dict[str, list[tuple[float, str]]]:
    """docs/performance.md's measured times of README's commands: command -> [(seconds, episodes)]."""
    section = (
        (ROOT / "docs" / "performance.md").read_text(encoding="utf-8").split("## README's two commands")[1]
    )
    section = section.split("\n## ")[0]
    rows: dict[str, list[tuple[float, str]]] = {}
    for match in ROW.finditer(section):
        if match["command"] != "Command":
            rows.setdefault(match["command"], []).append((_seconds(match["time"]), match["episodes"]))
    return rows


# --------------------------------------------------------------------------- the checks
#: README's statements with numbers: (pattern, what checks it); a check returns the problems
Check = Callable[[re.Match[str], dict], list[str]]
COUNTS = re.compile(r"the core install runs (\d+)\s+episodes, `\[rl\]` adds (\d+), `\[crowd\]` (\d+)\)")
QUICK = re.compile(
    r"python evaluate\.py +# install, run the quick leaderboard \(under (\d+) min on (\d+) idle cores\)"
)
TESTS = re.compile(
    r"python -m pytest -q +# install, run the tests \(([\d.]+)-([\d.]+) min on (\d+) idle cores, both used\)"
)
WORDS = {"one": 1, "two": 2, "three": 3, "four": 4, "six": 6, "eight": 8}


def _counts(match: re.Match[str], sources: dict) -> list[str]:
    stated = dict(zip(("core", "rl", "crowd"), map(int, match.groups()), strict=True))
    actual = {key: sources["counts"].get(key, 0) for key in stated}
    return [] if stated == actual else [f"README states {stated} episodes; the quick plan gives {actual}"]


def _half_minutes(seconds: float) -> float:
    return round(seconds / 30) / 2


def _quick(match: re.Match[str], sources: dict) -> list[str]:
    rows = sources["times"].get("python evaluate.py", [])
    problems = ["no measured time of `python evaluate.py` in docs/performance.md"] if not rows else []
    limit = 60 * int(match[1])
    problems += [f"`python evaluate.py` took {t} s, not under {match[1]} min" for t, _ in rows if t >= limit]
    if rows and rows[-1][1] != str(sources["counts"]["core"]):
        problems.append(
            f"the latest measured quick run had {rows[-1][1]} episodes; the plan has {sources['counts']['core']}: re-measure"
        )
    return problems + ([] if match[2] == "2" else [f"measured on 2 cores, README says {match[2]}"])


def _tests(match: re.Match[str], sources: dict) -> list[str]:
    rows = sources["times"].get("python -m pytest -q", [])
    low, high = float(match[1]), float(match[2])
    problems = [] if rows else ["no measured time of `python -m pytest -q` in docs/performance.md"]
    problems += [
        f"`python -m pytest -q` took {t:.0f} s ({_half_minutes(t)} min), not within {match[1]}-{match[2]} min"
        for t, _ in rows
        if not low <= _half_minutes(t) <= high
    ]
    return problems + ([] if match[3] == "2" else [f"measured on 2 cores, README says {match[3]}"])


def _tasks_and_maps(match: re.Match[str], sources: dict) -> list[str]:
    maps = sorted(p.stem for p in (ROOT / "koopman_envs" / "maps").glob("map*.json"))
    stated = (WORDS.get(match[1]), WORDS.get(match[2]))
    actual = (len(TASK_MAPS), len(maps))
    return [] if stated == actual else [f"README states {stated} tasks and maps; there are {actual}"]


def _per_cell(match: re.Match[str], sources: dict) -> list[str]:
    spec = quick_protocol()
    stated = (match[1], WORDS.get(match[2]))
    actual = ("high" if QUICK_SLIPS == ("high",) else "/".join(QUICK_SLIPS), spec.episodes)
    return [] if stated == actual else [f"README states {stated}; the quick protocol has {actual}"]


def _torch(match: re.Match[str], sources: dict) -> list[str]:
    pin = f"torch=={match[1]}"
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    return [] if pin in pyproject else [f"README's {pin} is not the pin of pyproject.toml"]


def _figure(match: re.Match[str], sources: dict) -> list[str]:
    script = (ROOT / "docs" / "make_figure.py").read_text(encoding="utf-8")
    wanted = (f'"map{match[1]}"', f"seed={match[2]}")
    return [] if all(w in script for w in wanted) else [f"docs/make_figure.py does not draw {wanted}"]


def _intervals(match: re.Match[str], sources: dict) -> list[str]:
    from evaluation.stats.statistics import wilson_interval

    # what the default does, not its __defaults__: a mutation run's trampolines hide those
    stated = float(match[1]) / 100
    return (
        []
        if wilson_interval(3, 10) == wilson_interval(3, 10, confidence=stated)
        else [f"README says {match[1]}% intervals; the default gives {wilson_interval(3, 10)} for 3 of 10"]
    )


def _second_run(match: re.Match[str], sources: dict) -> list[str]:
    # tests/test_cli.py's test_the_quick_start_can_be_run_twice runs README's command twice
    return [] if match[1] == "2" else [f"README names results-{match[1]}/; a second run writes results-2/"]


def _readme_block(entry: dict) -> Check:
    """The check of README's copy of ``entry``'s block (an item of data/pages.json with a
    ``"readme"``): the block is the generated page's, whose bytes
    test_no_published_page_is_edited_by_hand checks, so its numbers have that source."""

    def check(match: re.Match[str], sources: dict) -> list[str]:
        stale = entry["readme"] in stale_readme_blocks(match.string)
        return [f"README's {entry['readme']} block is not {entry['page']}'s: rebuild it"] if stale else []

    return check


#: every block a published page gives README.md (data/pages.json's ``"readme"``), each checked
READMES: list[tuple[re.Pattern[str], Check]] = [
    (
        re.compile(
            rf"^<!-- begin {re.escape(e['readme'])}\b.*?^<!-- end {re.escape(e['readme'])} -->$", re.M | re.S
        ),
        _readme_block(e),
    )
    for e in PAGES
    if "readme" in e
]


CHECKS: list[tuple[re.Pattern[str], Check]] = [
    *READMES,
    (COUNTS, _counts),
    (QUICK, _quick),
    (TESTS, _tests),
    (re.compile(r"(\w+) tasks, (\w+) maps"), _tasks_and_maps),
    (re.compile(r"paper\s+maps, (\w+) slip, (\w+) episodes per cell"), _per_cell),
    (re.compile(r"`torch==([\d.]+)`"), _torch),
    (re.compile(r"Map (\d) under high slip \(koopman-nmpc-robust, seed (\d+);"), _figure),
    (re.compile(r"leaderboard with (\d+)% intervals"), _intervals),
    (re.compile(r"goes to `results-(\d+)/`"), _second_run),
    (re.compile(r"koopnav-bench-v(\d+)"), lambda m, s: [] if m[1] == "1" else [f"suite v{m[1]}"]),
    # a comparison variant's name (rl-ppo-set-v0): a registered controller
    (
        re.compile(r"`([a-z-]+-v(\d+))`"),
        lambda m, s: [] if m[1] in registry.available() else [f"{m[1]} is no registered controller"],
    ),
]


def _prose(text: str) -> str:
    """README without what is checked elsewhere: its python blocks (run by test_docs_snippets)
    and link targets (paths), each replaced by spaces so that positions stay."""
    blank = lambda m: " " * len(m[0])  # noqa: E731
    text = re.sub(r"```python\n.*?```", blank, text, flags=re.DOTALL)
    return re.sub(r"\]\([^)]*\)", blank, text)


def readme_problems(text: str, sources: dict) -> list[str]:
    """Every way README ``text`` disagrees with ``sources`` (the counts and the measured times):
    a check whose statement is gone, a check that fails, a digit no check covers."""
    problems: list[str] = []
    covered: set[int] = set()
    for pattern, check in CHECKS:
        matches = list(pattern.finditer(text))
        if not matches:
            problems.append(f"README no longer states {pattern.pattern!r}: update tests/test_prose_checks.py")
        for match in matches:
            problems += check(match, sources)
            covered.update(range(*match.span()))
    prose = _prose(text)
    for number in re.finditer(r"\d+(?:[.,]\d+)*", prose):
        if not covered.issuperset(range(*number.span())):
            line = prose[: number.start()].count("\n") + 1
            problems.append(f"README line {line}: {number[0]!r} is checked by nothing")
    return problems


@pytest.fixture(scope="module")
def sources() -> Iterator[dict]:
    with pytest.MonkeyPatch.context() as monkeypatch:
        yield {"counts": quick_counts(monkeypatch), "times": measured_times()}


def test_every_number_of_the_readme_is_checked_against_its_source(sources) -> None:
    assert readme_problems(README, sources) == []


@pytest.mark.parametrize(
    ("old", "new", "complaint"),
    [
        ("runs 112", "runs 113", "episodes; the quick plan gives"),
        ("adds 40", "adds 24", "episodes; the quick plan gives"),
        ("(under 2 min", "(under 1 min", "not under 1 min"),
        ("(2.5-4.5 min", "(5-6 min", "not within 5-6 min"),
        ("eight maps", "nine maps", "tasks and maps"),
        ("two episodes per cell", "three episodes per cell", "the quick protocol has"),
        ("What is in it", "What is in it (12 envs)", "'12' is checked by nothing"),
    ],
)
def test_a_readme_number_edited_by_hand_fails(sources, old, new, complaint) -> None:
    assert old in README
    problems = readme_problems(README.replace(old, new, 1), sources)
    assert any(complaint in problem for problem in problems), problems


def test_getting_started_repeats_the_readmes_commands_and_times() -> None:
    """docs/getting_started.md shows README's two commands with their times, word for word, so
    that the checks above hold for both pages."""
    guide = (ROOT / "docs" / "getting_started.md").read_text(encoding="utf-8")
    for pattern in (QUICK, TESTS):
        stated = pattern.search(README)
        assert stated is not None and stated[0] in guide, stated


def test_getting_started_offers_the_shallow_clone_with_the_measured_sizes() -> None:
    """docs/getting_started.md names ``git clone --depth 1`` with the sizes docs/layout.md's "What
    a clone weighs" measured (bench/clone_size.py), so that a newcomer need not fetch the history."""
    guide = (ROOT / "docs" / "getting_started.md").read_text(encoding="utf-8")
    weighs = (ROOT / "docs" / "layout.md").read_text(encoding="utf-8")
    whole = re.search(r"\*\*The clone\*\*: ([\d.]+) MB on disk", weighs)
    shallow = re.search(r"`git clone --depth 1 [^`]*`, is ([\d.]+) MB on disk", weighs)
    assert whole is not None and shallow is not None
    assert "`git clone --depth 1" in guide
    assert f"{shallow[1]} MB on disk, against {whole[1]} MB for a whole clone" in guide


def test_a_new_measurement_that_disagrees_with_the_readme_fails(sources) -> None:
    slower = {**sources["times"], "python -m pytest -q": [(18 * 60.0, "-")]}
    assert any("not within 2.5-4.5 min" in p for p in readme_problems(README, {**sources, "times": slower}))
    fewer = {**sources["times"], "python evaluate.py": [(96.5, "104")]}
    assert any("re-measure" in p for p in readme_problems(README, {**sources, "times": fewer}))


# --------------------------------------------------------------------------- generated pages
def test_no_published_page_is_edited_by_hand() -> None:
    """Every page of data/pages.json is, byte for byte, what its generator last wrote, and
    README.md holds every block a page gives it (its headline) as the page holds it."""
    assert sorted(read_digests()) == sorted(entry["page"] for entry in PAGES)
    assert edited_pages() == []
    assert stale_readme_blocks() == []


def _edited_number(block: str) -> str:
    """``block`` with its first rate or estimate after the begin line changed (98% -> 198%,
    0.37 -> 10.37)."""
    head, _, body = block.partition("\n")
    number = re.search(r"\d+(?:\.\d+)?%|\d+\.\d+", body)  # a rate or an estimate, not a name's digit
    assert number is not None, body
    return head + "\n" + body.replace(number[0], "1" + number[0], 1)


#: the published pages that give README.md a block, and the block's name
README_BLOCKS = [(e["page"], e["readme"]) for e in PAGES if "readme" in e]


def test_every_readme_block_is_checked() -> None:
    """The bench headline and the sim-to-sim summary are among README's blocks, each its page's."""
    assert {
        ("docs/bench_results.md", "bench-headline"),
        ("docs/sim2sim_results.md", "sim2sim-transfer"),
    } <= set(README_BLOCKS)


@pytest.mark.parametrize(("page", "name"), README_BLOCKS)
def test_readmes_block_is_the_pages_block(page: str, name: str) -> None:
    """README's block is the page's, copied by docs/make_pages.py; a README without it, or with a
    number changed in it, is named."""
    text = (ROOT / page).read_text(encoding="utf-8")
    block = block_of(text, name)
    assert block is not None and block in README
    assert stale_readme_blocks(README.replace(block, "")) == [name]
    assert stale_readme_blocks(README.replace(block, _edited_number(block))) == [name]


@pytest.mark.parametrize(("page", "name"), README_BLOCKS)
def test_a_number_edited_in_a_readme_block_fails(sources, page: str, name: str) -> None:
    """README's check (every number has a source) names the block edited by hand, and its page."""
    block = block_of(README, name)
    assert block is not None
    problems = readme_problems(README.replace(block, _edited_number(block)), sources)
    assert problems == [f"README's {name} block is not {page}'s: rebuild it"], problems


def test_a_number_edited_by_hand_in_a_generated_page_fails() -> None:
    page = "docs/paper.md"
    text = (ROOT / page).read_text(encoding="utf-8")
    number = re.search(r"\b\d+/\d+\b", text)
    assert number is not None
    edited = text[: number.start()] + "1" + text[number.start() :]  # 20/20 -> 120/20
    assert edited_pages({page: edited.encode()}) == [page]
    assert page_digest(text.encode()) == read_digests()[page]


def test_make_pages_help_lists_the_pages_and_rebuilds_nothing(capsys) -> None:
    """``--help`` is the command line's help, not a page name: it exits 0 with the examples and
    every published page, before any generator runs."""
    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0
    shown = capsys.readouterr().out
    assert shown.startswith("usage: python docs/make_pages.py")
    assert "python docs/make_pages.py --check" in shown  # an example
    assert all(f"  {entry['page']}\n" in shown for entry in PAGES)


@pytest.mark.parametrize("argv", [["docs/result.md"], ["--check", "docs/lidar_results.md", "nope.md"]])
def test_make_pages_refuses_an_unknown_page_naming_the_known_ones(capsys, argv) -> None:
    """A name that is no published page is refused (exit 2) before any page is rebuilt, naming
    the pages it knows (and the near miss)."""
    assert main(argv) == 2
    shown = capsys.readouterr()
    complaint = shown.err
    assert f"page={argv[-1]!r} is not one of" in complaint
    assert all(repr(entry["page"]) in complaint for entry in PAGES)
    assert "== " not in shown.out  # no page was started
    if argv == ["docs/result.md"]:
        assert "did you mean 'docs/results.md'?" in complaint


# --------------------------------------------------------------------------- the intros' code numbers
# The results in docs/_intros/*.md are placeholders filled from the data (docs/make_prose_md.py;
# tests/test_prose_intros.py); the numbers they state about the code (a preset's values, a
# sensor's defaults, the protocol's start noise and mover speed) are checked here.
def _realistic_preset(match: re.Match[str]) -> list[str]:
    from koopman_envs.settings import UNCERTAINTY_PRESETS

    preset = UNCERTAINTY_PRESETS["realistic"]
    period_ms = 100  # the control period, 0.1 s
    stated = (
        float(match[1]) / 100,
        float(match[2]),
        int(match[3]),
        float(match[4]) / 100,
        WORDS.get(match[5]),
    )
    actual = (
        preset.pose_noise.xy,
        preset.pose_noise.heading,
        preset.comm.latency * period_ms,
        preset.comm.drop,
        preset.actuation_delay,
    )
    return [] if stated == actual else [f"the realistic preset is stated as {stated}; the code has {actual}"]


def _lidar_defaults(match: re.Match[str]) -> list[str]:
    from koopman_envs.settings import UNCERTAINTY_PRESETS, LidarConfig

    # the --lidar protocol names no lidar settings and no preset: the defaults, the nominal preset's noise
    actual = (LidarConfig().beams, UNCERTAINTY_PRESETS["nominal"].lidar.noise)
    stated = (int(match[1]), float(match[2]) / 100)
    return (
        []
        if stated == actual
        else [f"the lidar is stated as (beams, noise) {stated}; the protocol has {actual}"]
    )


def _tracker(match: re.Match[str]) -> list[str]:
    from koopman_envs.settings import MoverConfig

    actual = (MoverConfig().detection_range, MoverConfig().detection_noise)
    stated = (float(match[1]), float(match[2]) / 100)
    return [] if stated == actual else [f"the tracker is stated as {stated}; the default is {actual}"]


def _start_noise(match: re.Match[str]) -> list[str]:
    from evaluation.experiments.protocols import START_NOISE

    return (
        []
        if float(match[1]) / 100 == START_NOISE
        else [f"starts perturbed by {match[1]} cm, not {START_NOISE} m"]
    )


def _speed(match: re.Match[str]) -> list[str]:
    from evaluation.experiments.protocols import CROWD_SPEED

    return [] if float(match[1]) == CROWD_SPEED else [f"movers at {match[1]} m/s, not {CROWD_SPEED}"]


STARTS = (re.compile(r"starts perturbed\s+by (\d+) cm"), _start_noise)
INTRO_CHECKS: dict[str, list[tuple[re.Pattern[str], Callable[[re.Match[str]], list[str]]]]] = {
    "realistic_results.md": [
        (
            re.compile(
                r"\(([\d.]+) cm and ([\d.]+) rad of localization\s+noise with a drifting bias, messages"
                r"\s+(\d+) ms late and (\d+)% lost, (\w+) period of actuation delay"
            ),
            _realistic_preset,
        ),
        STARTS,
    ],
    "robustness_results.md": [STARTS],
    "lidar_results.md": [
        (re.compile(r"\((\d+) beams, (\d+) cm noise"), _lidar_defaults),
        (re.compile(r"movers at ([\d.]+) m/s"), _speed),
        STARTS,
    ],
    "crowd_results.md": [
        (re.compile(r"detections within (\d+) m with (\d+) cm of noise"), _tracker),
        (re.compile(r"movers at ([\d.]+) m/s"), _speed),
        STARTS,
    ],
}


def intro_problems(name: str, text: str) -> list[str]:
    """Every way the intro ``name``'s ``text`` misstates the code (a statement gone included)."""
    problems = []
    for pattern, check in INTRO_CHECKS[name]:
        matches = list(pattern.finditer(text))
        if not matches:
            problems.append(f"{name} no longer states {pattern.pattern!r}: update tests/test_prose_checks.py")
        for match in matches:
            problems += check(match)
    return problems


@pytest.mark.parametrize("name", sorted(INTRO_CHECKS))
def test_the_intros_numbers_about_the_code_are_the_codes(name: str) -> None:
    text = (ROOT / "docs" / "_intros" / name).read_text(encoding="utf-8")
    assert intro_problems(name, text) == []


@pytest.mark.parametrize(
    ("name", "old", "new", "complaint"),
    [
        ("realistic_results.md", "(3 cm and", "(2 cm and", "the realistic preset is stated as"),
        ("realistic_results.md", "5% lost", "10% lost", "the realistic preset is stated as"),
        ("crowd_results.md", "within 5 m", "within 8 m", "the tracker is stated as"),
        ("lidar_results.md", "(32 beams", "(64 beams", "the lidar is stated as"),
        ("robustness_results.md", "by 5 cm", "by 3 cm", "starts perturbed by 3 cm"),
    ],
)
def test_an_intros_code_number_edited_by_hand_fails(name: str, old: str, new: str, complaint: str) -> None:
    text = (ROOT / "docs" / "_intros" / name).read_text(encoding="utf-8")
    assert old in text
    assert any(complaint in p for p in intro_problems(name, text.replace(old, new, 1)))


# --------------------------------------------------------------------------- the tuning studies
def tuning_rows() -> list[str]:
    """docs/benchmark.md's rows of the finished tuning studies, written from each study's summary
    (``data/tuning/<name>/best.json``) and the adoption rule's decision on its log."""
    rows = []
    for folder in sorted(p for p in STUDIES_DIR.iterdir() if (p / BEST_FILE).is_file()):
        best = json.loads((folder / BEST_FILE).read_text())
        budget, tasks = best["budget"], 2 if best["task"] == "both" else 1
        n = best["best"]["episodes"]
        rows.append(
            f"| `{folder.name}` | {budget['configurations']} x {budget['layouts_per_task']} x "
            f"{budget['episodes_per_layout']} x {tasks} = {budget['episodes']:,} | "
            f"{best['defaults']['score']:.3f} ({best['defaults']['successes']}/{n}) | "
            f"{best['best']['score']:.3f} ({best['best']['successes']}/{n}) | {best['gain']:+.4f} | "
            f"{study_adoption(folder.name).verdict} |"
        )
    return rows


def tuning_problems(text: str) -> list[str]:
    """The rows of the tuning table of ``text`` (docs/benchmark.md) that are not the studies'."""
    table = text.split(
        "<!-- the rows tests/test_prose_checks.py checks against data/tuning/<name>/best.json -->"
    )
    if len(table) != 2:
        return ["docs/benchmark.md has no table of the shipped tuned defaults"]
    expected = tuning_rows()
    lines = table[1].strip().splitlines()[2:]  # after the header and its rule
    rows = lines[: next((i for i, line in enumerate(lines) if not line.startswith("|")), len(lines))]
    return [] if rows == expected else [f"the table states {rows}; the studies give {expected}"]


def test_the_tuning_table_is_the_studies_best_json() -> None:
    text = (ROOT / "docs" / "benchmark.md").read_text(encoding="utf-8")
    assert tuning_rows() and tuning_problems(text) == []
    edited = text.replace("0.414 (20/50)", "0.424 (20/50)", 1)  # a score edited by hand
    assert edited != text and tuning_problems(edited) != []
    # orca's tie stated as adopted
    edited = text.replace("| +0.0003 | defaults kept (a tie) |", "| +0.0003 | adopted |", 1)
    assert edited != text and tuning_problems(edited) != []


def tuning_status_problems(text: str) -> list[str]:
    """How docs/benchmark.md ``text`` states which tuning studies have finished, or which
    controllers the ablation's ``model`` factor compares, differently from data/tuning/ and
    :data:`evaluation.experiments.ablation.FACTORS`."""
    from evaluation.experiments.ablation import FACTORS

    problems = []
    finished = sorted(p.name for p in STUDIES_DIR.iterdir() if (p / BEST_FILE).is_file())
    said = re.search(r"The studies of (.+?) have\s+finished", text, re.S)
    named = sorted(re.findall(r"`([\w-]+)`", said[1])) if said else []
    if named != finished:
        problems.append(f"the finished studies are stated as {named}; data/tuning/ has {finished}")
    problems += [
        f"{name}'s study is said to be in progress" for name in finished if f"`{name}` is in progress" in text
    ]
    levels = tuple(FACTORS["model"][level][0] for level in ("learned", "nominal"))
    stated = re.findall(r"the ablation's `model` factor compares `([\w-]+)` with\s+`([\w-]+)`", text)
    if stated != [levels]:
        problems.append(f"the ablation's model factor is stated as {stated}; FACTORS has {levels}")
    return problems


def test_the_tuning_sections_status_is_the_studies_and_the_ablations() -> None:
    """docs/benchmark.md names every finished study as finished and the ablation's model factor
    as the code has it (it named koopman-nmpc's study in progress, and the factor's learned level
    koopman-nmpc, after the study was adopted and the factor moved to koopman-nmpc-v0)."""
    text = (ROOT / "docs" / "benchmark.md").read_text(encoding="utf-8")
    assert tuning_status_problems(text) == []
    edited = text.replace("`nominal-nmpc` and `koopman-nmpc` have", "`nominal-nmpc` have", 1)
    assert edited != text and len(tuning_status_problems(edited)) == 1
    edited = text.replace("compares `koopman-nmpc-v0` with", "compares `koopman-nmpc` with", 1)
    assert edited != text and len(tuning_status_problems(edited)) == 1


# --------------------------------------------------------------------------- the suite's own numbers
def _seed_span(seeds: list[int]) -> str:
    """``first-last``, then the seeds between them a split skipped (``without A and B``)."""
    skipped = sorted(set(range(seeds[0], seeds[-1] + 1)) - set(seeds))
    text = f"{seeds[0]:,}-{seeds[-1]:,}"
    if skipped:
        text += " without " + " and ".join(f"{s:,}" for s in skipped)
    return text


def suite_problems(text: str) -> list[str]:
    """How docs/benchmark.md ``text`` states koopnav-bench-v1 differently from its data: the split
    table (seed ranges, sizes), the seeds each split holds (read from the stored layouts), the
    tier cuts (``TIER_THRESHOLDS``) and the hash table (``manifest.json``)."""
    from koopman_envs import SPLITS, TASKS
    from koopman_envs.suites import SUITES, load_suite
    from koopman_envs.suites.measures import TIER_THRESHOLDS

    definition = SUITES["koopnav-bench-v1"]
    problems = []
    spans, hashes = [], []
    for split in SPLITS:
        suites = [load_suite(definition.name, task, split) for task in TASKS]
        seeds = {tuple(sorted(s.layout(i).seed for i in range(len(s)))) for s in suites}
        if len(seeds) != 1:
            problems.append(f"the tasks' {split} splits hold different seeds")
        spans.append(_seed_span(list(seeds.pop())))
        hashes.append(f"| {split} | " + " | ".join(f"`{s.sha256[:12]}`" for s in suites) + " |")
        first, stop = definition.split(split).seeds
        row = f"| `{split}` | [{first:,}, {stop:,}) | {definition.split(split).size} |"
        if row not in text:
            problems.append(f"the split table has no row {row!r}")
    held = f"the splits hold seeds {spans[0]}, {spans[1]},\n  and {spans[2]} "
    if held not in text:
        problems.append(f"the page does not state {held!r}")
    problems += [f"the hash table has no row {row!r}" for row in hashes if row not in text]
    cuts = ", ".join(
        f"{task.replace('_', ' ')} {low:g} and{chr(10) + '  ' if i == 0 else ' '}{high:g}"
        for i, (task, (low, high)) in enumerate(TIER_THRESHOLDS.items())
    )
    if f"train split: {cuts}." not in text:
        problems.append(f"the tier cuts are not stated as {cuts!r}")
    return problems


def test_the_suites_numbers_are_its_datas() -> None:
    """docs/benchmark.md's split table, seeds held, tier cuts and hashes against the stored suite
    (the page said 1,000,000-1,000,099 where validation runs to 1,000,101); an edit fails."""
    text = (ROOT / "docs" / "benchmark.md").read_text(encoding="utf-8")
    assert suite_problems(text) == []
    for old, new in (
        ("1,000,000-1,000,101 without", "1,000,000-1,000,099 without"),
        ("without 2,000,198", "without 2,000,199"),
        ("| validation | `2854d73a6beb`", "| validation | `2854d73a6bec`"),
        ("formation 0.4745", "formation 0.4746"),
        ("| `test` | [2,000,000, 3,000,000) | 200 |", "| `test` | [2,000,000, 3,000,000) | 100 |"),
    ):
        assert old in text, old
        assert suite_problems(text.replace(old, new, 1)) != [], new


def training_problems(text: str) -> list[str]:
    """How docs/benchmark.md ``text`` states the committed seed runs differently from
    ``data/training/``: how many of the driver's default plan are finished, and which, with each
    kept checkpoint's step and validation successes."""
    from evaluation.experiments.seeds import TRAINING_ROOT, finished_seeds
    from koopman_envs import TASKS

    script = (ROOT / "data" / "training" / "run.sh").read_text(encoding="utf-8")
    seeds = int(re.search(r'SEEDS="\$\{SEEDS:-(\d+)\}"', script)[1])  # type: ignore[index]
    policies = re.search(r"policies=\(([\w -]+)\)\n", script)[1].split()  # type: ignore[index]
    planned = len(policies) * len(TASKS) * seeds
    runs = [
        r
        for p in policies
        for t in TASKS
        for r in finished_seeds(ROOT / TRAINING_ROOT, p, t)
        if r.seed < seeds
    ]
    named = "; ".join(
        f"`{r.policy}` {r.task} seed {r.seed} (kept checkpoint step {r.validation['step']:,}, validation "
        f"{r.validation['successes']}/{r.validation['episodes']})"
        for r in runs
    )
    wanted = (
        f"Of the {planned} seed runs the driver plans by default (`{'` and `'.join(policies)}`, both tasks, "
        f"seeds 0-{seeds - 1}), {len(runs)} {'is' if len(runs) == 1 else 'are'} committed finished "
        f"(a `finished.json` under `data/training/`): {named}."
    )
    flat = " ".join(text.split())
    return [] if wanted in flat else [f"docs/benchmark.md does not state {wanted!r}"]


def test_the_seed_runs_paragraph_is_what_data_training_holds() -> None:
    text = (ROOT / "docs" / "benchmark.md").read_text(encoding="utf-8")
    assert training_problems(text) == []
    assert training_problems(text.replace("validation 22/50", "validation 23/50", 1)) != []
    # one more finished than the page says (whatever it says now: the count grows as seeds finish)
    count = re.search(r"(\d+)\s+(?:is|are)\s+committed\s+finished", text)  # wrapped anywhere
    assert count is not None
    more = text.replace(count[0], f"{int(count[1]) + 1} are committed finished", 1)
    assert training_problems(more) != []
