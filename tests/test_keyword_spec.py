"""One keyword spec for all fronts: engine.ENV_KEYWORDS declares and defaults the env keywords,
EngineConfig.create validates them, and every front takes, shows and forwards exactly those."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.keywords import ENV_KEYWORDS, FRONTS, env_keywords
from koopman_envs.fronts.gym_env import FormationEnv, TargetReachingEnv
from koopman_envs.fronts.parallel_env import KoopNavParallelEnv
from koopman_envs.fronts.vector_env import KoopNavVectorEnv

FO = "KoopNav-Formation-v0"

#: every way to build an env, with the front whose keywords it takes
BUILDERS: dict[str, tuple[str, Callable[..., Any]]] = {
    "gym class": ("gym", lambda **kw: FormationEnv(**kw)),
    "gym.make": ("gym", lambda **kw: gym.make(FO, **kw)),
    "gym.make_vec": ("vector", lambda **kw: gym.make_vec(FO, num_envs=2, **kw)),
    "parallel_env": ("parallel", lambda **kw: formation_v0.parallel_env(**kw)),
    "env (AEC)": ("parallel", lambda **kw: formation_v0.env(**kw)),
    "raw_env": ("parallel", lambda **kw: formation_v0.raw_env(**kw)),
}

#: one bad value per keyword, and the start of the message that names it
BAD = {
    "map": ("nowhere", "map='nowhere' is not one of"),
    "slip": ("extreme", "slip='extreme' is not one of"),
    "plant": (
        "mujuco",
        r"plant='mujuco' is not one of \['kinematic', 'mujoco'\] \(did you mean 'mujoco'\?\)",
    ),
    "n_robots": (0, "n_robots=0 must be an integer >= 1"),
    "goal_tolerance": (-1.0, "goal_tolerance=-1.0 must be a finite number > 0"),
    "robot_radius": (0.0, "robot_radius=0.0 must be a finite number > 0"),
    "n_obstacle_obs": (-1, "n_obstacle_obs=-1 must be an integer >= 0"),
    "random_map": (3, "random_map=3 must be a RandomMapConfig"),
    "start_noise": (-1.0, "start_noise=-1.0 must be a finite number >= 0"),
    "formation": ("ring", "formation='ring' is not one of"),
    "max_episode_steps": (0, "max_episode_steps=0 must be an integer >= 1"),
    "max_cycles": (0, "max_cycles=0 must be an integer >= 1"),
    "uncertainty": ("realstic", r"uncertainty='realstic' is not one of .* \(did you mean 'realistic'\?\)"),
    "pose_noise": (-0.1, r"pose_noise=-0.1 must be a finite number >= 0"),
    "sensing": ("lidars", r"sensing='lidars' is not one of \['state', 'lidar'\] \(did you mean 'lidar'\?\)"),
    "lidar": ({"beams": 8}, r"lidar=\{'beams': 8\} is given with sensing='state'; add sensing='lidar'"),
    "comm": ({"drop": 1.5}, r"comm.drop=1.5 must be a finite number >= 0 <= 1"),
    "actuation_delay": (-1, r"actuation_delay=-1 must be an integer >= 0"),
    "movers": ({"behaviour": "crowds"}, r"movers.behaviour='crowds' is not one of .*did you mean 'crowd'"),
}


def test_every_keyword_has_a_bad_value_here() -> None:
    assert sorted(BAD) == sorted(k.name for k in ENV_KEYWORDS)


@pytest.mark.parametrize(
    "front, constructor, own",
    [
        ("gym", TargetReachingEnv, ["render_mode"]),
        ("gym", FormationEnv, ["render_mode"]),
        ("vector", KoopNavVectorEnv, ["num_envs", "task", "autoreset_mode", "render_mode"]),
        ("parallel", KoopNavParallelEnv, ["task", "render_mode"]),
        ("parallel", target_reaching_v0.parallel_env, ["render_mode"]),
        ("parallel", formation_v0.env, ["render_mode"]),
        ("parallel", formation_v0.raw_env, ["render_mode"]),
    ],
)
def test_the_signatures_are_the_table(front: str, constructor: Callable, own: list[str]) -> None:
    """``inspect.signature`` / ``help()`` show the front's own parameters, then every env keyword
    the front takes, keyword-only, with the table's default."""
    parameters = list(inspect.signature(constructor).parameters.values())
    names = [p.name for p in parameters]
    rows = env_keywords(front)
    assert names == own + [k.name for k in rows]
    for parameter, row in zip(parameters[len(own) :], rows):
        assert parameter.kind is inspect.Parameter.KEYWORD_ONLY
        assert parameter.default == row.default and parameter.annotation == row.annotation


def test_only_pettingzoo_takes_max_cycles() -> None:
    assert {k.name for k in ENV_KEYWORDS} - {k.name for k in env_keywords("gym")} == {"max_cycles"}
    assert env_keywords("gym") == env_keywords("vector")
    assert env_keywords("parallel") == env_keywords() == ENV_KEYWORDS
    with pytest.raises(ValueError, match=r"front='aec' is not one of \['gym', 'vector', 'parallel'\]"):
        env_keywords("aec")
    assert FRONTS == ("gym", "vector", "parallel")


