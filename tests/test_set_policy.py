"""The set policy (rl-ppo-set): order-free, mask-exact, any team size; a tiny real training run."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import torch  # noqa: E402
from gymnasium import spaces  # noqa: E402

from baselines.curriculum import PARTS, STAGES, stage_parts  # noqa: E402
from baselines.features.set_features import (  # noqa: E402
    EGO_SIZE,
    MAX_TEAM,
    NEIGHBOUR_SIZE,
    OBSTACLE_SIZE,
    SetFeatureConfig,
    set_features,
)
from baselines.sb3.policy import RLSetPolicyController, load_policy, policy_command  # noqa: E402
from baselines.sb3.select import main as select_main  # noqa: E402
from baselines.sb3.set_encoder import SetEncoder  # noqa: E402
from baselines.sb3.train import main as train_main  # noqa: E402
from baselines.sb3.vec_env import KoopNavSB3VecEnv, MixtureVecEnv  # noqa: E402

CONFIG = SetFeatureConfig(neighbours=4, obstacles=3, sensing_radius=3.0)


def large_team(n: int) -> dict:
    """A wedge of more than 16 robots finds no room on a random map; a grid does (bench/scaling.py)."""
    return {"formation": "grid"} if n > 16 else {}


def team_blocks(env_id: str, n: int, seed: int = 0, **kwargs) -> tuple[np.ndarray, int, bool]:
    env = gym.make(env_id, n_robots=n, map="random", **large_team(n), **kwargs)
    obs, _ = env.reset(seed=seed)
    config = env.unwrapped.engine.config
    env.close()
    return obs.reshape(n, -1), config.n_obstacle_obs, config.task.formation


@pytest.fixture(scope="module")
def encoder() -> SetEncoder:
    torch.manual_seed(0)
    space = spaces.Box(-5, 5, shape=(CONFIG.size,), dtype=np.float32)
    return SetEncoder(space, CONFIG.as_dict(), width=16)


def slots(observation: np.ndarray, config: SetFeatureConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = EGO_SIZE
    b = a + config.neighbours * (NEIGHBOUR_SIZE + 1)
    ego = observation[..., :a]
    neighbours = observation[..., a:b].reshape(
        observation.shape[:-1] + (config.neighbours, NEIGHBOUR_SIZE + 1)
    )
    obstacles = observation[..., b:].reshape(observation.shape[:-1] + (config.obstacles, OBSTACLE_SIZE + 1))
    return ego, neighbours, obstacles


def join(ego: np.ndarray, neighbours: np.ndarray, obstacles: np.ndarray) -> np.ndarray:
    lead = ego.shape[:-1]
    return np.concatenate([ego, neighbours.reshape(lead + (-1,)), obstacles.reshape(lead + (-1,))], axis=-1)


def rows_sorted(rows: np.ndarray) -> np.ndarray:
    """The rows of a slot table in lexicographic order (its content as a set)."""
    return rows[np.lexsort(np.round(rows, 6).T[::-1])]


def encode(encoder: SetEncoder, observation: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return encoder(torch.as_tensor(observation, dtype=torch.float32)).numpy()


@pytest.mark.parametrize("n", [2, 7, 32])
def test_set_observations_have_one_size_for_every_team(n: int) -> None:
    blocks, listed, formation = team_blocks("KoopNav-TargetReaching-v0", n)
    observed = set_features(blocks, listed, formation, CONFIG)
    assert observed.shape == (n, CONFIG.size)
    assert np.isfinite(observed).all()
    _, neighbours, _ = slots(observed, CONFIG)
    present = neighbours[..., -1]
    assert set(np.unique(present)) <= {0.0, 1.0}
    # a robot reads at most K team-mates, and never more than there are
    assert (present.sum(axis=1) <= min(CONFIG.neighbours, n - 1)).all()


def test_neighbours_beyond_the_sensing_radius_are_masked() -> None:
    blocks, listed, formation = team_blocks("KoopNav-TargetReaching-v0", 6)
    near = set_features(blocks, listed, formation, SetFeatureConfig(5, 3, sensing_radius=0.05))
    far = set_features(blocks, listed, formation, SetFeatureConfig(5, 3, sensing_radius=100.0))
    config = SetFeatureConfig(5, 3)
    assert slots(far, config)[1][..., -1].sum() == 6 * 5  # everybody within 100 m
    # starts keep 0.3 m of clearance: nobody within 5 cm, and absent slots hold only zeros
    assert not slots(near, config)[1].any()


def test_the_encoder_ignores_the_order_of_neighbours_and_obstacles(encoder) -> None:
    blocks, listed, formation = team_blocks("KoopNav-TargetReaching-v0", 7, n_obstacle_obs=3)
    observed = set_features(blocks, listed, formation, CONFIG)
    ego, neighbours, obstacles = slots(observed, CONFIG)
    rng = np.random.default_rng(0)
    shuffled = join(
        ego,
        neighbours[:, rng.permutation(CONFIG.neighbours)],
        obstacles[:, rng.permutation(CONFIG.obstacles)],
    )
    assert not np.array_equal(shuffled, observed)
    np.testing.assert_allclose(encode(encoder, shuffled), encode(encoder, observed), rtol=1e-5, atol=1e-6)


def test_relabelling_the_team_leaves_each_robots_observation_unchanged() -> None:
    n = 6
    blocks, listed, formation = team_blocks("KoopNav-TargetReaching-v0", n, seed=3)
    env = gym.make("KoopNav-TargetReaching-v0", n_robots=n, map="random")
    env.reset(seed=3)
    engine = env.unwrapped.engine
    order = np.array([3, 0, 5, 1, 4, 2])
    # the same scene with the robots numbered in another order: rebuild the blocks from the state
    state, target = engine.state.copy(), engine.target.copy()
    engine.state[:] = state[..., order]
    engine.target[:] = target[..., order]
    relabelled = engine.features()[0]
    env.close()
    # every team-mate read (K >= N - 1): the sets must agree, in whatever order ties were listed
    config = SetFeatureConfig(neighbours=n - 1, obstacles=3)
    before = set_features(blocks, listed, formation, config)[order]
    after = set_features(relabelled, listed, formation, config)
    for robot in range(n):
        (ego_a, mates_a, obstacles_a), (ego_b, mates_b, obstacles_b) = (
            slots(after[robot], config),
            slots(before[robot], config),
        )
        np.testing.assert_allclose(ego_a, ego_b, atol=1e-6)
        np.testing.assert_allclose(rows_sorted(mates_a), rows_sorted(mates_b), atol=1e-6)
        np.testing.assert_allclose(obstacles_a, obstacles_b, atol=1e-6)


def test_masked_slots_change_nothing(encoder) -> None:
    blocks, listed, formation = team_blocks("KoopNav-TargetReaching-v0", 3, n_obstacle_obs=1)
    observed = set_features(blocks, listed, formation, CONFIG)
    ego, neighbours, obstacles = slots(observed, CONFIG)
    assert (neighbours[:, 2:, -1] == 0).all() and (obstacles[:, 1:, -1] == 0).all()  # 2 mates, 1 obstacle
    noisy_n, noisy_o = neighbours.copy(), obstacles.copy()
    rng = np.random.default_rng(1)
    noisy_n[:, 2:, :-1] = rng.normal(size=noisy_n[:, 2:, :-1].shape) * 5
    noisy_o[:, 1:, :-1] = rng.normal(size=noisy_o[:, 1:, :-1].shape) * 5
    np.testing.assert_array_equal(encode(encoder, join(ego, noisy_n, noisy_o)), encode(encoder, observed))
    # an unmasked slot does matter
    noisy_n[:, 0, 0] += 1.0
    assert not np.array_equal(encode(encoder, join(ego, noisy_n, noisy_o)), encode(encoder, observed))


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"neighbours": 0}, "neighbours=0"),
        ({"obstacles": 0}, "obstacles=0"),
        ({"sensing_radius": 0.0}, "sensing_radius=0.0"),
        ({"sensing_radius": -1.0}, "sensing_radius=-1.0"),
    ],
)
def test_bad_set_settings_are_rejected_with_the_value(fields, message) -> None:
    with pytest.raises(ValueError, match=message):
        SetFeatureConfig(**fields)


def test_a_team_beyond_the_supported_size_is_rejected() -> None:
    blocks = np.zeros((MAX_TEAM + 1, 9 + 3 * MAX_TEAM))
    with pytest.raises(ValueError, match=f"1..{MAX_TEAM} robots; these blocks hold {MAX_TEAM + 1}"):
        set_features(blocks, 0, False, CONFIG)


def test_every_curriculum_stage_covers_its_budget_and_builds() -> None:
    for task, stages in STAGES.items():
        assert sum(stage.share for stage in stages) == pytest.approx(1.0)
        for stage in stages:
            parts = stage_parts(task, stage)
            assert [(n, k) for n, k, _ in parts] == list(PARTS)
    # one part of the hardest stage: a mixture of two team sizes gives one observation shape
    task = "target_reaching"
    (n1, _, kw1), (n2, _, kw2) = stage_parts(task, STAGES[task][-1])[:2]
    mixture = MixtureVecEnv(
        [
            KoopNavSB3VecEnv("KoopNav-TargetReaching-v0", 2, seed=0, set_config=CONFIG, **kw1),
            KoopNavSB3VecEnv("KoopNav-TargetReaching-v0", 2, seed=9, set_config=CONFIG, **kw2),
        ]
    )
    assert mixture.num_envs == 2 * n1 + 2 * n2
    assert mixture.reset().shape == (2 * n1 + 2 * n2, CONFIG.size)
    mixture.close()


@pytest.fixture(scope="module")
def set_root(tmp_path_factory):
    """A real (tiny) curriculum run of the training command, then the selection command."""
    run = tmp_path_factory.mktemp("set_run")
    code = train_main(
        [
            "--env",
            "KoopNav-TargetReaching-v0",
            "--policy",
            "set",
            "--timesteps",
            "3000",  # one rollout per curriculum stage (4 steps of every robot of the parts)
            "--n-steps",
            "4",
            "--batch-size",
            "576",
            "--eval-freq",
            "1500",
            "--validation-episodes",
            "1",  # one held-out episode per checkpoint scores it (the tests read no rate)
            "--set-width",
            "16",
            # one torch thread: with two, their waits for each other cost 2-6 times the CPU of the
            # training itself when the cores are busy (an xdist worker beside the other)
            "--threads",
            "1",
            "--out",
            str(run),
        ]
    )
    assert code == 0
    root = tmp_path_factory.mktemp("set_policies")
    assert select_main(["--run", str(run), "--out", str(root / "target_reaching"), "--episodes", "1"]) == 0
    return root


def test_the_training_command_runs_the_curriculum_and_records_it(set_root) -> None:
    metadata = json.loads((set_root / "target_reaching" / "metadata.json").read_text())
    assert metadata["set_config"] == SetFeatureConfig().as_dict()
    assert [s["name"] for s in metadata["curriculum"]["stages"]] == ["basics", "crossing", "full"]
    assert metadata["trained_timesteps"] >= 3000 and metadata["robot_steps_per_second"] > 0
    assert metadata["selection"]["validation"], "the selection scored no candidate"
    assert "paper" not in metadata["selection"]["rule"]


def _tiny_run(out, *extra: str) -> list[str]:
    """The arguments of a tiny set-policy training run (the fixture's settings) into ``out``."""
    return [
        "--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--timesteps", "600", "--n-steps", "1",
        "--batch-size", "576", "--eval-freq", "100000", "--validation-episodes", "1", "--set-width", "16",
        "--out", str(out), *extra,
    ]  # fmt: skip


def test_fine_tuning_starts_from_the_given_policy_and_records_it(set_root, tmp_path, monkeypatch) -> None:
    import torch

    from baselines.sb3 import train

    source, _, _ = load_policy(set_root / "target_reaching", "target_reaching")
    started = {}

    def learn_nothing(self, model, venv, resumed=None):  # capture the weights training starts from
        started.update({k: v.clone() for k, v in model.policy.state_dict().items()})
        return venv

    monkeypatch.setattr(train.Trainer, "learn", learn_nothing)
    args = _tiny_run(
        tmp_path / "tuned", "--uncertainty", "realistic", "--init-from", str(set_root / "target_reaching")
    )
    assert train_main(args) == 0
    expected = source.policy.state_dict()
    assert started.keys() == expected.keys()
    assert all(torch.equal(started[k], expected[k]) for k in expected)
    metadata = json.loads((tmp_path / "tuned" / "metadata.json").read_text())
    assert metadata["uncertainty"] == "realistic"
    assert metadata["initialized_from"]["path"] == str(set_root / "target_reaching")
    assert metadata["initialized_from"]["uncertainty"] == "nominal"


def test_training_leaves_the_callers_torch_threads_as_they_were(tmp_path, monkeypatch) -> None:
    import torch

    from baselines.sb3 import train

    during = []

    def learn_nothing(self, model, venv, resumed=None):
        during.append(torch.get_num_threads())
        return venv

    monkeypatch.setattr(train.Trainer, "learn", learn_nothing)
    before = torch.get_num_threads()
    torch.set_num_threads(3)
    try:
        assert train_main(_tiny_run(tmp_path / "run", "--threads", "1")) == 0
        assert during == [1] and torch.get_num_threads() == 3
    finally:
        torch.set_num_threads(before)


def test_fine_tuning_from_a_policy_that_does_not_fit_is_refused_by_name(set_root, tmp_path, capsys) -> None:
    args = _tiny_run(tmp_path / "bad", "--set-width", "32", "--init-from", str(set_root / "target_reaching"))
    assert train_main(args) == 2
    assert "set_width is 16, this run needs 32" in capsys.readouterr().err
    assert not (tmp_path / "bad" / "policy.zip").exists()


@pytest.mark.parametrize("n", [2, 7, 32])
def test_one_policy_drives_any_team_size(set_root, n: int) -> None:
    ctrl = RLSetPolicyController(set_root)
    env = gym.make(
        "KoopNav-TargetReaching-v0", n_robots=n, map="random", max_episode_steps=5, **large_team(n)
    )
    obs, info = env.reset(seed=n)
    ctrl.reset(env.unwrapped.scenario, seed=n)
    for _ in range(5):
        action = ctrl.act(obs, info)
        assert action.shape == (2 * n,) and env.action_space.contains(action.astype(np.float32))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    env.close()


def test_batched_set_commands_equal_single_commands(set_root) -> None:
    model, norm, metadata = load_policy(set_root / "target_reaching", "target_reaching")
    config = SetFeatureConfig(**metadata["set_config"])
    venv = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=3, n_robots=5, map="random")
    obs, _ = venv.reset(seed=0)
    batched = policy_command(model, norm, "robot", obs, 5, 0.6, 0.8, set_config=config)
    single = np.stack([policy_command(model, norm, "robot", o, 5, 0.6, 0.8, set_config=config) for o in obs])
    np.testing.assert_allclose(batched, single, atol=1e-6)
    venv.close()


