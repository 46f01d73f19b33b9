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
- **aggregate**: the interquartile mean of the (layout, seed) scores (a seed's success rate on a
  layout) with rliable's stratified bootstrap, seeds re-drawn within each layout
  (:func:`evaluation.stats.clustered.layout_iqm_interval`, ``resample="within"``; Agarwal et al.
  2021), and beside it the interval that re-draws whole layouts, for a statement about unseen
  layouts;
- **the shipped seed**: :func:`chosen_seed`, the best by its validation record (never by test);
  ``--ship`` copies its policy into the controller's shipped folder.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evaluation.episodes.records import selection_key
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from evaluation.stats.clustered import layout_iqm_interval, layout_rate_interval
from koopman_envs import SPLITS, TASKS
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic

__all__ = [
    "FINISHED_FILE",
    "POLICIES",
    "TRAINING_ROOT",
    "SeedAggregate",
    "SeedRun",
    "aggregate",
    "chosen_seed",
    "evaluate_seeds",
    "finished_seeds",
    "main",
    "outcomes_by_label",
    "report_markdown",
    "ship",
]

#: where ``data/training/run.sh`` trains the seeds, and its marker of a finished seed
TRAINING_ROOT = Path("data/training")
FINISHED_FILE = "finished.json"
#: the learned policies the driver trains (registered controller names)
POLICIES = ("rl-ppo-set", "rl-ppo", "ippo")
#: the suite the seeds are trained and evaluated on
SUITE = "koopnav-bench-v1"


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


@dataclass(frozen=True)
class SeedAggregate:
    """A policy's result over seeds on one split (:func:`aggregate`).

    Attributes
    ----------
    seeds : tuple of int
        The seeds, in order.
    layouts : int
        Layouts every seed ran.
    per_seed : dict
        Seed -> (success rate, low, high), the interval over layouts.
    iqm : (float, float, float)
        IQM of the (layout, seed) scores and its stratified bootstrap interval (seeds within layouts).
    iqm_layouts : (float, float, float)
        The same IQM with whole layouts re-drawn.
    mean : float
        The plain mean success over every episode.
    """

    seeds: tuple[int, ...]
    layouts: int
    per_seed: dict[int, tuple[float, float, float]]
    iqm: tuple[float, float, float]
    iqm_layouts: tuple[float, float, float]
    mean: float


def aggregate(
    outcomes: Mapping[int, Mapping[Any, Sequence[bool | int]]], *, n_boot: int = 4000, seed: int = 0
) -> SeedAggregate:
    """Per-seed success and the interquartile mean over (layout, seed) scores.

    Parameters
    ----------
    outcomes : mapping
        ``outcomes[s][l]``: the successes (bools or 0/1) of training seed s's episodes on layout l; every seed
        on the same layouts.
    n_boot, seed
        Bootstrap replicates and the bootstrap's seed (the result is a function of the arguments).

    Returns
    -------
    SeedAggregate
        A layout's score for a seed is its success rate there; the IQM pools every (layout, seed)
        score as rliable pools (task, run) scores.

    Raises
    ------
    ValueError
        No seed, or seeds that ran different layouts (naming them).
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
    per_seed = {
        s: layout_rate_interval([outcomes[s][lay] for lay in layouts], n_boot=n_boot, seed=seed)
        for s in seeds
    }
    scores = [[sum(map(bool, outcomes[s][lay])) / len(outcomes[s][lay]) for s in seeds] for lay in layouts]
    episodes = [bool(x) for s in seeds for lay in layouts for x in outcomes[s][lay]]
    return SeedAggregate(
        seeds=tuple(seeds),
        layouts=len(layouts),
        per_seed=per_seed,
        iqm=layout_iqm_interval(scores, n_boot=n_boot, seed=seed, resample="within"),
        iqm_layouts=layout_iqm_interval(scores, n_boot=n_boot, seed=seed, resample="layouts"),
        mean=sum(episodes) / len(episodes),
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
) -> list[dict[str, Any]]:
    """Every finished seed of ``policies`` on ``tasks`` through the evaluator on ``split``, one
    run per task (every seed a controller variant; logged in ``out/<task>`` and resumed there);
    one summary per (policy, task): its seeds' runs, :func:`aggregate` and :func:`chosen_seed`."""
    from evaluation.execution.runner import evaluate
    from evaluation.experiments.protocols import suite_protocol

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
        for policy, seed_runs in runs.items():
            if seed_runs:
                result = aggregate({r.seed: by_label[r.label] for r in seed_runs}, n_boot=n_boot)
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


