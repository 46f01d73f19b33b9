"""``--ship`` (issue 60): the chosen seed's policy goes into the controller's shipped folder, the
former policies the first time into ``<folder>_v0`` (played by ``<policy>-v0``, never written
again), and nothing ships while a seed the driver plans is unfinished, or for a policy without a
``<policy>-v0``: refused by name, before anything moves. Tiny fake seed folders, no training."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import controllers
from controllers.registry import controller_class
from evaluation.exit_codes import BAD_INPUT_EXIT
from evaluation.experiments import seeds
from evaluation.experiments.seeds import FINISHED_FILE, finished_seeds, ship
from evaluation.experiments.seeds_shipping import check_shippable, shipped_folder

ROOT = Path(__file__).resolve().parents[1]
TASK = "formation"
PLAN = [("rl-ppo-set", TASK, k) for k in range(3)]


def _seed(root: Path, seed: int, *, finished: bool = True, policy: str = "rl-ppo-set") -> None:
    """A seed folder: its kept policy's files (their bytes name the seed) and validation record."""
    folder = root / policy / TASK / f"seed{seed}"
    (folder / TASK).mkdir(parents=True)
    for name in ("policy.zip", "obs_norm.npz", "metadata.json"):
        (folder / TASK / name).write_text(f"{name} of seed {seed}")
    record = {"step": 1000, "success_rate": 0.5 + seed / 10, "mean_final_distance": 1.0}
    (folder / "selection.json").write_text(json.dumps({"chosen": record}))
    if finished:
        (folder / FINISHED_FILE).write_text("{}")


def _former(policies: Path) -> None:
    """The policies shipped before the seeds, both tasks (the shipped task's with a file its
    seeds do not have)."""
    for task in ("target_reaching", TASK):
        (policies / "set" / task).mkdir(parents=True)
        (policies / "set" / task / "policy.zip").write_text(f"former {task}")
    (policies / "set" / TASK / "vecnormalize.pkl").write_text("former statistics")


def test_ippo_v0_plays_the_former_folder() -> None:
    cls = controller_class("ippo-v0")
    assert cls is not None and cls.shipped == "ippo_v0"
    assert issubclass(cls, controller_class("ippo"))  # type: ignore[arg-type]
    assert shipped_folder("ippo") == ROOT / "baselines" / "policies" / "ippo"
    for task in ("target_reaching", TASK):
        assert (ROOT / "baselines" / "policies" / "ippo_v0" / task / "policy.npz").is_file()
    assert "ippo-v0" in controllers.available() and "ippo-v0" not in controllers.available(variants=False)
    check_shippable("ippo", TASK, ROOT / "nowhere", [])  # nothing planned, a -v0 to keep the former


def test_rl_ppo_set_v0_plays_the_former_folder() -> None:
    cls = controller_class("rl-ppo-set-v0")
    assert cls is not None and cls.shipped == "set_v0"
    assert issubclass(cls, controller_class("rl-ppo-set"))  # type: ignore[arg-type]
    assert shipped_folder("rl-ppo-set") == ROOT / "baselines" / "policies" / "set"
    assert (ROOT / "baselines" / "policies" / "set_v0" / TASK / "policy.zip").is_file()
    # a comparison variant: runs when named, left out of default runs
    assert "rl-ppo-set-v0" in controllers.available()
    assert "rl-ppo-set-v0" not in controllers.available(variants=False)


