"""The ``plant`` keyword without MuJoCo's help: the kinematic default unchanged bit for bit, the
physics plant refused by name when MuJoCo is missing, and the surface checks (plain numpy)."""

from __future__ import annotations

import hashlib
import importlib.util
import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.engine.config import EngineConfig
from koopman_envs.sim.physics.surfaces import check_surface, floor_surface
from koopman_envs.sim.slip.zones import SlipZone

#: the digest of :func:`_kinematic_digest` computed on main before the plant keyword existed
#: (commit f920798): the default plant must stay the paper's, bit for bit
KINEMATIC_DIGEST = "1ecd9b9950c9eb420cfd463eb3cf35b9c4223e4af30ae130904d05a7ffc74f92"


def _kinematic_digest(**keywords: object) -> str:
    """SHA-256 of the observations, rewards and poses (rounded to 1e-9) of two seeded
    random-action rollouts: target reaching on map1, formation with slip zones and high slip."""
    digest = hashlib.sha256()
    cases = (("KoopNav-TargetReaching-v0", {}), ("KoopNav-Formation-v0", {"slip": "high", "map": "map5"}))
    for env_id, extra in cases:
        env = gym.make(env_id, **extra, **keywords)
        rng = np.random.default_rng(7)
        obs, info = env.reset(seed=3)
        for _ in range(60):
            action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
            obs, reward, terminated, truncated, info = env.step(action)
            for array in (obs, [reward], info["poses"]):
                digest.update(np.round(np.asarray(array, dtype=np.float64), 9).tobytes())
            if terminated or truncated:
                obs, info = env.reset()
        env.close()
    return digest.hexdigest()


def test_the_kinematic_plant_is_the_default_and_unchanged_bit_for_bit() -> None:
    assert _kinematic_digest() == KINEMATIC_DIGEST
    assert _kinematic_digest(plant="kinematic") == KINEMATIC_DIGEST


def test_the_physics_plant_without_mujoco_is_refused_with_the_install_hint(monkeypatch) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a)
    )
    with pytest.raises(ModuleNotFoundError, match=r"plant='mujoco'.*pip install 'koopnav\[physics\]'"):
        EngineConfig.create("target_reaching", plant="mujoco")


def test_an_unknown_plant_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"plant='mujuco' is not one of \['kinematic', 'mujoco'\].*'mujoco'"):
        EngineConfig.create("target_reaching", plant="mujuco")


@pytest.mark.parametrize("friction", [0, 0.0, 2.5, -1.0, math.nan, math.inf, True])
def test_a_friction_outside_zero_to_two_is_refused_by_name(friction: object) -> None:
    with pytest.raises(ValueError, match=r"slip=.* allowed: a number in \(0, 2\]"):
        floor_surface(friction)
    with pytest.raises(ValueError, match=r"surface=.* allowed: a number in \(0, 2\]"):
        SlipZone("circle", (0.0, 0.0, 1.0), 0.1, surface=friction)  # type: ignore[arg-type]


def test_an_unknown_surface_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"surface='ise' is not a surface.*'carpet', 'gravel', 'ice'.*'ice'"):
        check_surface("surface", "ise")
    with pytest.raises(ValueError, match=r"slip='mud' has no surface on plant='mujoco'; allowed: one of"):
        floor_surface("mud")
    with pytest.raises(ValueError, match=r"slip=\[0.1, 0.2\] has no surface on plant='mujoco'"):
        floor_surface([0.1, 0.2])
    with pytest.raises(ValueError, match=r"surface='lava' is not a surface"):
        SlipZone.from_dict({"circle": [0, 0, 1], "lambda": 0.2, "surface": "lava"})


def test_named_slip_settings_name_surfaces_and_zones_keep_theirs() -> None:
    assert [floor_surface(s) for s in ("nominal", "low", "high", "ice", 0.3)] == [
        "carpet", "gravel", "ice", "ice", 0.3
    ]  # fmt: skip
    zone = SlipZone.from_dict({"rect": [0, 0, 1, 1], "lambda": 0.4, "surface": "gravel"})
    assert zone.surface == "gravel"
    assert SlipZone.from_dict(zone.to_dict()).to_dict() == zone.to_dict()


def _run_spec(*words: str):
    from evaluation.cli import build_parser, spec_from_args

    return spec_from_args(build_parser().parse_args(list(words)))


def test_the_evaluator_s_plant_option_is_the_env_keyword() -> None:
    """``--plant mujoco`` is ``--env-kwargs plant=mujoco`` (the sim-to-sim protocol's switch);
    without it the run's env keywords hold no plant (the kinematic default)."""
    assert _run_spec("--plant", "mujoco").env_kwargs["plant"] == "mujoco"
    assert _run_spec("--plant", "mujoco").env_kwargs == _run_spec("--env-kwargs", "plant=mujoco").env_kwargs
    assert "plant" not in _run_spec().env_kwargs
    assert (
        _run_spec("--plant", "kinematic", "--env-kwargs", "plant=kinematic").env_kwargs["plant"]
        == "kinematic"
    )


@pytest.mark.parametrize(
    "words, message",
    [
        (
            ["--plant", "mujuco"],
            "argument --plant: invalid choice: 'mujuco' (choose from 'kinematic', 'mujoco')",
        ),
        (
            ["--plant", "mujoco", "--env-kwargs", "plant=kinematic"],
            "--plant mujoco and --env-kwargs plant='kinematic' set the same env keyword to different values",
        ),
    ],
)
def test_a_bad_or_clashing_plant_option_exits_2_by_name(tmp_path, capsys, words, message) -> None:
    import evaluate

    out = tmp_path / "run"
    args = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
    code: int | str | None
    try:  # argparse's refusal exits; the run's own checks return the exit code
        code = evaluate.main(
            [*args, "--episodes", "1", "--workers", "1", "--quiet", *words, "--out", str(out)]
        )
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err and "Traceback" not in err
    assert not (out / "episodes.jsonl").exists()