def _policy_directories(set_root) -> list:
    from baselines.sb3.policy import SHIPPED

    directories = [set_root / "target_reaching"] + [
        p for p in SHIPPED.glob("*") if (p / "policy.zip").exists()
    ]
    return directories + [p for p in SHIPPED.glob("*/*") if (p / "policy.zip").exists()]


def _masked_observations(model, rng, rows: int) -> np.ndarray:
    """Random normalized observations; a set policy's mask entries 0 or 1 (as the features give)."""
    from baselines.sb3.actor import compile_actor

    obs = (2 * rng.normal(size=(rows, model.observation_space.shape[0]))).astype(np.float32)
    for pool in compile_actor(model).sets:
        width = pool.slot_size + 1
        masks = np.arange(pool.columns.start + pool.slot_size, pool.columns.stop, width)
        obs[:, masks] = rng.random((rows, len(masks))) < 0.6
    return obs


def test_the_compiled_actor_acts_as_predict(set_root) -> None:
    """The compiled actor (baselines.sb3.actor) computes predict's deterministic action: equal within
    float32 rounding (it sums in another order than torch's kernels), for every shipped policy,
    the set encoder's masked slots included."""
    from baselines.sb3.policy import deterministic_action

    rng = np.random.default_rng(0)
    directories = _policy_directories(set_root)
    assert len(directories) >= 7  # the trained fixture and every shipped policy
    for directory in directories:
        model, _, _ = load_policy(directory)
        obs = _masked_observations(model, rng, 64)
        expected, _ = model.predict(obs, deterministic=True)
        np.testing.assert_allclose(deterministic_action(model, obs), expected, rtol=0, atol=2e-5)


