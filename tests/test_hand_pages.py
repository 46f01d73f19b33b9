"""Prose that cannot drift (issue 60) in the hand-written pages docs/benchmark.md and docs/physics.md
(tests/test_prose_checks.py does README's; tests/test_prose_pages.py the generated docs/paper.md),
by the audit of tests/helpers/hand_audit.py (its docstring says what a result-like token is and
the four ways one is covered): this file holds the two pages' claims and lists.

The claims check against the committed data (data/tuning/, data/physics_*, data/sim2sim_*,
data/publish.sh, the suite, the tuned presets, the code) or match the rows another test
rebuilds from the data (tests/test_prose_checks.py, tests/test_bench_page.py,
tests/test_physics_map1.py, tests/test_koopman_hold.py), as that test writes them. The tests
below show the audit on edited copies of the pages (never on the files).
"""

from __future__ import annotations

import functools
import json
import math
import re
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
from test_bench_page import SIZING, _controllers, _published_runs, sizing_problems  # noqa: E402
from test_koopman_hold import EPISODES, episode_rows, held_rows  # noqa: E402
from test_koopman_hold import MEASURED as MODEL_ERROR  # noqa: E402
from test_physics_map1 import PROBES, counts, failures, load, probes, table  # noqa: E402
from test_prose_checks import (  # noqa: E402
    STARTS,
    WORDS,
    suite_problems,
    training_problems,
    tuning_problems,
    tuning_rows,
)

from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.stats.layout_tests import sign_flip_p_text  # noqa: E402

from helpers.hand_audit import (  # noqa: E402
    Audit,
    CheckFn,
    Claim,
    code_value,
    exact,
    page_problems,
    pinned_problems,
    read,
    result_tokens,
    rows,
    same,
    shipped_seed_problems,
    whole_page,
)

PAGES = ("benchmark.md", "physics.md")


# ------------------------------------------------------------ docs/benchmark.md: the tuning studies
@functools.cache
def _studies() -> dict[str, dict]:
    """Each finished study: its best.json, the adoption rule's decision and its confirmation."""
    from controllers.tuning import BEST_FILE, STUDIES_DIR, study_adoption

    out = {}
    for folder in sorted(p for p in STUDIES_DIR.iterdir() if (p / BEST_FILE).is_file()):
        record = folder / "confirmation.json"
        out[folder.name] = {
            "best": json.loads((folder / BEST_FILE).read_text(encoding="utf-8")),
            "adoption": study_adoption(folder.name),
            "confirmation": json.loads(record.read_text(encoding="utf-8")) if record.is_file() else None,
        }
    return out


def confirmation_rows() -> list[str]:
    """The confirmation table's rows, from each confirmed study's ``confirmation.json``."""
    rows = []
    for name, study in _studies().items():
        c = study["confirmation"]
        if c is None:
            continue
        units = c["units"]
        rows.append(
            f"| {name} | {c['best_trial']} | {c['best_successes']}/{units} | {c['defaults_successes']}/{units} "
            f"| {sign_flip_p_text(c['p_value'], c['exact']).removeprefix('= ')} "
            f"| {'yes' if c['confirmed'] else '**no**'} |"
        )
    return rows


def _adopt_line(match: re.Match[str]) -> list[str]:
    """A line of ``adopt``'s output as the page shows it, against the rule's decision."""
    name = match[1]
    if name not in _studies():
        return [f"adopt's output names {name!r}, which has no finished study"]
    decision = _studies()[name]["adoption"]
    installed = "installed" if decision.adopted else "no"
    wanted = f"{decision}; {installed} controllers/tuned/{name}.json"
    return same(match[0], wanted, f"adopt's line of {name}")


def _budget(match: re.Match[str]) -> list[str]:
    budgets = {json.dumps(s["best"]["budget"], sort_keys=True) for s in _studies().values()}
    if len(budgets) != 1:
        return [f"the studies' budgets differ: {budgets}"]
    b = json.loads(budgets.pop())
    stated = tuple(int(n.replace(",", "")) for n in match.groups())
    actual = (b["configurations"], b["layouts_per_task"], b["episodes_per_layout"], b["episodes"])
    return same(stated, actual, "the studies' budget")


def _confirm_span(match: re.Match[str]) -> list[str]:
    spans = {
        (c["layouts"][1] - c["layouts"][0], c["layouts"][0], c["layouts"][1] - 1, c["units"])
        for s in _studies().values()
        if (c := s["confirmation"])
    }
    stated = tuple(int(n) for n in match.groups())
    return same({stated}, spans, "the confirmations' layouts and units")


def _gain(match: re.Match[str]) -> list[str]:
    """ "`NAME` gains [most, ]N [successes ]of M[ (A -> B)][, the largest gain]": the study's
    best against its defaults; "most" and "the largest" only for the largest gain."""
    name, most, gain, of, before, after, largest = match.groups()
    d = _studies()[name]["adoption"]
    problems = same(
        (int(gain), int(of)), (d.best_successes - d.defaults_successes, d.episodes), f"{name}'s gain"
    )
    if before is not None:
        problems += same((int(before), int(after)), (d.defaults_successes, d.best_successes), name)
    gains = {
        n: s["adoption"].best_successes - s["adoption"].defaults_successes for n, s in _studies().items()
    }
    if (most or largest) and gains[name] != max(gains.values()):
        problems.append(f"{name}'s gain is called the largest; the gains are {gains}")
    return problems


def _confirmed_counts(name: str, best: str, units: str, defaults: str) -> list[str]:
    c = _studies()[name]["confirmation"]
    return same(
        (int(best), int(units), int(defaults)),
        (c["best_successes"], c["units"], c["defaults_successes"]),
        f"{name}'s confirmation",
    )


def _dwa_confirmation(match: re.Match[str]) -> list[str]:
    layouts, best, units, defaults, p = match.groups()
    c = _studies()["dwa"]["confirmation"]
    return (
        _confirmed_counts("dwa", best, units, defaults)
        + same(int(layouts), c["layouts"][1] - c["layouts"][0], "dwa's fresh layouts")
        + same(p, f"{c['p_value']:.2g}", "dwa's confirmation p")
    )


def _study_margin(match: re.Match[str]) -> list[str]:
    d = _studies()[match[1]]["adoption"]
    stated = tuple(int(n) for n in match.groups()[1:])
    return same(stated, (d.best_successes, d.defaults_successes, d.episodes), f"{match[1]}'s study margin")


def _tie(match: re.Match[str]) -> list[str]:
    d = _studies()["orca"]["adoption"]
    return same((int(match[1]), int(match[2])), (d.best_successes, d.episodes), "orca's tie") + same(
        d.best_successes, d.defaults_successes, "orca's tie (best against defaults)"
    )


# ------------------------------------------------------------ docs/benchmark.md: the publication
@functools.cache
def _design() -> dict[str, list[str]]:
    """data/publish.sh's two test-suite runs: mode -> its controllers, in order."""
    runs = _published_runs()
    return {name: _controllers(runs[name]) for name in ("bench_test_realtime", "bench_test")}


def _tuned_pairs(labels: list[str]) -> int:
    return sum(label.endswith("-v0") and label.removesuffix("-v0") in labels for label in labels)


def _families(match: re.Match[str]) -> list[str]:
    """The per-task families: every controller against the reference (and, free, each tuned one
    against its -v0), times 2 tasks; the every-pair tables: every pair of a mode's controllers."""
    charged, free = _design()["bench_test_realtime"], _design()["bench_test"]
    stated = tuple(int(n) for n in match.groups())
    actual = (
        2 * (len(charged) - 1),
        len(charged) - 1,
        2 * (len(free) - 1 + _tuned_pairs(free)),
        len(free) - 1,
        _tuned_pairs(free),
    )
    return same(stated, actual, "the per-task families (m, controllers, m, against, tuned)")


def _every_pair(match: re.Match[str]) -> list[str]:
    stated = (int(match[1]), int(match[2]))
    actual = tuple(2 * math.comb(len(labels), 2) for labels in _design().values())
    return same(stated, actual, "the every-pair families' m (compute charged, free compute)")


def _points(m: int) -> str:
    """What a pooled family of ``m`` over both tasks' test layouts detects at psi = 0.3 [points]."""
    from evaluation.experiments.protocols import SUITE_EPISODES
    from evaluation.stats.families import detectable_difference
    from koopman_envs import TASKS
    from koopman_envs.suites import SUITES

    units = len(TASKS) * SUITES["koopnav-bench-v1"].split("test").size
    return f"{100 * detectable_difference(units, SUITE_EPISODES, discordance=0.3, family_size=m):.1f}"


def _pooled(match: re.Match[str]) -> list[str]:
    """The headline families: each mode's controllers against the reference, pooled over both
    tasks; the tuned pairs apart (m = 4), and what joining them would cost."""
    charged, free = _design()["bench_test_realtime"], _design()["bench_test"]
    m_charged, m_free, tuned = len(charged) - 1, len(free) - 1, _tuned_pairs(free)
    stated = match.groups()
    actual = (
        str(m_charged),
        _points(m_charged),
        str(m_free),
        _points(m_free),
        str(tuned),
        str(m_free + tuned),
        _points(m_free + tuned),
    )
    return same(stated, actual, "the headline families (m, points at psi = 0.3)")


def _units() -> int:
    from koopman_envs import TASKS
    from koopman_envs.suites import SUITES

    return len(TASKS) * SUITES["koopnav-bench-v1"].split("test").size


def _hours(seconds: float) -> float:
    return _units() * seconds / 3600


def _compute_row(match: re.Match[str]) -> list[str]:
    """A row of the compute table: its CPU-hours are the test split's units x its CPU-seconds per
    unit (each stated to the half second, so within that rounding), and the rows of the runs as
    listed now count data/publish.sh's controllers."""
    run, n, low, high, hours_low, hours_high, about = match.groups()
    problems = []
    for seconds, hours in ((low, hours_low), (high, hours_high)):
        lowest, highest = _hours(float(seconds) - 0.5), _hours(float(seconds) + 0.5)
        places = len(hours.split(".")[1]) if "." in hours else 0
        if not round(lowest, places) <= float(hours) <= round(highest, places):
            problems.append(
                f"the compute row {run!r} states {hours} CPU-hours for {seconds} CPU-seconds per unit; "
                f"{_units()} units give {_hours(float(seconds)):.2f}"
            )
    if about is not None and float(about) != (float(hours_low) + float(hours_high)) / 2:
        problems.append(f"the compute row {run!r} says about {about} CPU-hours, not the middle of its range")
    listed = {"`bench_test_realtime` (compute charged)": "bench_test_realtime"}
    listed["`bench_test` with `nominal-nmpc-v0` (as listed now)"] = "bench_test"
    if run in listed:
        problems += same(int(n), len(_design()[listed[run]]), f"the controllers of {run}")
    return problems


