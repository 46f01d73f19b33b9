"""What the sim-to-sim page (docs/sim2sim_results.md, issue 62) computes from the protocol's two
runs: per friction level, what is complete on both plants (a run may be published while it runs:
the rest is pending), and the complete controllers' paired statistics
(:mod:`evaluation.stats.transfer`). docs/make_sim2sim_md.py writes the page from it. Nothing here
runs an episode or formats a page.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from evaluation.experiments.sweep import load_sweep
from evaluation.reports.results import Results
from evaluation.stats.statistics import PairedComparison, paired_comparison
from evaluation.stats.transfer import (
    Ordering,
    PlantRow,
    Progress,
    RankAgreement,
    check_same_protocol,
    orderings,
    plant_differences,
    rank_agreement,
    restricted,
    run_progress,
)

__all__ = [
    "FINE_TUNED",
    "PLANTS",
    "Level",
    "against_source",
    "level_data",
    "shortfall",
    "slip_levels",
    "transfers",
]

#: the controllers trained on the physics plant, each with the kinematic controller it was
#: fine-tuned from: rows of their own (their kinematic column is the reverse direction), left out
#: of the verdicts that transfer (tests/test_sim2sim.py holds this to the shipped metadata). The
#: source is named by the label the published rows carry: they were run before rl-ppo-set shipped
#: its training seeds, so that label's policy is the one now named rl-ppo-set-v0, the policy
#: rl-ppo-set-physics was fine-tuned from (docs/rl.md)
FINE_TUNED = {"rl-ppo-set-physics": "rl-ppo-set"}

#: the two plants, in the order of the command line, as the page names them
PLANTS = ("kinematic", "physics")


@dataclass(frozen=True)
class Level:
    """One friction level of the two runs: what is complete on both plants, and its statistics.

    ``pending`` maps each controller left out to why (its episodes on each plant that is short);
    ``kinematic`` and ``physics`` hold the complete controllers' records only (None: none is
    complete). ``rows``, ``found`` and ``agreement`` are computed on those alone: ``found`` and the
    Holm adjustment of ``rows`` on the :attr:`transferred` controllers only (a :data:`FINE_TUNED`
    row is adjusted on its own)."""

    level: Any
    declared: int
    pending: dict[str, str]
    kinematic: Results | None
    physics: Results | None
    rows: list[PlantRow]
    found: list[Ordering]
    agreement: RankAgreement | None

    @property
    def transferred(self) -> list[PlantRow]:
        """The rows of the controllers tuned or trained on the kinematic plant (no :data:`FINE_TUNED`)."""
        return [row for row in self.rows if row.controller not in FINE_TUNED]


def shortfall(progress: dict[str, dict[str, Progress]], controller: str) -> str | None:
    """Why ``controller`` is pending (``N of M episodes on the physics plant``), None when it is
    complete on both plants."""
    short = [
        f"{p[controller].done:,} of {p[controller].planned:,} episodes on the {plant} plant"
        for plant, p in progress.items()
        if not p[controller].complete
    ]
    return "; ".join(short) or None


def level_data(level: Any, kinematic: Results | None, physics: Results | None) -> Level:
    """A level's :class:`Level` from its two runs (None: the level has no log yet on that plant)."""
    if kinematic is None or physics is None:
        known = kinematic if kinematic is not None else physics
        declared = known.config["controllers"] if known is not None else []
        missing = " and ".join(plant for plant, run in zip(PLANTS, (kinematic, physics)) if run is None)
        return Level(
            level,
            len(declared),
            {c: f"not started on the {missing} plant" for c in declared},
            None,
            None,
            [],
            [],
            None,
        )
    check_same_protocol(kinematic.config, physics.config)
    progress = {plant: run_progress(run) for plant, run in zip(PLANTS, (kinematic, physics))}
    pending = {}
    for controller in kinematic.config["controllers"]:
        why = shortfall(progress, controller)
        if why is not None:
            pending[controller] = why
    complete = [c for c in kinematic.config["controllers"] if c not in pending]
    if not complete:
        return Level(level, len(kinematic.config["controllers"]), pending, None, None, [], [], None)
    before, after = restricted(kinematic, complete), restricted(physics, complete)
    assert isinstance(before, Results) and isinstance(after, Results)
    ranked = [c for c in complete if c not in FINE_TUNED]
    # the tests of transfer are the transferred controllers' alone, each family Holm-adjusted
    # over them (the page counts and tables those): a fine-tuned row is no transfer, so it is
    # neither in the plant differences' family nor in the pairwise one; its own row is compared
    # on its own (its kinematic column, and its source on the physics plant)
    moved = (restricted(before, ranked), restricted(after, ranked)) if ranked else None
    rows = plant_differences(*moved) if moved else []
    tuned = [c for c in complete if c in FINE_TUNED]
    if tuned:
        rows += plant_differences(restricted(before, tuned), restricted(after, tuned))
    rows.sort(key=lambda row: complete.index(row.controller))
    return Level(
        level,
        len(kinematic.config["controllers"]),
        pending,
        before,
        after,
        rows,
        orderings(*moved) if moved else [],
        rank_agreement(before, after, ranked) if len(ranked) >= 2 else None,
    )


def transfers(found: list[Ordering]) -> list[Ordering]:
    """The orderings of controllers tuned or trained on the kinematic plant (no :data:`FINE_TUNED`)."""
    return [o for o in found if o.a not in FINE_TUNED and o.b not in FINE_TUNED]


def against_source(records: list[dict[str, Any]], name: str) -> PairedComparison | None:
    """``name`` against the controller it was fine-tuned from on one run's episodes (both tasks),
    paired on the (task, layout, map, seed) units both ran; None when they share none."""
    outcomes: dict[str, dict[tuple, bool]] = {name: {}, FINE_TUNED[name]: {}}
    for r in records:
        if r.get("controller") in outcomes and r.get("status", "ok") == "ok":
            unit = (r["env_id"], r.get("layout"), r["map"], r["seed"])
            outcomes[r["controller"]][unit] = bool(r["success"])
    shared = sorted(set(outcomes[name]) & set(outcomes[FINE_TUNED[name]]), key=repr)
    if not shared:
        return None
    return paired_comparison(
        [outcomes[name][u] for u in shared], [outcomes[FINE_TUNED[name]][u] for u in shared]
    )


def slip_levels(path: str) -> tuple[dict[Any, Results], list[Any], dict[str, Any]]:
    """A sim-to-sim run's friction levels with a log, every level its manifest sweeps, and the
    manifest."""
    done, _, manifest = load_sweep(path)
    if "slip" not in done:
        raise ValueError(f"the run in {path!r} is not swept over the friction level (--sweep slip=...)")
    [axis] = [entry for entry in manifest["axes"] if entry["key"] == "slip"]
    return dict(done["slip"]), list(axis["levels"]), manifest
