"""BenchMARL runs KoopNav's tasks unchanged: TorchRL specs check out and MAPPO / IPPO train (real runs)."""

from __future__ import annotations

import importlib.util
import json
from typing import TYPE_CHECKING

import numpy as np
import pytest

# the [benchmarl] extra: skipped without it, found without importing it (importing it costs several
# CPU-s, which every pytest-xdist worker would pay at collection)
if importlib.util.find_spec("benchmarl") is None:
    pytest.skip("needs benchmarl", allow_module_level=True)

if TYPE_CHECKING:
    from benchmarl.experiment import ExperimentConfig


#: the members of ``KoopNavTask``, by name (checked below)
TASKS = ("TARGET_REACHING", "FORMATION")


@pytest.mark.parametrize("vectorized", [True, False], ids=["vector-env", "pettingzoo"])
@pytest.mark.parametrize("name", TASKS)
def test_every_task_builds_torchrl_envs_that_pass_the_spec_check(name: str, vectorized: bool) -> None:
    from torchrl.envs.utils import check_env_specs

    from baselines.marl.benchmarl_task import TASK_CONFIGS, KoopNavTask

    member = getattr(KoopNavTask, name)
    task = member.get_task()
    assert task.config == TASK_CONFIGS[member.name.lower()]
    task.config["vectorized"] = vectorized
    env = task.get_env_fun(num_envs=2, continuous_actions=True, seed=0, device="cpu")()
    check_env_specs(env)
    # the vector env is one batched TorchRL env; a PettingZoo env is one environment
    assert env.batch_size == ((2,) if vectorized else ())
    assert list(task.group_map(env)) == ["robot"] and len(task.group_map(env)["robot"]) == 3
    assert task.max_steps(env) == 100
    # BenchMARL builds its networks from one environment's specs, whichever the batch
    assert task.observation_spec(env)["robot", "observation"].shape[0] == 3
    assert task.action_spec(env)["robot", "action"].shape == (3, 2)


def test_the_parametrized_tasks_are_every_task() -> None:
    """TASKS names BenchMARL's tasks without importing BenchMARL at collection: it is every one."""
    from baselines.marl.benchmarl_task import KoopNavTask

    assert list(KoopNavTask.__members__) == list(TASKS)


def test_yaml_configs_round_trip(tmp_path) -> None:
    from baselines.marl.benchmarl_task import TASK_CONFIGS, KoopNavTask, write_task_yaml

    for path in write_task_yaml(tmp_path):
        member = KoopNavTask[path.stem.upper()]
        assert member.get_from_yaml(str(path)).config == TASK_CONFIGS[path.stem]


def experiment_config(folder) -> ExperimentConfig:
    from benchmarl.experiment import ExperimentConfig

    config = ExperimentConfig.get_from_yaml()
    config.max_n_iters, config.max_n_frames = 2, None
    config.on_policy_collected_frames_per_batch = 200
    config.on_policy_n_envs_per_worker = 2
    config.on_policy_n_minibatch_iters = 2
    config.on_policy_minibatch_size = 100
    config.evaluation, config.evaluation_interval, config.evaluation_episodes = True, 200, 2
    config.render, config.loggers, config.save_folder = False, ["csv"], str(folder)
    return config


@pytest.mark.parametrize(
    ("name", "algorithm"),
    [
        ("FORMATION", "mappo"),
        # the same task code under another algorithm (14 CPU-s); target reaching's envs pass
        # TorchRL's spec check in the default run (test_every_task_builds_torchrl_envs_...)
        pytest.param("TARGET_REACHING", "ippo", marks=pytest.mark.slow),
    ],
)
def test_benchmarl_trains_on_a_koopnav_task(tmp_path, name: str, algorithm: str) -> None:
    from benchmarl.algorithms import IppoConfig, MappoConfig
    from benchmarl.experiment import Experiment
    from benchmarl.models.mlp import MlpConfig

    from baselines.marl.benchmarl_task import KoopNavTask

    member = getattr(KoopNavTask, name)
    task = member.get_task()
    task.config.update({"n_robots": 5, "slip": "high", "max_cycles": 50})
    experiment = Experiment(
        task=task,
        algorithm_config={"mappo": MappoConfig, "ippo": IppoConfig}[algorithm].get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=experiment_config(tmp_path),
    )
    before = [p.detach().clone() for p in experiment.policy.parameters()]
    experiment.run()
    assert experiment.n_iters_performed == 2 and experiment.total_frames == 400
    after = list(experiment.policy.parameters())
    assert any(not np.allclose(a.numpy(), b.detach().numpy()) for a, b in zip(before, after, strict=True))
    # BenchMARL's own report: evaluation returns of the 5 robots, and KoopNav's info logged
    report = json.loads(next(tmp_path.glob("*/*.json")).read_text())
    run = report["koopnav"][member.name.lower()][experiment.algorithm_name]["seed_0"]
    assert run["step_2"]["step_count"] == 400
    assert len(run["step_2"]["return"]) == 2 and np.isfinite(run["step_2"]["return"]).all()  # 2 eval episodes
    scalars = {p.stem for p in tmp_path.glob("*/*/scalars/*.csv")}
    assert {"eval_reward_episode_reward_mean", "collection_robot_info_is_success"} <= scalars


