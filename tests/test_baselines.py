"""RL baseline: a short real training run, loading, deterministic play, clear errors."""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import controllers  # noqa: E402
from baselines.sb3.policy import SHIPPED, TASK_ENV, RLPolicyController, load_policy  # noqa: E402
from baselines.sb3.train import main as train_main  # noqa: E402
from baselines.sb3.vec_env import KoopNavSB3VecEnv, robot_features  # noqa: E402
from koopman_envs.sim.maps.map_spec import MapSpec  # noqa: E402

# robot 0 starts 5 cm from an obstacle's surface: driving forward hits it on the first step
CRASH = MapSpec(
    "crash",
    obstacles=[[0.75, 0.0, 0.5]],
    starts=[[0.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, -2.0, 0.0]],
    targets=[[3.0, 0.0, 0.0], [3.0, 2.0, 0.0], [3.0, -2.0, 0.0]],
)


@pytest.fixture(scope="module")
def trained_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("policies")
    code = train_main(
        [
            "--env",
            "KoopNav-Formation-v0",
            "--timesteps",
            "1024",
            "--n-envs",
            "8",
            "--n-steps",  # rollouts of 8 envs x 3 robots x 32 steps, one minibatch each
            "32",
            "--batch-size",
            "768",
            "--eval-freq",
            "100000",
            "--threads",  # one torch thread, as tests/test_set_policy.py's fixture (why there)
            "1",
            "--out",
            str(root / "formation"),
        ]
    )
    assert code == 0
    return root


def play(ctrl, seed: int = 0) -> tuple[dict, list]:
    env = gym.make("KoopNav-Formation-v0", map="map3", max_episode_steps=60)
    obs, info = env.reset(seed=seed)
    ctrl.reset(env.unwrapped.scenario, seed=seed)
    actions = []
    while True:
        action = ctrl.act(obs, info)
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            return info, actions


def test_short_training_saves_a_loadable_policy(trained_root) -> None:
    model, norm, metadata = load_policy(trained_root / "formation")
    assert metadata["timesteps"] == 1024 and metadata["algo"] == "ppo"
    assert {"stable_baselines3", "torch"} <= set(metadata["versions"])
    assert metadata["layout"] == "robot"
    assert metadata["features"] == "bearing+headings"
    assert norm["mean"].shape == (36,)  # one robot's block + 3 + 2 x 2: the policy is shared by the robots
    info, actions = play(RLPolicyController(policy_root=trained_root))
    assert len(actions) > 0 and all(a.shape == (6,) for a in actions)
    assert all(np.all(np.abs(a[0::2]) <= 0.6 + 1e-9) for a in actions)


