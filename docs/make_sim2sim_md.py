"""Write docs/sim2sim_results.md from the sim-to-sim protocol's two runs (issue 62).

Usage::

    python docs/make_sim2sim_md.py KINEMATIC PHYSICS --out PAGE.md [--intro FILE] [--title TEXT]

KINEMATIC and PHYSICS are the same protocol run on the two plants, each swept over the friction
level (``python evaluate.py ... --sweep slip=nominal,high``, carpet and ice, and the same with
``--plant mujoco``; ``data/publish.sh`` runs ``sim2sim_kinematic`` and ``sim2sim_physics``): sweep
directories or their publications (``data/NAME/``, ``data/NAME.tar.xz``). Their settings must
differ by the plant only, else the page is refused naming what differs.

Per friction level the page has one paired table: each controller's success on both plants with
its Wilson interval, the paired difference (physics - kinematic) with Newcombe's interval, the
exact McNemar p and its Holm adjustment over the level's controllers
(:mod:`evaluation.stats.transfer`); then which controller orderings transfer: a pair of
controllers of one task is a verdict on a plant when the run's own paired table (Holm over its
pairs) says one succeeds more often than the other, and the page says which verdicts of the
kinematic plant hold on the physics plant, which are lost or reversed, and which appear there
only. At this sample size the pairwise rule is mostly silent, so each level also says whether
the ranking transfers: Kendall's tau-b between the controllers' success rates on the two plants,
with a seeded bootstrap interval over (task, layout) clusters, and which controllers' own success
changes significantly (:func:`evaluation.stats.transfer.rank_agreement`,
:func:`~evaluation.stats.transfer.significant_changes`). The ``--intro`` file is a template as
for the other pages (``docs/make_prose_md.py``), its runs named by their files
(``sim2sim_physics@slip=high``).

A run may be partial (published as it runs): a (level, controller) whose episodes are not all in
both publications (the count each run's header plans: layouts x tasks x episodes) is named as
pending, with how many it has on which plant, and left out of every table and test until it is
complete; a level with nothing complete on both plants says so. The summary of every level (which
verdicts transfer) is the block :data:`SUMMARY`, which ``python docs/make_pages.py`` copies into
README.md (``"readme"`` in ``data/pages.json``); tests/test_prose_checks.py checks README's copy
against the page.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.experiments.sim2sim import (  # noqa: E402
    FINE_TUNED,
    Level,
    against_source,
    level_data,
    slip_levels,
    transfers,
)
from evaluation.reports.results import Results  # noqa: E402
from evaluation.stats.designs import table_power  # noqa: E402
from evaluation.stats.transfer import (  # noqa: E402
    RANK_RESAMPLES,
    RANK_SEED,
    TRANSFER_ALPHA,
    Ordering,
    PlantRow,
    significant_changes,
)
from koopman_envs import task_for_env  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402
from koopman_envs.params import SLIP_SURFACES  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one
from make_prose_md import expand_template  # noqa: E402

INTRO = """The sim-to-sim protocol (issue 62; [The physics plant](physics.md)): the same controllers,
tuned or trained on the kinematic plant, run on the kinematic plant and on the MuJoCo robots
(`--plant mujoco`), on the same layouts, starts and seeds, at every friction level
(`--sweep slip=...`). Each pair of episodes differs by the plant only."""

#: the name of the block README.md copies from the page (docs/make_pages.py, ``"readme"``)
SUMMARY = "sim2sim-transfer"
#: what a verdict became on the physics plant, in the page's words
_FATES = {
    "holds": "hold on the physics plant",
    "lost": "are no longer significant there",
    "reversed": "reverse",
}


def _percent(rate: float) -> str:
    return f"{100 * rate:.0f}%"


def _interval(low: float, high: float) -> str:
    return f"[{100 * low:.0f}, {100 * high:.0f}]"


def _points(value: float) -> str:
    return f"{100 * value:+.0f}"


def _signed_interval(low: float, high: float) -> str:
    return f"[{_points(low)}, {_points(high)}]"


def _p(value: float) -> str:
    return "-" if value != value else f"{value:.3f}" if value >= 0.001 else "<0.001"


def level_title(level: Any) -> str:
    """A friction level's heading: the physics floor and the setting's name."""
    surface = SLIP_SURFACES.get(str(level), str(level))
    return f"{surface.capitalize()} (`slip={level}`)"


def plant_table(rows: list[PlantRow]) -> str:
    """The paired table of one friction level, as Markdown."""
    lines = [
        "| controller | pairs | kinematic | physics | physics - kinematic [points] | p | p (Holm) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(
            f"| {row.controller} | {row.pairs} | {_percent(row.first)} {_interval(*row.first_interval)} | "
            f"{_percent(row.second)} {_interval(*row.second_interval)} | {_points(row.difference)} "
            f"{_signed_interval(row.low, row.high)} | {_p(row.p_value)} | {_p(row.p_holm)} |"
        )
    return "\n".join(lines)


#: what one pair of the page's tables is
PLANT_UNIT = "one episode unit (task, layout, seed) on both plants"


def plant_power(rows: list[PlantRow]) -> str:
    """The power statement below :func:`plant_table` (:func:`evaluation.stats.designs.table_power`):
    the level's family, the pairs per controller and their pooled discordance."""
    return table_power(
        [row.pairs for row in rows], [row.discordant for row in rows], rows[0].family_size, PLANT_UNIT
    ).sentence()


