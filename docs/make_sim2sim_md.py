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
only. The ``--intro`` file is a template as for the other pages (``docs/make_prose_md.py``),
its runs named by their files (``sim2sim_physics@slip=high``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.experiments.sweep import load_sweep  # noqa: E402
from evaluation.reports.results import Results  # noqa: E402
from evaluation.stats.statistics import PairedComparison, paired_comparison  # noqa: E402
from evaluation.stats.transfer import (  # noqa: E402
    TRANSFER_ALPHA,
    Ordering,
    PlantRow,
    check_same_protocol,
    orderings,
    plant_differences,
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

#: the controllers trained on the physics plant, each with the kinematic controller it was
#: fine-tuned from: rows of their own (their kinematic column is the reverse direction), left out
#: of the verdicts that transfer (tests/test_sim2sim.py holds this to the shipped metadata)
FINE_TUNED = {"rl-ppo-set-physics": "rl-ppo-set"}

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


def summary_sentence(found: dict[Any, list[Ordering]]) -> str:
    """How many of the kinematic plant's verdicts hold on the physics plant, level by level."""
    counts = []
    for level, orderings_ in found.items():
        kept = transfers(orderings_)
        verdicts = [o for o in kept if o.first != 0]
        held = sum(o.verdict == "holds" for o in verdicts)
        new = sum(o.verdict == "new" for o in kept)
        surface = SLIP_SURFACES.get(str(level), str(level))
        counts.append(f"{surface} {held} of {len(verdicts)}" + (f" (and {new} new)" if new else ""))
    return (
        "**Which verdicts transfer.** Of the orderings of two controllers significant on the kinematic "
        "plant, these hold on the physics plant at each friction level: " + "; ".join(counts) + ". "
        "Each level's section names them, and those lost, reversed or new."
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


def fine_tuned_table(rows: list[PlantRow], physics: Results) -> str:
    """The :data:`FINE_TUNED` rows of one friction level: each against its source on the physics
    plant (paired, McNemar), and its success on both plants."""
    lines = [
        "| controller | fine-tuned from | pairs | physics | its source on physics | difference [points] | p "
        "| kinematic |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        test = against_source(physics.records, row.controller)
        if test is None:
            continue
        lines.append(
            f"| {row.controller} | {FINE_TUNED[row.controller]} | {test.n} | {_percent(test.rate_a)} | "
            f"{_percent(test.rate_b)} | {_points(test.difference)} {_signed_interval(test.low, test.high)} | "
            f"{_p(test.p_value)} | {_percent(row.first)} {_interval(*row.first_interval)} |"
        )
    return "\n".join(lines)


def level_section(level: Any, kinematic: Results, physics: Results, found: list[Ordering]) -> str:
    """One friction level's part of the page (``found``: its :func:`orderings`)."""
    rows = plant_differences(kinematic, physics)
    transferred = [row for row in rows if row.controller not in FINE_TUNED]
    tuned = [row for row in rows if row.controller in FINE_TUNED]
    parts = [
        f"## {level_title(level)}",
        plant_table(transferred),
        f"Holm's adjustment over the level's {len(rows)} tests. **Which verdicts transfer**: "
        + transfer_sentence(transfers(found)),
    ]
    if tuned:
        parts += [
            "**Fine-tuned on the physics plant** (a separate row, not a transfer: trained on the "
            "physics plant's train layouts, so its kinematic column is the reverse direction): against "
            "the policy it was fine-tuned from, paired on the physics plant's episodes (Newcombe's 95% "
            "interval, exact McNemar p).",
            fine_tuned_table(tuned, physics),
        ]
    return "\n\n".join(parts)


def _slip_levels(path: str) -> tuple[dict[Any, Results], dict[str, Any]]:
    """A sim-to-sim run's finished friction levels and its manifest."""
    done, missing, manifest = load_sweep(path)
    if "slip" not in done:
        raise ValueError(f"the run in {path!r} is not swept over the friction level (--sweep slip=...)")
    if missing:
        print(f"note: levels of {path!r} not finished yet, left out: {', '.join(missing)}", file=sys.stderr)
    return dict(done["slip"]), manifest


def page(kinematic_path: str, physics_path: str, title: str, intro: str) -> str:
    """The page's Markdown from the two runs.

    Raises
    ------
    ValueError
        A run that is not a friction sweep, two runs that differ by more than the plant (named),
        or no friction level finished in both.
    """
    kinematic, kinematic_manifest = _slip_levels(kinematic_path)
    physics, physics_manifest = _slip_levels(physics_path)
    shared = [level for level in kinematic if level in physics]
    if not shared:
        raise ValueError(f"no friction level is finished in both runs ({list(kinematic)}; {list(physics)})")
    for level in shared:
        check_same_protocol(kinematic[level].config, physics[level].config)
    parts = [
        f"# {title}",
        intro,
        "Commands:\n\n"
        + "\n".join(f"    {m.get('command', '')}" for m in (kinematic_manifest, physics_manifest)),
        "Per friction level and controller: the success rate over both tasks' paired episodes on each "
        "plant with its 95% Wilson interval, the paired difference with Newcombe's 95% interval and "
        "the exact McNemar p, Holm-adjusted over the level's controllers. A verdict is a paired "
        "difference in success between two controllers of one task with a Holm-adjusted p below "
        f"{TRANSFER_ALPHA} in that plant's own table of every pair (the run's report: Holm over its pairs).",
    ]
    found = {level: orderings(kinematic[level], physics[level]) for level in shared}
    parts.append(summary_sentence(found))
    parts += [level_section(level, kinematic[level], physics[level], found[level]) for level in shared]
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
