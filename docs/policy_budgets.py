"""The training budget a shipped policy's metadata records, as the result pages state it
(docs/make_results_md.py's note on unequal data)."""

from __future__ import annotations

import json
from pathlib import Path

#: the shipped policies' folders
POLICIES = Path(__file__).resolve().parents[1] / "baselines" / "policies"


def robot_steps(folder: str) -> str:
    """The budget of the policies in ``baselines/policies/FOLDER/<task>`` in millions of
    robot-steps (SB3's set policies record robot-steps, ``timesteps``; BenchMARL's frames count
    the whole team): ``18 M per task``, or ``24 M and 16 M`` (target reaching, formation)."""
    budgets = []
    for task in ("target_reaching", "formation"):
        meta = json.loads((POLICIES / folder / task / "metadata.json").read_text(encoding="utf-8"))
        budget = meta["timesteps"] if "timesteps" in meta else meta["frames"] * meta["n_robots"]
        budgets.append(f"{budget / 1e6:.0f} M")
    return f"{budgets[0]} per task" if len(set(budgets)) == 1 else " and ".join(budgets)