def _named(ordering: Ordering, sign: int) -> str:
    """``a > b (task)`` with the winner first."""
    winner, loser = (ordering.a, ordering.b) if sign > 0 else (ordering.b, ordering.a)
    task = task_for_env(ordering.env_id).name.replace("_", " ")
    return f"`{winner}` > `{loser}` ({task})"


def _listed(items: list[str]) -> str:
    return ", ".join(items)


def transfer_sentence(found: list[Ordering]) -> str:
    """What became of the kinematic plant's verdicts on the physics plant, from ``found``."""
    by_fate: dict[str, list[Ordering]] = {}
    for ordering in found:
        by_fate.setdefault(ordering.verdict, []).append(ordering)
    verdicts = sum(len(by_fate.get(fate, [])) for fate in _FATES)
    if verdicts == 0:
        text = f"No ordering of two controllers is significant on the kinematic plant (of {len(found)} pairs)"
    else:
        parts = [
            f"{len(by_fate[fate])} {words}: "
            + _listed([_named(o, o.first) for o in by_fate[fate]])
            + (
                f" (now {_listed([_named(o, o.second) for o in by_fate[fate]])})"
                if fate == "reversed"
                else ""
            )
            for fate, words in _FATES.items()
            if by_fate.get(fate)
        ]
        text = (
            f"Of the {verdicts} orderings significant on the kinematic plant (of {len(found)} pairs), "
            + "; ".join(parts)
        )
    new = by_fate.get("new", [])
    if new:
        text += f"; {len(new)} appear on the physics plant only: " + _listed(
            [_named(o, o.second) for o in new]
        )
    return text + "."


def _tau(value: float) -> str:
    return "undefined" if math.isnan(value) else f"{value:.2f}"


def pending_sentence(pending: dict[str, str], declared: int) -> str:
    """The controllers left out of a level, grouped by how far they are (``declared``: how many
    the level has; when every one is pending alike they are counted, not named)."""
    by_reason: dict[str, list[str]] = {}
    for controller, why in pending.items():
        by_reason.setdefault(why, []).append(f"`{controller}`")
    return "; ".join(
        f"every controller ({declared}) is pending: {why}"
        if len(names) == declared
        else f"{_listed(names)} (pending: {why})"
        for why, names in by_reason.items()
    )


def agreement_sentence(level: Level) -> str:
    """The rank agreement of a level with its interval, in words."""
    found = level.agreement
    if found is None:
        return "Fewer than two controllers are complete: no ranking to compare."
    assert level.kinematic is not None
    if math.isnan(found.tau):  # every controller's success ties on a plant: no order to compare
        return (
            f"The ranking of the {found.controllers} controllers cannot be compared between the plants: "
            "on one of them every controller succeeds equally often, so Kendall's tau-b is undefined."
        )
    clusters = "(task, layout)" if level.kinematic.config.get("suite") else "(task, map, seed)"
    resamples = f"{RANK_RESAMPLES:,} resamples"
    if found.resamples < RANK_RESAMPLES:  # a resample whose rates all tie on a plant has no tau
        resamples = f"the {found.resamples:,} of {RANK_RESAMPLES:,} resamples with a tau"
    return (
        f"The ranking of the {found.controllers} controllers by success agrees between the plants with "
        f"Kendall's tau-b = {_tau(found.tau)} (95% interval [{_tau(found.low)}, {_tau(found.high)}], "
        f"a percentile bootstrap of {resamples} of the "
        f"{found.clusters} {clusters} clusters, seed {RANK_SEED}; 1 is the same order, 0 none, "
        "-1 reversed)."
    )