def _compute_rows(text: str) -> dict[str, tuple[float, float]]:
    rows = re.finditer(r"^\| (.+?) \| \d+ \| [\d.]+-[\d.]+ \| ([\d.]+)-([\d.]+)[^|]*\|$", text, re.M)
    return {row[1]: (float(row[2]), float(row[3])) for row in rows}


def _both_modes(match: re.Match[str]) -> list[str]:
    """ "Both modes now take about A CPU-hours (L-H) instead of about B": the sum of the two runs'
    rows as listed now, against twice the row before."""
    rows = _compute_rows(match.string)
    charged = rows["`bench_test_realtime` (compute charged)"]
    free = rows["`bench_test` with `nominal-nmpc-v0` (as listed now)"]
    before = rows["before: every registered controller and the three `-v0`, per mode"]
    low, high = charged[0] + free[0], charged[1] + free[1]
    stated = (float(match[2]), float(match[3]), float(match[1]), float(match[4]))
    actual = (round(low), round(high, 1), round((low + high) / 2), 2 * round(sum(before) / 2))
    return same(stated, actual, "both modes' CPU-hours (low, high, about; before)")


@functools.cache
def _logged_wall() -> dict[str, tuple[int, int]]:
    """Per controller, (episodes, summed wall_seconds rounded) of the published free-compute bench
    run (data/bench_test), read through the publications' bounded reader."""
    episodes: dict[str, int] = {}
    seconds: dict[str, float] = {}
    with extracted_archive(ROOT / "data" / "bench_test") as run:
        for line in (run / "episodes.jsonl").read_text(encoding="utf-8").splitlines()[1:]:
            record = json.loads(line)
            label = record["controller"]
            episodes[label] = episodes.get(label, 0) + 1
            seconds[label] = seconds.get(label, 0.0) + record["wall_seconds"]
    return {label: (episodes[label], round(seconds[label])) for label in episodes}


def _tuned_nmpc_wall(match: re.Match[str]) -> list[str]:
    """ "its N episodes logged A s of wall time against B s for `koopman-nmpc-v0`": the published
    free-compute run's records of koopman-nmpc and koopman-nmpc-v0."""
    tuned, hand_set = _logged_wall()["koopman-nmpc"], _logged_wall()["koopman-nmpc-v0"]
    stated = (int(match[1]), int(match[2].replace(",", "")), int(match[3].replace(",", "")))
    return same(
        stated, (tuned[0], tuned[1], hand_set[1]), "koopman-nmpc's and koopman-nmpc-v0's logged wall time"
    )


# ------------------------------------------------------------ docs/physics.md
@functools.cache
def _map1() -> dict[str, list[str]]:
    """The Map 1 section's blocks as tests/test_physics_map1.py writes them from the records."""
    runs = load()
    return {"table": table(runs), "failures": failures(runs), "probes": probes(load((PROBES,)))}


def _failing() -> tuple[list[str], list[str]]:
    """The controllers that miss a seed on the physics plant: on both plants, physics only."""
    runs = load()
    missed = {
        plant: {name for name, cell in runs[plant].items() if not all(r["success"] for r in cell)}
        for plant in runs
    }
    return sorted(missed["mujoco"] & missed["kinematic"]), sorted(missed["mujoco"] - missed["kinematic"])


def _missed_by(match: re.Match[str]) -> list[str]:
    both, physics_only = _failing()
    n = len(both) + len(physics_only)
    return same((int(match[1]), int(match[2])), (n, n), "the controllers that miss a seed (below, those)")


def _fail_alike(match: re.Match[str]) -> list[str]:
    return same(WORDS.get(match[1].lower()), len(_failing()[0]), "the controllers that fail on both plants")


def _fail_physics(match: re.Match[str]) -> list[str]:
    return same(WORDS.get(match[1].lower(), match[1]), len(_failing()[1]), "those that fail on physics only")


WORDS.setdefault("five", 5)
WORDS.setdefault("nine", 9)


def _nominal_margin(match: re.Match[str]) -> list[str]:
    """nominal-nmpc's obstacle margin: the tuned preset's obstacle_offset and the hand-set one."""
    import controllers

    tuned = json.loads((ROOT / "controllers" / "tuned" / "nominal-nmpc.json").read_text(encoding="utf-8"))
    v0 = controllers.options("nominal-nmpc-v0").option("obstacle_offset").default
    return code_value(
        match[1],
        100 * tuned["options"]["obstacle_offset"],
        "the obstacle offsets [cm]: nominal-nmpc's",
        places=1,  # a study's output, rounded to the page's 0.1 cm
    ) + code_value(match[2], 100 * v0, "the obstacle offsets [cm]: nominal-nmpc-v0's")


def _tuned_offset(match: re.Match[str]) -> list[str]:
    tuned = json.loads((ROOT / "controllers" / "tuned" / "nominal-nmpc.json").read_text(encoding="utf-8"))
    return code_value(
        match[1] or match[2],
        100 * tuned["options"]["obstacle_offset"],
        "nominal-nmpc's tuned obstacle offset [cm]",
        places=1,  # a study's output, rounded to the page's 0.1 cm
    )


def _physics_constant(field: str, scale: float) -> CheckFn:
    def check(match: re.Match[str]) -> list[str]:
        from koopman_envs.params import PhysicsParams

        return same(
            float(match[1]), round(scale * getattr(PhysicsParams(), field), 6), f"PhysicsParams.{field}"
        )

    return check


def _timestep(match: re.Match[str]) -> list[str]:
    from koopman_envs.params import PARAMS, PhysicsParams

    step, period = PhysicsParams().timestep, PARAMS.dt
    stated = (float(match[1]), int(match[2]), float(match[3]))
    return same(
        stated, (1000 * step, round(period / step), period), "the timestep, its steps per period, the period"
    )


def _lag_band(match: re.Match[str]) -> list[str]:
    """tests/test_physics_plant.py's band: half the stated constant to 1.1 times it plus a step."""
    from koopman_envs.params import PhysicsParams

    constant = float(match[1])
    band = (f"{constant / 2:.3f}", f"{1.1 * constant + PhysicsParams().timestep:.3f}")
    return same((match[2], match[3]), band, "the lag test's band [s]")


# ------------------------------------------------------------ docs/physics.md: the sim-to-sim protocol
SIM2SIM = ("data/sim2sim_kinematic", "data/sim2sim_physics")


@functools.cache
def _sim2sim() -> dict[str, dict]:
    """Each sim-to-sim publication's design (controllers, layouts, tasks, episodes per layout,
    friction levels) and its episodes so far."""
    from evaluation.experiments.sim2sim import slip_levels

    out = {}
    for path in SIM2SIM:
        done, levels, _ = slip_levels(str(ROOT / path))
        config = next(iter(done.values())).config
        suite = config["suite"]
        out[path] = {
            "controllers": len(config["controllers"]),
            "layouts": suite["layouts"][1] - suite["layouts"][0],
            "tasks": len(suite["tasks"]),
            "episodes": suite["episodes_per_layout"],
            "levels": levels,
            "records": sum(len(results.records) for results in done.values()),
        }
    return out


def _sim2sim_design() -> dict:
    """The design both publications share (a sim-to-sim pair differs by the plant only)."""
    designs = [{k: v for k, v in d.items() if k != "records"} for d in _sim2sim().values()]
    return designs[0] if all(d == designs[0] for d in designs) else {"differ": designs}


def _planned() -> int:
    """The episodes a sim-to-sim run plans on one plant."""
    d = _sim2sim_design()
    return d["controllers"] * d["layouts"] * d["tasks"] * d["episodes"] * len(d["levels"])


def _sim2sim_runs(match: re.Match[str]) -> list[str]:
    """ "Every controller a default run takes (N: ...), the suite's first L test layouts of both
    tasks (...), one episode each, on carpet and on ice": the publications' design."""
    d = _sim2sim_design()
    stated = (int(match[1]), int(match[2]), WORDS.get(match[3], match[3]))
    return same(
        stated, (d.get("controllers"), d.get("layouts"), d.get("episodes")), "the sim-to-sim design"
    ) + same(d.get("levels"), ["nominal", "high"], "the sim-to-sim friction levels (carpet and ice)")


def _fine_tune_cost(match: re.Match[str]) -> list[str]:
    """The fine-tune's CPU and wall time: those docs/rl.md pins (tests/test_hand_pages_rl.py)."""
    rl = re.search(
        r"Each run took (\d+)-(\d+) min of wall time and (\d+) and (\d+) CPU-seconds", read("rl.md")
    )
    source = (rl[3], rl[4], rl[1], rl[2]) if rl else None
    return same(match.groups(), source, "the physics fine-tune's CPU-seconds and wall minutes (docs/rl.md)")


def _sim2sim_estimate(match: re.Match[str]) -> list[str]:
    """What the protocol costs, from the measured rates the paragraph pins: the calibration per
    friction level (kinds x rate x budget), the episodes of each plant (the publications' design)
    at their CPU-seconds each, the whole in CPU-hours (each figure to the places stated)."""
    (low, high, per, kinds, budget, level, calibration, physics, controllers, layouts, tasks, floors) = (
        match.groups()[:12]
    )
    physics_minutes, physics_rate, kinematic, kinematic_minutes, kinematic_rate, hours = match.groups()[12:]
    from evaluation.cli.options import build_parser

    d = _sim2sim_design()
    n = lambda s: float(s.replace(",", ""))  # noqa: E731
    problems = code_value(
        budget, build_parser().get_default("calibration_budget"), "the evaluator's calibration budget"
    )
    scale = WORDS.get(kinds, 0) * n(budget) / n(per) / 60
    if not scale * n(low) <= n(level) <= scale * n(high):
        problems.append(f"{level} CPU-minutes per level is outside {scale * n(low):g}-{scale * n(high):g}")
    problems += same(n(calibration), len(d.get("levels", [])) * n(level), "the calibration's CPU-minutes")
    problems += same(
        (int(controllers), int(layouts), int(tasks), int(floors)),
        (d.get("controllers"), d.get("layouts"), d.get("tasks"), len(d.get("levels", []))),
        "the sim-to-sim design (controllers, layouts, tasks, floors)",
    )
    problems += same((int(physics), int(kinematic)), (_planned(), _planned()), "the episodes of each plant")
    problems += same(
        (int(physics_minutes), int(kinematic_minutes)),
        (round(_planned() * n(physics_rate) / 60), round(_planned() * n(kinematic_rate) / 60)),
        "the episodes' CPU-minutes (physics, kinematic)",
    )
    total = (n(calibration) + int(physics_minutes) + int(kinematic_minutes)) / 60
    problems += same(int(hours), round(total), "the protocol's CPU-hours")
    return problems


