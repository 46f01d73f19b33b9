"""A training seed that resumes mid-run, bit for bit (issue 60): the resume checkpoint's file is
checked by name (foreign, torn, altered, another run's), and a tiny PPO run interrupted after a
resume checkpoint and resumed ends with the weights, optimizer state, normalizer and checkpoint
table of the run that was never interrupted."""

from __future__ import annotations

import json
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest

from baselines.resume import RESUME_FILE, ResumeRefused, check_resume, read_resume, write_resume
from baselines.resume import main as check_main

from helpers.training import TINY_SB3, one_seed_driver, restart_after_a_torn_checkpoint

SUITE = "koopnav-bench-v1"
TINY = TINY_SB3  # the tiny set-policy run of tests/helpers/training.py
IDENTITY = {"seed": 3, "net": [16, 16]}


# ----------------------------------------------------------------------------- the file
def test_a_resume_file_reads_back_what_was_written(tmp_path) -> None:
    path = write_resume(tmp_path / RESUME_FILE, "sb3-ppo", IDENTITY, {"steps": 768, "array": [1.5, 2.5]})
    assert read_resume(path, "sb3-ppo", {"net": [16, 16], "seed": 3}) == {"steps": 768, "array": [1.5, 2.5]}
    assert check_resume(path)["kind"] == "sb3-ppo"
    assert [p.name for p in tmp_path.iterdir()] == [RESUME_FILE]  # the temporary file renamed


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda b: b"PK\x03\x04" + b[4:], "is not a KoopNav resume checkpoint"),
        (
            lambda b: b.replace(b"KOOPNAV-RESUME 1", b"KOOPNAV-RESUME 9", 1),
            "has format '9'; this KoopNav reads 1",
        ),
        (lambda b: b[:-7], r"is torn: its payload has \d+ bytes, its header says \d+"),
        (lambda b: b[:-1] + bytes([b[-1] ^ 1]), "is altered: its payload's SHA-256 differs"),
        (lambda b: b.split(b"\n", 1)[0] + b"\n{not json", "has no readable header"),
        (lambda b: b"", "is not a KoopNav resume checkpoint"),
    ],
)
def test_a_foreign_torn_or_altered_file_is_refused_by_name(tmp_path, damage, message) -> None:
    path = write_resume(tmp_path / RESUME_FILE, "sb3-ppo", IDENTITY, list(range(100)))
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(ResumeRefused, match=message) as refused:
        read_resume(path, "sb3-ppo", IDENTITY)
    assert str(path) in str(refused.value)
    assert check_main([str(path)]) == 2


def test_a_file_of_another_trainer_or_other_settings_is_refused_naming_them(tmp_path) -> None:
    path = write_resume(tmp_path / RESUME_FILE, "sb3-ppo", IDENTITY, None)
    with pytest.raises(ResumeRefused, match="written by a 'sb3-ppo' run; this is a 'benchmarl' run"):
        read_resume(path, "benchmarl", IDENTITY)
    with pytest.raises(ResumeRefused, match=r"other settings \(seed: logged 3, now 4\)"):
        read_resume(path, "sb3-ppo", {**IDENTITY, "seed": 4})
    with pytest.raises(ResumeRefused, match="cannot be read"):
        read_resume(tmp_path / "absent.ckpt", "sb3-ppo", IDENTITY)
    assert check_main([str(path), "sb3-ppo"]) == 0 and check_main([str(path), "benchmarl"]) == 2


def test_a_checkpoint_from_before_the_plant_options_still_fits_and_a_physics_run_differs() -> None:
    """``--plant`` and ``--slips`` came after resume checkpoints were written (seeds of
    data/training/run.sh): left at their default they are not in the identity, given they are."""
    pytest.importorskip("stable_baselines3")
    import argparse

    from baselines.sb3.resume_state import resume_identity
    from baselines.sb3.train_options import build_parser

    argv = ["--policy", "set", "--suite", SUITE, "--out", "o"]
    now = vars(build_parser().parse_args(argv))
    before = argparse.Namespace(**{k: v for k, v in now.items() if k not in ("plant", "slips")})
    assert resume_identity(argparse.Namespace(**now)) == resume_identity(before)
    physics = build_parser().parse_args([*argv, "--plant", "mujoco", "--slips", "nominal", "high"])
    assert resume_identity(physics) == {
        **resume_identity(before),
        "plant": "mujoco",
        "slips": ["nominal", "high"],
    }


