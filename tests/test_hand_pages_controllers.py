"""Prose that cannot drift (issue 60) in the hand-written page docs/controllers.md, by the audit of
tests/helpers/hand_audit.py; this file holds the page's claims and lists.

Every result-like token of the page is one of:

- **checked against its source** by a claim: the controllers' option defaults and the code's
  constants (ORCA's and DWA's settings tables, the stall monitor, the adaptive and robust
  NMPCs), the tuning studies (data/tuning/, by tests/test_hand_pages.py's checks), the
  published ``data/cbf_gamma.tar.xz`` (the gamma table, rebuilt here with the evaluator's own
  paired statistics), or the generated docs/results.md (whose bytes are hashed);
- **a repeat** of a number of a table of its own section, in a row its sentence names;
- **a measurement with no committed record** (:data:`MEASURED`), pinned word for word with the
  command that measured it;
- **no result** (:data:`NOT_RESULTS`).
"""

from __future__ import annotations

import functools
import json
import re
import tarfile
from collections import defaultdict
from pathlib import Path

import pytest
from test_hand_pages import _option, _preset, _studies, _tie
from test_hand_pages_rl import cells, generated

from helpers.hand_audit import Audit, CheckFn, Claim, code_value, page_problems, pinned_problems, read, same

ROOT = Path(__file__).resolve().parents[1]
PAGE = "controllers.md"


# --------------------------------------------------------------------------- the sources
def _default(controller: str, option: str) -> object:
    import controllers

    return controllers.options(controller).option(option).default


def _defaults(*fields: tuple[str, str, float]) -> CheckFn:
    """Each group of the match is ``fields[i]`` = (controller, option, scale), exactly."""

    def check(match: re.Match[str]) -> list[str]:
        problems = []
        for stated, (name, option, scale) in zip(match.groups(), fields, strict=True):
            value = _default(name, option)
            assert isinstance(value, int | float), (name, option, value)
            problems += code_value(stated, scale * value, f"{name}'s {option} default")
        return problems

    return check


def _constant(module: str, name: str, scale: float = 1.0) -> CheckFn:
    def check(match: re.Match[str]) -> list[str]:
        import importlib

        value = getattr(importlib.import_module(module), name)
        return code_value(match[1], scale * value, f"{module}.{name}")

    return check


def _dt() -> float:
    from koopman_envs.params import PARAMS

    return PARAMS.dt


@functools.cache
def cbf_runs() -> dict[tuple[str, str], dict[tuple[str, str, int], dict]]:
    """data/cbf_gamma.tar.xz: (task, controller label) -> (map, slip, trial) -> its episode."""
    with tarfile.open(ROOT / "data" / "cbf_gamma.tar.xz") as tar:
        member = tar.extractfile("cbf_gamma/episodes.jsonl")
        assert member is not None
        lines = member.read().decode("utf-8").splitlines()
    out: dict[tuple[str, str], dict[tuple[str, str, int], dict]] = defaultdict(dict)
    for line in lines:
        record = json.loads(line)
        if "env_id" not in record:
            continue
        task = "formation" if "Formation" in record["env_id"] else "target reaching"
        out[task, record["controller"]][record["map"], record["slip"], record["trial"]] = record
    return dict(out)


def _rates(task: str, label: str) -> tuple[int, int]:
    """Success and collision-free [%] of a gamma's episodes."""
    episodes = list(cbf_runs()[task, label].values())
    n = len(episodes)
    return (
        round(100 * sum(e["success"] for e in episodes) / n),
        round(100 * sum(e["collision"] is None for e in episodes) / n),
    )


def _paired(task: str, label: str) -> object:
    from evaluation.stats.statistics import paired_comparison

    mine, reference = cbf_runs()[task, label], cbf_runs()[task, "nominal-nmpc"]
    keys = sorted(mine)
    assert keys == sorted(reference), "the gamma run is not paired with nominal-nmpc"
    return paired_comparison([mine[k]["success"] for k in keys], [reference[k]["success"] for k in keys])


def _signed(x: float) -> str:
    value = round(100 * x)
    return f"+{value}" if value >= 0 else str(value)


def _interval(task: str, label: str) -> str:
    c = _paired(task, label)
    return f"{_signed(c.difference)} [{_signed(c.low)}, {_signed(c.high)}]"  # type: ignore[attr-defined]