def _sim2sim_more(match: re.Match[str]) -> list[str]:
    """Gravel (one more friction level: its calibration and half the episodes again) and one more
    layout (its episodes on both plants), at the paragraph's rates [CPU-minutes]."""
    level = re.search(r"that is about (\d+) CPU-minutes per friction level", match.string)
    rates = re.search(
        r"at ([\d.]+)\s+CPU-seconds each\) and \d+ kinematic ones \(about \d+ at ([\d.]+)\)", match.string
    )
    if level is None or rates is None:
        return ["the paragraph no longer states the calibration per level and the episodes' rates"]
    per_episode = float(rates[1]) + float(rates[2])
    d = _sim2sim_design()
    per_level = _planned() // len(d["levels"])
    per_layout = _planned() // d["layouts"]
    return same(
        (int(match[1]), int(match[2])),
        (round(int(level[1]) + per_level * per_episode / 60), round(per_layout * per_episode / 60)),
        "gravel's and a further layout's CPU-minutes",
    )


# ------------------------------------------------------------ constants of the code
def _constant(value: Callable[[], float], scale: float, what: str) -> CheckFn:
    """A number stated in ``scale`` units of the code's ``value()`` (e.g. 100 for cm of metres)."""

    def check(match: re.Match[str]) -> list[str]:
        return same(float(match[1]), round(scale * value(), 6), what)

    return check


def _params(name: str) -> Callable[[], float]:
    def value() -> float:
        import koopman_envs.params as params

        return float(getattr(params, name))

    return value


def _dt() -> float:
    from koopman_envs.params import PARAMS

    return PARAMS.dt


def _confirmation_level() -> float:
    from evaluation.tune.confirm import CONFIRMATION_LEVEL

    return CONFIRMATION_LEVEL


def _power() -> float:
    import inspect

    from evaluation.stats.families import power_statement

    return float(inspect.signature(power_statement).parameters["power"].default)


def _per_configuration() -> float:
    per = {s["best"]["budget"]["episodes_per_configuration"] for s in _studies().values()}
    return float(per.pop()) if len(per) == 1 else math.nan


def _suite_megabytes() -> float:
    folder = ROOT / "koopman_envs" / "suites" / "data" / "koopnav-bench-v1"
    return round(sum(p.stat().st_size for p in folder.glob("*/*.json.gz")) / 1e6, 1)


def _surface(match: re.Match[str]) -> list[str]:
    from koopman_envs.params import SLIP_SURFACES, SURFACES

    low, high = SURFACES[SLIP_SURFACES[match[1]]]
    return same((match[2], float(match[3]), float(match[4])), (SLIP_SURFACES[match[1]], low, high), match[1])


def _coverage_band(match: re.Match[str]) -> list[str]:
    """The tests' band around 95% coverage: three binomial SDs over the samples [points]."""
    stated = (match[1], match[4])
    actual = tuple(f"{300 * math.sqrt(0.95 * 0.05 / int(n)):.1f}" for n in (match[2], match[3]))
    return same(stated, actual, "the coverage band (points)")


def _learned_seeds_case(match: re.Match[str]) -> list[str]:
    source = (ROOT / "tests" / "test_learned_seeds.py").read_text(encoding="utf-8")
    case = f"for p in (0.{match[1]}, 0.{match[2]})"
    return [] if case in source else [f"tests/test_learned_seeds.py holds no case {case!r}"]


def _fewest_layouts(match: re.Match[str]) -> list[str]:
    """The fewest layouts whose exact sign-flip test can give p <= alpha: 2 / 2^L <= alpha."""

    def fewest(alpha: float) -> int:
        return next(n for n in range(1, 64) if 2 / 2**n <= alpha)

    first, alpha, second, alpha2, m = match.groups()
    stated = (int(first), int(second))
    return same(stated, (fewest(float(alpha)), fewest(float(alpha2) / int(m))), "the fewest layouts")


# ------------------------------------------------------------ the tuned presets' values
def _option(name: str, option: str) -> float:
    """``option`` of the controller or preset ``name`` as shipped: a tuned preset's file, else the
    registered default (a ``-v0`` keeps the hand-set one); a pair of weights by its first entry."""
    tuned = ROOT / "controllers" / "tuned" / f"{name}.json"
    if tuned.is_file():
        value = json.loads(tuned.read_text(encoding="utf-8"))["options"][option]
    else:
        import controllers

        value = controllers.options(name).option(option).default
    return float(value[0] if isinstance(value, list | tuple) else value)


def _preset(*fields: tuple[str, str] | tuple[str, str, int]) -> CheckFn:
    """Each group of the match is ``fields[i]`` = (controller, option): exactly, or (controller,
    option, places) where the page rounds a tuned value (a study's output) to ``places``."""

    def check(match: re.Match[str]) -> list[str]:
        problems = []
        for stated, (name, option, *places) in zip(match.groups(), fields, strict=True):
            problems += code_value(stated, _option(name, option), f"{name}'s {option}", *places)
        return problems

    return check


# ------------------------------------------------------------ the claims of each page
TUNED = "controllers/tuned/*.json and the -v0 presets' defaults"


def _shipped_seed(match: re.Match[str]) -> list[str]:
    """ "target reaching seed K (validation S/E, mean final distance D m, kept checkpoint step C of
    T robot-steps trained)": the shipped rl-ppo-set policy's metadata.json (docs/rl.md's table)."""
    return shipped_seed_problems(match)


def _shipped_ippo_seed(match: re.Match[str]) -> list[str]:
    """ "target reaching seed K (validation S/E, mean final distance D m, kept checkpoint frame C
    of T frames trained)": the shipped ippo policy's metadata.json (docs/rl.md's table)."""
    return shipped_seed_problems(match, policy="ippo")