def changes_sentence(level: Level) -> str:
    """The controllers whose own success differs significantly between the plants, with direction."""
    changed = [row for row in significant_changes(level.rows) if row.controller not in FINE_TUNED]
    family = f"Holm over the level's {len(level.transferred)} controllers, p below {TRANSFER_ALPHA}"
    if not changed:
        return f"No controller's own success differs significantly between the plants ({family})."
    named = [
        f"`{row.controller}` {'gains' if row.difference > 0 else 'loses'} {abs(100 * row.difference):.0f} "
        f"points {_signed_interval(row.low, row.high)}"
        for row in changed
    ]
    return f"On the physics plant {_listed(named)} ({family}); every other controller's difference is not significant."


#: what a level with fewer than two complete controllers of one task says of the pairwise verdicts
_NO_PAIR = "no pair of controllers of one task is complete on both plants, so no pairwise verdict is tested"


def pairwise_sentence(level: Level) -> str:
    """The count of the kinematic plant's pairwise verdicts that hold on the physics plant."""
    kept = transfers(level.found)
    verdicts = [o for o in kept if o.first != 0]
    new = sum(o.verdict == "new" for o in kept)
    if not kept:
        return _NO_PAIR
    if not verdicts:
        text = (
            f"no ordering of two controllers of one task is significant on the kinematic plant (of {len(kept)} "
            "pairs, Holm over the pairs), so no pairwise verdict is there to transfer"
        )
    else:
        held = sum(o.verdict == "holds" for o in verdicts)
        text = f"{held} of the {len(verdicts)} orderings significant on the kinematic plant (of {len(kept)} pairs) hold"
    return text + (f"; {new} appear on the physics plant only" if new else "")


def level_summary(level: Level) -> str:
    """A level's item of the summary block."""
    head = f"- **{level_title(level.level)}**"
    if level.kinematic is None:
        return (
            f"{head}: no controller is complete on both plants yet, nothing is tested: "
            f"{pending_sentence(level.pending, level.declared)}."
        )
    pairs = {row.pairs for row in level.transferred}
    each = f"{pairs.pop()} paired episodes each" if len(pairs) == 1 else "paired episodes as tabled"
    text = (
        f"{head} ({len(level.transferred)} controllers, {each}): {pairwise_sentence(level)}. "
        f"{agreement_sentence(level)} {changes_sentence(level)}"
    )
    if level.pending:
        text += f" Left out until complete: {pending_sentence(level.pending, level.declared)}."
    return text


def summary_block(levels: list[Level]) -> str:
    """The summary every level gives, between the lines README.md copies (:data:`SUMMARY`)."""
    lines = [
        f"<!-- begin {SUMMARY}: written by `python docs/make_pages.py docs/sim2sim_results.md` from the "
        "committed data (docs/make_sim2sim_md.py); an edit by hand fails the tests -->",
        "**Which verdicts transfer** from the kinematic plant to the physics plant (MuJoCo), per friction "
        "level: the pairwise verdicts of the kinematic plant that hold on the physics plant, the rank "
        "agreement of the controllers' success between the plants, and the controllers whose success "
        "changes significantly.",
        "",
        *(level_summary(level) for level in levels),
        f"<!-- end {SUMMARY} -->",
    ]
    return "\n".join(lines)


def fine_tuned_table(rows: list[PlantRow], physics: Results) -> str:
    """The :data:`FINE_TUNED` rows of one friction level: each against its source on the physics
    plant (paired, McNemar), and its success on both plants."""
    lines = [
        "| controller | fine-tuned from | pairs | physics | its source on physics | difference [points] | p "
        "| kinematic |",
        "|---|---|---|---|---|---|---|---|",
    ]
    tests = []
    for row in rows:
        test = against_source(physics.records, row.controller)
        if test is None:
            continue
        tests.append(test)
        lines.append(
            f"| {row.controller} | {FINE_TUNED[row.controller]} | {test.n} | {_percent(test.rate_a)} | "
            f"{_percent(test.rate_b)} | {_points(test.difference)} {_signed_interval(test.low, test.high)} | "
            f"{_p(test.p_value)} | {_percent(row.first)} {_interval(*row.first_interval)} |"
        )
    if not tests:
        return "\n".join(lines)
    # each fine-tuned row is its own test (no Holm): a family of one per row, as the table reports it
    power = table_power([t.n for t in tests], [t.only_a + t.only_b for t in tests], 1, PLANT_UNIT)
    return "\n".join(lines) + "\n\n" + power.sentence()


