"""Every model-based controller navigating on what its robots see (controllers.perception.front):
Map 1 completed on beams only, the map known and unknown; the perception deterministic; no
truth read with the perception in the loop."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from test_observed_view import _poisoned

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.calibration import calibrate_controller
from koopman_envs.engine.plant import make_plant
from koopman_envs.episodes.single import run_episode

ENV = "KoopNav-TargetReaching-v0"
#: the controllers that complete Map 1 (seed 0) with exact state, and so must on beams
QUICK = ["nominal-nmpc", "orca", "dwa", "dmpc-nominal", "mpc-cbf"]
#: those of QUICK whose defaults need the evaluator's calibration offer first (cached): their tuned
#: presets widen the margins by the calibrated residual (uncertainty_margin > 0)
NEEDS_CALIBRATION = {"mpc-cbf", "nominal-nmpc"}
#: those that learn a model first (the evaluator's calibration offer, cached)
CALIBRATED = ["koopman-nmpc", "adaptive-koopman-nmpc", "dmpc-koopman"]


def _episode(
    name: str, map_known: bool, movers: int = 0, seed: int = 0, calibrate: bool = False, **env_kwargs
):
    env = gym.make(
        ENV,
        map="map1",
        sensing="lidar",
        lidar={"map_known": map_known},
        movers={"count": movers},
        **env_kwargs,
    )
    try:
        ctrl = controllers.make(name)
    except ImportError as exc:  # orca needs the [crowd] extra
        pytest.skip(str(exc))
    if calibrate:
        calibrate_controller(ctrl, make_plant(ENV, slip="nominal", seed=0), seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return run_episode(env, ctrl, seed=seed), ctrl


@pytest.mark.parametrize("map_known", [True, False], ids=["map-known", "map-unknown"])
@pytest.mark.parametrize(
    # slow: a whole Map 1 episode each (issue 61); the central NMPC keeps the default run's case
    "name",
    [pytest.param(n, marks=[] if n == "nominal-nmpc" else [pytest.mark.slow]) for n in QUICK],
)
def test_map1_is_completed_on_beams_only(name: str, map_known: bool) -> None:
    result, ctrl = _episode(name, map_known, calibrate=name in NEEDS_CALIBRATION)
    assert result.outcome == "success", (name, result.outcome, result.steps)
    assert ctrl.perception is not None
    assert ctrl.stats().summary()["perception_ms_median"] > 0


#: the one that cannot (docs/perception.md): on the unknown map robot 1 is squeezed between the
#: obstacle at (1.3, -0.4) and robot 0 at step 64 and the distributed Koopman NMPC's pair row
#: gives way (a team-mate collision, not an obstacle); dmpc-nominal completes the same episode
_SQUEEZED = pytest.mark.xfail(strict=True, reason="dmpc-koopman: team-mate collision on the unknown map")


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, map_known",
    [
        pytest.param(name, known, marks=[_SQUEEZED] if (name, known) == ("dmpc-koopman", False) else [])
        for name in CALIBRATED
        for known in (True, False)
    ],
)
def test_map1_is_completed_on_beams_only_by_the_learned_models(
    name: str, map_known: bool, tmp_path, monkeypatch
) -> None:
    monkeypatch.setenv("KOOPNAV_CACHE", str(tmp_path))
    result, _ = _episode(name, map_known, calibrate=True)
    assert result.outcome == "success", (name, result.outcome, result.steps)


def test_with_the_map_known_and_no_movers_the_beams_change_nothing() -> None:
    """The perception only adds what the map does not hold: on Map 1 without movers the NMPC's
    episode through the lidar is the one on exact state, step for step (the hand-set NMPC, which
    needs no calibration)."""
    lidar, _ = _episode("nominal-nmpc-v0", map_known=True)
    env = gym.make(ENV, map="map1")
    state = run_episode(env, controllers.make("nominal-nmpc-v0"), seed=0)
    assert lidar.steps == state.steps
    np.testing.assert_array_equal(lidar.final_distance, state.final_distance)


def test_the_perception_is_deterministic() -> None:
    """Same seed, same episode (movers tracked, map unknown), in one process and in another; 30
    periods, the robots still driving among the movers (a whole episode, 102 periods, is 3x longer).
    Consensus drives (core install, no extra): it sees through the same perception front as DWA
    (the tracked movers in its repulsion) and decides in less than half of DWA's
    CPU time (2.2 against 4.9 CPU-s for these 30 periods, fresh interpreter, numba cache warm)."""
    first, _ = _episode("consensus", map_known=False, movers=4, seed=3, max_episode_steps=30)
    again, _ = _episode("consensus", map_known=False, movers=4, seed=3, max_episode_steps=30)
    assert first.steps == 30 and first.truncated
    assert (first.outcome, first.steps) == (again.outcome, again.steps)
    np.testing.assert_array_equal(first.final_distance, again.final_distance)
    code = (
        "import gymnasium as gym, numpy as np, koopman_envs, controllers;"
        "from koopman_envs.episodes.single import run_episode;"
        f"env = gym.make({ENV!r}, map='map1', sensing='lidar', lidar={{'map_known': False}}, movers={{'count': 4}},"
        " max_episode_steps=30);"
        "r = run_episode(env, controllers.make('consensus'), seed=3);"
        "print(r.steps, repr(np.asarray(r.final_distance).tolist()))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split()[0] == str(first.steps)
    assert out.strip().split(" ", 1)[1] == repr(np.asarray(first.final_distance).tolist())


@pytest.mark.parametrize(
    # slow: the NMPC's and DWA's 30 periods, seconds each (issue 61); ORCA and consensus by default
    "name",
    [
        pytest.param("nominal-nmpc-v0", marks=pytest.mark.slow),
        "orca",
        pytest.param("dwa", marks=pytest.mark.slow),
        "consensus",
    ],
)
def test_poisoned_truth_changes_no_action_with_perception_in_the_loop(name: str) -> None:
    """Lidar, 4 movers, the map unknown and a noisy preset: a controller handed infos whose true
    fields are garbage acts exactly as with the real ones (the NMPC with its hand-set defaults,
    which need no calibration)."""
    env = gym.make(
        ENV, map="map1", sensing="lidar", lidar={"map_known": False, "noise": 0.02}, movers={"count": 4}
    )
    try:
        honest, fooled = controllers.make(name), controllers.make(name)
    except ImportError as exc:
        pytest.skip(str(exc))
    obs, info = env.reset(seed=2)
    honest.reset(env, seed=2)
    fooled.reset(env, seed=2)
    for _ in range(30):
        a = np.asarray(honest.act(obs, info))
        b = np.asarray(fooled.act(obs, _poisoned(info)))
        assert np.array_equal(a, b), name
        obs, _, terminated, truncated, info = env.step(a)
        if terminated or truncated:
            break


def test_the_lidar_protocol_sweeps_state_beams_and_beams_only() -> None:
    """``--lidar``: every controller that perceives (the set policies too; rl-ppo refuses lidar),
    among movers, swept over exact state, the beams with the map, and the beams only; the
    level 'lidar with the map known' of both axes is one run (the same episodes)."""
    from evaluation.cli import build_parser, run_from_args
    from evaluation.experiments.protocols import LIDAR_AXES
    from evaluation.experiments.sweep import level_aliases, parse_sweep

    args = build_parser().parse_args(["--lidar"])
    run = run_from_args(args)
    spec = run.spec
    assert run.sweep == LIDAR_AXES and run.reference == "koopman-nmpc"
    assert args.sweep is None and args.reference is None  # read, not changed
    names = [c.name for c in spec.controllers]
    assert "koopman-nmpc" in names and "rl-ppo-set-movers" in names and "rl-ppo" not in names
    assert spec.env_kwargs["sensing"] == "lidar" and spec.env_kwargs["movers"]["count"] > 0
    aliases = level_aliases(spec, [parse_sweep(a) for a in run.sweep])
    assert aliases == {"lidar.map_known=true": "sensing=lidar"}
