"""The crowd fault section's last column, success without the unavoidable collisions: success
among the episodes that no collision not at the robot's fault ended (issue 60: "success ... with
and without the collisions the robot could not avoid"), on hand-made records."""

from __future__ import annotations

from typing import Any

from evaluation.reports.sections import TableBlock
from evaluation.reports.sections.fault_split import _row, fault_section
from evaluation.stats.statistics import wilson_interval


def _record(key: int, success: bool, collision: str | None = None, at_fault: bool = False) -> dict[str, Any]:
    return {
        "key": f"k{key}",
        "controller": "orca",
        "success": success,
        "collision": collision,
        "collision_at_fault": at_fault,
        "success_excusing_unavoidable": success,
    }


def test_success_without_the_unavoidable_leaves_the_episodes_a_mover_ended_out() -> None:
    # 10 episodes: 4 successes, 3 ended by a mover (not the robot's fault), 2 at the robot's fault
    records = [_record(i, True) for i in range(4)]
    records += [_record(4 + i, False, "mover", at_fault=False) for i in range(3)]
    records += [_record(7 + i, False, "mover", at_fault=True) for i in range(2)]
    records += [_record(9, False)]
    row = _row("orca", 8, records)
    assert (row.episodes, row.successes, row.not_at_fault, row.at_fault, row.unhit) == (10, 4, 3, 2, 7)
    assert row.unhit_ci == wilson_interval(4, 7)
    section = fault_section([row], "movers.count", "bash data/publish.sh crowd_faults")
    block = section.blocks[-1]
    assert isinstance(block, TableBlock)
    header, cells = block.table[0], block.table[1][0]
    assert header[-1] == "Success without the unavoidable [%]"
    assert cells[-1].split(" [")[0] == f"{100 * 4 / 7:.0f}"  # 57, against 40 with them
    assert cells[3].split(" [")[0] == "40"


def test_success_without_the_unavoidable_is_na_when_a_mover_ended_every_episode() -> None:
    row = _row("orca", 16, [_record(i, False, "mover", at_fault=False) for i in range(3)])
    assert row.unhit == 0 and row.unhit_ci is None
    block = fault_section([row], "movers.count", "cmd").blocks[-1]
    assert isinstance(block, TableBlock) and block.table[1][0][-1] == "n/a"