def test_selection_scores_the_run_on_held_out_layouts_and_writes_a_loadable_policy(
    trained_root, tmp_path
) -> None:
    from baselines.sb3.select import main as select_main

    assert (
        select_main(
            [
                "--run",
                str(trained_root / "formation"),
                "--out",
                str(tmp_path / "formation"),
                "--episodes",
                "3",
            ]
        )
        == 0
    )
    _, _, metadata = load_policy(tmp_path / "formation")
    selection = metadata["selection"]
    # the only candidate, the final policy, after whole rollouts: 2 x (8 envs x 3 robots x 32 steps)
    assert selection["selected_timesteps"] == metadata["trained_timesteps"] == 1536
    assert len(selection["validation"]) == 1
    assert 0.0 <= selection["validation"][0]["validation_success_rate"] <= 1.0
    assert metadata["env_id"] == "KoopNav-Formation-v0"
    assert select_main(["--run", str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2


def test_batched_commands_equal_single_commands(trained_root) -> None:
    from baselines.sb3.policy import policy_command

    model, norm, metadata = load_policy(trained_root / "formation")
    env = gym.make_vec("KoopNav-Formation-v0", num_envs=3, map="random")
    obs, _ = env.reset(seed=0)
    args = (model, norm, "robot", obs, 3, 0.6, 0.785, metadata["features"])
    batch = policy_command(*args)
    assert batch.shape == (3, 6)
    for k in range(3):
        np.testing.assert_allclose(
            policy_command(model, norm, "robot", obs[k], 3, 0.6, 0.785, metadata["features"]),
            batch[k],
            atol=1e-6,
        )


def test_inference_is_deterministic(trained_root) -> None:
    _, first = play(RLPolicyController(policy_root=trained_root), seed=3)
    _, second = play(RLPolicyController(policy_root=trained_root), seed=3)
    np.testing.assert_array_equal(np.asarray(first), np.asarray(second))


def test_missing_and_corrupt_policy_files(tmp_path, trained_root) -> None:
    with pytest.raises(ValueError, match="holds no trained policy; train one per task with ") as refused:
        RLPolicyController(policy_root=tmp_path / "empty")
    for task, env_id in TASK_ENV.items():  # each task's command, not one task's for both
        assert f"{task}: `python -m baselines.sb3.train --env {env_id} --algo ppo --out runs/{task}`" in str(
            refused.value
        )
    broken = tmp_path / "broken" / "formation"
    broken.mkdir(parents=True)
    for name in ("policy.zip", "obs_norm.npz", "metadata.json"):
        (broken / name).write_bytes((trained_root / "formation" / name).read_bytes())
    (broken / "policy.zip").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match="corrupt or unreadable.*python -m baselines.sb3.train"):
        load_policy(broken)
    (broken / "obs_norm.npz").unlink()
    with pytest.raises(ValueError, match=r"\['obs_norm.npz'\] are missing"):
        load_policy(broken)


def test_registered_through_the_entry_point() -> None:
    assert "rl-ppo" in controllers.available()


@pytest.mark.skipif(not (SHIPPED / "formation").exists(), reason="no shipped policy yet")
@pytest.mark.parametrize("env_id", ["KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"])
def test_shipped_policies_play_an_episode(env_id: str) -> None:
    ctrl = controllers.make("rl-ppo")
    env = gym.make(env_id, max_episode_steps=100)
    obs, info = env.reset(seed=0)
    ctrl.reset(env.unwrapped.scenario, seed=0)
    obs, *_ = env.step(ctrl.act(obs, info))
    assert env.observation_space.contains(obs)


def test_robot_layout_assigns_the_crash_to_the_robot_that_crashed() -> None:
    venv = KoopNavSB3VecEnv(
        "KoopNav-TargetReaching-v0", 2, seed=0, layout="robot", collision_penalty=5.0, map=CRASH
    )
    assert venv.num_envs == 6 and venv.observation_space.shape == (30,)
    obs = venv.reset()
    assert obs.shape == (6, 30)
    forward = np.tile([1.0, 0.0], (6, 1)).astype(np.float32)  # full speed ahead, no turn
    obs, rewards, dones, infos = venv.step(forward)
    assert dones.all()
    truncated = [info["TimeLimit.truncated"] for info in infos]
    assert truncated == [False, True, True] * 2  # robot 0 terminal, its team-mates bootstrapped
    progress = 10.0 * 0.06  # the env's progress term for 6 cm straight ahead
    effort = 0.01 * 1.0
    np.testing.assert_allclose(rewards[1:3], progress - effort, atol=1e-4)  # no team penalty
    np.testing.assert_allclose(rewards[0], progress - effort - 10.0 - 5.0, atol=1e-4)
    np.testing.assert_array_equal(infos[0]["terminal_observation"], infos[3]["terminal_observation"])
    assert obs.shape == (6, 30)  # already the next episode's first observation


def test_vector_env_robot_rewards_match_the_pettingzoo_rewards() -> None:
    from koopman_envs import formation_v0

    vec = gym.make_vec("KoopNav-Formation-v0", num_envs=1, map="random", slip="random")
    par = formation_v0.parallel_env(map="random", slip="random")
    vec.reset(seed=4)
    par.reset(seed=4)
    rng = np.random.default_rng(0)
    for _ in range(30):
        action = rng.uniform(-0.6, 0.6, (3, 2))
        _, reward, *_, info = vec.step(action[None])
        _, rewards, *_ = par.step({f"robot_{i}": action[i] for i in range(3)})
        np.testing.assert_array_equal(info["robot_rewards"][0], [rewards[f"robot_{i}"] for i in range(3)])


def test_precision_shaping_is_the_log_distance_potential_difference() -> None:
    free = MapSpec(
        "free",
        obstacles=[[8.0, 8.0, 0.5]],
        starts=CRASH.starts,
        targets=[[0.5, 0.0, 0.0], [3.0, 2.0, 0.0], [3.0, -2.0, 0.0]],
    )
    forward = np.tile([1.0, 0.0], (3, 1)).astype(np.float32)
    rewards = {}
    for weight in (0.0, 5.0):
        venv = KoopNavSB3VecEnv("KoopNav-TargetReaching-v0", 1, seed=0, precision_shaping=weight, map=free)
        venv.reset()
        rewards[weight] = np.array([venv.step(forward)[1] for _ in range(12)])  # robot 0 overshoots
    d0 = np.array([0.5, 3.0, 3.0])
    distances = np.abs(d0[None] - 0.06 * np.arange(13)[:, None])
    potential = 5.0 * np.log(distances + 0.05)
    np.testing.assert_allclose(rewards[5.0] - rewards[0.0], potential[:-1] - potential[1:], atol=1e-4)


def test_mover_shaping_charges_each_robot_its_nearest_movers_proximity() -> None:
    from baselines.features.set_features import SetFeatureConfig
    from baselines.shaping import MOVER_SHAPING_BAND

    movers = {"count": 6, "speed": 0.3, "radius": 0.2}
    kwargs = {"set_config": SetFeatureConfig(movers=4), "map": "random", "movers": movers}
    shaped = KoopNavSB3VecEnv("KoopNav-TargetReaching-v0", 4, seed=0, mover_shaping=0.3, **kwargs)
    plain = KoopNavSB3VecEnv("KoopNav-TargetReaching-v0", 4, seed=0, **kwargs)
    shaped.reset(), plain.reset()
    still = np.zeros((12, 2), dtype=np.float32)
    charged = 0
    for _ in range(150):
        rewards = [env.step(still)[1] for env in (shaped, plain)]
        cost = rewards[1] - rewards[0]
        assert np.all(cost >= -1e-6)
        charged += int((cost > 1e-6).sum())
    assert charged > 0  # robots standing among movers get charged
    # the cost of one state, by hand: a robot 0.25 m (surface) from its nearest mover pays w * (1 - 0.25/0.5)
    poses = np.zeros((1, 3, 3))
    poses[0, :, 0] = [0.0, 5.0, 10.0]
    mover_states = np.zeros((1, 6, 4))
    mover_states[0, :, 0] = 20.0
    mover_states[0, 0, 0] = 0.65  # 0.65 - 0.2 (robot) - 0.2 (mover) = 0.25 m from robot 0
    cost = shaped.shaping.mover_cost({"poses": poses, "movers": mover_states})
    np.testing.assert_allclose(cost, [[0.3 * (1 - 0.25 / MOVER_SHAPING_BAND), 0.0, 0.0]], atol=1e-12)
    with pytest.raises(ValueError, match=r"mover_shaping=-1.0 must be a finite number >= 0"):
        KoopNavSB3VecEnv("KoopNav-TargetReaching-v0", 1, mover_shaping=-1.0, **kwargs)


def test_neighbour_headings_are_relative_and_match_what_the_controller_sees() -> None:
    blocks = np.zeros((3, 27))
    blocks[:, 6] = 1.0  # distances
    blocks[:, 2:4] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]  # headings 0, pi/2, pi
    out = robot_features(blocks, "bearing+headings")
    assert out.shape == (3, 27 + 3 + 4)
    np.testing.assert_allclose(out[0, 30:], [0, 1, -1, 0], atol=1e-7)  # robots 1, 2 seen by robot 0
    np.testing.assert_allclose(out[1, 30:], [0, -1, 0, 1], atol=1e-7)  # robots 0, 2 seen by robot 1
    np.testing.assert_allclose(out[2, 30:], [-1, 0, 0, -1], atol=1e-7)  # robots 0, 1 seen by robot 2
    # the training adapter and the controller build the same inputs from the same state
    venv = KoopNavSB3VecEnv("KoopNav-Formation-v0", 1, seed=2, features="bearing+headings", map="map4")
    adapter_obs = venv.reset()
    env = gym.make("KoopNav-Formation-v0", map="map4")
    obs, _ = env.reset(seed=2)
    np.testing.assert_array_equal(adapter_obs, robot_features(obs.reshape(3, -1), "bearing+headings"))
    assert venv.observation_space.contains(adapter_obs[0])
    with pytest.raises(ValueError, match="features='all' is not one of"):
        robot_features(blocks, "all")