# --------------------------------------------------------------------------- the checks
def _gamma_row(match: re.Match[str]) -> list[str]:
    gamma = match[1]
    label = "nominal-nmpc" if gamma.startswith("distance rows") else f"mpc-cbf-gamma{gamma.split(' ')[0]}"
    stated = tuple(int(n) for n in match.groups()[1:5])
    actual = (*_rates("target reaching", label), *_rates("formation", label))
    problems = same(stated, actual, f"the gamma table's {label} rates [%] (data/cbf_gamma.tar.xz)")
    if match[6] is not None:
        problems += same(
            (match[6], match[7]),
            (_interval("target reaching", label), _interval("formation", label)),
            f"the gamma table's {label} paired differences",
        )
    if "mpc-cbf-v0" in gamma:
        problems += same(
            float(gamma.split(" ")[0]), _option("mpc-cbf-v0", "cbf_gamma"), "mpc-cbf-v0's cbf_gamma"
        )
    return problems


def _gamma_tests(match: re.Match[str]) -> list[str]:
    """ "McNemar p >= A, B after Holm": the smallest p of the gamma rows against the distance rows."""
    from evaluation.stats.statistics import holm_adjusted

    labels = [label for (task, label) in cbf_runs() if label != "nominal-nmpc" and task == "formation"]
    p = [_paired(task, label).p_value for task in ("target reaching", "formation") for label in labels]  # type: ignore[attr-defined]
    return same(
        (match[1], match[2]), (f"{min(p):.2f}", f"{min(holm_adjusted(p)):.3f}"), "the gamma rows' McNemar p"
    )


def _ipopt_map3(match: re.Match[str]) -> list[str]:
    """mpc-cbf under IPOPT (the paper protocol) on Map 3 in formation: time-outs, a follower short."""
    fm = cells("mpc-cbf", "formation")
    text = generated("results.md")
    start = text.index("(mpc-cbf), formation\n")
    block = text[start : text.index("\n## ", start)]
    rows = re.findall(
        r"^\| map3 \| (nominal|low) \| (\d+)/(\d+) \[[^|]+\| (\d+)/(\d+) \[[^|]+\| ([^|]+) \|", block, re.M
    )
    timeouts = sum(int(sr) - int(s) for _, s, _, sr, _, _ in rows)
    episodes = sum(int(n) for _, _, n, _, _, _ in rows)
    farthest = [max(float(x) for x in re.findall(r"([\d.]+)\+-", r[5])) for r in rows]
    return (
        same(
            (int(match[1]), int(match[2])),
            (timeouts, episodes),
            "mpc-cbf's time-outs on Map 3 (docs/results.md)",
        )
        + same(fm[("map3", "nominal")][0] + fm[("map3", "low")][0], 0, "mpc-cbf's Map 3 successes")
        + same(
            all(int(match[3]) <= f <= int(match[4]) for f in farthest),
            True,
            f"the farthest follower {farthest} cm",
        )
    )


def _orca_tie(match: re.Match[str]) -> list[str]:
    return _tie(match)


def _dwa_study(match: re.Match[str]) -> list[str]:
    d = _studies()["dwa"]["adoption"]
    c = _studies()["dwa"]["confirmation"]
    stated = tuple(int(n) for n in match.groups()[:6])
    actual = (
        d.best_successes,
        d.episodes,
        d.defaults_successes,
        (c["layouts"][1] - c["layouts"][0]),
        c["best_successes"],
        c["units"],
    )
    return (
        same(stated, actual, "dwa's study and confirmation (data/tuning/dwa/)")
        + same(int(match[7]), c["defaults_successes"], "dwa's confirmation defaults")
        + same(match[8], f"{c['p_value']:.2g}", "dwa's confirmation p")
        + same(c["confirmed"], False, "dwa's confirmation")
    )


def _cbf_study(match: re.Match[str]) -> list[str]:
    d = _studies()["mpc-cbf"]["adoption"]
    places = len(match[1].split(".")[1])
    return same(
        float(match[1]), round(_option("mpc-cbf", "cbf_gamma"), places), "mpc-cbf's cbf_gamma"
    ) + same(
        (int(match[2]), int(match[3]), int(match[4])),
        (d.best_successes, d.episodes, d.defaults_successes),
        "mpc-cbf's study (data/tuning/mpc-cbf/)",
    )


def _stall(match: re.Match[str]) -> list[str]:
    from controllers.mpc.detour import STALL_DISTANCE, STALL_PERIODS

    return same(
        (float(match[1]), int(match[2])),
        (100 * STALL_DISTANCE, STALL_PERIODS),
        "the stall monitor (cm, periods)",
    )


def _yield(match: re.Match[str]) -> list[str]:
    from controllers.mpc.detour import DETOUR_PERIODS, YIELD_CLEARANCE

    return same(
        (float(match[1]), float(match[2])),
        (round(DETOUR_PERIODS * _dt(), 6), YIELD_CLEARANCE),
        "a yield (s, m)",
    )


def _memory(match: re.Match[str]) -> list[str]:
    forgetting = _default("adaptive-koopman-nmpc", "forgetting")
    assert isinstance(forgetting, float)
    return same(float(match[1]), forgetting, "the forgetting factor") + same(
        float(match[2]), round(_dt() / (1 - forgetting), 6), "the forgetting's memory [s]"
    )


