"""The named observation layout (koopman_envs/layout.py, issue 44): every env front carries
it, its parts hold what their names say on real observations under every setting that adds or
removes a part, and a wrong name or index is refused by name."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import formation_v0
from koopman_envs.layout import ObservationLayout
from koopman_envs.settings import MoverConfig
from koopman_envs.tasks.observation import FAR

TR, FM = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
SETTINGS = [
    (TR, {}),
    (FM, {}),
    (TR, {"n_robots": 5, "map": "random"}),
    (FM, {"sensing": "lidar"}),
    (TR, {"uncertainty": "realistic"}),
    (FM, {"movers": {"count": 3}}),
    (TR, {"movers": {"count": 3}, "sensing": "lidar"}),
    (TR, {"movers": {"count": 2}, "uncertainty": "realistic"}),
]


@pytest.mark.parametrize("env_id, kwargs", SETTINGS, ids=[f"{e[8:12]}-{sorted(k)}" for e, k in SETTINGS])
def test_the_parts_hold_what_their_names_say(env_id: str, kwargs: dict) -> None:
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=3)
    layout = env.unwrapped.scenario.observation_layout
    n = env.unwrapped.scenario.n_robots
    blocks = obs.reshape(n, -1).astype(np.float64)
    assert layout.size == blocks.shape[1]
    own = np.asarray(info["observed_poses"])  # what each robot believes of itself
    np.testing.assert_allclose(blocks[:, layout["position"]], own[:, :2], atol=1e-5)
    np.testing.assert_allclose(
        blocks[:, layout["heading"]], np.c_[np.cos(own[:, 2]), np.sin(own[:, 2])], atol=1e-6
    )
    target = blocks[:, layout["target"]]
    np.testing.assert_allclose(blocks[:, layout.entry("target_distance")], np.hypot(*target.T), atol=1e-5)
    assert layout["team"].stop - layout["team"].start == 3 * (n - 1)
    lidar = kwargs.get("sensing") == "lidar"
    assert layout.has("beams") == lidar and layout.has("obstacles") == (not lidar)
    if lidar:
        np.testing.assert_allclose(blocks[:, layout["beams"]], np.asarray(info["lidar_ranges"]), atol=1e-5)
    else:  # the listed obstacles' clearances: nearest first, absent ones FAR
        gaps = blocks[:, layout["obstacles"]][:, 2::3]
        assert np.all(np.diff(gaps, axis=1) >= -1e-6) and np.all(gaps <= FAR)
    assert layout.has("formation_error") == (env_id == FM)
    assert layout.has("messages") == ("uncertainty" in kwargs)
    # movers are listed only when the robots sense the state: the rule decided in one place
    listed = MoverConfig().observed if "movers" in kwargs and not lidar else 0
    assert layout.movers == listed
    if layout.movers:
        assert layout["movers"].stop == layout.size


def test_every_front_carries_the_same_layout() -> None:
    single = gym.make(FM, uncertainty="realistic")
    single.reset(seed=0)
    vector = gym.make_vec(FM, num_envs=2, uncertainty="realistic")
    vector.reset(seed=0)
    parallel = formation_v0.parallel_env(uncertainty="realistic")
    parallel.reset(seed=0)
    layout = single.unwrapped.scenario.observation_layout
    assert vector.unwrapped.scenario(1).observation_layout == layout
    assert parallel.scenario.observation_layout == layout
    assert vector.single_observation_space.shape == (3 * layout.size,)


def test_a_wrong_part_or_entry_is_refused_by_name() -> None:
    layout = ObservationLayout(3, 4, formation=False)
    with pytest.raises(KeyError, match=r"no part 'formation_error'.*'team'"):
        layout["formation_error"]
    with pytest.raises(IndexError, match=r"part 'heading' has 2 entries; index 2"):
        layout.entry("heading", 2)
    assert layout.entry("target_heading", 1) == 8 and layout["obstacles"] == slice(15, 27)
    assert ObservationLayout.for_settings(3, 4, True, 16, False, 5).movers == 0  # lidar: no list


def test_the_observation_contract_is_exported_by_the_package() -> None:
    """The layout and what controllers receive are the package's face (issue 61), as the
    item entries were: ``from koopman_envs import ObservationLayout, Observed``."""
    from koopman_envs import layout, observed

    for name, module in (("ObservationLayout", layout), ("PartOffsets", layout), ("Observed", observed)):
        assert name in koopman_envs.__all__, name
        assert getattr(koopman_envs, name) is getattr(module, name), name


def test_the_pettingzoo_modules_are_attributes_of_the_package() -> None:
    import subprocess
    import sys

    code = (
        "import koopman_envs; env = koopman_envs.formation_v0.parallel_env(); env.reset(seed=0); "
        "print(len(env.agents), koopman_envs.target_reaching_v0.__name__)"
    )
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["3", "koopman_envs.target_reaching_v0"]


def test_the_dict_observation_is_the_flat_one_resliced() -> None:
    from koopman_envs.fronts.dict_observation import DictObservation

    flat_env = gym.make(FM, uncertainty="realistic", movers={"count": 2})
    dict_env = DictObservation(gym.make(FM, uncertainty="realistic", movers={"count": 2}))
    layout = flat_env.unwrapped.observation_layout  # known before the first reset
    assert dict_env.layout == layout and set(dict_env.observation_space) == {p for p, _ in layout.parts}
    flat, _ = flat_env.reset(seed=2)
    parts, _ = dict_env.reset(seed=2)
    for _ in range(5):
        assert dict_env.observation_space.contains(parts)
        blocks = flat.reshape(3, -1)
        for name, _width in layout.parts:
            assert np.array_equal(parts[name], blocks[:, layout[name]]), name
        action = np.full(flat_env.action_space.shape, 0.1, dtype=np.float32)
        flat, *_ = flat_env.step(action)
        parts, *_ = dict_env.step(action)
    with pytest.raises(TypeError, match="needs a KoopNav env"):
        DictObservation(gym.make("CartPole-v1"))
