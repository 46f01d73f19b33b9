"""How far a run is: the episodes its header plans and how many of them it logged.

A run may be published while it runs (the sim-to-sim levels, the test suite's two benchmark modes):
what is not complete is pending, and left out of every table and test until it is.
:func:`planned_episodes` reads what a run plans per (task, controller) from its header, and
:class:`Progress` holds one count against its plan. The sim-to-sim page counts per controller over
every task (:func:`evaluation.stats.transfer.run_progress`), the benchmark page per (task,
controller) (:func:`evaluation.reports.bench.load_mode`); both read this one definition.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from evaluation.run.plan import RANDOM_MAP
from koopman_envs import SUITE_PREFIX

__all__ = ["Progress", "planned_episodes"]


@dataclass(frozen=True)
class Progress:
    """How far one controller of one run is: ``done`` of ``planned`` episodes (of one task, or
    summed over every task: the caller's choice, the same for both counts)."""

    done: int
    planned: int

    @property
    def complete(self) -> bool:
        """Whether every planned episode is logged (``done >= planned``): only then may a table or
        a test read the controller's records."""
        return self.done >= self.planned


def planned_episodes(config: Mapping[str, Any], env_id: str) -> int:
    """The episodes a run plans per controller of task ``env_id``, from its header: per map, a
    suite's selected layouts x episodes per layout (the whole split without a selection), the
    ``random`` row's ``random_maps`` trials, any other map's ``episodes``; times the slips (one
    when the header names none)."""
    suite = config.get("suite")
    per_map = []
    for name in (config.get("maps") or {}).get(env_id, []):
        if suite and env_id in suite.get("tasks", {}) and str(name).startswith(SUITE_PREFIX):
            selected = suite.get("layouts")
            layouts = suite["tasks"][env_id]["size"] if selected is None else selected[1] - selected[0]
            per_map.append(int(layouts) * int(suite["episodes_per_layout"]))
        elif name == RANDOM_MAP and config.get("random_maps"):
            per_map.append(int(config["random_maps"]))
        else:
            per_map.append(int(config["episodes"]))
    return sum(per_map) * len(config.get("slips") or [None])