def _held_out(match: re.Match[str]) -> list[str]:
    """The labelled paragraph's held-out figures repeat the page's seeds 10-14 counts."""
    earlier = re.search(r"`orca` \d+/48 and (\d+/80), `dwa` \d+/48\s+and (\d+/80)", match.string)
    assert earlier
    return same((match[1], match[2]), (earlier[1], earlier[2]), "the held-out figures (seeds 10-14)")


def _crowd_horizon(match: re.Match[str]) -> list[str]:
    from koopman_envs.sim.movers import crowd

    return (
        same(float(match[1]), _default("orca", "time_horizon_obstacles"), "orca's time_horizon_obstacles")
        + same(float(match[2]), crowd.ORCA_HORIZON_OBSTACLE, "the crowd's obstacle horizon")
        + same(float(match[3]), _default("orca", "time_horizon_obstacles"), "orca's time_horizon_obstacles")
    )


def _gamma_extreme(match: re.Match[str]) -> list[str]:
    label = f"mpc-cbf-gamma{match[1]}"
    success, free = _rates("formation", label)
    success0, free0 = _rates("formation", "nominal-nmpc")
    stated = tuple(int(n) for n in match.groups()[1:])
    return same(
        stated, (free, free0, success, success0), f"{label} against the distance rows in formation [%]"
    )


def _wilson(match: re.Match[str]) -> list[str]:
    """A count's 95% Wilson interval, as the page's tables state it (the interval is checked; the
    count is not, so it stays a token of its own)."""
    from evaluation.stats.statistics import wilson_interval

    k, n = (int(x) for x in match[0].split(" ")[0].split("/"))
    low, high = int(match[1]), int(match[2])
    a, b = wilson_interval(k, n, 0.95)
    return same((low, high), (round(100 * a), round(100 * b)), f"the Wilson interval of {k}/{n} [%]")


def _fewer(match: re.Match[str]) -> list[str]:
    before, n, after, m, stated = (int(x) for x in match.groups())
    return same(
        stated, round(100 * (1 - (after / m) / (before / n))), f"{before}/{n} -> {after}/{m}: fewer [%]"
    )


def _eight_robots(match: re.Match[str]) -> list[str]:
    """ "(A% and B% fewer collisions)": consensus-free's and rl-ppo's rows of the 8-robot table."""
    start = match.string.index("**Eight robots on random maps, high slip**")
    rows = dict(
        (m[1], (int(m[2]), int(m[3])))
        for m in re.finditer(
            r"^\| ([\w-]+) \| \d+ \| (\d+)/\d+ \[[^]]*\] / (\d+)/\d+", match.string[start:], re.M
        )
    )
    actual = tuple(
        round(100 * (1 - after / before)) for before, after in (rows["consensus-free"], rows["rl-ppo"])
    )
    return same((int(match[1]), int(match[2])), actual, "the 8-robot table's fewer collisions [%]")


def _episode_costs(match: re.Match[str]) -> list[str]:
    from controllers.base import BaseController
    from controllers.mpc.variants import KoopmanNMPC, NominalNMPC

    stated = tuple(int(n) for n in match.groups())
    actual = (BaseController.episode_cost, NominalNMPC.episode_cost, KoopmanNMPC.episode_cost)
    return same(stated, actual, "the episode costs (default, nominal NMPC, Koopman-NMPC)")


def _cost_ratio(match: re.Match[str]) -> list[str]:
    """mpc-cbf's cost against nominal-nmpc's: the ratio of the two medians the page states."""
    return same(match[3], f"{float(match[1]) / float(match[2]):.2f}", "mpc-cbf's cost ratio")