def test_a_robots_action_does_not_depend_on_the_batch(set_root) -> None:
    """The property a batched evaluation rests on: a row's action is the same bit for bit alone,
    in a batch of any size and at any place in it (torch's batched forward is not)."""
    from baselines.sb3.actor import compile_actor

    rng = np.random.default_rng(1)
    for directory in _policy_directories(set_root):
        model, _, _ = load_policy(directory)
        actor = compile_actor(model)
        obs = _masked_observations(model, rng, 97)
        batch = actor(obs)
        alone = np.concatenate([actor(obs[i : i + 1]) for i in range(len(obs))])
        np.testing.assert_array_equal(batch, alone)
        order = rng.permutation(len(obs))
        np.testing.assert_array_equal(actor(obs[order]), batch[order])
        np.testing.assert_array_equal(actor(obs[:5]), batch[:5])


def test_a_policy_the_actor_does_not_compile_goes_through_predict(set_root) -> None:
    """A policy with a part baselines.sb3.actor does not compile (here a SiLU activation) is not
    compiled, and its actions come from predict."""
    import torch

    from baselines.sb3.actor import compile_actor
    from baselines.sb3.policy import deterministic_action

    model, _, _ = load_policy(set_root / "target_reaching")
    model.policy.mlp_extractor.policy_net[1] = torch.nn.SiLU()
    assert compile_actor(model) is None
    obs = _masked_observations(load_policy(set_root / "target_reaching")[0], np.random.default_rng(2), 8)
    expected, _ = model.predict(obs, deterministic=True)
    np.testing.assert_array_equal(deterministic_action(model, obs), expected)


