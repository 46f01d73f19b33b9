"""Learned policies over training seeds: every seed on the test suite, per seed and aggregated.

``python -m evaluation.experiments.seeds --out runs/seeds`` (docs/benchmark.md#learned-policies)

``bash data/training/run.sh`` trains each learned policy with seeds 0..N-1 on the suite's train
layouts, each seed's checkpoint chosen on the validation layouts, into
``data/training/<policy>/<task>/seed<k>/`` (a policy root: ``<task>/`` holds the kept policy,
``selection.json`` its validation table, ``finished.json`` marks a finished seed). This command
runs every finished seed through the evaluator on a split of the suite (``test`` by default), each
seed a controller variant ``<policy>@seed<k>`` (the registered controller with ``policy_root`` its
seed folder), every variant on the same (layout, episode) units, and reports:

- **per seed**: its success rate with the two-stage interval over layouts
  (:func:`evaluation.stats.clustered.layout_rate_interval`);
- **aggregate**: rliable's interquartile mean over runs, one score per (stratum, seed): a seed's
  success rate over the split's layouts (one stratum by default), as rliable scores each (task,
  run) (:func:`evaluation.stats.clustered.run_aggregate_interval`; Agarwal et al. 2021), with an
  interval that re-draws the layouts within each stratum, and beside it the mean over seeds. With
  fewer than 4 seeds the IQM trims nothing: the report leads with the mean and says so;
- **the shipped seed**: :func:`chosen_seed`, the best by its validation record (never by test);
  ``--ship`` copies its policy into the controller's shipped folder (:func:`ship`: the first time,
  the former policies move to ``<folder>_v0``, which ``<policy>-v0`` plays; refused by name while
  a seed the driver plans is unfinished, or without a ``<policy>-v0``).

The published run is ``bash data/publish.sh seeds`` (``OUT`` = ``data/runs/seeds``, packed into
``data/seeds/`` by ``bash data/publish.sh pack``); :func:`evaluation.experiments.seeds_published.read_publication` reads it back,
with the seeds' validation records from their folders, and ``docs/make_seeds_md.py`` writes
docs/seeds_results.md from it.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evaluation.episodes.records import selection_key
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from evaluation.experiments.seeds_shipping import check_shippable, keep_former, shipped_folder
from evaluation.stats.clustered import layout_rate_interval, run_aggregate_interval
from koopman_envs import SPLITS, TASKS
from koopman_envs.checks import check_choice
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic

__all__ = [
    "FINISHED_FILE",
    "IQM_MIN_RUNS",
    "POLICIES",
    "REPORTS",
    "TRAINING_ROOT",
    "DRIVER",
    "SeedAggregate",
    "SeedRun",
    "aggregate",
    "chosen_seed",
    "evaluate_seeds",
    "finished_seeds",
    "main",
    "outcomes_by_label",
    "report_markdown",
    "planned_seeds",
    "ship",
]

#: where ``data/training/run.sh`` trains the seeds, and its marker of a finished seed
TRAINING_ROOT = Path("data/training")
FINISHED_FILE = "finished.json"
#: the learned policies the driver trains (registered controller names)
POLICIES = ("rl-ppo-set", "rl-ppo", "ippo")
#: the suite the seeds are trained and evaluated on
SUITE = "koopnav-bench-v1"
#: the layout fields of an episode record that can stratify the aggregate (``--strata``)
STRATA = ("layout_tier", "layout_family")


@dataclass(frozen=True)
class SeedRun:
    """One finished training seed.

    Attributes
    ----------
    policy : str
        The registered controller that plays it.
    task : str
        ``"target_reaching"`` or ``"formation"``.
    seed : int
        The training seed.
    folder : Path
        Its seed folder, a policy root (``<folder>/<task>/`` holds the kept policy).
    validation : dict
        The chosen checkpoint's validation record (``selection.json``'s ``chosen``).
    """

    policy: str
    task: str
    seed: int
    folder: Path
    validation: dict[str, Any]

    @property
    def label(self) -> str:
        """Its row in the evaluator's reports: ``<policy>@seed<k>``."""
        return f"{self.policy}@seed{self.seed}"


