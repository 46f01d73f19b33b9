"""``--report``: the expected-best curves of several studies and the table of what tuning gained."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from controllers.tuning import STUDY_FILE
from evaluation.tune.log import read_study
from evaluation.tune.scoring import expected_max_curve


@dataclass(frozen=True)
class StudySummary:
    """One study as the report shows it."""

    controller: str
    task: str
    budget: dict[str, Any]
    scores: list[float]

    @property
    def defaults_score(self) -> float:
        return self.scores[0]

    @property
    def best_score(self) -> float:
        return max(self.scores)


def load_summary(folder: str | os.PathLike[str]) -> StudySummary:
    """The summary of the study logged in ``folder`` (read only: a torn line is left in place)."""
    header, trials, _ = read_study(Path(folder) / STUDY_FILE, repair=False)
    if not trials:
        raise ValueError(f"{folder}: the study has no finished trial yet")
    return StudySummary(header["controller"], header["task"], header["budget"], [t.score for t in trials])


def report_markdown(studies: Sequence[StudySummary]) -> str:
    """The table of ``--report``: controller, budget, the defaults' score, the best, the gain."""
    rows = [
        "| controller | task | budget (configurations x layouts x episodes) | defaults' score | best score | gain |",
        "|---|---|---|---|---|---|",
    ]
    for s in studies:
        b = s.budget
        budget = (
            f"{len(s.scores)} of {b['configurations']} x {b['layouts_per_task']} x {b['episodes_per_layout']}"
        )
        rows.append(
            f"| `{s.controller}` | {s.task} | {budget} | {s.defaults_score:.3f} | {s.best_score:.3f} "
            f"| {s.best_score - s.defaults_score:+.3f} |"
        )
    return "\n".join(rows) + "\n"


def report_figure(studies: Sequence[StudySummary], path: str | os.PathLike[str]) -> None:
    """The expected best validation score against the configurations tried, one curve per study."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for s in studies:
        curve = expected_max_curve(s.scores)
        ax.plot(range(1, len(curve) + 1), curve, marker="o", markersize=3, label=f"{s.controller} ({s.task})")
    ax.set_xlabel("configurations tried (n)")
    ax.set_ylabel("expected best validation score")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Expected best of n configurations (Dodge et al. 2019)")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
