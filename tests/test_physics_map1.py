"""docs/physics.md's "Map 1: every controller on the physics plant" (issue 62's third target): its
tables and counts are rebuilt from the committed episode records, so a cell edited by hand, a
controller registered since the run, or a record left out fails here.

Refresh after a new run of the section's two commands (``--out`` A on the physics plant, B on the
kinematic one)::

    python tests/test_physics_map1.py reduce A B   # writes data/physics_map1/{mujoco,kinematic}.jsonl
    python tests/test_physics_map1.py probes C D   # the nominal-nmpc probes' runs (physics plant)
    python tests/test_physics_map1.py              # prints the tables and counts for the page
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: the evaluator's records (``episodes.jsonl``) of the section's two runs, reduced to :data:`FIELDS`
DATA = ROOT / "data" / "physics_map1"
PLANTS = ("mujoco", "kinematic")
FIELDS = ("controller", "plant", "seed", "success", "collision", "steps", "final_distance")
SEEDS = (0, 1, 2)
SECTION = "## Map 1: every controller on the physics plant"
#: the file of the runs that took ``nominal-nmpc``'s tuned preset apart on the physics plant
PROBES = "nominal_nmpc_probes"


def reduce_run(sources: list[Path], target: Path) -> None:
    """Write the evaluator's ``episodes.jsonl`` files ``sources`` as the reduced records at ``target``.

    Final distances are kept to 0.1 mm (the page shows whole centimetres). An episode that raised
    has no outcome to show, so it is refused by key rather than left out of a count.
    """
    records = [json.loads(line) for path in sources for line in path.read_text(encoding="utf-8").splitlines()]
    episodes = [r for r in records if "key" in r]  # a run's first line is its configuration
    failed = [r["key"] for r in episodes if r.get("status") != "ok"]
    if failed:
        raise ValueError(
            f"episodes that did not finish ok in {[str(p) for p in sources]}: {failed}; rerun them with --resume"
        )
    kept = [
        {
            "controller": r["controller"],
            "plant": json.loads(r["env_kwargs"])["plant"],
            "seed": r["seed"],
            "success": r["success"],
            "collision": r["collision"],
            "steps": r["steps"],
            "final_distance": [round(d, 4) for d in r["final_distance"]],
        }
        for r in sorted(episodes, key=lambda r: (r["controller"], r["seed"]))
    ]
    target.write_text("".join(json.dumps(r) + "\n" for r in kept), encoding="utf-8")


def load(names: tuple[str, ...] = PLANTS) -> dict[str, dict[str, list[dict]]]:
    """``{plant: {controller: records sorted by seed}}`` of the committed files ``names``."""
    out: dict[str, dict[str, list[dict]]] = {}
    for name in names:
        for line in (DATA / f"{name}.jsonl").read_text(encoding="utf-8").splitlines():
            record = json.loads(line)
            out.setdefault(record["plant"], {}).setdefault(record["controller"], []).append(record)
    for cells in out.values():
        for cell in cells.values():
            cell.sort(key=lambda r: r["seed"])
    return out


def ending(record: dict) -> str:
    """How an episode ended: ``reached``, a collision's kind, or ``time limit``."""
    return "reached" if record["success"] else record["collision"] or "time limit"


def outcome(cell: list[dict]) -> str:
    """Successes out of the seeds, and how the others ended (each kind once, in seed order)."""
    wins = sum(r["success"] for r in cell)
    others = list(dict.fromkeys(ending(r) for r in cell if not r["success"]))
    return f"{wins}/{len(cell)}" + (f" ({', '.join(others)})" if others else "")


def table(runs: dict[str, dict[str, list[dict]]]) -> list[str]:
    """The section's table: one row per controller, successes on each plant."""
    out = ["| controller | physics plant (carpet) | kinematic plant |", "|---|---|---|"]
    for name in sorted(runs["mujoco"]):
        out.append(f"| {name} | {outcome(runs['mujoco'][name])} | {outcome(runs['kinematic'][name])} |")
    return out


def episode(record: dict) -> str:
    """One episode: how and after how many control periods it ended, and each robot's final
    distance to its target [cm]."""
    distances = ", ".join(f"{d:.0f}" for d in np.asarray(record["final_distance"]) * 100.0)
    return f"{ending(record)}, {record['steps']}: {distances}"


def failures(runs: dict[str, dict[str, list[dict]]]) -> list[str]:
    """Every episode of the controllers that miss a seed on either plant."""
    out = ["| controller | plant | seed 0 | seed 1 | seed 2 |", "|---|---|---|---|---|"]
    for name in sorted(runs["mujoco"]):
        if all(r["success"] for plant in PLANTS for r in runs[plant][name]):
            continue
        for plant in PLANTS:
            out.append(f"| {name} | {plant} | " + " | ".join(episode(r) for r in runs[plant][name]) + " |")
    return out


def probes(runs: dict[str, dict[str, list[dict]]]) -> list[str]:
    """The table of :data:`PROBES`: each configuration's successes and episodes."""
    out = ["| configuration | successes | seed 0 | seed 1 | seed 2 |", "|---|---|---|---|---|"]
    for name, cell in runs["mujoco"].items():
        out.append(f"| `{name}` | {outcome(cell)} | " + " | ".join(episode(r) for r in cell) + " |")
    return out


def counts(runs: dict[str, dict[str, list[dict]]]) -> list[str]:
    """The section's counts, as its prose words them."""
    physics = runs["mujoco"].values()
    every = sum(all(r["success"] for r in cell) for cell in physics)
    two = sum(sum(r["success"] for r in cell) >= 2 for cell in physics)
    return [
        f"{every} of the {len(runs['mujoco'])} complete Map 1 on the physics plant in every seed",
        f"{two} in at least 2 of 3",
    ]


def _section() -> str:
    page = (ROOT / "docs" / "physics.md").read_text(encoding="utf-8")
    assert page.count(SECTION) == 1, SECTION
    return page.split(SECTION, 1)[1].split("\n## ", 1)[0]


def test_the_data_are_every_registered_controller_on_both_plants_in_every_seed() -> None:
    import controllers
    from controllers.tuning import WEIGHT_VARIANTS

    runs = load()
    assert set(runs) == set(PLANTS)
    for plant, cells in runs.items():
        # recorded before rl-ppo-set-v0 was registered: its rl-ppo-set rows are those policies
        assert set(cells) == set(controllers.available()) - WEIGHT_VARIANTS, plant
        for name, cell in cells.items():
            assert all(set(r) == set(FIELDS) for r in cell), (plant, name)
            assert tuple(r["seed"] for r in cell) == SEEDS, (plant, name)


def test_the_section_s_tables_and_counts_are_the_committed_episodes() -> None:
    section, runs = _section(), load()
    for block in (table(runs), failures(runs), probes(load((PROBES,)))):
        text = "\n".join(block)
        assert f"\n\n{text}\n\n" in section, text  # whole: no row added or dropped by hand
    for phrase in counts(runs):
        assert phrase in section, phrase


if __name__ == "__main__":
    if sys.argv[1:2] == ["reduce"]:
        for plant, run in zip(PLANTS, sys.argv[2:4], strict=True):
            reduce_run([Path(run) / "episodes.jsonl"], DATA / f"{plant}.jsonl")
    elif sys.argv[1:2] == ["probes"]:
        reduce_run([Path(run) / "episodes.jsonl" for run in sys.argv[2:]], DATA / f"{PROBES}.jsonl")
    runs = load()
    for block in (table(runs), failures(runs), counts(runs), probes(load((PROBES,)))):
        print("\n".join(block), end="\n\n")