@pytest.mark.parametrize("builder", BUILDERS)
def test_every_keyword_reaches_the_one_check(builder: str) -> None:
    """A bad value of each keyword the front takes fails with EngineConfig.create's message."""
    front, make = BUILDERS[builder]
    for row in env_keywords(front):
        if builder == "gym.make" and row.name == "max_episode_steps":
            continue  # gym.make keeps it for its TimeLimit wrapper
        value, message = BAD[row.name]
        with pytest.raises(ValueError, match=message):
            make(**{row.name: value})


@pytest.mark.parametrize("builder", BUILDERS)
def test_unknown_keywords_are_named_with_the_allowed_ones(builder: str) -> None:
    front, make = BUILDERS[builder]
    with pytest.raises(
        TypeError,
        match=r"got an unexpected keyword argument 'n_robot'; unknown keyword arguments \['n_robot'\] \(did you mean 'n_robots' "
        r"for 'n_robot'\?\); allowed: \[.*'render_mode'.*'formation'",
    ):
        make(n_robot=4)
    if front != "parallel":
        with pytest.raises(TypeError, match=r"unknown keyword arguments \['max_cycles'\]"):
            make(max_cycles=5)


def test_engine_config_create_takes_the_table_and_nothing_else() -> None:
    config = EngineConfig.create("formation", map="random", n_robots=5, formation="grid", max_cycles=9)
    assert config.n_robots == 5 and config.random_map.formation == "grid" and config.max_episode_steps == 9
    defaults = EngineConfig.create("formation")
    assert defaults.map_name == "map3" and defaults.n_robots == 3 and defaults.formation is None
    assert defaults.max_episode_steps is None  # no front: no default limit
    assert EngineConfig.create("formation", front="vector").max_episode_steps == 600
    with pytest.raises(
        TypeError,
        match=r"the KoopNav env got an unexpected keyword argument 'colour'; unknown keyword arguments \['colour'\]",
    ):
        EngineConfig.create("formation", colour="red")
    with pytest.raises(
        TypeError,
        match=r"the gym env got an unexpected keyword argument 'max_cycles'; unknown keyword arguments \['max_cycles'\]",
    ):
        EngineConfig.create("formation", front="gym", max_cycles=3)


def test_the_gymnasium_class_given_a_limit_truncates_by_itself() -> None:
    env = FormationEnv(max_episode_steps=3)
    env.reset(seed=0)
    flags = [env.step(np.zeros(6))[2:4] for _ in range(3)]
    assert flags == [(False, False), (False, False), (False, True)]
    wrapped = gym.make(FO, max_episode_steps=3)  # gym.make: the TimeLimit wrapper's limit
    assert wrapped.unwrapped.config.max_episode_steps is None


def test_the_docs_list_every_keyword() -> None:
    """The env docstrings' Arguments table and the PettingZoo modules' make call are generated;
    the environments guide's keyword list is written by hand, so it is held to the table here."""
    readme = (Path(__file__).parents[1] / "docs" / "environments.md").read_text()
    for row in ENV_KEYWORDS:
        assert f"`{row.name}`" in readme, row.name
        assert f"| {row.name} |" in FormationEnv.__doc__ or row.name == "max_cycles"
        assert f"{row.name}=" in formation_v0.__doc__ and f"{row.name}=" in target_reaching_v0.__doc__


def test_the_evaluator_takes_the_table_as_env_kwargs() -> None:
    from evaluation.run.spec import RunSpec

    spec = RunSpec(
        "KoopNav-Formation-v0",
        ["consensus"],
        maps=["random"],
        env_kwargs={"formation": "line", "n_robots": 6},
    )
    spec.validate()
    assert spec.env_settings()["formation"] == "line"
    with pytest.raises(
        ValueError, match=r"env_kwargs: 'colour' is not one the environments take; allowed: .*'formation'"
    ):
        spec.replace(env_kwargs={"colour": "red"}).validate()


def test_a_command_line_option_checks_its_value_with_the_keywords_own_check() -> None:
    """``keyword_argument`` (the trainers' ``--plant``): the row's default, doc and check; a bad
    value ends the command naming the value, the allowed ones and a close match (argparse exits 2)."""
    pytest.importorskip("mujoco", reason="the --plant row checks mujoco: the [physics] extra")
    import argparse

    from koopman_envs import env_keyword, keyword_argument

    parser = argparse.ArgumentParser(prog="p", exit_on_error=False)
    parser.add_argument("--plant", **keyword_argument("plant"))
    assert parser.parse_args([]).plant == "kinematic" == env_keyword("plant").default
    assert parser.parse_args(["--plant", "mujoco"]).plant == "mujoco"
    with pytest.raises(argparse.ArgumentError, match=BAD["plant"][1]):
        parser.parse_args(["--plant", BAD["plant"][0]])
    assert "TurtleBot3-class robots in MuJoCo" in keyword_argument("plant")["help"]
    with pytest.raises(ValueError, match=r"'plants' is not an env keyword \(did you mean 'plant'\?\)"):
        env_keyword("plants")