def test_a_fine_tune_that_grows_mover_slots_starts_as_its_source(set_root, tmp_path, monkeypatch) -> None:
    """A set policy without movers seeds a run with mover slots: the grown policy acts exactly as
    its source on observations with movers present (the movers' columns start at zero)."""
    import torch

    from baselines.features.set_features import MOVER_SIZE, SetFeatureConfig
    from baselines.sb3 import train

    source, _, _ = load_policy(set_root / "target_reaching", "target_reaching")
    started = {}

    def learn_nothing(self, model, venv, resumed=None):
        started["policy"] = model.policy
        return venv

    monkeypatch.setattr(train.Trainer, "learn", learn_nothing)
    args = _tiny_run(
        tmp_path / "grown", "--movers", '{"count": 4}', "--init-from", str(set_root / "target_reaching")
    )
    assert train_main(args) == 0
    grown = started["policy"]
    old = SetFeatureConfig(
        **json.loads((set_root / "target_reaching" / "metadata.json").read_text())["set_config"]
    )
    rng = np.random.default_rng(0)
    base = rng.uniform(-1, 1, (32, old.size)).astype(np.float32)
    movers = rng.uniform(-1, 1, (32, 4, MOVER_SIZE + 1)).astype(np.float32)
    movers[..., -1] = 1.0  # every mover slot present
    with torch.no_grad():
        theirs = source.policy.get_distribution(torch.as_tensor(base)).distribution.mean
        mine = grown.get_distribution(
            torch.as_tensor(np.hstack([base, movers.reshape(32, -1)]))
        ).distribution.mean
    torch.testing.assert_close(mine, theirs)
    metadata = json.loads((tmp_path / "grown" / "metadata.json").read_text())
    assert metadata["set_config"]["movers"] == 4 and metadata["movers"] == {"count": 4}
    assert metadata["initialized_from"]["grown"]  # the heads' first layers grew