def _benchmark_claims() -> list[Claim]:
    studies = "data/tuning/*/{best,confirmation}.json and the adoption rule"
    publish = "data/publish.sh's runs (tests/test_bench_page.py parses them)"
    claims = [
        Claim(
            re.compile(r"^\| `(?:train|validation|test)` \| \[[\d,]+, [\d,]+\) \| \d+ \|.*$", re.M),
            whole_page(suite_problems),
            "suite_problems (tests/test_prose_checks.py)",
        ),
        *rows(tuning_rows(), "tuning_problems (tests/test_prose_checks.py)"),
        Claim(
            re.compile(r"^<!-- the rows tests/test_prose_checks.py checks against data/tuning.*$", re.M),
            whole_page(tuning_problems),
            "tuning_problems (tests/test_prose_checks.py)",
        ),
        Claim(
            re.compile(
                r"(target reaching|formation)\s+seed (\d+) \(validation (\d+)/(\d+),\s+mean\s+final\s+distance\s+"
                r"([\d.]+) m,\s+kept\s+checkpoint\s+step ([\d,]+) of ([\d,]+) robot-steps\s+trained\)"
            ),
            _shipped_seed,
            "baselines/policies/set/<task>/metadata.json (the shipped seed)",
        ),
        Claim(
            re.compile(
                r"(target reaching|formation)\s+seed (\d+) \(validation (\d+)/(\d+),\s+mean\s+final\s+distance\s+"
                r"([\d.]+) m,\s+kept\s+checkpoint\s+frame\s+([\d,]+) of ([\d,]+) frames\s+trained\)"
            ),
            _shipped_ippo_seed,
            "baselines/policies/ippo/<task>/metadata.json (the shipped seed)",
        ),
        Claim(
            re.compile(r"Of the \d+ seed runs the driver plans by default.*?validation \d+/\d+\)\.", re.S),
            whole_page(training_problems),
            "training_problems (tests/test_prose_checks.py)",
        ),
        Claim(
            re.compile(rf"^<!-- begin {SIZING}\b.*?^<!-- end {SIZING} -->$", re.M | re.S),
            whole_page(sizing_problems),
            "sizing_problems (tests/test_bench_page.py)",
        ),
        Claim(
            re.compile(r"The design detects about [\d.]+-[\d.]+ points at psi = 0\.3"),
            whole_page(sizing_problems),
            "sizing_problems (tests/test_bench_page.py)",
        ),
        *rows(confirmation_rows(), "data/tuning/*/confirmation.json"),
        Claim(
            re.compile(r"^([\w-]+): (?:adopted|defaults kept \([^)]*\)): trial .*$", re.M),
            _adopt_line,
            studies,
            whole=True,
        ),
        Claim(
            re.compile(
                r"(\d+) configurations x (\d+)\s+validation layouts per task x (\d+) episode x both "
                r"tasks \(([\d,]+) episodes\)"
            ),
            _budget,
            "data/tuning/*/best.json's budget",
        ),
        Claim(
            re.compile(
                r"`--confirm (\d+)`: validation layouts (\d+)-(\d+) of\s+both tasks, (\d+) paired units"
            ),
            _confirm_span,
            "data/tuning/*/confirmation.json",
        ),
        Claim(
            re.compile(
                r"`([\w-]+)` gains (most, )?(\d+) (?:successes )?of (\d+)(?: \((\d+) -> (\d+)\))?"
                r"(, the largest gain)?"
            ),
            _gain,
            studies,
        ),
        Claim(
            re.compile(
                r"which did not hold on (\d+) fresh validation layouts per task \((\d+) of (\d+) "
                r"against\s+(\d+),\s+p = ([\d.]+)\)"
            ),
            _dwa_confirmation,
            studies,
        ),
        Claim(
            re.compile(r"confirmed on fresh layouts \((\d+) of\s+(\d+) against (\d+)\)"),
            lambda m: _confirmed_counts("koopman-nmpc", *m.groups()),
            studies,
        ),
        Claim(re.compile(r"(dwa)'s study margin \((\d+) against (\d+) of (\d+)\)"), _study_margin, studies),
        Claim(re.compile(r"`orca`'s best ties its defaults on successes \((\d+) of (\d+)\)"), _tie, studies),
        Claim(
            re.compile(
                r"m = (\d+) \((\d+) controllers x 2 tasks\) with compute charged, (\d+) with free compute "
                r"\((\d+)\s+against the reference and (\d+) tuned against their `-v0`, x 2 tasks\)"
            ),
            _families,
            publish,
        ),
        Claim(
            re.compile(r"The every-pair tables \(m = (\d+) and\s+(\d+), each corrected over every pair"),
            _every_pair,
            publish,
        ),
        Claim(
            re.compile(
                r"m = (\d+) with compute charged \(([\d.]+) points at psi =\s+0\.3: the issue's 10-point "
                r"target met\) and (\d+) with free compute \(([\d.]+) points\)\. The (?:\d+) tuned\s+"
                r"controllers against their `-v0` \(free compute\) do not join it: they form their own "
                r"pooled family\s+\(m = (\d+)\), because .*? \(m = (\d+), ([\d.]+) points\)",
                re.S,
            ),
            _pooled,
            publish + " and detectable_difference",
        ),
        Claim(
            re.compile(
                r"^\| (.+?) \| (\d+) \| ([\d.]+)-([\d.]+) \| ([\d.]+)-([\d.]+)(?: \(about (\d+)\))? \|$", re.M
            ),
            _compute_row,
            "the test split's units x CPU-seconds per unit; " + publish,
        ),
        Claim(
            re.compile(
                r"Both modes now take about (\d+) CPU-hours \(([\d.]+)-([\d.]+)\) instead of about (\d+)"
            ),
            _both_modes,
            "the compute table's rows",
        ),
        Claim(
            re.compile(
                r"its (\d+) episodes logged ([\d,]+) s of wall time against ([\d,]+) s for\s+`koopman-nmpc-v0`"
            ),
            _tuned_nmpc_wall,
            "data/bench_test's records of koopman-nmpc and koopman-nmpc-v0 (wall_seconds)",
        ),
        Claim(
            re.compile(
                r"It plans over (\d+) steps \((\d+) before\), with a\s+lighter input weight \(([\d.]+)\), "
                r"wider obstacle margins \(([\d.]+) m against the paper's ([\d.]+) m\), a\s+narrower robot "
                r"margin \(([\d.]+) m\) and its calibrated residual widening them \(`uncertainty_margin`\s+"
                r"([\d.]+)\)"
            ),
            _preset(
                ("koopman-nmpc", "horizon"),
                ("koopman-nmpc-v0", "horizon"),
                ("koopman-nmpc", "r_input", 3),
                ("koopman-nmpc", "obstacle_offset", 3),
                ("koopman-nmpc-v0", "obstacle_offset"),
                ("koopman-nmpc", "robot_offset", 4),
                ("koopman-nmpc", "uncertainty_margin", 1),
            ),
            TUNED,
        ),
        Claim(
            re.compile(
                r"looks further ahead \(`horizon`\s+(\d+) against (\d+)\) and widens the obstacle margin "
                r"\(([\d.]+) m against ([\d.]+)\) with an uncertainty\s+margin \(([\d.]+) against (0)\)"
            ),
            _preset(
                ("koopman-nmpc", "horizon"),
                ("koopman-nmpc-v0", "horizon"),
                ("koopman-nmpc", "obstacle_offset", 3),
                ("koopman-nmpc-v0", "obstacle_offset"),
                ("koopman-nmpc", "uncertainty_margin", 1),
                ("koopman-nmpc-v0", "uncertainty_margin"),
            ),
            TUNED,
        ),
        Claim(
            re.compile(
                r"\(`obstacle_offset` ([\d.]+) m, `robot_offset` ([\d.]+) m, `uncertainty_margin` ([\d.]+)\) "
                r"and softens the\s+barrier \(`cbf_gamma` ([\d.]+)\); its hand-set rate, ([\d.]+),"
            ),
            _preset(
                ("mpc-cbf", "obstacle_offset", 3),
                ("mpc-cbf", "robot_offset", 3),
                ("mpc-cbf", "uncertainty_margin", 1),
                ("mpc-cbf", "cbf_gamma", 2),
                ("mpc-cbf-v0", "cbf_gamma"),
            ),
            TUNED,
        ),
        Claim(
            re.compile(
                r"looks further ahead \(`horizon`\s+(\d+) periods against (\d+)\), widens the obstacle margin "
                r"\(`obstacle_offset` ([\d.]+) m against ([\d.]+)\)\s+and adds an uncertainty margin "
                r"\(([\d.]+) against (0)\)"
            ),
            _preset(
                ("nominal-nmpc", "horizon"),
                ("nominal-nmpc-v0", "horizon"),
                ("nominal-nmpc", "obstacle_offset", 3),
                ("nominal-nmpc-v0", "obstacle_offset"),
                ("nominal-nmpc", "uncertainty_margin", 2),
                ("nominal-nmpc-v0", "uncertainty_margin"),
            ),
            TUNED,
        ),
        Claim(STARTS[0], lambda m: STARTS[1](m), "evaluation.experiments.protocols.START_NOISE"),
        Claim(
            re.compile(r"`STRICT_CLEARANCE_MARGIN` = (\d+) cm"),
            _constant(_params("STRICT_CLEARANCE_MARGIN"), 100, "STRICT_CLEARANCE_MARGIN [cm]"),
            "koopman_envs.params",
            whole=True,
        ),
        Claim(
            re.compile(r"`STRICT_CLEARANCE_MARGIN` \((\d+) cm; a contact counts\)"),
            _constant(_params("STRICT_CLEARANCE_MARGIN"), 100, "STRICT_CLEARANCE_MARGIN [cm]"),
            "koopman_envs.params",
        ),
        Claim(
            re.compile(r"`PATH_RATIO_MIN_DISTANCE` = (\d+) cm"),
            _constant(_params("PATH_RATIO_MIN_DISTANCE"), 100, "PATH_RATIO_MIN_DISTANCE [cm]"),
            "koopman_envs.params",
        ),
        Claim(
            re.compile(r"`max_episode_steps` x ([\d.]+) s\)"),
            _constant(_dt, 1, "the control period [s]"),
            "koopman_envs.params.PARAMS.dt",
        ),
        Claim(
            re.compile(r"has more successes there and p < ([\d.]+)"),
            _constant(_confirmation_level, 1, "the confirmation's level"),
            "evaluation.tune.confirm.CONFIRMATION_LEVEL",
        ),
        Claim(
            re.compile(r"on the very (\d+) episodes it was picked on"),
            _constant(_per_configuration, 1, "a study's episodes per configuration"),
            "data/tuning/*/best.json's budget",
        ),
        Claim(
            re.compile(r"more than ([\d,]+) episodes per cell"),
            lambda m: same(
                int(m[1].replace(",", "")),
                int(_params("MAX_EPISODES_PER_CELL")()),
                "the episodes per cell's limit",
            ),
            "koopman_envs.params.MAX_EPISODES_PER_CELL",
        ),
        Claim(
            re.compile(r"(\d+)% power"),
            _constant(_power, 100, "power_statement's power [%]"),
            "evaluation.stats.families.power_statement",
        ),
        Claim(
            re.compile(r"95% \+- ([\d.]+) points over (\d+) samples \((\d+) and \+- ([\d.]+) points"),
            _coverage_band,
            "three binomial SDs of a 95% coverage",
        ),
        Claim(
            re.compile(r"1\.0 for a\s+policy at (\d+)% and for one at (\d+)%"),
            _learned_seeds_case,
            "tests/test_learned_seeds.py's case",
        ),
        Claim(
            re.compile(
                r"With fewer layouts than reach alpha/m \((\d+) at ([\d.]+), (\d+) at ([\d.]+)/(\d+)\)"
            ),
            _fewest_layouts,
            "the exact sign-flip test's smallest p, 2 / 2^L",
        ),
        Claim(
            re.compile(r"<split>\.json\.gz`, ([\d.]+) MB in all"),
            _constant(_suite_megabytes, 1, "the suite's data [MB]"),
            "the files' sizes",
        ),
    ]
    return claims


def _page_cells(text: str, row: str) -> list[list[str]]:
    """The cells of every table row of ``text`` that matches ``row`` (a pattern from the row's start)."""
    return [
        [cell.strip() for cell in line.strip().strip("|").split("|")]
        for line in re.findall(r"^\|.*\|$", text, re.M)
        if re.match(row, line)
    ]


def _span(values: list[float], places: int) -> str:
    return f"{min(values):.{places}f}-{max(values):.{places}f}"


def _map1_repeats(match: re.Match[str]) -> list[str]:
    """The Map 1 closed-loop prose against its table (whose rows come from data/physics_closed_loop/)."""
    text = match.string

    def cell(controller: str, floor: str, column: int) -> str:
        return _page_cells(text, rf"\| `{re.escape(controller)}` \| {floor} \|")[0][column]

    nominal, low, short, ends = match.groups()
    return [
        *same(
            nominal.replace(" of ", "/"),
            cell("nominal-nmpc", "nominal", 2),
            "nominal-nmpc's successes on carpet",
        ),
        *same(
            " ".join(low.split()).replace(" of ", "/"),
            cell("nominal-nmpc", "low", 2),
            "nominal-nmpc's successes on gravel",
        ),
        *same(short, cell("koopman-nmpc", "nominal", 4), "koopman-nmpc's mean distance on carpet"),
        *same(
            ends,
            cell("koopman-nmpc:velocity=true", "nominal", 4),
            "the velocity lift's mean distance on carpet",
        ),
    ]


def _held_figures(text: str) -> dict[str, str]:
    """What the held-inputs prose states of its table (whose rows come from
    data/physics_model_error/): the table's columns 5 and 7 are the circle's and the windows'
    ratios, 9 the circle speed."""
    section = text[
        text.index("### Held identification inputs") : text.index("### Refits on the model's own rollouts")
    ]
    ice_random = _page_cells(section, r"\| high \(ice\) \| 1\.\.30 \| ")
    ice_velocity = _page_cells(section, r"\| high \(ice\) \| [\d.]+ \| (?:memory 3 \+ )?velocity \|")
    other = _page_cells(section, r"\| (?:low \(gravel\)|nominal \(carpet\)) \| [\d.]+ \| (?!unicycle)")
    return {
        "memory 3 + velocity's random-hold ratio": next(
            c[6] for c in ice_random if c[2] == "memory 3 + velocity"
        ),
        "the random holds' circle ratios on ice": _span([float(c[4]) for c in ice_random], 1),
        "the velocity lifts' circle speeds on ice": _span([float(c[8]) for c in ice_velocity], 2),
        "the held lifts' ratios on gravel and carpet": _span([float(c[6]) for c in other], 1),
    }


def _held_repeats(match: re.Match[str]) -> list[str]:
    """Each group of the match against :func:`_held_figures`, in its order (an empty group: not
    stated here)."""
    figures = _held_figures(match.string)
    return [
        problem
        for (what, actual), stated in zip(figures.items(), match.groups(), strict=True)
        if stated
        for problem in same(" ".join(stated.split()), actual, what)
    ]


def _map1_short(match: re.Match[str]) -> list[str]:
    """How far short a controller ended on the physics plant, against every seed of its row in
    the Map 1 table (whose rows come from data/physics_map1/): each distance stated is one of the
    row's (the seed and robot numbers left out)."""
    controller, said = match[1], match[2]
    found = _page_cells(match.string, rf"\| {re.escape(controller)} \| mujoco \|")
    if not found:
        return [f"the Map 1 table has no mujoco row of {controller}"]
    distances = {n for cell in found[0][2:] for n in re.findall(r"\d+", cell.split(":")[-1])}
    said = re.sub(r"\b(?:seeds?|robots?) \d+(?: and \d+)?", "", said)
    return [
        f"{controller}'s {n} cm short is in no seed of its mujoco row of the Map 1 table"
        for n in re.findall(r"\d+", said)
        if n not in distances
    ]


