"""The refusal of a resume on other weights, and the note of a log written before the digests,
name the log they are about (evaluation.episodes.runlog.read_log hands its path to
evaluation.episodes.log_weights): a sweep has one log per level, and a message without the path
does not say which one to fix."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from evaluation import RunSpec, evaluate
from evaluation.episodes.log_weights import WEIGHTS_KEY
from evaluation.episodes.runlog import LogError, read_log

from helpers.extras import needs_extra

pytestmark = needs_extra("stable_baselines3")  # rl-ppo's episodes need stable-baselines3

SHIPPED = Path(__file__).resolve().parents[1] / "baselines" / "policies"


def _spec(controller: str) -> RunSpec:
    return RunSpec(
        envs="KoopNav-Formation-v0",
        controllers=[controller],
        maps=["map3"],
        slips=["high"],
        episodes=1,
        env_kwargs={"max_episode_steps": 3},
    )


def _policy(tmp_path: Path, source: str) -> Path:
    root = tmp_path / "policy"
    shutil.rmtree(root, ignore_errors=True)
    shutil.copytree(SHIPPED / source / "formation", root / "formation")
    return root


def test_the_refusal_and_the_note_name_the_log(tmp_path: Path) -> None:
    root = _policy(tmp_path, "set")
    mine = f"rl-ppo-set:policy_root={root},label=mine"
    out = tmp_path / "run"
    evaluate(_spec(mine), workers=1, out=out, progress=False)
    log = out / "episodes.jsonl"
    _policy(tmp_path, "set_realistic")  # other weights in the same folder
    config = _spec(mine).resolved().config(1, "process")
    with pytest.raises(LogError) as refused:
        read_log(log, config, repair=False)
    assert str(refused.value).startswith(f"{log} cannot be resumed: mine (formation: logged sha256 ")
    # the same log as written before the digests: resumed unchecked, and the note names it
    header, *records = log.read_text().splitlines(keepends=True)
    old = json.loads(header)
    del old["config"][WEIGHTS_KEY]
    log.write_text(json.dumps(old) + "\n" + "".join(records))
    _, notes = read_log(log, config, repair=False)
    assert [n for n in notes if "written before run logs recorded" in n] == [
        f"{log} was written before run logs recorded the learned controllers' weights: whether mine "
        "play the weights of its logged episodes cannot be checked (its header stays without digests)"
    ]