def test_the_trainer_refuses_a_resume_without_a_checkpoint_by_name(tmp_path, capsys) -> None:
    pytest.importorskip("stable_baselines3")
    from baselines.sb3.train import main

    out = tmp_path / "run"
    argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, *TINY]
    assert (
        main([*argv, "--timesteps", "384", "--validation-layouts", "1", "--out", str(out), "--resume"]) == 2
    )
    assert f"resume checkpoint '{out / RESUME_FILE}' cannot be read" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*argv, "--out", str(out), "--resume-every", "-1"])


# ----------------------------------------------------------------------------- bit for bit
class Interrupted(Exception):
    """Stands for the process being stopped."""


def _run(out: Path, *extra: str, seed: int = 3) -> int:
    from baselines.sb3.train import main

    argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, "--seed", str(seed)]
    argv += ["--timesteps", "1536", "--eval-freq", "768", "--validation-layouts", "1", "--threads", "1"]
    return main([*argv, *TINY, "--out", str(out), *extra])


def _entries(zip_path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(zip_path) as archive:
        return {name: archive.read(name) for name in ("policy.pth", "policy.optimizer.pth")}


def _state(root: Path) -> dict[str, object]:
    """Everything a run leaves that training fixes: every policy's weights and Adam state and
    normalizer, and the checkpoint table."""
    found: dict[str, object] = {}
    for policy in sorted(root.rglob("policy.zip")):
        name = str(policy.parent.relative_to(root))
        found[name] = _entries(policy)
        found[name + "/obs_norm"] = (policy.parent / "obs_norm.npz").read_bytes()
    selection = json.loads((root / "selection.json").read_text())
    found["checkpoints"] = [{k: v for k, v in c.items() if k != "root"} for c in selection["checkpoints"]]
    found["chosen"] = selection["chosen"]["step"]
    return found


def stop_in_the_third_rollout_and_resume(
    run: Callable[..., int], stopped: Path, monkeypatch: pytest.MonkeyPatch
) -> bytes:
    """``run(stopped, "--resume-every", "1")`` stopped 6 env steps into its third rollout (after
    the resume checkpoint of rollout 2), then ``run(stopped, "--resume", ...)`` to its end;
    returns the resume checkpoint's bytes as the stop left them."""
    from baselines.sb3.training_callbacks import PeriodicCheckpoints

    on_step = PeriodicCheckpoints._on_step
    steps_after_saving = {2: 0}  # env steps since the resume checkpoint after rollout 2

    def stop_in_the_third_rollout(self: PeriodicCheckpoints) -> bool:
        if self.saved_at in steps_after_saving:
            steps_after_saving[self.saved_at] += 1
            if steps_after_saving[self.saved_at] > 6:
                raise Interrupted
        return on_step(self)

    with monkeypatch.context() as patch:
        patch.setattr(PeriodicCheckpoints, "_on_step", stop_in_the_third_rollout)
        with pytest.raises(Interrupted):
            run(stopped, "--resume-every", "1")
    assert check_resume(stopped / RESUME_FILE)["kind"] == "sb3-ppo"
    assert not (stopped / "selection.json").exists()  # stopped before the end
    saved = (stopped / RESUME_FILE).read_bytes()
    assert run(stopped, "--resume", "--resume-every", "1") == 0
    return saved


@pytest.mark.slow
def test_an_interrupted_run_resumed_ends_bit_for_bit_as_the_uninterrupted_one(
    tmp_path, monkeypatch, capsys
) -> None:
    """4 rollouts; resume checkpoints after each; the process stopped 6 steps into the third
    rollout (after the checkpoint at 768 steps was scored), then resumed: the same bytes as a run
    that never stopped and never wrote a resume checkpoint."""
    pytest.importorskip("stable_baselines3")

    assert _run(tmp_path / "whole", "--resume-every", "0") == 0
    assert not (tmp_path / "whole" / RESUME_FILE).exists()
    stopped = tmp_path / "stopped"
    saved = stop_in_the_third_rollout_and_resume(_run, stopped, monkeypatch)
    assert _state(stopped) == _state(tmp_path / "whole")
    metadata = json.loads((stopped / "target_reaching" / "metadata.json").read_text())
    assert metadata["resumed_from_timesteps"] == [768]
    assert not (stopped / RESUME_FILE).exists()  # finished: nothing left to resume
    assert (stopped / "progress-before-resume-at-768.csv").is_file()

    # the same file under a run with another seed: refused by name, before any work
    other = tmp_path / "other"
    other.mkdir()
    (other / RESUME_FILE).write_bytes(saved)
    assert _run(other, "--resume", seed=4) == 2
    assert "other settings (seed: logged 3, now 4)" in capsys.readouterr().err
    assert sorted(p.name for p in other.iterdir()) == [RESUME_FILE]


@pytest.mark.slow
def test_a_curriculum_run_resumes_at_a_stage_boundary_and_mid_stage_bit_for_bit(
    tmp_path, monkeypatch
) -> None:
    """The set policy's curriculum (no --suite): rollouts of 432 robot-steps, stage "basics" in
    rollouts 0-2, "crossing" from rollout 3 (its env built and reset before the checkpoint), so a
    stop after the checkpoint at rollout 3 resumes at the stage boundary and one at rollout 5
    inside the stage; both end as the run that never stopped."""
    pytest.importorskip("stable_baselines3")
    from baselines.sb3.train import main
    from baselines.sb3.training_callbacks import PeriodicCheckpoints

    argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--timesteps", "4608", "--n-steps", "1"]
    argv += [
        "--batch-size",
        "576",
        "--eval-freq",
        "100000",
        "--validation-episodes",
        "1",
        "--set-width",
        "16",
    ]
    argv += ["--threads", "1", "--seed", "2"]
    assert main([*argv, "--out", str(tmp_path / "whole"), "--resume-every", "0"]) == 0
    on_step = PeriodicCheckpoints._on_step
    for stop in (3, 5):

        def stop_after_saving(self: PeriodicCheckpoints, stop: int = stop) -> bool:
            if self.saved_at == stop:
                raise Interrupted
            return on_step(self)

        out = tmp_path / f"stopped{stop}"
        with monkeypatch.context() as patch:
            patch.setattr(PeriodicCheckpoints, "_on_step", stop_after_saving)
            with pytest.raises(Interrupted):
                main([*argv, "--out", str(out), "--resume-every", "1"])
        assert main([*argv, "--out", str(out), "--resume"]) == 0
        assert _entries(out / "policy.zip") == _entries(tmp_path / "whole" / "policy.zip")
        assert (out / "obs_norm.npz").read_bytes() == (tmp_path / "whole" / "obs_norm.npz").read_bytes()
        assert json.loads((out / "metadata.json").read_text())["resumed_from_timesteps"] == [432 * stop]


# ----------------------------------------------------------------------------- the driver
@pytest.mark.slow
def test_the_driver_resumes_a_seed_with_a_sound_checkpoint_and_restarts_one_without(
    tmp_path, monkeypatch
) -> None:
    """data/training/run.sh on a seed folder left by an interrupted run: resumed from its resume
    checkpoint (the trainer run with the driver's own settings, stopped in its third rollout);
    with a torn checkpoint, refused by name, removed and trained from the start."""
    pytest.importorskip("stable_baselines3")
    from baselines.sb3.train import main
    from baselines.sb3.training_callbacks import PeriodicCheckpoints

    seed_dir = tmp_path / "rl-ppo-set" / "target_reaching" / "seed0"
    sb3_args = [*TINY, "--eval-freq", "768"]
    driver = one_seed_driver(
        "rl-ppo-set",
        "target_reaching",
        tmp_path,
        900,
        TIMESTEPS="1536",
        RESUME_EVERY="1",
        SB3_ARGS=" ".join(sb3_args),
    )

    # the trainer as the driver runs it (run.sh's train()), stopped after the checkpoint at 768 steps
    argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, "--seed", "0"]
    argv += ["--validation-layouts", "1", "--threads", "1", "--timesteps", "1536", *sb3_args]
    on_step = PeriodicCheckpoints._on_step

    def stop_after_the_second_rollout(self: PeriodicCheckpoints) -> bool:
        if self.saved_at == 2:
            raise Interrupted
        return on_step(self)

    with monkeypatch.context() as patch:
        patch.setattr(PeriodicCheckpoints, "_on_step", stop_after_the_second_rollout)
        with pytest.raises(Interrupted):
            main([*argv, "--resume-every", "1", "--out", str(seed_dir)])
    resumed = driver()
    assert resumed.returncode == 0, resumed.stderr
    assert "seed 0: unfinished run in" in resumed.stdout and "resuming from its checkpoint" in resumed.stdout
    marker = json.loads((seed_dir / "finished.json").read_text())
    assert marker["sessions"] == 1  # the driver's one session (the stopped one was the test's)
    metadata = json.loads((seed_dir / "target_reaching" / "metadata.json").read_text())
    assert metadata["resumed_from_timesteps"] == [768]
    assert "resumed from" in (seed_dir / "train.log").read_text()

    restart_after_a_torn_checkpoint(seed_dir, driver)
    metadata = json.loads((seed_dir / "target_reaching" / "metadata.json").read_text())
    assert metadata["resumed_from_timesteps"] == []