def _physics_claims() -> list[Claim]:
    map1 = "tests/test_physics_map1.py (data/physics_map1/)"
    held = [
        row
        for path in sorted(MODEL_ERROR.glob("*.json"))
        for r in json.loads(path.read_text(encoding="utf-8"))
        for row in held_rows(r)
    ]
    episodes = [
        row
        for path in sorted(EPISODES.glob("*.jsonl"))
        for row in episode_rows([json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()])
    ]
    return [
        *rows(_map1()["table"] + _map1()["failures"] + _map1()["probes"], map1),
        *[Claim(exact(phrase), lambda m: [], map1) for phrase in counts(load())],
        Claim(
            re.compile(r"is missed by the (\d+) below\. Every episode of those (\d+) on both plants"),
            _missed_by,
            "data/physics_map1/",
        ),
        Claim(re.compile(r"\b(\w+) fail on both plants alike"), _fail_alike, "data/physics_map1/"),
        Claim(re.compile(r"\b(\w+) fail on the physics plant only"), _fail_physics, "data/physics_map1/"),
        Claim(
            re.compile(r"the margin grows from\s+([\d.]+) cm to|the ([\d.]+) cm offset left as tuned"),
            _tuned_offset,
            "controllers/tuned/nominal-nmpc.json",
        ),
        Claim(
            re.compile(
                r"never below `obstacle_offset` \(([\d.]+) cm; the defaults:\s+no uncertainty margin, "
                r"([\d.]+) cm\)"
            ),
            _nominal_margin,
            "controllers/tuned/nominal-nmpc.json, nominal-nmpc-v0",
        ),
        Claim(
            re.compile(
                r"`(koopman-nmpc-v0|koopman-nmpc|koopman-nmpc-robust|adaptive-koopman-nmpc|nominal-nmpc)`"
                r"(?:, the hand-set controller| on its tuned preset)?\s+\(((?:robot|seed|\d)[^)]*cm\s+short[^)]*)\)"
            ),
            _map1_short,
            "the Map 1 table (tests/test_physics_map1.py, data/physics_map1/)",
        ),
        *rows(held, "tests/test_koopman_hold.py (data/physics_model_error/)"),
        *rows(episodes, "tests/test_koopman_hold.py (data/physics_closed_loop/)"),
        Claim(
            re.compile(
                r"in most seeds \((\d+ of \d+) on carpet, (\d+\s+of \d+) on gravel[^)]*\)\. The pose-only "
                r"Koopman-NMPC stops short in every seed\s+\(time limit, ([\d.]+) cm short on carpet on average\)"
                r"\. The velocity lift reaches the targets once on\s+carpet \([^)]*\) and ends ([\d.]+) cm"
            ),
            _map1_repeats,
            "the Map 1 closed-loop table (tests/test_koopman_hold.py, data/physics_closed_loop/)",
        ),
        Claim(
            re.compile(
                r"memory 3 \+ velocity ([\d.]+)\s+times the unicycle's error over the windows, and ([\d.]+-[\d.]+) "
                r"times on the circle, whose speed the\s+velocity lifts still predict as ([\d.]+-[\d.]+) m/s\."
                r"[\s\S]*?On gravel and carpet every lift is still ([\d.]+-[\d.]+\s+)times worse"
            ),
            _held_repeats,
            "the held-inputs table (tests/test_koopman_hold.py, data/physics_model_error/)",
        ),
        Claim(
            re.compile(
                r"()()they predict ([\d.]+-[\d.]+) m/s where the[\s\S]*?these models are ([\d.]+-[\d.]+) times the"
            ),
            _held_repeats,
            "the held-inputs table (tests/test_koopman_hold.py, data/physics_model_error/), stated again",
        ),
        Claim(
            re.compile(r"Timestep\*\*: ([\d.]+) ms, (\d+) physics steps per ([\d.]+) s control period"),
            _timestep,
            "PhysicsParams.timestep, RobotParams.dt",
        ),
        Claim(
            re.compile(r'^\| `"(\w+)"` \| (\w+)[^|]* \| ([\d.]+)-([\d.]+) \|$', re.M),
            _surface,
            "koopman_envs.params.SURFACES, SLIP_SURFACES",
        ),
        Claim(
            re.compile(r"\| XM430-W210-T geared (\d+)x faster: "),
            _physics_constant("gear_factor", 1.0),
            "PhysicsParams.gear_factor",
        ),
        Claim(
            re.compile(r"lag of \*\*([\d.]+) s\*\*"),
            _physics_constant("motor_time_constant", 1.0),
            "PhysicsParams.motor_time_constant",
        ),
        Claim(
            re.compile(
                r"constant is the sum, ([\d.]+) s.*?between half the stated constant and 1\.1 times it "
                r"plus one physics step \(([\d.]+)-([\d.]+) s",
                re.S,
            ),
            _lag_band,
            "the stated constant and PhysicsParams.timestep",
        ),
        Claim(
            re.compile(
                r"Every controller a default run takes \((\d+): every registered one but the `-v0` variants of the\s+"
                r"tuned presets, which run only when named\), the suite's first (\d+) test layouts of both tasks \(the\s+"
                r"tuner never saw them\), (\w+) episode each, on carpet and on ice"
            ),
            _sim2sim_runs,
            "the publications " + " and ".join(SIM2SIM),
        ),
        Claim(
            re.compile(r"One of the (\d+) is not a transfer"),
            lambda m: same(int(m[1]), _sim2sim_design().get("controllers"), "the sim-to-sim controllers"),
            "the publications " + " and ".join(SIM2SIM),
        ),
        Claim(
            re.compile(
                r"each fine-tune is a training run of its own: (\d+)\s+and (\d+) CPU-seconds for the two tasks "
                r"\((\d+)-(\d+) minutes of wall time each"
            ),
            _fine_tune_cost,
            "docs/rl.md's pinned fine-tune times",
        ),
        Claim(
            re.compile(
                r"Calibrating on the physics plant took (\d+)-(\d+) CPU-seconds per ([\d,]+)\s+team-transitions for "
                r"each of the (\w+) kinds that calibrate.*?At the evaluator's ([\d,]+) that is about (\d+) "
                r"CPU-minutes per friction level.*?about (\d+) CPU-minutes of calibration, (\d+) physics episodes "
                r"\((\d+) controllers,.*? x (\d+) layouts x (\d+) tasks x (\d+) floors; about (\d+) CPU-minutes at "
                r"([\d.]+)\s+CPU-seconds each\) and (\d+) kinematic ones \(about (\d+) at ([\d.]+)\), \*\*about "
                r"(\d+) CPU-hours with one\s+worker\*\*",
                re.S,
            ),
            _sim2sim_estimate,
            "the pinned rates, the evaluator's calibration budget and the publications' design",
        ),
        Claim(
            re.compile(r"The kinematic run took [\d,]+ s of wall time for its (\d+) episodes"),
            lambda m: same(
                int(m[1]), _sim2sim()[SIM2SIM[0]]["records"], "the kinematic publication's episodes"
            ),
            "the publication " + SIM2SIM[0],
        ),
        Claim(
            re.compile(
                r"and [\d,]+ s for the (\d+) rerun after .*?`python -m evaluation\.forget ([\w -]+?) --", re.S
            ),
            lambda m: same(
                int(m[1]),
                len(m[2].split()) * _planned() // _sim2sim_design()["controllers"],
                "the rerun's episodes",
            ),
            "the forgotten controllers x each one's episodes",
        ),
        Claim(
            re.compile(
                r"would add about (\d+) CPU-minutes; each further layout about (\d+) CPU-minutes on both"
            ),
            _sim2sim_more,
            "the paragraph's rates and the publications' design",
        ),
    ]


# --------------------------------------------------------------------------- measured, unrecorded
# What measured each (the page's words pinned; an edit fails as a phrase no longer stated).
PAGE_SIZE = (
    "python bench/bench_page_size.py (a synthetic full-size publication), run by hand; output not committed"
)
EPISODE_TIMES = (
    "python evaluate.py --suite koopnav-bench-v1 --split test --layouts N --controllers NAME --workers 1, "
    "wall time per episode timed by hand at about twice the machine's load (2026-11-29)"
)
CHEAP_RUN = (
    "/usr/bin/time python evaluate.py --suite koopnav-bench-v1 --split test --layouts 3 --controllers consensus "
    "consensus-free rl-ppo rl-ppo-set ippo orca --workers 1 (2026-11-29)"
)
GATE_CELLS = (
    "bash .ci/leaderboard.sh's cells run with orca's study best (orca:OPTIONS), by hand; not committed"
)
SB3_RESUME = (
    "python -m baselines.sb3.train --policy set --suite koopnav-bench-v1 (the real settings), one resume checkpoint "
    "sized and timed by hand"
)
IPPO_RESUME = (
    "python -m baselines.marl.benchmarl_train --task formation --algorithm ippo --suite koopnav-bench-v1 "
    "(36,000 frames, stopped at 24,000), the checkpoint sized and its hash check timed by hand"
)
TINY_RUN = (
    "TRAINING_ROOT=/tmp/tr SEEDS=2 TIMESTEPS=3000 FRAMES=400 VALIDATION_LAYOUTS=2 ... bash data/training/run.sh "
    "rl-ppo-set ippo, then python -m evaluation.experiments.seeds --root /tmp/tr --layouts 4 (the page's commands), "
    "timed by hand"
)
THROUGHPUT = (
    "python -m baselines.sb3.train --suite koopnav-bench-v1 --threads 1 (196,608 steps) and python -m "
    "baselines.marl.benchmarl_train --suite koopnav-bench-v1 (120,000 frames): rates read from their logs by hand"
)
ESTIMATE = (
    "arithmetic on the throughput above and the shipped policies' training rates (an estimate, not run)"
)
SIMULATION = (
    "the coverage and size simulations of tests/test_clustered_statistics.py, their figures printed by hand"
)
INTERVAL_TIME = "layout_rate_interval on 200 layouts x 5 episodes with 4000 resamples, timed by hand"
STEP_RESPONSE = "a 0.5 m/s step on carpet, one 5 ms physics step at a time, by hand (tests/test_physics_plant.py holds the band)"
TRAIL = "tests/test_physics_fronts.py's straight run at 0.6 m/s for 3 s, its values printed by hand (it holds 6.75 cm +-10 %)"
TIMESTEP_CHECK = (
    "5 s of full-speed driving and turning at 2.5, 5 and 10 ms physics steps, by hand; not committed"
)
TURN = "tests/test_physics_plant.py's turn at 0.6 m/s and pi/4 rad/s for 3 s, its values printed by hand"
MODEL_ERROR_1M = (
    "python bench/physics_model_error.py (its defaults: --levels high low nominal --budget 1000000 --seed 0); "
    "output not committed"
)
HELD_ONE_OFF = (
    "a one-off check, not shipped: held inputs of 5, 10 and 20 periods, 50,000 team-transitions per fit"
)
MODEL_ERROR_MEMORY = "python bench/physics_model_error.py --levels high nominal --budget 100000 --memory 1 2 3; output not committed"
VELOCITY_PROTOTYPE = (
    "a one-off prototype, not shipped: 30,000 team-transitions on ice, the circle on 10 teams"
)
MODEL_ERROR_VELOCITY = (
    "python bench/physics_model_error.py --levels high / nominal low --budget 100000 --episodes 2 --memory 1|2|3 "
    "--velocity (the section's four commands); output not committed"
)
CLOSED_LOOP_MEMORY = (
    "python evaluate.py --env KoopNav-TargetReaching-v0 --maps map1 --slips nominal --episodes 3 --plant mujoco "
    "--controllers koopman-nmpc-v0:memory=3 koopman-nmpc-v0 --calibration-budget 100000 (2026-11-29), and the solve "
    "times of its NMPC timed by hand; records not committed"
)
BENCH_TIME = (
    "/usr/bin/time of the section's python bench/physics_model_error.py commands on the shared machine"
)
REFIT_PROTOTYPE = "a one-off prototype, not shipped: a second refit on the same ice data"
MAP1_TIME = "/usr/bin/time of the Map 1 section's two python evaluate.py runs and of the 2026-11-30 rerun"
MAP1_PROBE = (
    "an earlier run of the Map 1 table probing koopman-nmpc's model where seed 0 stops; not committed"
)
RESIDUAL = "the calibration cache's entry of nominal-nmpc's residual on the physics robots (13 cm = 2.56 x 5.2); not committed"
STEP_TIMES = (
    "per env-step CPU time, best of 5 windows of 2,000 steps (mj_step stubbed), at 8d7e200 and after, by hand"
)
SPEED_BEFORE_AFTER = "python bench/physics_speed.py --seconds 2 --repeats 3 --envs 16, at 8d7e200 and after"
MUJOCO_ONE_OFF = (
    "MuJoCo's step timed by solver and Jacobian, and a 20 s state comparison, by hand; not committed"
)
SPEED_LOADS = "python bench/physics_speed.py (its defaults) at 4a00b79, at loads 3.5 and 29.9"
PY_SPY = "py-spy record -r 200 over 15 CPU-seconds of env.step with random actions on the default map"
SIM2SIM_FIRST = (
    "/usr/bin/time python evaluate.py --suite koopnav-bench-v1 --split test --layouts 0:2 --slips high "
    "--calibration-budget 20000 (and --plant mujoco), the calibrations timed apart, by hand; not committed"
)
SIM2SIM_WALL = (
    "the wall time the sim-to-sim kinematic run and its rerun logged (bash data/publish.sh sim2sim_kinematic)"
)
SPEED_IDLE = "python bench/physics_speed.py (its defaults) at 5134e6c on the idle machine (2026-11-30)"
SYNTHETIC_REFIT = "a one-off check, not shipped: the refit on a synthetic team with a bounded acceleration"
REFIT_AGAINST = (
    "the refit table (data/physics_model_error/*refits1.json, its rows checked by tests/test_koopman_hold.py) "
    "against the velocity table's figures, compared by hand"
)