def _claims() -> list[Claim]:
    options = "the controllers' option defaults (controllers.options)"
    studies = "data/tuning/*/{best,confirmation}.json and the adoption rule"
    results = "docs/results.md (data/paper.tar.xz; the page's hash)"
    cbf = "data/cbf_gamma.tar.xz (the evaluator's paired statistics)"
    return [
        Claim(
            re.compile(
                r"are the paper's: horizon (\d+), its Q/R, \+([\d.]+) m\s+toward obstacles; the plain names run their "
                r"tuned presets \(horizon (\d+) and (\d+),"
            ),
            _preset(
                ("koopman-nmpc-v0", "horizon"),
                ("koopman-nmpc-v0", "obstacle_offset"),
                ("koopman-nmpc", "horizon"),
                ("nominal-nmpc", "horizon"),
            ),
            "controllers/tuned/*.json and the -v0 presets' defaults",
        ),
        Claim(
            re.compile(r"the two NMPCs with margins widened to (\d+)x their own calibrated prediction error"),
            lambda m: [
                problem
                for name in ("koopman-nmpc-robust", "nominal-nmpc-robust")
                for problem in code_value(
                    m[1], _option(name, "uncertainty_margin"), f"{name}'s uncertainty_margin"
                )
            ],
            "the -robust presets' defaults",
        ),
        Claim(
            re.compile(
                r"gave `mpc-cbf` ([\d.]+) ms\s+median / [\d.]+ ms p95 per decision against `nominal-nmpc`'s ([\d.]+) / "
                r"[\d.]+ ms, ([\d.]+)x"
            ),
            _cost_ratio,
            "the two medians it follows (pinned)",
        ),
        Claim(
            re.compile(
                r"with k = (\d+); the `-v0` names keep the paper's margins, and the tuned\s+presets set their own k "
                r"\(([\d.]+) and ([\d.]+)\)"
            ),
            _preset(
                ("koopman-nmpc-robust", "uncertainty_margin"),
                ("koopman-nmpc", "uncertainty_margin", 1),
                ("nominal-nmpc", "uncertainty_margin", 2),
            ),
            "controllers/tuned/*.json and the -robust presets' defaults",
        ),
        Claim(
            re.compile(
                r"`gamma` \(1/s, \(0, 1/dt\], default ([\d.]+)\),\s+`margin` \(m, \[0, 1\], default ([\d.]+)\), "
                r"`lookahead` \(m, \(0, 0.5\], default ([\d.]+)\), `omega_weight` \(cost of\s+a change of omega "
                r"against one of v, \(0, 100\], default ([\d.]+)\)"
            ),
            _defaults(
                ("safe:consensus-free", "safety_gamma", 1.0),
                ("safe:consensus-free", "safety_margin", 1.0),
                ("safe:consensus-free", "safety_lookahead", 1.0),
                ("safe:consensus-free", "safety_omega_weight", 1.0),
            ),
            "the safety filter's option defaults",
        ),
        Claim(
            re.compile(r"`prior_weight=(\d+)` calibration-like"),
            _defaults(("adaptive-koopman-nmpc", "prior_weight", 1.0)),
            "the controllers' option defaults (controllers.options)",
        ),
        Claim(
            re.compile(
                r"`uncertainty_margin` \(default (\d+)\) times the RMS one-step position residual of the last\s+`residual_window=(\d+)`"
            ),
            _defaults(
                ("adaptive-koopman-nmpc", "uncertainty_margin", 1.0),
                ("adaptive-koopman-nmpc", "residual_window", 1.0),
            ),
            "the controllers' option defaults (controllers.options)",
        ),
        Claim(
            re.compile(
                r"`episode_cost`\s+\((\d+) by default; the nominal NMPC (\d+), the\s+Koopman-NMPC (\d+);"
            ),
            _episode_costs,
            "the classes' episode_cost",
        ),
        Claim(
            re.compile(r"a robot that moved less than\s+(\d+) cm in (\d+) periods"),
            _stall,
            "controllers.mpc.detour",
        ),
        Claim(
            re.compile(r"a robot that has not moved (\d+) cm in (\d+) periods"),
            _stall,
            "controllers.mpc.detour",
        ),
        Claim(
            re.compile(r"for (\d+) s its goal is a point\s+([\d.]+) m beyond"),
            _yield,
            "controllers.mpc.detour.DETOUR_PERIODS, YIELD_CLEARANCE",
        ),
        Claim(re.compile(r"`forgetting=([\d.]+)` \(~(\d+) s of\s+memory\)"), _memory, options),
        Claim(
            re.compile(
                r"`uncertainty_margin=(\d+)`, as\s+the central `-robust` NMPCs\): each robot's obstacle margin widens to (\d+) times"
            ),
            _defaults(
                ("dmpc-koopman-robust", "uncertainty_margin", 1.0),
                ("dmpc-nominal-robust", "uncertainty_margin", 1.0),
            ),
            options,
        ),
        Claim(
            re.compile(r"^\| time horizon, agents \| ([\d.]+) s \|", re.M),
            _defaults(("orca", "time_horizon", 1.0)),
            options,
        ),
        Claim(
            re.compile(
                r"^\| time horizon, obstacles \| ([\d.]+) s \| ours: ([\d.]+) s \(the crowd's\).*? with ([\d.]+) s \(see below\) \|$",
                re.M,
            ),
            _crowd_horizon,
            options + " and koopman_envs.sim.movers.crowd",
        ),
        Claim(
            re.compile(r"^\| `acc_lim_x`, `acc_lim_theta` \| ([\d.]+) m/s\^2, ([\d.]+) rad/s\^2 \|", re.M),
            _defaults(("dwa", "acc_lim_x", 1.0), ("dwa", "acc_lim_theta", 1.0)),
            options,
        ),
        Claim(
            re.compile(r"^\| `sim_time`, `sim_granularity` \| ([\d.]+) s, ([\d.]+) m \|", re.M),
            _defaults(("dwa", "sim_time", 1.0), ("dwa", "sim_granularity", 1.0)),
            options,
        ),
        Claim(
            re.compile(r"^\| `vth_samples` \| (\d+) \|", re.M),
            _defaults(("dwa", "vth_samples", 1.0)),
            options,
        ),
        Claim(
            re.compile(r"^\| `vx_samples` \| (\d+) \|", re.M), _defaults(("dwa", "vx_samples", 1.0)), options
        ),
        Claim(
            re.compile(
                r"^\| `path_distance_bias`, `goal_distance_bias`, `occdist_scale` \| ([\d.]+), ([\d.]+), ([\d.]+) \|",
                re.M,
            ),
            _defaults(
                ("dwa", "path_distance_bias", 1.0),
                ("dwa", "goal_distance_bias", 1.0),
                ("dwa", "occdist_scale", 1.0),
            ),
            options,
        ),
        Claim(
            re.compile(r"tied them \((\d+) of (\d+) successes each\)"),
            _orca_tie,
            studies,
        ),
        Claim(
            re.compile(
                r"its study's best \((\d+) of (\d+) against (\d+)\) was not confirmed on (\d+) fresh validation layouts "
                r"per\s+task \((\d+) of (\d+) against (\d+), p = ([\d.]+)\)"
            ),
            _dwa_study,
            studies,
        ),
        Claim(
            re.compile(r"\(([\d/]+), ([\d/]+)\);\s+read their protocol rows"),
            _held_out,
            "the page's seeds 10-14 counts",
        ),
        Claim(
            re.compile(
                r"`cbf_gamma` ([\d.]+) \(\[Shipped tuned defaults\][^)]*\): (\d+) of (\d+)\s+validation successes against the hand-set preset's (\d+)\)"
            ),
            _cbf_study,
            studies + " and controllers/tuned/mpc-cbf.json",
        ),
        Claim(
            re.compile(
                r"^\| (distance rows \(`nominal-nmpc`\)|[\d.]+(?: \(`mpc-cbf-v0`\))?) \| (\d+)% \((\d+)%\) \| (\d+)% \((\d+)%\) \| "
                r"(?:- \||([+-]\d+ \[[+-]?\d+, [+-]?\d+\]) / ([+-]\d+ \[[+-]?\d+, [+-]?\d+\]) \|)$",
                re.M,
            ),
            _gamma_row,
            cbf,
        ),
        Claim(re.compile(r"\(McNemar p >= ([\d.]+), ([\d.]+) after Holm\)"), _gamma_tests, cbf),
        Claim(
            re.compile(
                r"times out on Map 3 in formation\s+in (\d+) of (\d+) nominal- and low-slip episodes, a follower parked (\d+)-(\d+) cm"
            ),
            _ipopt_map3,
            results,
        ),
        Claim(
            re.compile(
                r"at ([\d.]+) the formation is collision-free in (\d+)% of episodes against (\d+)%, and succeeds in (\d+)%\s+against (\d+)%"
            ),
            _gamma_extreme,
            cbf,
        ),
        Claim(
            re.compile(r"\d+/\d+ \[(\d+)-(\d+)%\]"),
            _wilson,
            "evaluation.stats.statistics.wilson_interval",
        ),
        Claim(
            re.compile(r"(\d+)/(\d+) \[[^]]*\] / (\d+)/(\d+) \[[^]]*\] \((\d+)% fewer\)"),
            _fewer,
            "the rows' own counts",
        ),
        Claim(
            re.compile(r"without avoidance of their own \((\d+)% and (\d+)%\s+fewer collisions\)"),
            _eight_robots,
            "the 8-robot table's rows",
        ),
    ]


