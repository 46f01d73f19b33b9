"""No built-in controller reads the true state: each is handed infos whose true fields are
poisoned and must act exactly as with the real ones, under runtime uncertainty; and what they
read (koopman_envs.observed) is what the robots believe, not the truth.

This is the quick check of every registered controller (NaN, a few steps). NaN fails every
comparison silently, so tests/test_truth_isolation.py runs whole episodes where team-mates and
movers come close, with plausible lies as well as NaN in the true fields, and checks that the
learned policies read the observation and nothing else."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.calibration import calibrate_controller
from koopman_envs import Observed
from koopman_envs.engine.plant import make_plant
from koopman_envs.observed import OBSERVED_KEYS, SENSED_KEYS

#: every built-in controller and preset (rl-ppo needs the [rl] extra, as everywhere)
NAMES = list(controllers.available())
STEPS = 4


def _poisoned(info: dict[str, Any]) -> dict[str, Any]:
    """``info`` with every field outside the observed view replaced by garbage."""
    bad: dict[str, Any] = {}
    for key, value in info.items():
        if key in OBSERVED_KEYS:
            bad[key] = value
        elif isinstance(value, np.ndarray) and value.dtype.kind == "f":
            bad[key] = np.full_like(value, np.nan)
        elif isinstance(value, np.ndarray):
            bad[key] = np.zeros_like(value)
        else:
            bad[key] = type(value)() if not isinstance(value, bool) else not value
    return bad


@pytest.mark.parametrize("name", NAMES)
def test_poisoned_truth_changes_no_action(name: str, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("KOOPNAV_CACHE", str(tmp_path))
    if name.startswith("rl-"):
        pytest.importorskip("stable_baselines3")
    env_id = "KoopNav-Formation-v0"
    env = gym.make(env_id, uncertainty="harsh")
    try:
        honest, fooled = controllers.make(name), controllers.make(name)
    except ImportError as exc:  # an optional extra (orca: [crowd]); the board names it and skips
        pytest.skip(str(exc))
    for ctrl in (honest, fooled):  # a small calibration (the evaluator's step), in a private cache
        calibrate_controller(ctrl, make_plant(env_id, slip="high", budget=2000, seed=0), seed=0)
    obs, info = env.reset(seed=5)
    honest.reset(env, seed=5)
    fooled.reset(env, seed=5)
    for _ in range(STEPS):
        a = np.asarray(honest.act(obs, info))
        b = np.asarray(fooled.act(obs, _poisoned(info)))
        assert np.array_equal(a, b), name
        obs, _, terminated, truncated, info = env.step(a)
        if terminated or truncated:
            break


def test_the_view_is_what_the_robots_believe() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", uncertainty="harsh", sensing="lidar")
    _, info = env.reset(seed=1)
    for _ in range(5):
        _, _, _, _, info = env.step(np.zeros(6))
    view = Observed.from_info(info)
    # every sensed field but the movers' (this env has none), and none of what a controller's
    # front-ends (radio, estimator, perception) hand on (an env never writes them)
    sensed = {key for key in SENSED_KEYS if getattr(view, key) is not None}
    assert sensed == set(SENSED_KEYS) - {"observed_movers", "mover_tracked"}
    assert all(getattr(view, key) is None for key in (*OBSERVED_KEYS[len(SENSED_KEYS) :], "pose_age"))
    assert not view.perceived
    assert view.poses is view.observed_poses and not np.array_equal(view.distances, info["distances"])
    assert not np.array_equal(view.observed_poses, info["poses"])  # noisy estimates
    # harsh: 3 periods of latency, so a team-mate is never heard of fresher than that
    heard = view.message_age[~np.eye(3, dtype=bool)]
    assert ((heard >= 3) | (heard == -1)).all() and (heard >= 3).any()
    assert view.lidar_ranges is not None and view.lidar_ranges.shape == (3, 32)


def test_without_uncertainty_the_view_is_the_truth() -> None:
    env = gym.make("KoopNav-Formation-v0")
    _, info = env.reset(seed=0)
    assert np.array_equal(info["observed_poses"], info["poses"])
    assert all(np.array_equal(info["known_poses"][i], info["poses"]) for i in range(3))
    assert (info["message_age"] == 0).all() and "lidar_ranges" not in info
    view = Observed.from_info(info)  # the earlier API's aliases, equal to the truth bit for bit
    assert np.array_equal(view.poses, info["poses"]) and np.array_equal(view.distances, info["distances"])


@pytest.mark.parametrize("bad", [np.nan, 1.5, np.inf, 2.0**63])
def test_an_age_that_is_no_whole_number_of_periods_is_refused(bad: float) -> None:
    """A NaN or fractional ``message_age`` is refused naming the key and the entry, not cast to
    an arbitrary integer (NaN gave -2**63 with only a RuntimeWarning): its readers act on it."""
    ages = np.array([[0.0, 2.0], [-1.0, 0.0]])
    ages[1, 0] = bad
    with pytest.raises(ValueError, match=r"message_age\[1, 0\]=.* is not a whole number of periods"):
        Observed.from_info({"poses": np.zeros((2, 3)), "message_age": ages})
    with pytest.raises(TypeError, match="message_age has dtype"):
        Observed.from_info({"poses": np.zeros((2, 3)), "message_age": ages.astype(str)})


def test_whole_ages_are_read_as_given() -> None:
    """Whole ages pass: an int64 array as it is (not copied), whole floats exactly."""
    ages = np.array([[0, 3], [-1, 0]], dtype=np.int64)
    assert Observed.from_info({"poses": np.zeros((2, 3)), "message_age": ages}).message_age is ages
    read = Observed.from_info({"poses": np.zeros((2, 3)), "message_age": ages.astype(float)}).message_age
    assert read.dtype == np.int64 and np.array_equal(read, ages)