MEASURED: dict[str, dict[str, str]] = {
    "benchmark.md": {
        "the page was 743 KB (6,001 lines; the generator 602 CPU-seconds) with 19 controllers": PAGE_SIZE,
        "it is 86 KB (791 lines)": PAGE_SIZE,
        "258 KB (1,968 rows; the generator 255 CPU-seconds for both)": PAGE_SIZE,
        "`orca` 5 s, `dwa` 17 s, `mpc-cbf` 33 s, the NMPCs about 15-30 s": EPISODE_TIMES,
        "2.5, 8.5, 16.5 and 7.5-15 s": EPISODE_TIMES + " (halved: two runs per core)",
        "(36 episodes) took 38 CPU-seconds": CHEAP_RUN,
        "21 of 40 against 35 of 40": GATE_CELLS,
        "about 3 h on a loaded core": THROUGHPUT,
        "about 4 min at the shared machine's 2,046 robot-steps/s": THROUGHPUT,
        "one checkpoint measured 2.8 MiB, written in 0.28 s and read back in 0.24 s": SB3_RESUME,
        "that checkpoint was 19.0 MB (19,017,784 bytes;": IPPO_RESUME,
        "its hash check 0.07 CPU-s": IPPO_RESUME,
        "took 6 min 0 s": TINY_RUN,
        "4 test layouts per task took 32 s": TINY_RUN,
        "where a run got 44-48% of a core": THROUGHPUT,
        "`rl-ppo-set` on the suite: 2,046 robot-steps/s": THROUGHPUT,
        "`ippo`: 937 frames/s": THROUGHPUT,
        "50 validation layouts: about 15-20 s": THROUGHPUT,
        "would take about 20 h": ESTIMATE,
        "adds about 10 min per seed": ESTIMATE,
        "about 7-9 h one at a time": ESTIMATE,
        "(5,870 robot-steps/s for `rl-ppo-set`, 3,444 frames/s for `ippo`) give 6.6 h": ESTIMATE,
        "take about 4-5 h": ESTIMATE,
        "covers about 76-81%": SIMULATION,
        "covered 97-99% of beta-binomial samples (98.9% at rho = 0.1)": SIMULATION,
        "an interval takes about 0.1-0.2 s": INTERVAL_TIME,
        "rejects at 5% +- 3.3 points": SIMULATION,
    },
    "physics.md": {
        "alone, it lags 0.0125 s": STEP_RESPONSE,
        "reaches 63 % of it after 0.105 s (measured, one 5 ms step": STEP_RESPONSE,
        "(6.7 cm on carpet against 6.75; 19.9 cm on ice": TRAIL,
        "checked against a 2.5 ms run over 5 s of full-speed driving and turning: at most 4 mm apart on carpet and "
        "10 mm on ice, where a 10 ms step is 12 and 29 mm apart": TIMESTEP_CHECK,
        "in a turn at 0.6 m/s and pi/4 rad/s for 3 s it ends 7 cm": TURN,
        "(the motor lag), 10 cm on gravel and 50 cm on ice": TURN,
        "took 25-58 minutes": MODEL_ERROR_1M,
        "| high (ice) | 140.0 / 16.9 | 8.31 | 62.1 / 13.0 | 4.79 | 1.51 / 5.81 |": MODEL_ERROR_1M,
        "| low (gravel) | 142.2 / 2.8 | 50.31 | 58.1 / 3.3 | 17.38 | 2.74 / 5.62 |": MODEL_ERROR_1M,
        "| nominal (carpet) | 146.5 / 4.0 | 36.89 | 52.0 / 3.0 | 17.14 | 2.82 / 5.18 |": MODEL_ERROR_1M,
        "| high (ice) | 0.300 / 0.002 / 0.300 | 0.117 / 0.418 | 0.01 / 0.77 |": MODEL_ERROR_1M,
        "| low (gravel) | 0.300 / 0.019 / 0.300 | 0.233 / 0.418 | 0.09 / 0.93 |": MODEL_ERROR_1M,
        "| nominal (carpet) | 0.298 / 0.052 / 0.300 | 0.261 / 0.418 | 0.20 / 0.97 |": MODEL_ERROR_1M,
        "circle errors of 126, 114 and 96 cm against the unicycle's 3.9; on ice to 0.04-0.14 m/s, 131-136 cm": HELD_ONE_OFF,
        "| high (ice) | pose only | 141.3 | 8.39 | 61.9 | 4.78 | 1.51 | 0.004 |": MODEL_ERROR_MEMORY,
        "| | memory 1 | 143.2 | 8.50 | 56.4 | 4.35 | 1.43 | 0.025 |": MODEL_ERROR_MEMORY,
        "| | memory 2 | 142.1 | 8.43 | 50.0 | 3.86 | 1.32 | 0.052 |": MODEL_ERROR_MEMORY,
        "| | memory 3 | 137.0 | 8.13 | 44.3 | 3.42 | 1.22 | 0.080 |": MODEL_ERROR_MEMORY,
        "| | unicycle | 16.9 | | 13.0 | | 5.81 | 0.300 |": MODEL_ERROR_MEMORY,
        "| nominal (carpet) | pose only | 146.2 | 36.81 | 51.7 | 17.05 | 2.82 | 0.053 |": MODEL_ERROR_MEMORY,
        "| | memory 1 | 125.4 | 31.57 | 23.0 | 7.58 | 1.36 | 0.184 |": MODEL_ERROR_MEMORY,
        "| | memory 2 | 90.5 | 22.80 | 9.5 | 3.14 | 0.74 | 0.244 |": MODEL_ERROR_MEMORY,
        "| | memory 3 | 76.1 | 19.15 | 4.6 | 1.51 | 0.60 | 0.267 |": MODEL_ERROR_MEMORY,
        "| | unicycle | 4.0 | | 3.0 | | 5.18 | 0.298 |": MODEL_ERROR_MEMORY,
        "the circle's speed as 0.37 m/s with one remembered command and 0.33 m/s with two": VELOCITY_PROTOTYPE,
        "circle errors of 129 and 95 cm": VELOCITY_PROTOTYPE,
        "| high (ice) | pose only | 141.3 | 8.39 | 61.5 | 4.89 | 1.51 | 0.004 |": MODEL_ERROR_VELOCITY,
        "| | memory 1 | 143.2 | 8.50 | 56.1 | 4.45 | 1.43 | 0.025 |": MODEL_ERROR_VELOCITY,
        "| | memory 2 | 142.1 | 8.43 | 49.8 | 3.96 | 1.32 | 0.052 |": MODEL_ERROR_VELOCITY,
        "| | velocity | 148.3 | 8.80 | 17.3 | 1.37 | 0.46 | 0.155 |": MODEL_ERROR_VELOCITY,
        "| | memory 3 | 137.0 | 8.13 | 44.1 | 3.50 | 1.22 | 0.080 |": MODEL_ERROR_VELOCITY,
        "| | memory 2 + velocity | 113.3 | 6.72 | 10.7 | **0.85** | 0.28 | 0.262 |": MODEL_ERROR_VELOCITY,
        "| | memory 3 + velocity | 112.7 | 6.69 | 10.2 | **0.81** | 0.28 | 0.265 |": MODEL_ERROR_VELOCITY,
        "| | unicycle | 16.9 | | 12.6 | | 5.81 | 0.300 |": MODEL_ERROR_VELOCITY,
        "| low (gravel) | pose only | 139.7 | 49.40 | 58.6 | 17.65 | 2.75 | 0.022 |": MODEL_ERROR_VELOCITY,
        "| | memory 1 | 131.7 | 46.58 | 36.1 | 10.86 | 1.91 | 0.126 |": MODEL_ERROR_VELOCITY,
        "| | velocity | 107.9 | 38.16 | 11.3 | 3.41 | 1.48 | 0.219 |": MODEL_ERROR_VELOCITY,
        "| | unicycle | 2.8 | | 3.3 | | 5.62 | 0.300 |": MODEL_ERROR_VELOCITY,
        "| nominal (carpet) | pose only | 146.2 | 36.81 | 51.9 | 17.25 | 2.82 | 0.053 |": MODEL_ERROR_VELOCITY,
        "| | memory 1 | 125.4 | 31.57 | 23.1 | 7.66 | 1.36 | 0.184 |": MODEL_ERROR_VELOCITY,
        "| | velocity | 88.3 | 22.22 | 8.7 | 2.89 | 1.72 | 0.250 |": MODEL_ERROR_VELOCITY,
        "| | unicycle | 4.0 | | 3.0 | | 5.18 | 0.300 |": MODEL_ERROR_VELOCITY,
        "the closed-loop error on ice 3.6-fold": MODEL_ERROR_VELOCITY + " (61.5 / 17.3 of its table)",
        "every lift is still 3-17 times worse": MODEL_ERROR_VELOCITY
        + " (its table's gravel and carpet ratios)",
        "(0/3, time limit, 17 cm short on average)": CLOSED_LOOP_MEMORY,
        "settled 4.4 cm from the targets": CLOSED_LOOP_MEMORY,
        "with one robot 14.5 cm short": CLOSED_LOOP_MEMORY,
        "against 82 ms for the pose-only model": CLOSED_LOOP_MEMORY,
        "with stage blocks of 33 rows": CLOSED_LOOP_MEMORY,
        "cost 30-40 times the single-threaded time": CLOSED_LOOP_MEMORY,
        "a solve took 269 ms of CPU with `memory=2` and 338 ms with `velocity=True` before, 14 and 16 ms": CLOSED_LOOP_MEMORY,
        "0.35 s and 0.25 s after": CLOSED_LOOP_MEMORY,
        "(one run, 19 minutes of wall clock and 295 CPU-seconds at load 18)": BENCH_TIME,
        "(9.5 cm; circle 104.3 cm)": REFIT_PROTOTYPE,
        "The bench took 245-339 CPU-seconds and 24-32 minutes of wall clock per floor": BENCH_TIME,
        "(to the 0.1 mm kept)": MAP1_TIME + " (the records keep 0.1 mm)",
        "The rerun took 659 s of wall time": MAP1_TIME,
        "(9 episodes, one worker,": MAP1_TIME,
        "and 15 s on the kinematic plant": MAP1_TIME,
        "took 44 minutes of wall time and 635 CPU-seconds": MAP1_TIME,
        "8 minutes and 72 CPU-seconds on the kinematic plant": MAP1_TIME,
        "a first run of every controller on the suite's first 2 test layouts of both tasks on ice (76 episodes, "
        "`--calibration-budget 20000`) took 244 CPU-seconds on the physics plant and 174 on the kinematic plant: "
        "about 2.6 and 2.2 CPU-seconds per episode once the calibrations (34 s on the physics plant, about 1 s on "
        "the kinematic)": SIM2SIM_FIRST,
        "Calibrating on the physics plant took 27-30 CPU-seconds per 50,000": SIM2SIM_FIRST,
        "The kinematic run took 7,144 s of wall time": SIM2SIM_WALL,
        "and 799 s for the 80 rerun": SIM2SIM_WALL,
        "about 480 s (2,006 s of wall time)": MAP1_TIME,
        "it predicts 0.5 cm of progress per period for 0.3 m/s": MAP1_PROBE,
        "a drift of 0.2 cm per period backwards at rest": MAP1_PROBE,
        "(to 0.03 cm per period at those poses)": MAP1_PROBE,
        "5.2 cm per robot on the physics robots": RESIDUAL,
        "to 13 cm on the physics plant": RESIDUAL,
        "| the env-step without MuJoCo's step (`mj_step` a no-op) | 86, 93, 96 us | 62, 69, 71 us |": STEP_TIMES,
        "| the whole env-step | 483, 529, 594 us | 433, 486, 576 us |": STEP_TIMES,
        "| kinematic single env | 9,098, 17,065, 17,647 | 15,418, 17,297, 17,242 |": SPEED_BEFORE_AFTER,
        "| physics single env (1 thread) | 1,708, 1,871, 1,918 | 1,792, 1,701, 2,051 |": SPEED_BEFORE_AFTER,
        "| physics vector env, 16 envs, 1 thread | 2,131, 2,487, 2,626 | 2,422, 2,720, 2,365 |": SPEED_BEFORE_AFTER,
        "The 25 us saved per env-step": STEP_TIMES + " (the first row's before and after)",
        "27 constraint rows) at 18-25 us each": MUJOCO_ONE_OFF,
        "(45, 65 and 68 against 36 us per step in one run)": MUJOCO_ONE_OFF,
        "(by up to 1.7e-7 in the state after 20 s)": MUJOCO_ONE_OFF,
        "A 10 ms step would double the rate at 12-29 mm of drift against a 2.5 ms reference over 5 s of "
        "full-speed turning (5 ms: 4-10 mm)": TIMESTEP_CHECK,
        "| kinematic single env | 7,486 | 29,051 | 3,908 | 32,556 |": SPEED_LOADS,
        "| physics single env (1 thread) | 967 | 2,307 | 247 | 1,998 |": SPEED_LOADS,
        "| physics vector env, 16 envs, 1 thread | 663 | 2,209 | 286 | 2,211 |": SPEED_LOADS,
        "| physics vector env, 16 envs, 2 threads | 2,231 | 2,390 | 494 | 2,214 |": SPEED_LOADS,
        "(`py-spy record -r 200`, 15 CPU-seconds": PY_SPY,
        "76.6 % of the step's samples": PY_SPY,
        "the observation and `info`) 15 %": PY_SPY,
        "`PassiveEnvChecker`) 8 %. Cutting the Python to nothing would give at most 1.3 times": PY_SPY,
        "| kinematic single env | 40,003 | 40,008 | |": SPEED_IDLE,
        "| physics single env (1 thread) | 2,932 | 2,932 | 58,637 |": SPEED_IDLE,
        "| physics vector env, 16 envs, 1 thread | 3,051 | 3,052 | 61,028 |": SPEED_IDLE,
        "| physics vector env, 16 envs, 2 threads | 4,954 | 2,858 | 99,088 |": SPEED_IDLE,
        "on one thread (1.6 times)": SPEED_IDLE + " (4,954 / 3,051 of its table)",
        # prose that repeats a table's figure without naming its row (so no repeat), pinned
        "level 1-2 minutes with the calibrations cached": BENCH_TIME,
        "the pose-only lift's figures are within 1.3 cm of it": MODEL_ERROR_MEMORY
        + " against the 1M table's command",
        "(physics on the circle: 0.300 m/s on ice, 0.298 on carpet.)": MODEL_ERROR_MEMORY,
        "where a period's move is 97 % explained by the last second's commands": MODEL_ERROR_1M
        + " (its carpet row's 0.97)",
        "to 1.5 times the unicycle's, and the one-step": MODEL_ERROR_MEMORY + " (its carpet memory 3 row)",
        "before it explain 77 % of its move": MODEL_ERROR_1M + " (its ice row's 0.77)",
        "average 0.12 m/s while commanded 0.42 m/s": MODEL_ERROR_1M + " (its ice row's 0.117 / 0.418)",
        "where the robots average 0.12 m/s.": MODEL_ERROR_1M + " (its ice row's 0.117)",
        "(physics on the circle: 0.300 m/s on ice and gravel, 0.298 on carpet; the two ice": MODEL_ERROR_VELOCITY,
        "where the unicycle's closed-loop error is 3 cm": MODEL_ERROR_VELOCITY
        + " (its gravel and carpet unicycle rows)",
        "2.89 times the unicycle's (`hold=1`) to 2.26 and 1.94, and its circle error from 107.9 and 88.3 cm": (
            MODEL_ERROR_VELOCITY + " (hold=1) and the held-inputs table"
        ),
        "112.7 cm on the circle, 6.69 times the unicycle's, 10.2 cm over the windows": MODEL_ERROR_VELOCITY,
        "8.3 times the unicycle's on the circle and 4.8 times on closed-loop data": MODEL_ERROR_1M
        + " (its ice row's ratios 8.31 and 4.79)",
        "repeat the table above to within 0.5 cm": MODEL_ERROR_VELOCITY
        + " against the memory table's command",
        "(10.7 cm against 12.6: ratio 0.85; with three commands 10.2 cm, 0.81)": MODEL_ERROR_VELOCITY,
        "speed as 0.262 m/s": MODEL_ERROR_VELOCITY + " (its ice memory 2 + velocity row)",
        "and 6.7 times the unicycle's error on the circle": MODEL_ERROR_VELOCITY + " (its ice rows)",
        "completed 3 of 3 seeds (121, 127 and 180": CLOSED_LOOP_MEMORY,
        "22,837), 2 of 3 (seed 1 as before": CLOSED_LOOP_MEMORY,
        "a median of 3.1 s per solve in the first run and 1.7 s in the second": CLOSED_LOOP_MEMORY,
        "(wall 3.5 s and 4.6 s before": CLOSED_LOOP_MEMORY,
        "against 5.1 and 5.4 ms of CPU": CLOSED_LOOP_MEMORY,
        "3.5 s of CPU with memory or velocity, 0.8 s pose only": CLOSED_LOOP_MEMORY,
        "falls from 4.89 times the unicycle's": MODEL_ERROR_VELOCITY + " (its ice pose-only row)",
        "(within 0.3 cm on every floor)": REFIT_AGAINST,
        "from 5.3 to 6.7 cm and two to 5.7": SYNTHETIC_REFIT,
        "ended 31, 25 and 8 cm short too)": MAP1_PROBE,
        "(2,231 and 494 env-steps/s of wall clock at the two loads": SPEED_LOADS,
        "second core: 4,954 env-steps/s against 3,051": SPEED_IDLE,
    },
}