# --------------------------------------------------------------------------- pinned
# What measured each (the page's words pinned; an edit fails as a phrase no longer stated).
RTI_HISTORY = (
    "python evaluate.py --paper --solver rti|ipopt and 20-seed perturbed-start cells, before the stall resolution "
    "(results.md's real-time iteration section); not committed"
)
RESCUE_BOARD = "the quick leaderboard's formation cells (bash .ci/leaderboard.sh) with and without --fallback-solver ipopt, by hand"
RESCUE_ROBUSTNESS = (
    "docs/robustness_results.md's command at the 5 cm pose-noise level, run twice (with and without "
    "--fallback-solver none) on the shared machine; not committed"
)
UNSTALL = "python evaluate.py --maps map2 --episodes 10 (perturbed starts, nominal and high slip), before and after unstall"
ONLINE_UPDATE = "python bench/online_update.py on a quiet machine; output not committed"
QUICK_BOARD = "the quick board's cells (bash .ci/leaderboard.sh, paper maps, high slip, 10 seeds per cell); not committed"
FORMATION_GOAL = (
    "python evaluate.py --paper --controllers dmpc-nominal dmpc-nominal:formation_goal=target (formation), "
    "paired by hand; not committed"
)
CIRCLE = "python -m controllers.koopman accuracy (30 slip realizations) per setting, its output by hand; not committed"
CONSENSUS_SPEED = (
    "python bench/policy_speed.py (consensus), the median of docs/performance.md's RL-policy-speed table"
)
CLASSIC_CHOICE = (
    "the settings' choice runs: both classic controllers on the four paper maps, nominal and high slip, with and "
    "without uncertainty=realistic, seeds 0-2 (48 episodes) and 10-14 (80), by hand"
)
CLASSIC_BOARD = (
    "python evaluate.py --controllers orca dwa consensus --episodes 5 on 2 cores (the section's command)"
)
CLASSIC_SPEED = (
    "python bench/policy_speed.py --robots 3 16 --seeds 2 --controllers orca dwa consensus (2026-11-27; "
    "the section's command), and the same bench before the compiled kernels"
)
SLALOM = "tests/test_mpc_cbf.py's slalom, seeds 0-5 at high and nominal slip, its values printed by hand (the test pins seed 0)"
CBF_COST = "python bench/policy_speed.py --controllers orca dwa consensus nominal-nmpc mpc-cbf (the section's command)"
FILTER = (
    "python bench/safety_filter.py (5 trials per cell) and python bench/safety_filter.py --episodes 10 "
    "--controllers consensus-free rl-ppo --skip-timing (the section's commands); not committed"
)
FILTER_EIGHT = (
    "python evaluate.py --env KoopNav-TargetReaching-v0 --maps random --slips high --episodes 20|12 --env-kwargs "
    "n_robots=8 ... (the section's commands); not committed"
)

