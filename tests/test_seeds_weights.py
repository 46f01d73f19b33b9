"""A seeds publication's page reads each seed's validation record from its seed folder; a seed
retrained (or replaced) after the run would stand there beside the success of the weights the
run played. The run's header records those weights (evaluation/run/weights.py): the reader now
refuses a seed folder whose policy files are not the logged ones, naming both digests. A log
written before the digests were recorded (the committed validation fixture) is not checked."""

from __future__ import annotations

import json
import shutil
import tarfile
from pathlib import Path

import pytest

from evaluation.episodes.log_weights import WEIGHTS_KEY
from evaluation.experiments.seeds import TRAINING_ROOT
from evaluation.experiments.seeds_published import read_publication
from evaluation.run import files_digest

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "data" / "seeds_validation_layouts0-2.tar.xz"
POLICY_FILES = ("policy.zip", "obs_norm.npz", "metadata.json")
TASK = "target_reaching"


def _digest(seed_folder: Path) -> str | None:
    return files_digest([seed_folder / TASK / name for name in POLICY_FILES])


def _publication(tmp_path: Path, training: Path) -> Path:
    """The fixture's run with the header the current code writes: each seed's digest."""
    with tarfile.open(FIXTURE) as tar:
        tar.extractall(tmp_path / "unpacked", filter="data")
    log = tmp_path / "unpacked" / "seeds" / TASK / "episodes.jsonl"
    header, rest = log.read_text(encoding="utf-8").split("\n", 1)
    doc = json.loads(header)
    doc["config"][WEIGHTS_KEY] = {
        f"rl-ppo-set@seed{k}": {TASK: _digest(training / "rl-ppo-set" / TASK / f"seed{k}")} for k in range(3)
    }
    log.write_text(json.dumps(doc) + "\n" + rest, encoding="utf-8")
    return log.parent.parent


def test_a_seed_retrained_after_the_run_is_refused_by_name(tmp_path) -> None:
    training = tmp_path / "training"
    shutil.copytree(ROOT / TRAINING_ROOT / "rl-ppo-set" / TASK, training / "rl-ppo-set" / TASK)
    run = _publication(tmp_path, training)
    published = read_publication(run, training, n_boot=50)  # the weights played: read as before
    assert [r.seed for r in published.summaries[0]["runs"]] == [0, 1, 2]
    seed1 = training / "rl-ppo-set" / TASK / "seed1"
    logged = _digest(seed1)
    shutil.copy(training / "rl-ppo-set" / TASK / "seed2" / TASK / "policy.zip", seed1 / TASK / "policy.zip")
    now = _digest(seed1)
    assert now != logged
    with pytest.raises(
        ValueError, match=rf"rl-ppo-set@seed1 played policy files of sha256 {logged}"
    ) as refused:
        read_publication(run, training, n_boot=50)
    assert f"now holds sha256 {now}" in str(refused.value)
    assert "python -m evaluation.forget rl-ppo-set@seed1" in str(refused.value)


def test_a_log_without_digests_is_read_unchecked(tmp_path) -> None:
    with tarfile.open(FIXTURE) as tar:
        tar.extractall(tmp_path, filter="data")
    published = read_publication(tmp_path / "seeds", ROOT / TRAINING_ROOT, n_boot=50)
    assert [r.seed for r in published.summaries[0]["runs"]] == [0, 1, 2]