#: what reads like a result but is a setting, a definition or an input (and why)
NOT_RESULTS: dict[str, dict[str, str]] = {
    "benchmark.md": {
        "on a 5 cm grid": "the density measure's grid, a setting",
        "the 1/3 and 2/3 quantiles": "the definition of the tier cuts (suite_problems checks the cuts)",
        "as p = 1": "the convention for a comparison that could not run",
        "counted in m as p = 1": "the convention for a pending comparison",
        "the IQM of 0/1 scores": "0/1 names binary scores",
        "a 95% interval": "the intervals' level, a setting",
        "A 95% interval drawn that way": "the intervals' level, a setting",
        "At 5 episodes and rho = 0.3": "the design of the example",
        "on 60 layouts x 5 episodes, 95%": "the simulation's design and level",
        "For 200 layouts x 5 episodes": "the design the interval was timed on, an input",
    },
    "physics.md": {
        "does not divide the 0.1 s control period": "the control period, a setting",
        "a step to 0.5 m/s": "the step response test's input",
        "1.1 times it": "the test's tolerance, whose band the lag claim checks",
        "Driving straight at 0.6 m/s": "the straight run's input speed",
        "limits are |v| <= 0.6 m/s": "the paper's speed limit",
        "tops out at 0.26 m/s": "the datasheet's top speed",
        "(24.2 rad/s no-load: 0.8 m/s at the rim, room for 0.6 m/s": "the model's motor limit and the paper's speed limit",
        "the 281 x 306 mm footprint to within 4 %": "the datasheet's footprint against the model's disc",
        "accelerating at the 0.1 s lag's 6 m/s": "the motor lag's acceleration (0.6 m/s over 0.1 s)",
        "(the circle's 0.3 m/s, held for 21 s)": "the circle test's input (210 periods)",
        "(20 of 5 ms per env-step)": "the physics substeps, a setting",
        "on both plants (95% Wilson": "the intervals' level, a setting of the page",
        "where the target was at most 0.7 times": "the issue's target for the ratio, a threshold",
        "a steady 0.09 m/s^2 turn": "the circle test's centripetal acceleration (0.3 m/s x 0.3 rad/s), its input",
        "whose command changes every 0.1 s": "the control period, a setting",
        "so also 15 in at least 2 of 3: issue 62's target (every controller in at least 2 of 3)": (
            "issue 62's target, the threshold the checked count of 15 is held to"
        ),
        "MuJoCo's 20 substeps of 5 ms": "the physics substeps and timestep, settings (the Timestep claim)",
        "the model keeps 5 ms": "the physics timestep, a setting (the Timestep claim)",
        "(defaults: best of 3 windows of 2 s, 16 environments; 5 ms steps": "bench/physics_speed.py's defaults and the timestep, settings",
        "The issue's target, 2,000 env-steps/s single-threaded, is not shown": "the issue's speed target, a threshold",
        "at the issue's 2,000 env-steps/s within the spread": "the issue's speed target, a threshold",
        "The issue's target, at least 2,000 env-steps/s": "the issue's speed target, a threshold",
    },
}