MEASURED: dict[str, str] = {
    "(0/10 against 10/10 at nominal slip for both NMPCs; 0/20 against 9/20 for Koopman-NMPC": RTI_HISTORY,
    "(high slip, 20 episodes) the rescue is worth a few episodes: Koopman-NMPC 25% with it against 15% without, "
    "the distributed Koopman-NMPC 50% against 35%": RESCUE_BOARD,
    "at 0.3-2 s per rescue": RESCUE_BOARD,
    "Koopman-NMPC 24% without it against 15% with it (+9 pp [-3, +21], McNemar p = 0.21, 80 episodes), nominal NMPC "
    "18% against 13% (+5 [-7, +17], p = 0.52), adaptive Koopman-NMPC 55% against 33% (+22 [+5, +36], p = 0.02, the "
    "51 episodes the first run finished), the distributed NMPCs equal (40 episodes each)": RESCUE_ROBUSTNESS,
    "at 0.3-2 s a call: the mean wall time per step was 47-125 ms with it and 3-8 ms without": RESCUE_ROBUSTNESS,
    "in 10 of 10 perturbed-start episodes of each NMPC": UNSTALL,
    "Koopman-NMPC reaches 4 of 10 with the real-time iteration and 4 of 10 with IPOPT": UNSTALL,
    "(0.25 ms for 3 robots on a quiet machine, against 6 ms for a batch refit": ONLINE_UPDATE,
    "`dmpc-koopman-robust` succeeds in 100% of the target-reaching and 95% of the": QUICK_BOARD,
    "(41/60 vs 40/60, McNemar p = 1.0)": FORMATION_GOAL,
    "| nominal, minimal | 2.01, 2.00, 2.02 | same | 0.022, 0.022, 0.022 | RMSE 2.12, 2.10, 2.08 |": CIRCLE,
    "| high, minimal | 2.02, 3.00, 8.89 | 2.02, 6.31+-2.75, 12.08+-4.61 | 0.022, 0.075, 0.168 | RMSE 2.12, 10.10, "
    "24.27; Hausdorff 0.022, 0.068, 0.234 |": CIRCLE,
    "| high, extended | 2.03, 2.94, 8.85 | 2.03, 6.34+-2.76, 12.10+-4.63 | 0.022, 0.074, 0.168 | |": CIRCLE,
    "0.2 ms per step (median": CONSENSUS_SPEED,
    "18 of 48 episodes reached their targets against 47 of 48": CLASSIC_CHOICE,
    "22 of 48 episodes against 45 of 48": CLASSIC_CHOICE,
    "41 of 48 episodes (contacts under slip, stalls in gaps the plan squeezed through) against 45 of 48": CLASSIC_CHOICE,
    "seeds 0-2 (48 episodes), and then on seeds 10-14 (80 episodes, not used for the choice): `orca` 47/48 and "
    "72/80, `dwa` 45/48 and 73/80 (`consensus`: 14/48)": CLASSIC_CHOICE,
    "The default board, 5 episodes per cell (high slip, perturbed starts; 10 episodes per controller and task)": (
        CLASSIC_BOARD + " (its design)"
    ),
    "cores (30 s;": CLASSIC_BOARD,
    "| formation | `dwa` | 90% [60-100] | 4.8 cm | 7.9 ms |": CLASSIC_BOARD,
    "| formation | `orca` | 80% [40-100] | 0.7 cm | 0.1 ms |": CLASSIC_BOARD,
    "| formation | `consensus` | 60% [30-90] | 5.3 cm | 0.1 ms |": CLASSIC_BOARD,
    "| target reaching | `orca` | 90% [60-100] | 0.5 cm | 0.1 ms |": CLASSIC_BOARD,
    "| target reaching | `dwa` | 90% [60-100] | 4.8 cm | 8.8 ms |": CLASSIC_BOARD,
    "| target reaching | `consensus` | 40% [17-69] | 2.3 cm | 0.1 ms |": CLASSIC_BOARD,
    "`orca` 0.12 / 0.16 ms at 3 robots and 0.21 / 0.25 ms at 16; `dwa` 0.98 / 1.31 ms and 4.5 / 5.7 ms; "
    "`consensus` 0.08 / 0.10 and 0.14 / 0.17 ms": CLASSIC_SPEED,
    "`dwa` 1.28 / 5.5 ms and 8.6 / 20.6 ms": CLASSIC_SPEED,
    "the numpy took 2.0 ms at 3 robots and 17.0 ms at 16 in the same bench before the first three kernels, 5 ms "
    "per three-robot decision on Map 3": CLASSIC_SPEED,
    "crossed the margin in 6/6 episodes and collided in 5; gamma 0.2 collided in 4/6; gamma 0.1 reached the target "
    "in 6/6": SLALOM,
    "gamma 0.2 keeps 2.0 cm and gamma 0.1 2.8 cm": SLALOM,
    "it is 4-8x faster per step": RTI_HISTORY,
    "gave `mpc-cbf` 2.0 ms median / 2.4 ms p95 per decision against `nominal-nmpc`'s 1.7 / 2.0 ms": CBF_COST,
    "the filter alone takes 0.050 ms median, 0.11 ms p95 per step for 3 robots and 0.067 / 0.11 ms for 16": FILTER,
    "single outliers up to 8 ms": FILTER,
    "| consensus-free | 10 | 40/40 [91-100%] / 2/40 [1-17%] (95% fewer) | 0/40 / 8/40 |": FILTER,
    "| rl-ppo | 10 | 10/40 [14-40%] / 0/40 [0-9%] | 30/40 / 36/40 |": FILTER,
    "| nominal-nmpc | 5 | 7/20 [18-57%] / 0/20 [0-16%] | 9/20 / 12/20 |": FILTER,
    "succeeds in only 12 of 40 episodes": FILTER,
    "succeeded in 16 of 20 episodes (5 per cell), and 12 of 20 with the filter on top": FILTER,
    "| consensus-free | 20 | 20/20 [84-100%] / 2/20 [3-30%] (90% fewer) | 0/20 [0-16%] / 2/20 [3-30%] |": FILTER_EIGHT,
    "| rl-ppo | 20 | 18/20 [70-97%] / 0/20 [0-16%] | 1/20 [1-24%] / 4/20 [8-42%] |": FILTER_EIGHT,
    "| nominal-nmpc | 12 | 6/12 [25-75%] / 2/12 [5-45%] (67% fewer) | 4/12 [14-61%] / 5/12 [19-68%] |": FILTER_EIGHT,
    "five of the 12 episodes run the full 60 s without arriving": FILTER_EIGHT,
    "takes about 1 s per step": FILTER_EIGHT,
}