#: the seed driver (the seeds it trains; read back by ``evaluation.experiments.seeds_published``), whose defaults are the planned seeds (:func:`planned_seeds`)
DRIVER = TRAINING_ROOT / "run.sh"


def planned_seeds(script: str | os.PathLike[str] = DRIVER) -> list[tuple[str, str, int]]:
    """The seed runs the driver ``script`` (``data/training/run.sh``) plans by default, as
    ``(policy, task, seed)`` in its order: its default policies, each on its default tasks, seeds
    0 to its default ``SEEDS`` - 1.

    Raises
    ------
    ValueError
        The script does not state a default (naming which), or names a policy or task that is not
        one (naming it and the allowed ones).
    """
    text = read_text(script, MAX_TEXT_BYTES, what="seed driver", expected="data/training/run.sh")
    found = {
        "SEEDS": re.search(r'^SEEDS="\$\{SEEDS:-(\d+)\}"$', text, re.M),
        "policies": re.search(r"\|\| policies=\(([\w -]+)\)$", text, re.M),
        "TASKS": re.search(r'"\$\{TASKS:-([\w ]+)\}"', text),
    }
    missing = [name for name, match in found.items() if match is None]
    if missing:
        raise ValueError(f"{script} states no default {', '.join(missing)} (as data/training/run.sh does)")
    policies = found["policies"][1].split()  # type: ignore[index]
    tasks = found["TASKS"][1].split()  # type: ignore[index]
    for policy in policies:
        check_choice(f"{script}: default policy", policy, POLICIES)
    for task in tasks:
        check_choice(f"{script}: default task", task, list(TASKS))
    seeds = int(found["SEEDS"][1])  # type: ignore[index]
    return [(p, t, k) for p in policies for t in tasks for k in range(seeds)]


def _read_json(path: Path) -> Any:
    return json.loads(read_text(path, MAX_TEXT_BYTES, what="training record", expected="JSON"))


def finished_seeds(root: str | os.PathLike[str], policy: str, task: str) -> list[SeedRun]:
    """The finished seeds of ``policy`` on ``task`` under ``root`` (``seed<k>/`` folders with
    ``finished.json``), by seed; unfinished folders are left out."""
    runs = []
    for marker in Path(root, policy, task).glob(f"seed*/{FINISHED_FILE}"):
        folder = marker.parent
        number = folder.name.removeprefix("seed")
        if not number.isdigit():
            continue
        selection = _read_json(folder / "selection.json")
        runs.append(SeedRun(policy, task, int(number), folder, dict(selection["chosen"])))
    return sorted(runs, key=lambda run: run.seed)


def chosen_seed(runs: Sequence[SeedRun]) -> SeedRun:
    """The seed that ships: the highest validation success of its kept checkpoint, ties broken by
    the lower mean final distance, then the lower seed (:func:`~evaluation.episodes.records.selection_key`,
    the checkpoints' rule). Test results play no part."""
    if not runs:
        raise ValueError("no finished seed to choose from")

    def order(run: SeedRun) -> tuple[float, float, int]:
        validation = run.validation
        return selection_key(validation["success_rate"], validation.get("mean_final_distance"), -run.seed)

    return max(runs, key=order)


#: the fewest runs whose IQM trims anything (``trim_mean(x, 0.25)`` cuts ``int(n / 4)`` at each end)
IQM_MIN_RUNS = 4


@dataclass(frozen=True)
class SeedAggregate:
    """A policy's result over seeds on one split (:func:`aggregate`).

    Attributes
    ----------
    seeds : tuple of int
        The seeds, in order.
    layouts : int
        Layouts every seed ran.
    strata : tuple
        The strata of the layouts that each hold one score per seed (``(None,)``: the whole split).
    per_seed : dict
        Seed -> (success rate, low, high), the interval over layouts.
    iqm : (float, float, float)
        rliable's IQM of the (stratum, seed) success rates, and its interval with the layouts
        re-drawn within each stratum.
    mean : (float, float, float)
        The mean of the same scores, the same interval.
    """

    seeds: tuple[int, ...]
    layouts: int
    strata: tuple[Any, ...]
    per_seed: dict[int, tuple[float, float, float]]
    iqm: tuple[float, float, float]
    mean: tuple[float, float, float]

    @property
    def lead(self) -> str:
        """``"mean"`` with fewer than :data:`IQM_MIN_RUNS` seeds (the IQM trims nothing and is the
        mean), else ``"iqm"``."""
        return "iqm" if len(self.seeds) >= IQM_MIN_RUNS else "mean"


