"""An ippo seed that resumes mid-run, bit for bit (issue 60): ``python -m
baselines.marl.benchmarl_train --resume-every N`` writes a resume checkpoint
(:mod:`baselines.marl.benchmarl_resume`) that ``--resume`` refuses by name when it is missing,
another trainer's or another run's, and a tiny IPPO run interrupted after one and resumed ends with
the weights of the run that was never interrupted."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from baselines.marl import benchmarl_resume, benchmarl_train
from baselines.marl.benchmarl_options import build_parser
from baselines.resume import RESUME_FILE, ResumeRefused, check_resume, write_resume

from helpers.training import TINY_IPPO_BATCHES, one_seed_driver, restart_after_a_torn_checkpoint

pytest.importorskip("benchmarl")

#: a tiny IPPO run: 2 envs, 5 iterations of 200 frames, one epoch of 2 minibatches each
TINY = [
    "--task",
    "target_reaching",
    "--algorithm",
    "ippo",
    "--frames",
    "1000",
    *TINY_IPPO_BATCHES,
    "--max-cycles",
    "60",
    "--seed",
    "5",
    "--threads",
    "1",
]


def _identity(*extra: str) -> dict[str, object]:
    return benchmarl_resume.resume_identity(build_parser().parse_args([*TINY, *extra, "--out", "x"]))


# ----------------------------------------------------------------------------- refusals, fast
def test_the_identity_leaves_out_where_and_when_and_keeps_what_is_trained() -> None:
    assert _identity("--resume", "--resume-every", "3") == _identity()
    assert "out" not in _identity() and _identity()["seed"] == 5 and _identity()["threads"] == 1
    assert _identity("--seed", "6") != _identity()


def test_a_resume_without_a_checkpoint_is_refused_by_name_before_any_work(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    assert benchmarl_train.main([*TINY, "--resume", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(out / RESUME_FILE) in err
    assert not out.exists()  # nothing started


def test_a_checkpoint_of_another_trainer_or_run_is_refused_naming_why(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    out.mkdir()
    args = build_parser().parse_args([*TINY, "--out", str(out)])
    write_resume(out / RESUME_FILE, "sb3-ppo", benchmarl_resume.resume_identity(args), {})
    with pytest.raises(ResumeRefused, match="written by a 'sb3-ppo' run; this is a 'benchmarl-ppo' run"):
        benchmarl_resume.read(out, args)
    write_resume(out / RESUME_FILE, benchmarl_resume.KIND, _identity("--seed", "6"), {})
    with pytest.raises(ResumeRefused, match=r"other settings \(seed: logged 6, now 5\)"):
        benchmarl_resume.read(out, args)
    (out / RESUME_FILE).write_bytes((out / RESUME_FILE).read_bytes()[:-3])  # torn
    with pytest.raises(ResumeRefused, match="is torn"):
        benchmarl_resume.read(out, args)
    assert benchmarl_train.main([*TINY, "--resume", "--out", str(out)]) == 2
    assert "is torn" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == [RESUME_FILE]  # nothing started


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--resume-every", "-1"], "--resume-every=-1: allowed >= 0"),
        (["--resume-every", "2", "--curriculum"], "one-stage runs only, not --curriculum or --stages"),
        (["--resume", "--stages", '[{"share": 1}]'], "one-stage runs only, not --curriculum or --stages"),
    ],
)
def test_bad_resume_options_are_refused_by_name(tmp_path, capsys, extra, message) -> None:
    with pytest.raises(SystemExit) as exit_info:
        benchmarl_train.main([*TINY, *extra, "--out", str(tmp_path / "run")])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


# ----------------------------------------------------------------------------- bit for bit
class Interrupted(Exception):
    """The test's stop (a kill between two resume checkpoints)."""