def test_the_movers_set_reads_the_listed_movers() -> None:
    from baselines.features.set_features import MOVER_SIZE, SetFeatureConfig, set_features, split_movers

    env = gym.make("KoopNav-TargetReaching-v0", movers=dict(count=2, observed=3, tracking=False))
    obs, info = env.reset(seed=1)
    blocks, movers = split_movers(obs.reshape(3, -1), env.unwrapped.scenario.observation_layout)
    assert movers.shape == (3, 3, MOVER_SIZE) and (movers[:, 2, 4] == 30).all()  # the third absent
    config = SetFeatureConfig(movers=3, sensing_radius=100.0)
    features = set_features(blocks, (blocks.shape[-1] - 15) // 3, False, config, movers)
    slots = features[:, -3 * (MOVER_SIZE + 1) :].reshape(3, 3, MOVER_SIZE + 1)
    assert (slots[:, :2, -1] == 1).all() and (slots[:, 2] == 0).all()  # two present, one masked
    np.testing.assert_allclose(slots[:, 0, 0], np.clip(movers[:, 0, 0] / 3.0, -3, 3), rtol=1e-6)
    plain = set_features(blocks, (blocks.shape[-1] - 15) // 3, False, SetFeatureConfig(sensing_radius=100.0))
    np.testing.assert_array_equal(features[:, : plain.shape[-1]], plain)  # appended after the others
