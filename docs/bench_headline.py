"""README.md's headline block of docs/bench_results.md (:data:`HEADLINE`, issue 60): per task the
test split's leaderboard (success, compute charged, per layout tier, free compute beside it), then
the paper track's success per controller. docs/make_bench_md.py places it at the top of the page;
``python docs/make_pages.py`` copies it into README.md. Every cell is the evaluator's
(:mod:`evaluation.reports.bench`); this module only lays them out.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from controllers.tuning import WEIGHT_VARIANTS  # noqa: E402
from evaluation.reports.bench import (  # noqa: E402
    BenchMode,
    declared_tasks,
    headline_rows,
    paper_track_rows,
    paper_variants_note,
)
from evaluation.reports.results import Results  # noqa: E402
from evaluation.reports.sections import suite_heading, task_label  # noqa: E402
from koopman_envs import TIERS  # noqa: E402

__all__ = ["HEADLINE", "headline", "paper_track", "shipped_before_clause"]

#: the name of the block README.md copies from the page (docs/make_pages.py, ``"readme"``)
HEADLINE = "bench-headline"


def _scope(modes: Sequence[BenchMode]) -> str:
    """What the runs are, from the first published mode's header."""
    for mode in modes:
        if mode.results is not None:
            return suite_heading(mode.results.config)
    return "Suite koopnav-bench-v1, split test"


def headline(modes: Sequence[BenchMode], paper: Results | None, paper_path: str = "data/paper.tar.xz") -> str:
    """README's headline block: per task the test split's leaderboard (success, compute charged,
    per tier, free compute beside it), then the paper track's success per controller."""
    lines = [
        f"<!-- begin {HEADLINE}: written by `python docs/make_pages.py docs/bench_results.md` "
        "from the committed data (docs/make_bench_md.py); an edit by hand fails the tests -->"
    ]
    if not any(mode.progress for mode in modes):  # neither run published yet
        runs = " and ".join(f"`{mode.path.as_posix()}`" for mode in modes)
        lines += [
            f"**The held-out test split of koopnav-bench-v1**: pending, {runs} are not published yet "
            f"(`bash data/publish.sh {' '.join(mode.run for mode in modes)}`, then `bash data/publish.sh pack`).",
            "",
            *paper_track(paper, paper_path),
            f"<!-- end {HEADLINE} -->",
        ]
        return "\n".join(lines) + "\n"
    lines += [
        "**The held-out test split of koopnav-bench-v1.** "
        + _scope(modes)
        + ". No controller was tuned or trained on it; every one runs its shipped defaults, high slip. "
        "Success with 95% intervals over layouts (the wider of Wilson's and the two-stage bootstrap, "
        "layouts then episodes); the decision time charged to the robots (`--realtime`), by layout "
        "tier, and free compute beside it.",
        "",
    ]
    for env_id in declared_tasks(modes):
        lines += [
            f"| {task_label(env_id)} | Compute charged | " + " | ".join(TIERS) + " | Free compute |",
            "|---|---|" + "---|" * len(TIERS) + "---|",
        ]
        lines += ["| " + " | ".join(row) + " |" for row in headline_rows(modes, env_id)]
        lines.append("")
    lines += paper_track(paper, paper_path)
    lines.append(f"<!-- end {HEADLINE} -->")
    return "\n".join(lines) + "\n"


def shipped_before_clause() -> str:
    """``", and for `ippo`, ... the policies ... (now `ippo-v0`, ...)"``: the learned controllers
    whose training seeds chosen on validation shipped after the paper track was published, whose
    paper-track rows are therefore the policies now named ``<name>-v0``
    (:data:`controllers.tuning.WEIGHT_VARIANTS`)."""
    variants = sorted(WEIGHT_VARIANTS)
    learned = ", ".join(f"`{v.removesuffix('-v0')}`" for v in variants)
    now = ", ".join(f"`{v}`" for v in variants)
    return f", and for {learned} the policies shipped before their training seeds chosen on validation (now {now})"


def paper_track(paper: Results | None, path: str = "data/paper.tar.xz") -> list[str]:
    """The paper track's lines: success per controller and task on the paper's protocol
    (``paper``, read from ``path``; None: not published)."""
    if paper is None:
        return [f"**The paper track**: pending, `{path}` is not published.", ""]
    config = paper.config
    slips = ", ".join(config["slips"])
    lines = [
        f"**The paper track**: the paper's protocol on its own maps (each task's two hand-made maps; "
        f"slip {slips}; {config['episodes']} episodes per cell; IPOPT; free compute), on which ORCA's "
        "and DWA's hand-set defaults were chosen. Each row ran with the defaults of the code it was "
        "published from: the hand-set ones (now `NAME-v0`) for a controller whose tuned preset came "
        f"later{shipped_before_clause()} (docs/benchmark.md). Success with 95% intervals."
        + paper_variants_note(config),
        "",
    ]
    tasks, rows = paper_track_rows(paper)
    lines += [
        "| Controller | " + " | ".join(task_label(t) for t in tasks) + " |",
        "|---|" + "---|" * len(tasks),
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return lines + [""]