def test_ship_moves_the_former_policies_once_and_copies_the_chosen_seed(tmp_path: Path) -> None:
    training, policies = tmp_path / "training", tmp_path / "policies"
    for k in range(3):
        _seed(training, k)
    _former(policies)
    runs = finished_seeds(training, "rl-ppo-set", TASK)
    target = ship(runs[2], policies=policies, plan=PLAN)
    assert target == policies / "set" / TASK
    assert (target / "policy.zip").read_text() == "policy.zip of seed 2"
    # the seed's files only: a former file it has not would be read with the seed's weights
    assert sorted(p.name for p in target.iterdir()) == ["metadata.json", "obs_norm.npz", "policy.zip"]
    assert (policies / "set_v0" / TASK / "vecnormalize.pkl").is_file()
    # every task's former policies kept in set_v0; the task not shipped yet keeps its former
    # policy under the controller's own name (a copy, not a move: it is never left without one)
    assert (policies / "set_v0" / TASK / "policy.zip").read_text() == f"former {TASK}"
    assert (policies / "set_v0" / "target_reaching" / "policy.zip").read_text() == "former target_reaching"
    assert (policies / "set" / "target_reaching" / "policy.zip").read_text() == "former target_reaching"
    assert sorted(p.name for p in (policies / "set").iterdir()) == ["formation", "target_reaching"]
    assert not list(policies.glob("*.partial"))
    # a second ship never writes to the existing set_v0
    ship(runs[0], policies=policies, plan=PLAN)
    assert (policies / "set" / TASK / "policy.zip").read_text() == "policy.zip of seed 0"
    assert (policies / "set_v0" / TASK / "policy.zip").read_text() == f"former {TASK}"
    assert not (policies / "set_v0" / "set").exists()


def test_ship_refuses_while_a_planned_seed_is_unfinished_naming_it(tmp_path: Path) -> None:
    training, policies = tmp_path / "training", tmp_path / "policies"
    _seed(training, 0)
    _seed(training, 2, finished=False)  # training: no finished.json
    _former(policies)
    (run,) = finished_seeds(training, "rl-ppo-set", TASK)
    with pytest.raises(ValueError, match=r"rl-ppo-set formation: planned seeds \[1, 2\] of \[0, 1, 2\]"):
        ship(run, policies=policies, plan=PLAN)
    # refused before anything moved or was written
    assert sorted(p.name for p in policies.iterdir()) == ["set"]
    assert (policies / "set" / TASK / "policy.zip").read_text() == f"former {TASK}"
    # seeds the plan does not name are not waited for; the plan's own are
    check_shippable("rl-ppo-set", TASK, run.folder.parent, [("rl-ppo-set", TASK, 0), ("rl-ppo-set", "x", 5)])


def test_ship_refuses_a_policy_without_a_v0_controller_by_name(tmp_path: Path, monkeypatch) -> None:
    training = tmp_path / "training"
    _seed(training, 0, policy="ippo")
    (run,) = finished_seeds(training, "ippo", TASK)
    # ippo-v0 plays ippo_v0/; were it to play another folder, ippo's former policies would be
    # left reachable by no name
    monkeypatch.setattr(controller_class("ippo-v0"), "shipped", "elsewhere")
    refused = r"no registered controller 'ippo-v0' plays ippo_v0/ \(its shipped folder: 'elsewhere'\)"
    with pytest.raises(ValueError, match=refused):
        ship(run, policies=tmp_path / "policies", plan=[("ippo", TASK, 0)])
    assert not (tmp_path / "policies").exists()
    with pytest.raises(ValueError, match=r"rl-ppo has no shipped folder of its own"):
        shipped_folder("rl-ppo")


def test_the_command_refuses_ship_before_any_episode(tmp_path: Path, monkeypatch, capsys) -> None:
    """``--ship`` with an unfinished planned seed exits 2 naming it, without evaluating."""
    training = tmp_path / "training"
    _seed(training, 0)

    def no_episodes(*args, **kwargs):
        raise AssertionError("evaluated before refusing --ship")

    monkeypatch.setattr(seeds, "evaluate_seeds", no_episodes)
    argv = ["--root", str(training), "--policies", "rl-ppo-set", "--tasks", TASK, "--ship"]
    assert seeds.main([*argv, "--out", str(tmp_path / "out")]) == BAD_INPUT_EXIT
    assert "planned seeds [1, 2] of [0, 1, 2] are not finished" in capsys.readouterr().err