def aggregate(
    outcomes: Mapping[int, Mapping[Any, Sequence[bool | int]]],
    *,
    strata: Mapping[Any, Any] | None = None,
    n_boot: int = 4000,
    seed: int = 0,
) -> SeedAggregate:
    """Per-seed success and the aggregate over seeds, in rliable's unit.

    Parameters
    ----------
    outcomes : mapping
        ``outcomes[s][l]``: the successes (bools or 0/1) of training seed s's episodes on layout l;
        every seed on the same layouts.
    strata : mapping, optional
        Layout -> its stratum (e.g. its tier): one score per (stratum, seed); default one stratum.
    n_boot, seed
        Bootstrap replicates and the bootstrap's seed (the result is a function of the arguments).

    Returns
    -------
    SeedAggregate
        A seed's score in a stratum is its success rate over the stratum's episodes (rliable's
        (task, run) score); the IQM and the mean pool the (stratum, seed) scores
        (:func:`evaluation.stats.clustered.run_aggregate_interval`, layouts re-drawn).

    Raises
    ------
    ValueError
        No seed, seeds that ran different layouts, or ``strata`` missing a layout (naming them).
    """
    seeds = sorted(outcomes)
    if not seeds:
        raise ValueError("outcomes holds no seed")
    layouts = sorted(outcomes[seeds[0]])
    for s in seeds[1:]:
        if sorted(outcomes[s]) != layouts:
            raise ValueError(
                f"seed {s} ran layouts {sorted(outcomes[s])}, seed {seeds[0]} ran {layouts}: "
                "the seeds are compared on the same layouts"
            )
    missing = [] if strata is None else [lay for lay in layouts if lay not in strata]
    if missing:
        raise ValueError(f"strata has no stratum for layouts {missing}")
    labels = None if strata is None else [strata[lay] for lay in layouts]
    per_seed = {
        s: layout_rate_interval([outcomes[s][lay] for lay in layouts], n_boot=n_boot, seed=seed)
        for s in seeds
    }
    runs = [[outcomes[s][lay] for lay in layouts] for s in seeds]
    return SeedAggregate(
        seeds=tuple(seeds),
        layouts=len(layouts),
        strata=(None,) if labels is None else tuple(dict.fromkeys(labels)),
        per_seed=per_seed,
        iqm=run_aggregate_interval(runs, labels, "iqm", n_boot=n_boot, seed=seed),
        mean=run_aggregate_interval(runs, labels, "mean", n_boot=n_boot, seed=seed),
    )


def outcomes_by_label(records: Iterable[Mapping[str, Any]]) -> dict[str, dict[int, list[bool]]]:
    """A suite run's episode records as ``{controller label: {layout: [success, ...]}}`` (an
    episode that raised is a failure)."""
    out: dict[str, dict[int, list[bool]]] = {}
    for record in records:
        out.setdefault(record["controller"], {}).setdefault(int(record["layout"]), []).append(
            record.get("success") is True
        )
    return out


#: what the command writes beside its logs (``main``), left out of its publication
REPORTS = ("seeds.md", "seeds.json")


