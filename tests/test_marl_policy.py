"""The BenchMARL policies as controllers (baselines.marl.marl_policy): the exported numpy actor acts as
BenchMARL's own deterministic policy does, and the controller refuses what it cannot read."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from baselines.marl.marl_policy import MappoController, actor_command
from koopman_envs.episodes.single import run_episode

TR = "KoopNav-TargetReaching-v0"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A BenchMARL MAPPO policy for target reaching (its initial weights: no training is needed to
    compare two implementations of one actor), its export, and the export as a policy folder."""
    pytest.importorskip("benchmarl")
    from benchmarl.experiment import ExperimentConfig

    from baselines.marl.benchmarl_task import KoopNavTask
    from baselines.marl.benchmarl_train import experiment, export_actor

    folder = tmp_path_factory.mktemp("mappo")
    config = ExperimentConfig.get_from_yaml()
    config.max_n_iters, config.loggers, config.render, config.evaluation = 1, [], False, False
    config.on_policy_collected_frames_per_batch, config.on_policy_n_envs_per_worker = 200, 2
    config.save_folder = str(folder)
    run = experiment(KoopNavTask.TARGET_REACHING.get_task(), config, "mappo")
    arrays = export_actor(run.policy)
    root = folder / "root" / "target_reaching"
    root.mkdir(parents=True)
    np.savez(root / "policy.npz", **arrays)
    size = int(arrays["weight_0"].shape[1])
    metadata = {"n_robots": 3, "observation_size": size, "arrays": sorted(arrays), "algorithm": "mappo"}
    (root / "metadata.json").write_text(json.dumps(metadata))
    return run.policy, arrays, folder / "root"


def test_the_numpy_actor_acts_as_benchmarls_deterministic_policy(exported) -> None:
    import torch
    from tensordict import TensorDict
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    policy, arrays, _ = exported
    obs = torch.randn(64, 3, arrays["weight_0"].shape[1]) * 3
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        expected = policy(TensorDict({("robot", "observation"): obs}, batch_size=[64]))["robot", "action"]
    ours = actor_command(arrays, obs.numpy())
    np.testing.assert_allclose(ours, expected.numpy(), atol=2e-6)
    assert (np.abs(ours) <= arrays["high"] + 1e-6).all()


def test_the_controller_plays_the_exported_policy_on_the_observed_blocks(exported) -> None:
    _, arrays, root = exported
    env = gym.make(TR, map="map1", uncertainty="realistic", movers={"count": 2})
    ctrl = MappoController(root)
    obs, info = env.reset(seed=0)
    ctrl.reset(env, seed=0)
    command = ctrl.act(obs, info)
    layout = env.unwrapped.scenario.observation_layout
    blocks = obs.reshape(3, -1)
    keep = [
        i
        for name, _ in layout.parts
        if name not in ("messages", "movers")
        for i in range(*layout[name].indices(layout.size))
    ]
    np.testing.assert_array_equal(command, actor_command(arrays, blocks[:, keep]).reshape(-1))
    result = run_episode(gym.make(TR, map="map1"), ctrl, seed=0)
    assert result.steps > 0 and ctrl.stats().summary()["solve_ms_median"] > 0


def test_what_the_policy_cannot_read_is_refused_by_name(exported, tmp_path) -> None:
    _, _, root = exported
    ctrl = MappoController(root)
    with pytest.raises(
        ValueError, match=r"takes teams of 3 robots .* not n_robots=5; rl-ppo-set runs any team size"
    ):
        run_episode(gym.make(TR, map="random", n_robots=5), ctrl, seed=0)
    with pytest.raises(ValueError, match=r"mappo reads the listed obstacles of sensing='state'"):
        run_episode(gym.make(TR, map="map1", sensing="lidar"), ctrl, seed=0)
    with pytest.raises(ValueError, match=r"no policy for task 'formation'"):
        run_episode(gym.make("KoopNav-Formation-v0", map="map3"), ctrl, seed=0)
    with pytest.raises(ValueError, match=r"no trained policies in .*benchmarl_train"):
        MappoController(tmp_path / "nothing")


def test_an_export_with_observation_statistics_standardizes_first(exported) -> None:
    """A policy trained on standardized observations (``--normalize-observations``) carries its
    statistics, and the numpy actor applies them as the TorchRL env did in training."""
    _, arrays, _ = exported
    width = arrays["weight_0"].shape[1]
    rng = np.random.default_rng(0)
    mean = rng.normal(size=width).astype(np.float32)
    std = rng.uniform(0.5, 3.0, size=width).astype(np.float32)
    blocks = rng.normal(size=(5, 3, width)) * 3
    scaled = (blocks.astype(np.float32) - mean) / std
    with_stats = {**arrays, "obs_mean": mean, "obs_std": std}
    np.testing.assert_array_equal(actor_command(with_stats, blocks), actor_command(arrays, scaled))