#: what reads like a result but is a setting, a definition or an input (and why)
NOT_RESULTS: dict[str, str] = {
    "robustness sweep's 5 cm pose-noise level": "the sweep's level, a setting",
    "start noise 5 cm, seeds 0-2": "the choice runs' start noise, a setting",
    "start noise 5 cm, seeds 0-5": "the slalom test's start noise, a setting",
    "| success [95% CI] |": "the intervals' level, a table header",
    "95% Wilson intervals": "the intervals' level, a setting",
    "(at least 90% fewer collisions)": "the issue's target, not a result",
    "(1 ms at 3, 5 ms at 16)": "issue 45's targets, not results",
    "(target: within\n1.5x)": "the issue's target for mpc-cbf's cost, not a result",
}

AUDIT = Audit(
    page=PAGE,
    owner="tests/test_hand_pages_controllers.py",
    claims=_claims,
    measured=MEASURED,
    not_results=NOT_RESULTS,
    repeats=[
        ("## MPC with control barrier constraints (`mpc-cbf`)", "## Safety filter"),
        ("## Safety filter", "## RL baseline"),
    ],
)


# --------------------------------------------------------------------------- the tests
def test_every_result_of_controllers_md_is_checked_or_pinned() -> None:
    assert page_problems(read(PAGE), AUDIT) == []