def evaluate_seeds(
    root: str | os.PathLike[str],
    policies: Sequence[str],
    tasks: Sequence[str],
    *,
    split: str = "test",
    layouts: Any = None,
    episodes: int = 1,
    seed: int = 0,
    workers: int | None = None,
    out: str | os.PathLike[str] | None = None,
    n_boot: int = 4000,
    strata: str | None = None,
) -> list[dict[str, Any]]:
    """Every finished seed of ``policies`` on ``tasks`` through the evaluator on ``split``, one
    run per task (every seed a controller variant; logged in ``out/<task>`` and resumed there);
    one summary per (policy, task): its seeds' runs, :func:`aggregate` and :func:`chosen_seed`.
    ``strata``: a layout field of the records (one of :data:`STRATA`) whose values each hold one
    score per seed; default the whole split."""
    from evaluation.execution.runner import evaluate
    from evaluation.experiments.protocols import suite_protocol

    if strata is not None:
        strata = check_choice("strata", strata, STRATA)
    summaries = []
    for task in tasks:
        runs = {policy: finished_seeds(root, policy, task) for policy in policies}
        variants = {r.label: (r.policy, {"policy_root": str(r.folder)}) for rs in runs.values() for r in rs}
        if not variants:
            continue
        spec = suite_protocol(SUITE, split).replace(
            envs=(TASKS[task].env_id,), controllers=variants, episodes=episodes, seed=seed, layouts=layouts
        )
        folder = None if out is None else Path(out) / task
        resume = folder is not None and (folder / "episodes.jsonl").exists()
        records = list(evaluate(spec, workers=workers, out=folder, resume=resume).records)
        by_label = outcomes_by_label(records)
        groups = None if strata is None else {int(r["layout"]): r[strata] for r in records}
        for policy, seed_runs in runs.items():
            if seed_runs:
                result = aggregate(
                    {r.seed: by_label[r.label] for r in seed_runs}, strata=groups, n_boot=n_boot
                )
                suite = next(r["suite"] for r in records if r["controller"] == seed_runs[0].label)
                summaries.append(
                    {
                        "policy": policy,
                        "task": task,
                        "suite": suite,
                        "runs": seed_runs,
                        "aggregate": result,
                        "chosen": chosen_seed(seed_runs),
                    }  # fmt: skip
                )
    return summaries


def _interval(value: tuple[float, float, float]) -> str:
    return f"{100 * value[0]:.1f}% [{100 * value[1]:.1f}, {100 * value[2]:.1f}]"