def test_a_policy_trained_with_features_reads_them_beside_its_block(tmp_path) -> None:
    """An export of ``--features bearing+headings`` (its metadata says so): the controller appends
    baselines.features.robot_features to each robot's block before the actor, as the TorchRL env did in
    training; an unknown feature set and a width that does not fit are refused by name."""
    from baselines.features.robot_features import feature_count, robot_features

    env = gym.make(TR, map="map1")
    obs, info = env.reset(seed=2)
    block = env.unwrapped.scenario.observation_layout.size
    width = feature_count(block, 3, "bearing+headings")
    rng = np.random.default_rng(0)
    arrays = {
        "weight_0": rng.normal(size=(16, width)).astype(np.float32) / 4,
        "bias_0": np.zeros(16, np.float32),
        "weight_1": rng.normal(size=(4, 16)).astype(np.float32),
        "bias_1": np.zeros(4, np.float32),
        "low": np.array([-0.6, -0.8], np.float32),
        "high": np.array([0.6, 0.8], np.float32),
    }
    root = tmp_path / "root" / "target_reaching"
    root.mkdir(parents=True)
    np.savez(root / "policy.npz", **arrays)
    metadata = {
        "n_robots": 3,
        "observation_size": width,
        "features": "bearing+headings",
        "arrays": sorted(arrays),
    }
    (root / "metadata.json").write_text(json.dumps(metadata))
    ctrl = MappoController(root.parent)
    ctrl.reset(env, seed=2)
    expected = actor_command(
        arrays, robot_features(obs.reshape(3, -1).astype(np.float64), "bearing+headings")
    )
    np.testing.assert_array_equal(ctrl.act(obs, info), expected.reshape(-1))
    for bad, match in (
        ({"features": "bearings"}, "features='bearings' is not one of"),
        ({"features": None}, "reads blocks of"),
    ):
        (root / "metadata.json").write_text(json.dumps({**metadata, **bad}))
        with pytest.raises(ValueError, match=match):
            MappoController(root.parent).reset(env, seed=2)


@pytest.mark.parametrize(
    ("task", "env_id", "map_name"),
    [("target_reaching", TR, "random"), ("formation", "KoopNav-Formation-v0", "map3")],
)
def test_the_shipped_ippo_policies_load_without_pickle_and_arrive(
    task: str, env_id: str, map_name: str
) -> None:
    """``ippo`` (registered; numpy alone): each task's export holds arrays only, its metadata the
    command that trained it, and it settles a team (one real closed-loop episode: a random layout, as
    in training, and a paper formation map)."""
    import controllers
    from baselines.marl.marl_policy import SHIPPED

    # ippo ships the seed chosen on the benchmark's validation layouts; ippo-v0 the random-layout
    # policies it shipped before (their command as it was run: the module path of that release)
    commands = {
        "ippo": f"python -m baselines.marl.benchmarl_train --task {task} --algorithm ippo --suite koopnav-bench-v1 ",
        "ippo_v0": f"python -m baselines.benchmarl_train --task {task} ",
    }
    for folder, command in commands.items():
        directory = SHIPPED / folder / task
        metadata = json.loads((directory / "metadata.json").read_text())
        assert metadata["algorithm"] == "ippo" and metadata["task"] == task and metadata["n_robots"] == 3
        assert metadata["command"].startswith(command), (folder, metadata["command"])
        with np.load(directory / "policy.npz", allow_pickle=False) as arrays:  # arrays only, no objects
            assert sorted(arrays.files) == metadata["arrays"]
    assert {"ippo", "ippo-v0"} <= set(controllers.available())
    for name in ("ippo", "ippo-v0"):
        result = run_episode(gym.make(env_id, map=map_name), controllers.make(name), seed=0)
        assert result.success, (name, result.outcome, result.final_distance)


# slow: the evaluator twice, once with two worker processes loading the policies, about 4 CPU-s
# (issue 61); the shipped policies' episodes stay in the default run
@pytest.mark.slow
def test_ippo_in_the_evaluator_same_records_in_one_process_or_two_and_options_checked() -> None:
    """The registered ``ippo`` through the evaluator: the same seeds give the same records bit for
    bit whether its episodes run in this process or in two worker processes, and a misspelt
    option is refused before any episode with a did-you-mean."""
    import evaluate as ev

    spec = ev.RunSpec(
        envs=[TR, "KoopNav-Formation-v0"],
        controllers=["ippo"],
        maps=["map1", "map3"],
        slips=["high"],
        episodes=2,
        seed=3,
        env_kwargs={"max_episode_steps": 120},
    )
    timing = {
        "wall_seconds",
        "solve_ms",
        "solve_ms_median",
        "solve_ms_p95",
        "controller_extra",
        "calibration",
    }

    def records(workers: int) -> list[dict]:
        results = ev.evaluate(spec, workers=workers)
        return sorted(
            ({k: v for k, v in r.items() if k not in timing} for r in results.records), key=lambda r: r["key"]
        )

    one, two = records(1), records(2)
    assert len(one) == 8 and one == two  # 2 tasks x 2 maps x 2 seeds
    with pytest.raises(ValueError, match=r"unknown option 'policy_rot' \(did you mean 'policy_root'\?\)"):
        ev.evaluate(spec.replace(controllers=["ippo:policy_rot=x"]), workers=1)
