"""A run's log header names the tuned preset file each controller's defaults come from, and a
resume across a change of that file is refused (evaluation.run.weights.run_presets,
evaluation.episodes.log_weights.PRESETS_KEY): before, the header kept only the options typed on
the command line, so a run paused, then resumed after `python -m evaluation.tune adopt` (or a pull)
changed a preset, played other defaults under the same row, silently.

The tests point the presets at a copy of controllers/tuned (controllers.tuning.presets.TUNED_DIR);
the committed presets are never edited.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import controllers.tuning.presets as presets
from evaluation import RunSpec, evaluate
from evaluation.episodes.log_weights import PRESETS_KEY, WEIGHTS_KEY
from evaluation.episodes.runlog import LogError, read_log
from evaluation.run import files_digest, run_presets

FILE = "tuned/consensus.json"


@pytest.fixture
def tuned(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A copy of the shipped tuned presets, which the run reads its preset digests from."""
    copy = tmp_path / "tuned"
    shutil.copytree(presets.TUNED_DIR, copy)
    monkeypatch.setattr(presets, "TUNED_DIR", copy)
    return copy


def _spec(*controllers: str) -> RunSpec:
    return RunSpec(
        envs="KoopNav-Formation-v0",
        controllers=list(controllers),
        maps=["map3"],
        slips=["high"],
        episodes=1,
        env_kwargs={"max_episode_steps": 3},
    )


def _header(out: Path) -> dict:
    return json.loads((out / "episodes.jsonl").read_text().splitlines()[0])["config"]


def _retune(path: Path) -> None:
    """Another preset in the same file, as `python -m evaluation.tune adopt` would write it."""
    document = json.loads(path.read_text())
    document["options"]["goal_gain"] = 2 * document["options"]["goal_gain"]
    path.write_text(json.dumps(document, indent=2) + "\n")


def test_a_resume_after_the_preset_file_changed_is_refused_by_name(tuned: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    evaluate(_spec("consensus"), workers=1, out=out, progress=False)
    first = files_digest([tuned / "consensus.json"])
    assert first is not None
    assert _header(out)[PRESETS_KEY] == {"consensus": {FILE: first}}
    assert WEIGHTS_KEY not in _header(out)  # consensus loads no policy
    log = out / "episodes.jsonl"
    before = log.read_bytes()
    _retune(tuned / "consensus.json")
    second = files_digest([tuned / "consensus.json"])
    assert second not in (None, first)
    config = _spec("consensus").resolved().config(1, "process")
    with pytest.raises(LogError) as refused:
        read_log(log, config, repair=False)
    message = str(refused.value)
    assert message.startswith(
        f"{log} cannot be resumed: consensus ({FILE}: logged sha256 {first}, now {second})"
    )
    assert "another tuned preset" in message and "evaluation.forget" in message
    with pytest.raises(LogError, match=f"consensus \\({FILE}: logged sha256 {first}, now {second}\\)"):
        evaluate(_spec("consensus"), workers=1, out=out, resume=True, progress=False)
    assert log.read_bytes() == before  # nothing changed in the log


def test_an_unchanged_preset_resumes(tuned: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    evaluate(_spec("consensus"), workers=1, out=out, progress=False)
    header = _header(out)
    config = _spec("consensus").resolved().config(1, "process")
    done, notes = read_log(out / "episodes.jsonl", config, repair=False)
    assert len(done) == 1
    assert not any("preset" in note for note in notes), notes
    evaluate(_spec("consensus"), workers=1, out=out, resume=True, progress=False)
    assert _header(out) == header


def test_a_v0_variant_records_no_preset_and_resumes_across_a_change(tuned: Path, tmp_path: Path) -> None:
    configs = _spec("consensus-v0", "safe:koopman-nmpc", "consensus-free", "orca").resolved().controllers
    assert configs is not None
    # the -v0 variant runs the hand-set defaults, the hand-set ablation consensus-free and orca no
    # tuned file; a wrapped tuned controller reads its preset
    assert run_presets(configs) == {
        "safe:koopman-nmpc": {"tuned/koopman-nmpc.json": files_digest([tuned / "koopman-nmpc.json"])}
    }
    out = tmp_path / "run"
    evaluate(_spec("consensus-v0"), workers=1, out=out, progress=False)
    assert PRESETS_KEY not in _header(out)
    _retune(tuned / "consensus.json")
    config = _spec("consensus-v0").resolved().config(1, "process")
    done, notes = read_log(out / "episodes.jsonl", config, repair=False)
    assert len(done) == 1 and notes == []


def test_a_log_written_before_the_preset_digests_resumes_unchecked(tuned: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    evaluate(_spec("consensus"), workers=1, out=out, progress=False)
    log = out / "episodes.jsonl"
    header, *records = log.read_text().splitlines(keepends=True)
    old = json.loads(header)
    del old["config"][PRESETS_KEY]
    log.write_text(json.dumps(old) + "\n" + "".join(records))
    _retune(tuned / "consensus.json")  # nothing can tell: it resumes as before, saying so
    config = _spec("consensus").resolved().config(1, "process")
    done, notes = read_log(log, config, repair=False)
    assert len(done) == 1
    unchecked = [note for note in notes if "records no tuned preset digests" in note]
    assert len(unchecked) == 1 and "whether consensus run on the tuned presets" in unchecked[0], notes
    assert unchecked[0].startswith(str(log))
    evaluate(_spec("consensus"), workers=1, out=out, resume=True, progress=False)
    assert PRESETS_KEY not in _header(out)  # a digest would claim the unchecked episodes' preset
