"""A learned controller added to a run logged without digests because none of its controllers
loads a policy (a model-based run, as the current code writes it) takes its digests from then
on: before, such a log was taken for one written before digests were recorded, the note said
so, and the added controller's weights were never checked (a policy swapped while the run was
paused was played under the same row, unrefused)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from evaluation import RunSpec, evaluate
from evaluation.episodes.log_weights import WEIGHTS_KEY
from evaluation.episodes.runlog import LogError, read_log
from evaluation.run import files_digest

from helpers.extras import needs_extra

pytestmark = needs_extra("stable_baselines3")  # rl-ppo's episodes need stable-baselines3

SHIPPED = Path(__file__).resolve().parents[1] / "baselines" / "policies"
POLICY_FILES = ("policy.zip", "obs_norm.npz", "metadata.json")


def _policy(tmp_path: Path, source: str) -> Path:
    root = tmp_path / "policy"
    shutil.rmtree(root, ignore_errors=True)
    shutil.copytree(SHIPPED / source / "formation", root / "formation")
    return root


def _spec(*controllers: str) -> RunSpec:
    return RunSpec(
        envs="KoopNav-Formation-v0",
        controllers=list(controllers),
        maps=["map3"],
        slips=["high"],
        episodes=1,
        env_kwargs={"max_episode_steps": 3},
    )


def _config(out: Path) -> dict:
    return json.loads((out / "episodes.jsonl").read_text().splitlines()[0])["config"]


def test_a_learned_controller_added_to_a_model_based_run_is_checked_from_then_on(tmp_path) -> None:
    out = tmp_path / "run"
    evaluate(_spec("consensus"), workers=1, out=out, progress=False)
    assert WEIGHTS_KEY not in _config(out)  # no controller loads a policy: nothing to record
    root = _policy(tmp_path, "set")
    learned = f"rl-ppo-set:policy_root={root},label=mine"
    config = _spec("consensus", learned).resolved().config(1, "process")
    done, notes = read_log(out / "episodes.jsonl", config, repair=False)
    assert len(done) == 1
    assert not any("written before run logs recorded" in note for note in notes), notes
    evaluate(_spec("consensus", learned), workers=1, out=out, resume=True, progress=False)
    first = files_digest([root / "formation" / name for name in POLICY_FILES])
    assert _config(out)[WEIGHTS_KEY] == {"mine": {"formation": first}}
    # its episodes logged, a policy swapped in its folder is refused by name
    root = _policy(tmp_path, "set_realistic")
    second = files_digest([root / "formation" / name for name in POLICY_FILES])
    with pytest.raises(LogError, match=f"mine \\(formation: logged sha256 {first}, now {second}\\)"):
        evaluate(_spec("consensus", learned), workers=1, out=out, resume=True, progress=False)


def test_a_log_without_digests_names_only_its_played_learned_controllers(tmp_path) -> None:
    """An old log whose learned controller played stays unchecked (and says so, naming it alone,
    not the controller this resume adds)."""
    root = _policy(tmp_path, "set")
    out = tmp_path / "run"
    mine = f"rl-ppo-set:policy_root={root},label=mine"
    evaluate(_spec(mine), workers=1, out=out, progress=False)
    log = out / "episodes.jsonl"
    header, *records = log.read_text().splitlines(keepends=True)
    old = json.loads(header)
    del old["config"][WEIGHTS_KEY]
    log.write_text(json.dumps(old) + "\n" + "".join(records))
    added = f"rl-ppo-set:policy_root={root},label=added"
    config = _spec(mine, added).resolved().config(1, "process")
    _, notes = read_log(log, config, repair=False)
    unchecked = [note for note in notes if "written before run logs recorded" in note]
    assert len(unchecked) == 1 and "whether mine play" in unchecked[0], notes
    evaluate(_spec(mine, added), workers=1, out=out, resume=True, progress=False)
    assert WEIGHTS_KEY not in _config(out)  # a digest would claim mine's unchecked episodes