def test_an_interrupted_ippo_run_resumed_ends_bit_for_bit_as_the_uninterrupted_one(
    tmp_path, monkeypatch, capsys
) -> None:
    """Stopped 3 env steps into iteration 4 (after the resume checkpoint at 600 frames), resumed
    from it: the same exported weights as a run never stopped, and the resume recorded. Without
    the optimizers', envs' or generators' state (BenchMARL's own checkpoint) the weights differ
    (measured when this was written: each of the three alone breaks the equality)."""
    from baselines.marl.torchrl_env import KoopNavMultiAgentEnv

    def run(out: Path, *extra: str) -> int:
        return benchmarl_train.main([*TINY, "--no-normalize-observations", *extra, "--out", str(out)])

    assert run(tmp_path / "whole") == 0
    saves: list[int] = []
    steps_after = [0]
    save, step = benchmarl_resume.save, KoopNavMultiAgentEnv._step

    def counting_save(out: Path, args: object, now: object, *rest: object) -> Path:
        saves.append(int(now.total_frames))  # type: ignore[attr-defined]
        return save(out, args, now, *rest)  # type: ignore[arg-type]

    def stopping_step(self: KoopNavMultiAgentEnv, tensordict: object) -> object:
        if saves and saves[-1] == 600:
            steps_after[0] += 1
            if steps_after[0] > 3:
                raise Interrupted
        return step(self, tensordict)  # type: ignore[arg-type]

    stopped = tmp_path / "stopped"
    with monkeypatch.context() as patch:
        patch.setattr(benchmarl_resume, "save", counting_save)
        patch.setattr(KoopNavMultiAgentEnv, "_step", stopping_step)
        with pytest.raises(Interrupted):
            run(stopped, "--resume-every", "3")
    assert saves == [600] and check_resume(stopped / RESUME_FILE)["kind"] == "benchmarl-ppo"
    assert not (stopped / "policy.npz").exists()  # stopped before the end

    capsys.readouterr()
    assert run(stopped, "--resume", "--resume-every", "3") == 0
    assert f"resumed from {stopped / RESUME_FILE} at 600 frames; 400 left" in capsys.readouterr().out
    whole, resumed = np.load(tmp_path / "whole" / "policy.npz"), np.load(stopped / "policy.npz")
    assert sorted(whole.files) == sorted(resumed.files) and "weight_0" in whole.files
    for key in whole.files:
        assert np.array_equal(whole[key], resumed[key]), key
    metadata = json.loads((stopped / "metadata.json").read_text())
    assert metadata["resumed_from_frames"] == [600] and metadata["frames"] == 1000
    assert json.loads((tmp_path / "whole" / "metadata.json").read_text())["resumed_from_frames"] == []
    assert not (stopped / RESUME_FILE).exists()  # finished: nothing left to resume
    # the resumed session logged into the interrupted session's BenchMARL folder
    assert len(list((stopped / "benchmarl").iterdir())) == 1


# ----------------------------------------------------------------------------- the driver
@pytest.mark.slow
def test_the_driver_resumes_an_ippo_seed_with_a_sound_checkpoint_and_restarts_one_without(
    tmp_path, monkeypatch
) -> None:
    """data/training/run.sh on an ippo seed folder left by an interrupted suite run (the trainer
    with the driver's own settings, stopped after its checkpoint at 400 frames): resumed, the
    validation table holding the stopped session's checkpoints too; with a torn checkpoint,
    refused by name, removed and trained from the start."""
    seed_dir = tmp_path / "ippo" / "formation" / "seed0"
    ippo_args = [*TINY_IPPO_BATCHES, "--eval-freq", "200"]
    driver = one_seed_driver(
        "ippo", "formation", tmp_path, 1800, FRAMES="600", RESUME_EVERY="1", IPPO_ARGS=" ".join(ippo_args)
    )

    # the trainer as the driver runs it (run.sh's train()), stopped after the checkpoint at 400 frames
    argv = ["--task", "formation", "--algorithm", "ippo", "--suite", "koopnav-bench-v1", "--seed", "0"]
    argv += ["--validation-layouts", "1", "--threads", "1", "--frames", "600", "--frames-per-batch", "12000"]
    argv += ["--minibatch-size", "1000", "--epochs", "5", "--normalize-advantage", "--envs", "200"]
    argv += ["--features", "bearing+headings", "--entropy-coef", "0.01", *ippo_args]
    save = benchmarl_resume.save

    def save_and_stop_at_400(out: Path, args: object, now: object, *rest: object) -> Path:
        written = save(out, args, now, *rest)  # type: ignore[arg-type]
        if int(now.total_frames) == 400:  # type: ignore[attr-defined]
            raise Interrupted
        return written

    with monkeypatch.context() as patch:
        patch.setattr(benchmarl_resume, "save", save_and_stop_at_400)
        with pytest.raises(Interrupted):
            benchmarl_train.main([*argv, "--resume-every", "1", "--out", str(seed_dir)])
    resumed = driver()
    assert resumed.returncode == 0, resumed.stderr
    assert "seed 0: unfinished run in" in resumed.stdout and "resuming from its checkpoint" in resumed.stdout
    assert json.loads((seed_dir / "finished.json").read_text())["sessions"] == 1  # the driver's one
    metadata = json.loads((seed_dir / "formation" / "metadata.json").read_text())
    assert metadata["resumed_from_frames"] == [400]
    assert "at 400 frames; 200 left" in (seed_dir / "train.log").read_text()
    record = json.loads((seed_dir / "selection.json").read_text())
    assert [c["step"] for c in record["checkpoints"]] == [200, 400, 600]  # 200 and 400: the stopped session's
    assert not (seed_dir / RESUME_FILE).exists()

    restart_after_a_torn_checkpoint(seed_dir, driver)
    metadata = json.loads((seed_dir / "formation" / "metadata.json").read_text())
    assert metadata["resumed_from_frames"] == []
    assert [c["step"] for c in json.loads((seed_dir / "selection.json").read_text())["checkpoints"]] == [
        200,
        400,
        600,
    ]