def test_a_three_robot_policy_sees_the_nearest_two_teammates_of_a_larger_team() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="random", n_robots=6)
    obs, info = env.reset(seed=3)
    blocks = obs.reshape(6, -1)
    full = robot_features(blocks, "bearing+headings")
    assert np.array_equal(robot_features(blocks, "bearing+headings", neighbours=5), full)
    small = robot_features(blocks, "bearing+headings", neighbours=2)
    n_obs_entries = blocks.shape[1] - 9 - 3 * 5
    assert small.shape == (6, 9 + 3 * 2 + n_obs_entries + 3 + 2 * 2)
    poses = info["poses"]
    for i in range(6):
        others = [j for j in range(6) if j != i]
        gaps = [np.hypot(*(poses[j, :2] - poses[i, :2])) for j in others]
        nearest = sorted(others[k] for k in np.argsort(gaps, kind="stable")[:2])  # radii are equal
        slots = [others.index(j) for j in nearest]
        expected = np.concatenate([blocks[i, 9 + 3 * k : 12 + 3 * k] for k in slots])
        np.testing.assert_allclose(small[i, 9:15], expected, rtol=1e-6)
        first = full.shape[1] - 2 * 5  # the relative headings of the five others
        heading = {j: full[i, first + 2 * others.index(j) : first + 2 * others.index(j) + 2] for j in nearest}
        np.testing.assert_allclose(small[i, -4:], np.concatenate([heading[j] for j in nearest]), rtol=1e-6)
    # a team of two: the missing team-mate reads like an absent obstacle
    two = robot_features(obs.reshape(6, -1)[:2, : 9 + 3], "bearing", neighbours=2)
    assert two.shape == (2, 9 + 6 + 3) and np.all(two[:, 12:15] == [0.0, 0.0, 30.0])