def test_reward_scale_scales_the_rewards_benchmarl_sees() -> None:
    """``reward_scale`` is a transform of the task (not an env keyword): the same rollout's
    rewards, times the scale; a scale <= 0 is refused by name."""
    import torch
    from torchrl.envs import TransformedEnv

    from baselines.marl.benchmarl_task import KoopNavTask

    rewards = []
    for scale in (1.0, 0.25):
        task = KoopNavTask.TARGET_REACHING.get_task()
        task.config["reward_scale"] = scale
        env = task.get_env_fun(num_envs=3, continuous_actions=True, seed=0, device="cpu")()
        transforms = task.get_env_transforms(env)
        assert len(transforms) == (0 if scale == 1.0 else 1)
        env = TransformedEnv(env, transforms[0]) if transforms else env
        torch.manual_seed(0)
        rewards.append(env.rollout(20, break_when_any_done=False)["next", "robot", "reward"])
    torch.testing.assert_close(rewards[1], rewards[0] * 0.25)
    task = KoopNavTask.TARGET_REACHING.get_task()
    task.config["reward_scale"] = 0.0
    env = task.get_env_fun(num_envs=1, continuous_actions=True, seed=0, device="cpu")()
    with pytest.raises(ValueError, match=r"reward_scale=0.0 must be > 0"):
        task.get_env_transforms(env)


@pytest.mark.parametrize(
    ("option", "value", "allowed"),
    [
        ("--lr", "0", "> 0"),
        ("--initial-std", "-1", "> 0"),
        ("--reward-scale", "0", "> 0"),
        ("--gae-lambda", "1.5", "in [0, 1]"),
    ],
)
def test_the_training_command_refuses_bad_settings_by_name_before_any_work(
    option: str, value: str, allowed: str, tmp_path, capsys
) -> None:
    from baselines.marl.benchmarl_train import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--task", "target_reaching", option, value, "--out", str(tmp_path / "run")])
    assert exit_info.value.code == 2
    assert f"{option}={float(value)!r}: allowed {allowed}" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()  # nothing started


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--epochs", "0"], "--epochs=0: allowed > 0"),
        (
            ["--envs", "200", "--frames-per-batch", "12001"],
            "--frames-per-batch=12001: allowed a multiple of --envs",
        ),
        (["--minibatch-size", "70000"], "--minibatch-size=70000: allowed in [1, --frames-per-batch]"),
        (["--stages", '[{"share": 0.5}, {"share": 0.4}]'], "the stages' shares sum to 0.9, not 1"),
        (["--stages", '[{"share": 1, "env": 3}]'], "stage 0: env=3 must be a JSON object"),
        (["--stages", '[{"share": 0}, {"share": 1}]'], "stage 0: share=0 must be a number > 0"),
        (["--stages", "[]"], "a non-empty JSON list of stages is needed"),
        (["--stages", '[{"share": 1}]', "--curriculum"], "not allowed with argument --stages"),
    ],
)
def test_the_training_schedule_and_stages_are_checked_before_any_work(
    options: list[str], message: str, tmp_path, capsys
) -> None:
    from baselines.marl.benchmarl_train import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--task", "target_reaching", *options, "--out", str(tmp_path / "run")])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_a_staged_training_resumes_each_stage_and_records_its_schedule(tmp_path) -> None:
    """Two stages of one iteration each (real training), standardized advantages: the second
    stage continues the first's checkpoint on its own layouts, and the export records it all."""
    from baselines.marl.benchmarl_train import main

    stages = [
        {"name": "open", "share": 0.5, "env": {"random_map": {"n_obstacles": 0}}},
        {"name": "two", "share": 0.5, "env": {"random_map": {"n_obstacles": 2}}},
    ]
    out = tmp_path / "run"
    argv = ["--task", "target_reaching", "--frames", "400", "--envs", "2", "--max-cycles", "20"]
    argv += ["--frames-per-batch", "200", "--minibatch-size", "100", "--epochs", "1", "--normalize-advantage"]
    assert main([*argv, "--stages", json.dumps(stages), "--out", str(out)]) == 0
    metadata = json.loads((out / "metadata.json").read_text())
    assert metadata["frames"] == 400 and metadata["normalize_advantage"] is True
    assert metadata["ppo"] == {"frames_per_batch": 200, "minibatch_size": 100, "epochs": 1}
    ran = metadata["curriculum"]["stages"]
    assert [(s["name"], s["frames_end"], s["env"]) for s in ran] == [
        ("open", 200, stages[0]["env"]),
        ("two", 400, stages[1]["env"]),
    ]
    assert metadata["env"]["random_map"] == {"n_obstacles": 2}  # the layouts the training ended on
    with np.load(out / "policy.npz") as arrays:
        assert {"weight_0", "obs_mean", "obs_std", "low", "high"} <= set(arrays.files)


def test_standardized_advantages_reach_benchmarls_loss(tmp_path) -> None:
    from baselines.marl.benchmarl_task import KoopNavTask
    from baselines.marl.benchmarl_train import experiment

    config = experiment_config(tmp_path)
    task = KoopNavTask.TARGET_REACHING.get_task()
    plain = experiment(task, config, "mappo")
    standardized = experiment(
        KoopNavTask.TARGET_REACHING.get_task(), config, "ippo", normalize_advantage=True
    )
    assert [loss.normalize_advantage for loss in plain.losses.values()] == [False]
    assert [loss.normalize_advantage for loss in standardized.losses.values()] == [True]