def report_markdown(summaries: Sequence[Mapping[str, Any]]) -> str:
    """The per-seed table and the aggregate table of :func:`evaluate_seeds`' summaries."""
    rows = [
        "| policy | task | seed | validation success (kept checkpoint) | test success [95% CI over layouts] | shipped |",
        "|---|---|---|---|---|---|",
    ]
    for s in summaries:
        result: SeedAggregate = s["aggregate"]
        for run in s["runs"]:
            shipped = "yes (chosen on validation)" if run.seed == s["chosen"].seed else ""
            rows.append(
                f"| `{s['policy']}` | {s['task']} | {run.seed} | {100 * run.validation['success_rate']:.1f}% "
                f"(step {run.validation['step']:,}) | {_interval(result.per_seed[run.seed])} | {shipped} |"
            )
    rows += [
        "",
        "| policy | task | split | seeds | layouts | IQM [stratified bootstrap] | IQM [layouts re-drawn] | mean |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in summaries:
        result = s["aggregate"]
        rows.append(
            f"| `{s['policy']}` | {s['task']} | {s['suite']} | {len(result.seeds)} | {result.layouts} | "
            f"{_interval(result.iqm)} | {_interval(result.iqm_layouts)} | {100 * result.mean:.1f}% |"
        )
    return "\n".join(rows) + "\n"


def ship(run: SeedRun) -> Path:
    """Copy the kept policy of ``run`` (the seed :func:`chosen_seed` picks) into its
    controller's shipped folder (``baselines/policies/<folder>/<task>/``); the folder written."""
    import controllers

    # the controller's own default root: the folder its shipped policies load from
    controller: Any = controllers.make(run.policy)  # an RL controller: it has a policy_root
    target = Path(controller.policy_root) / run.task
    source = run.folder / run.task
    for path in sorted(source.iterdir()):
        if path.is_file():
            write_atomic(target / path.name, path.read_bytes())
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
        "--ship", action="store_true", help="copy each chosen seed's policy to the shipped folder"
    )
    parser.add_argument("--out", required=True, help="the run logs (OUT/<task>/) and seeds.md, seeds.json")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Evaluate the seeds, write ``OUT/seeds.md`` and ``OUT/seeds.json``, print the tables."""
    from evaluation.run.suite_runs import layout_slice

    args = _parser().parse_args(argv)
    try:
        summaries = evaluate_seeds(
            args.root, args.policies, args.tasks, split=args.split, layouts=layout_slice(args.layouts),
            episodes=args.episodes, workers=args.workers, out=args.out, n_boot=args.n_boot,
        )  # fmt: skip
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    if not summaries:
        print(f"error: no finished seed of {args.policies} under {args.root}", file=sys.stderr)
        return BAD_INPUT_EXIT
    table = report_markdown(summaries)
    data = [
        {
            "policy": s["policy"], "task": s["task"], "suite": s["suite"], "chosen_seed": s["chosen"].seed,
            "seeds": [{"seed": r.seed, "folder": str(r.folder), "validation": r.validation,
                       "test": list(s["aggregate"].per_seed[r.seed])} for r in s["runs"]],
            "iqm": list(s["aggregate"].iqm), "iqm_layouts": list(s["aggregate"].iqm_layouts),
            "mean": s["aggregate"].mean, "layouts": s["aggregate"].layouts,
        }
        for s in summaries
    ]  # fmt: skip
    write_atomic(Path(args.out) / "seeds.md", table)
    write_atomic(Path(args.out) / "seeds.json", json.dumps(data, indent=1) + "\n")
    print(table)
    if args.ship:
        for s in summaries:
            print(f"shipped {s['chosen'].label} ({s['task']}) to {ship(s['chosen'])}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