def test_shipped_policy_drives_a_six_robot_team() -> None:
    from koopman_envs.episodes.single import run_episode

    env = gym.make("KoopNav-Formation-v0", map="random", n_robots=6, max_episode_steps=20)
    actions: list[np.ndarray] = []
    result = run_episode(
        env, controllers.make("rl-ppo"), seed=0, on_step=lambda step, action, info: actions.append(action)
    )
    assert result.steps >= 1 and len(actions) == result.steps
    assert all(a.shape == (6, 2) and np.all(np.isfinite(a)) for a in actions)


def test_bad_layout_and_penalty_are_rejected() -> None:
    with pytest.raises(ValueError, match="layout='agents' is not one of"):
        KoopNavSB3VecEnv("KoopNav-Formation-v0", 2, layout="agents")
    with pytest.raises(ValueError, match="collision_penalty=-1.0"):
        KoopNavSB3VecEnv("KoopNav-Formation-v0", 2, collision_penalty=-1.0)
    with pytest.raises(ValueError, match="precision_shaping=nan"):
        KoopNavSB3VecEnv("KoopNav-Formation-v0", 2, precision_shaping=float("nan"))


@pytest.mark.parametrize(
    "path", sorted(SHIPPED.glob("**/policy.zip")), ids=lambda p: str(p.parent.relative_to(SHIPPED))
)
def test_shipped_policies_load_without_running_a_pickle(path, monkeypatch) -> None:
    """Issue 31: a policy zip's pickles are code; the shipped ones load with none of them run,
    and act bit for bit as the plain (pickled) load does."""
    import cloudpickle
    from stable_baselines3 import PPO
    from stable_baselines3.common import save_util

    from baselines.safe_load import load_model

    plain = PPO.load(path, device="cpu")

    def refuse(*args, **kwargs):
        raise AssertionError("a pickle was run")

    monkeypatch.setattr(cloudpickle, "loads", refuse)
    monkeypatch.setattr(save_util.cloudpickle, "loads", refuse)
    safe = load_model(path, PPO)
    assert safe.observation_space == plain.observation_space and safe.action_space == plain.action_space
    obs = np.random.default_rng(0).normal(size=(256, *plain.observation_space.shape)).astype(np.float32)
    np.testing.assert_array_equal(
        safe.predict(obs, deterministic=True)[0], plain.predict(obs, deterministic=True)[0]
    )


def test_a_zip_with_a_foreign_pickle_is_refused_unless_trusted(tmp_path) -> None:
    import json
    import zipfile

    from stable_baselines3 import PPO

    from baselines.safe_load import UnsafePolicyFile, load_model

    source = SHIPPED / "formation" / "policy.zip"
    target = tmp_path / "policy.zip"
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            payload = old.read(item.filename)
            if item.filename == "data":
                data = json.loads(payload)
                data["surprise"] = {
                    ":type:": "<class 'function'>",
                    ":serialized:": data["clip_range"][":serialized:"],
                }
                payload = json.dumps(data).encode()
            new.writestr(item, payload)
    with pytest.raises(
        UnsafePolicyFile, match=r"the pickled field 'surprise' cannot be rebuilt.*allow_pickle=True"
    ):
        load_model(target, PPO)
    assert load_model(target, PPO, allow_pickle=True) is not None  # the user's explicit trust


def test_select_reads_a_run_s_metadata_bounded_and_refuses_what_is_no_object(tmp_path) -> None:
    """baselines.sb3.select read metadata.json with json.loads and no bound: nested past the bound
    it raised RecursionError, a list or a FIFO got past it."""
    from baselines.sb3.policy import PolicyFiles
    from baselines.sb3.select import read_metadata

    path = PolicyFiles(tmp_path).metadata
    path.write_text('{"timesteps": 5}', encoding="utf-8")
    assert read_metadata(tmp_path) == {"timesteps": 5}
    path.write_text("[" * 50_000 + "]" * 50_000, encoding="utf-8")
    with pytest.raises(ValueError, match=r"metadata.json: JSON nested 50000 levels deep"):
        read_metadata(tmp_path)
    path.write_text("[1, 2]", encoding="utf-8")
    with pytest.raises(
        ValueError, match=r"metadata.json: a training run's metadata is a JSON object, not list"
    ):
        read_metadata(tmp_path)
    path.unlink()
    os.mkfifo(path)
    with pytest.raises(ValueError, match=r"training metadata"):
        read_metadata(tmp_path)
