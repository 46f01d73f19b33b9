"""A run's log header names the weights each learned controller plays (evaluation/run/weights.py):
a resume whose controller would load other weights than its logged episodes did is refused by
name (before, a policy shipped while a run was paused was played for the rest of the run under
the same row); a log written before the digests were recorded still resumes, unchecked."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from evaluation import RunSpec, evaluate
from evaluation.episodes.log_weights import WEIGHTS_KEY
from evaluation.episodes.runlog import LogError, forget_controllers, read_log
from evaluation.reports.published import results_from_log
from evaluation.run import controller_configs, files_digest, run_weights

from helpers.extras import needs_extra

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "baselines" / "policies"
POLICY_FILES = ("policy.zip", "obs_norm.npz", "metadata.json")


def _policy(tmp_path: Path, source: str = "set") -> Path:
    """A policy root holding a copy of a shipped formation policy (``set``: rl-ppo-set's)."""
    root = tmp_path / "policy"
    shutil.rmtree(root, ignore_errors=True)
    shutil.copytree(SHIPPED / source / "formation", root / "formation")
    return root


def _spec(root: Path, *more: str) -> RunSpec:
    return RunSpec(
        envs="KoopNav-Formation-v0",
        controllers=[f"rl-ppo-set:policy_root={root},label=mine", "consensus", *more],
        maps=["map3"],
        slips=["high"],
        episodes=1,
        env_kwargs={"max_episode_steps": 3},
    )


def _header(out: Path) -> dict:
    return json.loads((out / "episodes.jsonl").read_text().splitlines()[0])


def test_every_learned_controller_has_the_digest_of_the_files_it_loads() -> None:
    configs = controller_configs(
        ["rl-ppo", "rl-ppo-set", "rl-ppo-set-v0", "rl-ppo-set-realistic", "rl-ppo-set-movers"]
        + ["rl-ppo-set-physics", "ippo", "ippo-v0"]
        + ["consensus", "orca", "safe:rl-ppo-set"]
    )
    weights = run_weights(configs, ["KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"])
    folders = {
        "rl-ppo": SHIPPED,
        "rl-ppo-set": SHIPPED / "set",
        "rl-ppo-set-v0": SHIPPED / "set_v0",
        "rl-ppo-set-realistic": SHIPPED / "set_realistic",
        "rl-ppo-set-movers": SHIPPED / "set_movers",
        "rl-ppo-set-physics": SHIPPED / "set_physics",
        "safe:rl-ppo-set": SHIPPED / "set",
    }
    assert sorted(weights) == sorted([*folders, "ippo", "ippo-v0"])  # the model-based ones load no policy
    for label, folder in folders.items():
        for task in ("target_reaching", "formation"):
            assert weights[label][task] == files_digest([folder / task / name for name in POLICY_FILES])
    for label, folder in (("ippo", "ippo"), ("ippo-v0", "ippo_v0")):
        for task in ("target_reaching", "formation"):
            ippo = SHIPPED / folder / task
            assert weights[label][task] == files_digest([ippo / "policy.npz", ippo / "metadata.json"])
    assert len(set(weights["rl-ppo-set"].values()) | set(weights["rl-ppo"].values())) == 4


@needs_extra("stable_baselines3")  # rl-ppo's episodes
def test_a_resume_on_other_weights_is_refused_by_name(tmp_path) -> None:
    root = _policy(tmp_path)
    out = tmp_path / "run"
    evaluate(_spec(root), workers=1, out=out, progress=False)
    logged = _header(out)["config"][WEIGHTS_KEY]
    assert list(logged) == ["mine"]  # consensus loads no policy
    first = logged["mine"]["formation"]
    assert first == files_digest([root / "formation" / name for name in POLICY_FILES])
    # the same weights: the resume goes on
    evaluate(_spec(root), workers=1, out=out, resume=True, progress=False)
    # another policy in the same folder (a seed shipped while the run was paused)
    root = _policy(tmp_path, "set_realistic")
    second = files_digest([root / "formation" / name for name in POLICY_FILES])
    assert second != first
    with pytest.raises(LogError) as refused:
        evaluate(_spec(root), workers=1, out=out, resume=True, progress=False)
    message = str(refused.value)
    assert f"mine (formation: logged sha256 {first}, now {second}) would play other weights" in message
    assert "python -m evaluation.forget LABEL -- OUT" in message and "Nothing was changed" in message
    assert _header(out)["config"][WEIGHTS_KEY]["mine"]["formation"] == first
    # its episodes dropped, it runs them all on the new weights, and the header says so
    assert forget_controllers(out, ["mine"]) == 1
    results = evaluate(_spec(root), workers=1, out=out, resume=True, progress=False)
    assert [r["controller"] for r in results.records] == ["mine", "consensus"]
    assert _header(out)["config"][WEIGHTS_KEY]["mine"]["formation"] == second


@needs_extra("stable_baselines3")  # rl-ppo's episodes
def test_a_log_without_digests_resumes_unchecked_and_keeps_none(tmp_path) -> None:
    """A log written before the digests were recorded (the bench's free-compute run) resumes, with a
    note; its header stays as it was, and a controller added to it does not give it digests."""
    root = _policy(tmp_path)
    out = tmp_path / "run"
    evaluate(_spec(root), workers=1, out=out, progress=False)
    log = out / "episodes.jsonl"
    header, *records = log.read_text().splitlines(keepends=True)
    old = json.loads(header)
    del old["config"][WEIGHTS_KEY]
    old_header = json.dumps(old) + "\n"
    log.write_text(old_header + "".join(records))
    root = _policy(tmp_path, "set_realistic")  # other weights: nothing can tell
    config = _spec(root).resolved().config(1, "process")
    done, notes = read_log(log, config)
    assert len(done) == 2
    assert any("written before run logs recorded the learned controllers' weights" in n for n in notes)
    assert any("whether mine play the weights of its logged episodes cannot be checked" in n for n in notes)
    assert log.read_text().splitlines(keepends=True)[0] == old_header
    # a controller added: the header names it, still without digests
    evaluate(_spec(root, "rl-ppo-set"), workers=1, out=out, resume=True, progress=False)
    new = _header(out)
    assert WEIGHTS_KEY not in new["config"]
    assert [c["label"] for c in new["config"]["controller_configs"]] == ["mine", "consensus", "rl-ppo-set"]
    # and the page readers read it as before
    assert len(results_from_log(log).records) == 3