# --------------------------------------------------------------------------- the two audits
AUDITS = {
    "benchmark.md": Audit(
        page="benchmark.md",
        owner="tests/test_hand_pages.py",
        claims=_benchmark_claims,
        measured=MEASURED["benchmark.md"],
        not_results=NOT_RESULTS["benchmark.md"],
    ),
    "physics.md": Audit(
        page="physics.md",
        owner="tests/test_hand_pages.py",
        claims=_physics_claims,
        measured=MEASURED["physics.md"],
        not_results=NOT_RESULTS["physics.md"],
        repeats=[
            # each sub-section's prose against its own tables
            ("## What the model learns", "### A lift with memory"),
            ("### A lift with memory", "### A lift with the velocity memory"),
            ("### A lift with the velocity memory", "### Held identification inputs"),
            ("### Held identification inputs", "### Refits on the model's own rollouts"),
            ("### Refits on the model's own rollouts", "## Map 1: every controller on the physics plant"),
            ("## Map 1: every controller on the physics plant", "## The sim-to-sim protocol"),
            ("## Speed", "## What a real TurtleBot3 has that the model does not"),
        ],
    ),
}


# --------------------------------------------------------------------------- the tests
@pytest.mark.parametrize("page", PAGES)
def test_every_result_of_the_hand_written_page_is_checked_or_pinned(page: str) -> None:
    assert page_problems(read(page), AUDITS[page]) == []


@pytest.mark.parametrize(
    ("page", "old", "new", "complaint"),
    [
        # against data/tuning/
        ("benchmark.md", "| dwa | 22 | 88/150 |", "| dwa | 22 | 89/150 |", "no longer states"),
        (
            "benchmark.md",
            "`consensus` gains 8 successes",
            "`consensus` gains 9 successes",
            "consensus's gain",
        ),
        ("benchmark.md", "`mpc-cbf` gains 15 of 50", "`mpc-cbf` gains most, 15 of 50", "called the largest"),
        ("benchmark.md", "(29 against 25 of 50)", "(29 against 24 of 50)", "dwa's study margin"),
        ("benchmark.md", "81, p = 0.46)", "81, p = 0.04)", "dwa's confirmation p"),
        ("benchmark.md", "(1,200 episodes)", "(1,250 episodes)", "the studies' budget"),
        ("benchmark.md", "trial 19 24/50", "trial 19 25/50", "adopt's line of koopman-nmpc"),
        # against data/publish.sh and the design
        ("benchmark.md", "(m = 90 and\n182,", "(m = 90 and\n156,", "every-pair families"),
        ("benchmark.md", "34 with free compute", "36 with free compute", "the per-task families"),
        ("benchmark.md", "(10.1 points)", "(9.1 points)", "the headline families"),
        ("benchmark.md", "| 10 | 48-63 | 5.3-6.9 |", "| 10 | 48-63 | 5.3-7.9 |", "states 7.9 CPU-hours"),
        ("benchmark.md", "| 10 | 48-63 | 5.3-6.9 |", "| 11 | 48-63 | 5.3-6.9 |", "the controllers of"),
        ("benchmark.md", "CPU-hours (14-18.5)", "CPU-hours (14-19.5)", "both modes' CPU-hours"),
        # against the code and the files
        ("benchmark.md", "0.4 MB in all", "0.5 MB in all", "the suite's data [MB]"),
        ("benchmark.md", "(6 at 0.05, 8 at", "(5 at 0.05, 8 at", "the fewest layouts"),
        ("benchmark.md", "input weight (0.060)", "input weight (0.070)", "koopman-nmpc's r_input"),
        ("benchmark.md", "(`cbf_gamma` 0.28)", "(`cbf_gamma` 0.29)", "mpc-cbf's cbf_gamma"),
        # a tuned value is rounded to the places its claim names, not to the page's
        ("benchmark.md", "(`cbf_gamma` 0.28)", "(`cbf_gamma` 0.3)", "mpc-cbf's cbf_gamma"),
        ("benchmark.md", "34 periods against 20", "36 periods against 20", "nominal-nmpc's horizon"),
        (
            "benchmark.md",
            "`STRICT_CLEARANCE_MARGIN` = 5 cm",
            "`STRICT_CLEARANCE_MARGIN` = 4 cm",
            "STRICT_CLEARANCE",
        ),
        # a measurement without a record, pinned
        ("benchmark.md", "took 38 CPU-seconds", "took 28 CPU-seconds", "no longer states the measurement"),
        # docs/physics.md: data/physics_map1/, data/physics_model_error/, the code, the pinned tables
        ("physics.md", "Every episode of those 9", "Every episode of those 8", "miss a seed (below, those)"),
        (
            "physics.md",
            "Five fail on the physics plant only",
            "Six fail on the physics plant only",
            "physics only",
        ),
        ("physics.md", "(7.8 cm; the defaults:", "(7.5 cm; the defaults:", "the obstacle offsets"),
        ("physics.md", "| 20 | velocity | 106.4 |", "| 20 | velocity | 106.5 |", "no longer states"),
        ("physics.md", "**Timestep**: 5 ms", "**Timestep**: 4 ms", "the timestep"),
        ("physics.md", "geared 3x faster", "geared 4x faster", "PhysicsParams.gear_factor"),
        ("physics.md", '| `"high"` | ice | 0.05-0.15 |', '| `"high"` | ice | 0.05-0.2 |', "high is stated"),
        (
            "physics.md",
            "| 2,932 | 2,932 | 58,637 |",
            "| 2,933 | 2,932 | 58,637 |",
            "no longer states the measurement",
        ),
        # docs/physics.md's sim-to-sim section: the publications' design, docs/rl.md, the estimates
        ("physics.md", "takes (20: every registered", "takes (19: every registered", "the sim-to-sim design"),
        (
            "physics.md",
            "for its 800 episodes",
            "for its 700 episodes",
            "the kinematic publication's episodes",
        ),
        ("physics.md", "for the 80 rerun", "for the 40 rerun", "the rerun's episodes"),
        ("physics.md", "389\nand 400 CPU-seconds", "389\nand 410 CPU-seconds", "the physics fine-tune's"),
        ("physics.md", "evaluator's 1,000,000", "evaluator's 2,000,000", "calibration budget"),
        (
            "physics.md",
            "about 35 CPU-minutes at 2.6",
            "about 45 CPU-minutes at 2.6",
            "the episodes' CPU-minutes",
        ),
        ("physics.md", "**about 2 CPU-hours", "**about 3 CPU-hours", "the protocol's CPU-hours"),
        ("physics.md", "about 60 CPU-minutes; each", "about 66 CPU-minutes; each", "gravel's"),
        ("physics.md", "took 7,144 s of wall", "took 7,244 s of wall", "no longer states the measurement"),
        # prose that repeats a committed table without naming its row: claims against the table
        ("physics.md", "(4-22 cm short)", "(4-23 cm short)", "adaptive-koopman-nmpc's 23 cm short"),
        (
            "physics.md",
            "(time limit, 16.6 cm short",
            "(time limit, 16.5 cm short",
            "koopman-nmpc's mean distance",
        ),
        ("physics.md", "predict 0.22-0.23 m/s where", "predict 0.22-0.24 m/s where", "circle speeds on ice"),
        ("physics.md", "memory 3 + velocity 0.89", "memory 3 + velocity 0.86", "random-hold ratio"),
        # a repeat of a table's figure
        (
            "physics.md",
            "8.3 times the unicycle's on the circle",
            "8.9 times the unicycle's on the circle",
            "'8.9 times' is checked by nothing",
        ),
    ],
)
def test_a_number_edited_by_hand_is_named(page: str, old: str, new: str, complaint: str) -> None:
    text = read(page)
    assert text.count(old) == 1, old
    problems = page_problems(text.replace(old, new), AUDITS[page])
    assert any(complaint in problem for problem in problems), problems


def test_the_tokens_are_the_result_like_numbers() -> None:
    """What the audit reads as a result (a quantity with its unit anywhere, a ratio with its "x",
    every number of a cell of numbers), and what it leaves: a map's number, a setting without a
    unit, code, link targets, the numbers of a cell of words."""
    text = (
        "Map 1 took 3.5 s and 12 CPU-seconds; 22/50 and 7 of 9 at p = 0.46 (m = 18), 9.8 points, 41%.\n"
        "It is 0.47x the rate, 7x faster, 2 x 3 robots, a 4x4 grid, `3x` and 1.5 times.\n"
        "`a 12 s code span` and [a link](page.md#run-12-s), horizon 28.\n\n"
        "| name | value | text |\n|---|---|---|\n| a | 1,234, 5.6 us | row 2 of the table, 7 cm |\n"
    )
    tokens = [text[a:b] for a, b in result_tokens(text)]
    assert tokens == [
        "3.5 s",
        "12 CPU-seconds",
        "22/50",
        "7 of 9",
        "p = 0.46",
        "m = 18",
        "9.8 points",
        "41%",
        "0.47x",
        "7x",
        "1.5 times",
        "1,234",
        "5.6",
        "5.6 us",
        "7 cm",
    ]


@pytest.mark.parametrize("page", PAGES)
def test_every_pinned_phrase_holds_a_result_and_names_why(page: str) -> None:
    assert AUDITS[page].measured
    assert pinned_problems(AUDITS[page]) == []