@pytest.mark.parametrize(
    ("old", "new", "complaint"),
    [
        # the option defaults and the code's constants
        (
            "| time horizon, obstacles | 4 s |",
            "| time horizon, obstacles | 3 s |",
            "orca's time_horizon_obstacles",
        ),
        ("| `vx_samples` | 7 |", "| `vx_samples` | 5 |", "dwa's vx_samples"),
        ("| 1.7 s, 0.025 m |", "| 1.5 s, 0.025 m |", "dwa's sim_time"),
        ("ours: 1 s (the crowd's)", "ours: 2 s (the crowd's)", "the crowd's obstacle horizon"),
        ("2 cm in 10 periods while", "3 cm in 10 periods while", "the stall monitor"),
        ("for 3 s its goal is a point", "for 4 s its goal is a point", "a yield"),
        ("`forgetting=0.98` (~5 s of", "`forgetting=0.98` (~10 s of", "the forgetting's memory"),
        ("tuned presets (horizon 28 and 34,", "tuned presets (horizon 30 and 34,", "koopman-nmpc's horizon"),
        (
            "set their own k (3.9 and 2.56)",
            "set their own k (3.9 and 2.66)",
            "nominal-nmpc's uncertainty_margin",
        ),
        ("`margin` (m, [0, 1], default 0.02)", "`margin` (m, [0, 1], default 0.03)", "safety_margin default"),
        (
            "the nominal NMPC 1, the\nKoopman-NMPC 2;",
            "the nominal NMPC 1, the\nKoopman-NMPC 3;",
            "the episode costs",
        ),
        # the tuning studies
        ("(22 of 50 successes each)", "(23 of 50 successes each)", "orca's tie"),
        ("(88 of 150 against 81, p = 0.46)", "(88 of 150 against 81, p = 0.04)", "dwa's confirmation p"),
        (
            "validation successes against the hand-set preset's 7",
            "validation successes against the hand-set preset's 9",
            "mpc-cbf's study",
        ),
        # data/cbf_gamma.tar.xz and docs/results.md
        ("| 0.2 | 87% (87%) |", "| 0.2 | 88% (87%) |", "mpc-cbf-gamma0.2 rates"),
        ("+5 [-6, +16] / -17 [-33, +2]", "+5 [-6, +16] / -17 [-30, +2]", "paired differences"),
        ("(McNemar p >= 0.11, 1.000 after Holm)", "(McNemar p >= 0.21, 1.000 after Holm)", "McNemar p"),
        (
            "collision-free in 88% of episodes against 72%",
            "collision-free in 88% of episodes against 70%",
            "distance rows in formation",
        ),
        (
            "in 20 of 20 nominal- and low-slip episodes",
            "in 18 of 20 nominal- and low-slip episodes",
            "time-outs on Map 3",
        ),
        # the tables' own arithmetic
        ("2/12 [5-45%]", "2/12 [5-48%]", "Wilson interval of 2/12"),
        ("(67% fewer)", "(60% fewer)", "fewer"),
        ("(90% and 100%\nfewer collisions)", "(90% and 95%\nfewer collisions)", "8-robot table's fewer"),
        # a pinned measurement
        (
            "| target reaching | `dwa` | 90% [60-100] | 4.8 cm | 8.8 ms |",
            "| target reaching | `dwa` | 90% [60-100] | 4.8 cm | 9.8 ms |",
            "no longer states",
        ),
        # a default stated rounded (0.03 for 0.025): the code's value is checked exactly
        ("| 1.7 s, 0.025 m |", "| 1.7 s, 0.03 m |", "dwa's sim_granularity default"),
        # a ratio (a token since the shared audit reads ratios)
        ("1.18x (target", "1.28x (target", "mpc-cbf's cost ratio"),
        ("margins widened to 3x", "margins widened to 4x", "koopman-nmpc-robust's uncertainty_margin"),
    ],
)
def test_a_number_of_controllers_md_edited_by_hand_is_named(old: str, new: str, complaint: str) -> None:
    text = read(PAGE)
    assert text.count(old) == 1, old
    problems = page_problems(text.replace(old, new), AUDIT)
    assert any(complaint in problem for problem in problems), problems


def test_every_pinned_phrase_of_controllers_md_holds_a_result_and_names_why() -> None:
    assert AUDIT.measured
    assert pinned_problems(AUDIT) == []