def report_markdown(summaries: Sequence[Mapping[str, Any]], split: str = "test") -> str:
    """The per-seed table and the aggregate table of :func:`evaluate_seeds`' summaries, the seeds'
    success on ``split`` (the split they ran on)."""
    rows = [
        f"| policy | task | seed | validation success (kept checkpoint) | {split} success [95% CI over layouts] "
        "| chosen (what --ship ships) |",
        "|---|---|---|---|---|---|",
    ]
    for s in summaries:
        result: SeedAggregate = s["aggregate"]
        for run in s["runs"]:
            # chosen, not shipped: the table is written before --ship copies it (and without it)
            chosen = "chosen on validation" if run.seed == s["chosen"].seed else ""
            rows.append(
                f"| `{s['policy']}` | {s['task']} | {run.seed} | {100 * run.validation['success_rate']:.1f}% "
                f"(step {run.validation['step']:,}) | {_interval(result.per_seed[run.seed])} | {chosen} |"
            )
    rows += [
        "",
        "| policy | task | split | seeds | layouts | aggregate over seeds [95% CI, layouts re-drawn] "
        "| IQM | mean |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in summaries:
        result = s["aggregate"]
        lead = (
            f"IQM {_interval(result.iqm)}"
            if result.lead == "iqm"
            else f"mean {_interval(result.mean)} ({len(result.seeds)} seed{'s' if len(result.seeds) != 1 else ''}: fewer than {IQM_MIN_RUNS}, "
            "the IQM trims nothing)"
        )
        rows.append(
            f"| `{s['policy']}` | {s['task']} | {s['suite']} | {len(result.seeds)} | {result.layouts} | "
            f"{lead} | {_interval(result.iqm)} | {_interval(result.mean)} |"
        )
    return "\n".join(rows) + "\n"


def ship(
    run: SeedRun,
    *,
    policies: str | os.PathLike[str] | None = None,
    plan: Sequence[tuple[str, str, int]] | None = None,
) -> Path:
    """Copy the kept policy of ``run`` (the seed :func:`chosen_seed` picks) into its
    controller's shipped folder (``baselines/policies/<folder>/<task>/``; ``policies``: another
    directory of shipped folders); the folder written.

    The first time (no ``<folder>_v0`` yet) the folder is first copied to ``<folder>_v0``, every
    task's former policies with it, which ``<policy>-v0`` plays (``rl-ppo-set-v0``); an existing
    ``<folder>_v0`` is never written to. The task's folder then holds the seed's files only; a
    task not shipped yet keeps its former policy. Refused (``ValueError``, by name, before anything is moved
    or written: :func:`~evaluation.experiments.seeds_shipping.check_shippable`) while a seed the
    driver plans for the policy and task (``plan``, default :func:`planned_seeds`) is unfinished,
    or when no ``<policy>-v0`` is registered.
    """
    check_shippable(run.policy, run.task, run.folder.parent, planned_seeds() if plan is None else plan)
    target = keep_former(shipped_folder(run.policy, policies)) / run.task
    source = run.folder / run.task
    names = sorted(path.name for path in source.iterdir() if path.is_file())
    for name in names:
        write_atomic(target / name, (source / name).read_bytes())
    for path in sorted(target.iterdir()):
        # a former policy's file the seed has not (an obs_norm.npz) would be read with its weights
        if path.is_file() and path.name not in names:
            path.unlink()
    return target


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m evaluation.experiments.seeds", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--root", default=str(TRAINING_ROOT), help="the seed folders (default data/training)")
    parser.add_argument("--policies", nargs="+", default=["rl-ppo-set", "ippo"], choices=POLICIES)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=list(TASKS))
    parser.add_argument("--split", default="test", choices=SPLITS, help="the suite split (default test)")
    parser.add_argument("--layouts", default=None, metavar="N|A:B", help="the first N layouts, or A to B-1")
    parser.add_argument("--episodes", type=int, default=1, help="episodes per layout (default 1)")
    parser.add_argument("--workers", type=int, default=None, help="evaluator processes (default: all cores)")
    parser.add_argument("--n-boot", type=int, default=4000, help="bootstrap replicates (default 4000)")
    parser.add_argument(
        "--strata",
        default=None,
        choices=STRATA,
        help="one score per (stratum, seed): the layouts' tier or family (default: the whole split)",
    )
    parser.add_argument(
        "--ship",
        action="store_true",
        help="copy each chosen seed's policy to the shipped folder (the former policies, the first "
        "time, to <folder>_v0 for <policy>-v0); refused while a planned seed is unfinished",
    )
    parser.add_argument("--out", required=True, help="the run logs (OUT/<task>/) and seeds.md, seeds.json")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Evaluate the seeds, write ``OUT/seeds.md`` and ``OUT/seeds.json``, print the tables."""
    from evaluation.run.suite_runs import layout_slice

    args = _parser().parse_args(argv)
    if args.ship:  # refused before any episode runs, by name (check_shippable)
        try:
            for policy in args.policies:
                for task in args.tasks:
                    for run in finished_seeds(args.root, policy, task)[:1]:
                        check_shippable(policy, task, run.folder.parent, planned_seeds())
        except ValueError as exc:
            print(f"error: --ship: {exc}", file=sys.stderr)
            return BAD_INPUT_EXIT
    try:
        summaries = evaluate_seeds(
            args.root, args.policies, args.tasks, split=args.split, layouts=layout_slice(args.layouts),
            episodes=args.episodes, workers=args.workers, out=args.out, n_boot=args.n_boot,
            strata=args.strata,
        )  # fmt: skip
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    if not summaries:
        print(f"error: no finished seed of {args.policies} under {args.root}", file=sys.stderr)
        return BAD_INPUT_EXIT
    table = report_markdown(summaries, args.split)
    data = [
        {
            "policy": s["policy"], "task": s["task"], "suite": s["suite"], "chosen_seed": s["chosen"].seed,
            "seeds": [{"seed": r.seed, "folder": str(r.folder), "validation": r.validation,
                       "test": list(s["aggregate"].per_seed[r.seed])} for r in s["runs"]],
            "iqm": list(s["aggregate"].iqm), "mean": list(s["aggregate"].mean),
            "leads_with": s["aggregate"].lead, "layouts": s["aggregate"].layouts,
        }
        for s in summaries
    ]  # fmt: skip
    markdown, summary = REPORTS
    write_atomic(Path(args.out) / markdown, table)
    write_atomic(Path(args.out) / summary, json.dumps(data, indent=1) + "\n")
    print(table)
    if args.ship:
        for s in summaries:  # every one checked before the first is moved or written
            check_shippable(s["policy"], s["task"], s["chosen"].folder.parent, planned_seeds())
        for s in summaries:
            print(f"shipped {s['chosen'].label} ({s['task']}) to {ship(s['chosen'])}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