def level_section(level: Level) -> str:
    """One friction level's part of the page."""
    parts = [f"## {level_title(level.level)}"]
    if level.kinematic is None or level.physics is None:
        parts.append(
            "No controller is complete on both plants yet, so this level has no table and no test: "
            f"{pending_sentence(level.pending, level.declared)}."
        )
        return "\n\n".join(parts)
    tuned = [row for row in level.rows if row.controller in FINE_TUNED]
    parts += [
        plant_table(level.transferred),
        f"Holm's adjustment over the level's {len(level.transferred)} tests. {changes_sentence(level)}",
        *([plant_power(level.transferred)] if level.transferred else []),
    ]
    if level.pending:
        parts.append(
            "**Pending**, left out of every table and test of this level until complete: "
            f"{pending_sentence(level.pending, level.declared)}."
        )
    parts += [
        f"**Does the ranking transfer?** {agreement_sentence(level)}",
        "**Which verdicts transfer**: "
        + (
            transfer_sentence(transfers(level.found))
            if transfers(level.found)
            else _NO_PAIR.capitalize() + "."
        ),
    ]
    if tuned:
        parts += [
            "**Fine-tuned on the physics plant** (a separate row, not a transfer: trained on the "
            "physics plant's train layouts, so its kinematic column is the reverse direction): against "
            "the policy it was fine-tuned from, paired on the physics plant's episodes (Newcombe's 95% "
            "interval, exact McNemar p).",
            fine_tuned_table(tuned, level.physics),
        ]
    return "\n\n".join(parts)


def page(kinematic_path: str, physics_path: str, title: str, intro: str) -> str:
    """The page's Markdown from the two runs.

    Raises
    ------
    ValueError
        A run that is not a friction sweep, two runs that differ by more than the plant (named),
        or no friction level with a log in both.
    """
    kinematic, kinematic_levels, kinematic_manifest = slip_levels(kinematic_path)
    physics, physics_levels, physics_manifest = slip_levels(physics_path)
    if kinematic_levels != physics_levels:
        raise ValueError(
            f"the runs sweep different friction levels ({kinematic_levels}; {physics_levels}): "
            "a sim-to-sim pair sweeps the same ones"
        )
    if not any(level in kinematic and level in physics for level in kinematic_levels):
        raise ValueError(f"no friction level has a log in both runs ({list(kinematic)}; {list(physics)})")
    levels = [level_data(level, kinematic.get(level), physics.get(level)) for level in kinematic_levels]
    parts = [
        f"# {title}",
        intro,
        "Commands:\n\n"
        + "\n".join(f"    {m.get('command', '')}" for m in (kinematic_manifest, physics_manifest)),
        "Per friction level and controller: the success rate over both tasks' paired episodes on each "
        "plant with its 95% Wilson interval, the paired difference with Newcombe's 95% interval and "
        "the exact McNemar p, Holm-adjusted over the level's controllers. A verdict is a paired "
        "difference in success between two controllers of one task with a Holm-adjusted p below "
        f"{TRANSFER_ALPHA} in that plant's own table of every pair (the run's report: Holm over its pairs). "
        "The rank agreement is Kendall's tau-b between the controllers' success rates on the two plants "
        "(both tasks pooled, the fine-tuned row left out), with a percentile bootstrap interval that "
        "resamples whole clusters, the same resample on both plants. A controller whose episodes are "
        "not all in both runs is pending: named, and left out of every table and test.",
        summary_block(levels),
    ]
    parts += [level_section(level) for level in levels]
    return "\n\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "kinematic", help="the protocol's run on the kinematic plant (a sweep directory or publication)"
    )
    parser.add_argument("physics", help="the same run with --plant mujoco")
    # no default page: the published one is a tracked file (docs/make_pages.py names it)
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/sim2sim_results.md")
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; this page draws no figure")
    parser.add_argument("--title", default="Sim-to-sim results")
    parser.add_argument("--intro", type=Path, help="a Markdown template whose text opens the page")
    args = parser.parse_args(argv)
    if args.intro is not None and not args.intro.is_file():
        print(f"error: --intro {str(args.intro)!r} is not a file", file=sys.stderr)
        return BAD_INPUT_EXIT
    try:
        intro = (
            INTRO
            if args.intro is None
            else expand_template(args.intro, [args.kinematic, args.physics]).strip()
        )
        text = page(args.kinematic, args.physics, args.title, intro)
    except ValueError as exc:  # the message names the run, the setting or the placeholder
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    write_atomic(Path(args.out), text)
    print(f"wrote {args.out}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
