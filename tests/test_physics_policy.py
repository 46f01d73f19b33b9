"""The learned policies fine-tuned on the physics plant (issue 62): the SB3 trainer's ``--plant``
and ``--slips`` on a benchmark suite, and the shipped ``rl-ppo-set-physics`` (docs/rl.md)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np
import pytest

import controllers
from baselines.suite_training import SuiteTraining

from helpers.training import TINY_SB3

pytest.importorskip("stable_baselines3")
pytest.importorskip("mujoco")

ROOT = Path(__file__).resolve().parents[1]
SUITE = "koopnav-bench-v1"
SHIPPED = ROOT / "baselines" / "policies" / "set_physics"
TASK_ENVS = {"target_reaching": "KoopNav-TargetReaching-v0", "formation": "KoopNav-Formation-v0"}


def _suite_argv(out: Path, *options: str) -> list[str]:
    argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, *options]
    return [*argv, "--timesteps", "384", "--validation-layouts", "1", *TINY_SB3, "--out", str(out)]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            ["--plant", "mujuco"],
            r"argument --plant: plant='mujuco' is not one of \['kinematic', 'mujoco'\] \(did you mean 'mujoco'\?\)",
        ),
        (["--slips", "nominal", "nominal"], r"slips=\['nominal', 'nominal'\] names a level twice"),
        (["--slips", "ice"], r"slips='ice' is not one of"),
    ],
)
def test_the_trainer_refuses_a_bad_plant_or_slip_by_name_before_any_work(
    options: list[str], message: str, tmp_path, capsys
) -> None:
    from baselines.sb3.train import main

    with pytest.raises(SystemExit) as exit_info:
        main(_suite_argv(tmp_path / "run", *options))
    assert exit_info.value.code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "run").exists()


def test_plant_and_slips_need_a_suite_the_curriculum_draws_kinematic_slips(tmp_path, capsys) -> None:
    from baselines.sb3.train import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--policy", "set", "--plant", "mujoco", "--out", str(tmp_path / "run")])
    assert exit_info.value.code == 2
    assert "--plant need --suite NAME (the curriculum runs the kinematic plant)" in capsys.readouterr().err


def test_a_physics_run_trains_on_every_slip_level_of_the_train_layouts_on_the_physics_plant(tmp_path) -> None:
    """The training env is one part per slip level, each on the physics plant and the train
    split, the envs split evenly; the checkpoints are scored on the same plant at each level."""
    from baselines.sb3.train import Trainer
    from baselines.sb3.train_options import build_parser
    from baselines.sb3.vec_env import MixtureVecEnv

    parser = build_parser()
    argv = _suite_argv(
        tmp_path / "run", "--plant", "mujoco", "--slips", "nominal", "high", "--resume-every", "0"
    )
    argv[argv.index("--n-envs") + 1] = "3"
    run = Trainer(parser.parse_args(argv), parser, argv)
    assert run.suite is not None and run.suite.plant == "mujoco"
    assert run.suite.slip_levels == ("nominal", "high")
    assert run.identity["plant"] == "mujoco"
    venv = run.make_venv(0)
    try:
        assert isinstance(venv, MixtureVecEnv)
        configs = [cast(Any, part.venv.unwrapped).config for part in venv.parts]
        assert [part.n_envs for part in venv.parts] == [2, 1]  # 3 envs over 2 levels
        assert [c.plant for c in configs] == ["mujoco", "mujoco"]
        assert [c.slip_label for c in configs] == ["nominal", "high"]
    finally:
        venv.close()
    kinematic = Trainer(parser.parse_args(_suite_argv(tmp_path / "k")), parser, None)
    assert "plant" not in kinematic.identity and kinematic.suite is not None
    assert "plant" not in kinematic.suite.env_kwargs()  # a kinematic run's keywords as before


def test_the_suite_keywords_name_the_plant_and_the_level() -> None:
    training = SuiteTraining(SUITE, "formation", plant="mujoco", slips=("nominal", "high"))
    training.check()
    high = training.env_kwargs("high")
    assert high["plant"] == "mujoco" and high["slip"] == "high"
    assert high["map"] == "suite:koopnav-bench-v1/train"
    assert training.env_kwargs()["slip"] == "nominal"
    with pytest.raises(ValueError, match=r"slip='low' is not one of \['nominal', 'high'\]"):
        training.env_kwargs("low")
    with pytest.raises(ValueError, match=r"plant='mujuco' is not one of"):
        SuiteTraining(SUITE, "formation", plant="mujuco").check()
    assert training.as_dict()["episodes_per_checkpoint"] == 2 * training.layouts


@pytest.mark.slow
def test_a_tiny_physics_run_scores_every_checkpoint_on_both_floors_and_records_the_plant(tmp_path) -> None:
    """A real run (768 robot-steps on the physics plant, half the envs on carpet, half on ice),
    each checkpoint played on one validation layout on both floors through the evaluator."""
    from baselines.sb3.train import main

    argv = _suite_argv(
        tmp_path / "run", "--plant", "mujoco", "--slips", "nominal", "high", "--resume-every", "0"
    )
    argv[argv.index("--timesteps") + 1] = "768"
    assert main([*argv, "--eval-freq", "384", "--threads", "1"]) == 0
    record = json.loads((tmp_path / "run" / "selection.json").read_text())
    assert [c["step"] for c in record["checkpoints"]] == [384, 768]
    assert all(c["episodes"] == 2 and c["errors"] == 0 for c in record["checkpoints"])  # 1 layout x 2 floors
    assert record["suite"]["plant"] == "mujoco" and record["suite"]["env"]["plant"] == "mujoco"
    metadata = json.loads((tmp_path / "run" / "target_reaching" / "metadata.json").read_text())
    assert metadata["plant"] == "mujoco" and metadata["suite"]["slips"] == ["nominal", "high"]


@pytest.mark.slow
def test_a_physics_run_resumed_mid_run_ends_bit_for_bit_as_the_uninterrupted_one(
    tmp_path, monkeypatch
) -> None:
    """The resume checkpoint pickles the physics vector env (its MuJoCo worlds pickle since
    ``PhysicsWorld.__getstate__``): a tiny run on carpet and ice stopped 6 steps into its third
    rollout, after the checkpoint at 768 robot-steps, and resumed ends as the run that never
    stopped (28 s on the shared machine)."""
    from test_training_resume import TINY, _state, stop_in_the_third_rollout_and_resume

    from baselines.sb3.train import main

    def run(out: Path, *extra: str) -> int:
        argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, "--seed", "3"]
        argv += ["--plant", "mujoco", "--slips", "nominal", "high", "--timesteps", "1536"]
        argv += ["--eval-freq", "768", "--validation-layouts", "1", "--threads", "1"]
        return main([*argv, *TINY, "--out", str(out), *extra])

    assert run(tmp_path / "whole", "--resume-every", "0") == 0
    stopped = tmp_path / "stopped"
    stop_in_the_third_rollout_and_resume(run, stopped, monkeypatch)
    assert _state(stopped) == _state(tmp_path / "whole")


# ----------------------------------------------------------------------------- the shipped policy
@pytest.mark.parametrize("task", list(TASK_ENVS))
def test_the_shipped_metadata_names_the_plant_the_source_and_the_selection(task: str) -> None:
    metadata = json.loads((SHIPPED / task / "metadata.json").read_text())
    assert metadata["plant"] == "mujoco" and metadata["suite"]["plant"] == "mujoco"
    assert metadata["suite"]["slips"] == ["nominal", "high"]
    # fine-tuned from the curriculum-trained set policies, which rl-ppo-set-v0 plays since
    # rl-ppo-set ships its seeds chosen on validation (the recorded path is where they were then)
    assert metadata["initialized_from"]["path"] == f"baselines/policies/set/{task}"
    source = json.loads((ROOT / "baselines/policies/set_v0" / task / "metadata.json").read_text())
    assert metadata["initialized_from"]["trained_timesteps"] == source["trained_timesteps"]
    assert metadata["trained_on"].startswith(f"koopnav-bench-v1/{task}/train@")
    selection = metadata["selection"]
    assert selection["suite"]["labels"]["selection"].startswith(f"koopnav-bench-v1/{task}/validation@")
    assert selection["chosen"]["step"] == metadata["selected_timesteps"]
    assert selection["chosen"] in selection["checkpoints"]
    assert "--plant mujoco" in metadata["command"] and "--init-from" in metadata["command"]
    assert not (SHIPPED / task / "checkpoints").exists()  # the chosen policy only


@pytest.mark.parametrize("plant", ["kinematic", "mujoco"])
@pytest.mark.parametrize("task", list(TASK_ENVS))
def test_the_physics_policy_loads_and_drives_on_both_plants(task: str, plant: str) -> None:
    from baselines import RLSetPhysicsPolicyController

    controller = controllers.make("rl-ppo-set-physics")
    assert isinstance(controller, RLSetPhysicsPolicyController) and controller.policy_root == SHIPPED
    env = gym.make(TASK_ENVS[task], plant=plant, max_episode_steps=15)
    obs, info = env.reset(seed=0)
    controller.reset(env, seed=0)
    start = info["poses"]
    for _ in range(15):
        action = np.asarray(controller.act(obs, info))
        assert action.shape == env.action_space.shape and np.all(np.isfinite(action))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    moved = np.linalg.norm(info["poses"][:, :2] - start[:, :2], axis=1)
    assert moved.max() > 0.05, moved  # it drives the robots