# ----------------------------------------------------------------------------- old checkpoints
def _as_written_before_the_layout(venv, extra_movers: int = 0) -> bytes:
    """``venv`` pickled as the adapter was before it kept the env's observation layout (d3391fd):
    the movers' count and the obstacle slots in its place; ``extra_movers`` miscounts the movers,
    as a checkpoint of another env would."""
    import pickle

    copy = pickle.loads(pickle.dumps(venv))
    layout = copy.__dict__.pop("_observed")
    copy.__dict__.update(_mover_slots=layout.movers + extra_movers, _n_obstacle_obs=layout.n_obstacle_obs)
    return pickle.dumps(copy)


@pytest.mark.parametrize("movers", [0, 2])
def test_a_vector_env_pickled_before_the_layout_resumes_and_steps_as_the_current_one(movers: int) -> None:
    """A resume checkpoint written by the adapter of before d3391fd (seed 1 of rl-ppo-set, 8.4 M
    steps in) unpickles into an adapter that steps as one pickled now, bit for bit; one whose
    counts are not its env's is refused by name."""
    import pickle

    import numpy as np

    pytest.importorskip("stable_baselines3", reason="the SB3 adapter needs the [rl] extra")
    from baselines.features.set_features import SetFeatureConfig
    from baselines.sb3.vec_env import KoopNavSB3VecEnv

    kwargs = {"movers": {"count": 2, "behaviour": "constant"}} if movers else {}
    venv = KoopNavSB3VecEnv(
        "KoopNav-TargetReaching-v0", 2, seed=0, set_config=SetFeatureConfig(movers=movers), **kwargs
    )
    venv.reset()
    old, now = pickle.loads(_as_written_before_the_layout(venv)), pickle.loads(pickle.dumps(venv))
    assert old._observed == now._observed and not hasattr(old, "_mover_slots")
    actions = np.random.default_rng(0).uniform(-1, 1, size=(5, venv.num_envs, 2)).astype(np.float32)
    for action in actions:
        for env in (old, now):
            env.step_async(action)
        (obs_old, rew_old, done_old, _), (obs_now, rew_now, done_now, _) = old.step_wait(), now.step_wait()
        np.testing.assert_array_equal(obs_old, obs_now, strict=True)
        np.testing.assert_array_equal(rew_old, rew_now, strict=True)
        np.testing.assert_array_equal(done_old, done_now, strict=True)
    with pytest.raises(
        ValueError, match=r"lists \d+ movers and \d+ obstacles per robot where its env's layout"
    ):
        pickle.loads(_as_written_before_the_layout(venv, extra_movers=1))
