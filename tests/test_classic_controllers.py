"""The classic baselines ``orca`` and ``dwa`` (controllers/classic/): they reach their targets,
keep apart from team-mates and obstacles, hold a formation, run under runtime uncertainty, refuse
bad options by name and never read the true state."""

from __future__ import annotations

import dataclasses
import importlib.util
import sys

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.classic.common import TeamView
from controllers.classic.dwa import DWAController, DWASettings
from controllers.classic.orca import ORCAController, ORCASettings, unicycle_tracking
from controllers.option_spec import spec_of
from koopman_envs.episodes.single import run_episode
from koopman_envs.settings import UNCERTAINTY_PRESETS
from koopman_envs.sim.maps.map_spec import MapSpec

#: ORCA runs through pyrvo (the [crowd] extra): without it its cases skip, as the board skips it
HAVE_PYRVO = importlib.util.find_spec("pyrvo") is not None
needs_pyrvo = pytest.mark.skipif(not HAVE_PYRVO, reason="orca needs pyrvo (the [crowd] extra)")
NAMES = ("orca", "dwa") if HAVE_PYRVO else ("dwa",)
TR, FORMATION = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
OPEN = MapSpec(
    "open",
    obstacles=[[8.0, 8.0, 0.5]],
    starts=[[-2.0, -1.0, 0.0], [-2.0, 0.0, 0.0], [-2.0, 1.0, 0.0]],
    targets=[[0.5, -1.0, 0.0], [0.5, 0.0, 0.0], [0.5, 1.0, 0.0]],
)
#: two robots that meet head-on halfway
HEAD_ON = MapSpec(
    "head-on",
    obstacles=[[8.0, 8.0, 0.5]],
    starts=[[-2.0, 0.0, 0.0], [2.0, 0.0, np.pi]],
    targets=[[2.0, 0.0, np.pi], [-2.0, 0.0, 0.0]],
)
#: one robot, a wall of discs right ahead of it, its target behind the wall
WALL = MapSpec(
    "wall",
    obstacles=[[0.55, y, 0.15] for y in np.arange(-0.9, 0.95, 0.3)],
    starts=[[0.0, 0.0, 0.0]],
    targets=[[3.0, 0.0, 0.0]],
)


def _episode(name: str, env_id: str, seed: int = 0, **env_kwargs):
    env = gym.make(env_id, **env_kwargs)
    ctrl = controllers.make(name)
    return run_episode(env, ctrl, seed=seed), ctrl


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize(
    ("env_id", "layout"), [(TR, OPEN), (TR, "map1"), (FORMATION, OPEN), (FORMATION, "map3")]
)
def test_reaches_the_targets(name: str, env_id: str, layout: MapSpec | str) -> None:
    result, ctrl = _episode(name, env_id, map=layout, slip="nominal")
    assert result.success, (name, env_id, result.collision, result.final_distance)
    assert np.all(result.final_distance < 0.1)
    assert ctrl.stats().steps == result.steps


@pytest.mark.parametrize("name", NAMES)
def test_two_robots_meeting_head_on_pass_without_contact(name: str) -> None:
    result, _ = _episode(name, TR, map=HEAD_ON, n_robots=2, slip="nominal")
    assert result.collision is None and result.success, (result.collision, result.final_distance)
    assert result.min_clearance["robot"] > 0.0
    # they left the line to pass: someone's path bent away from y = 0
    assert np.abs(result.trajectory[:, :, 1]).max() > 0.1


@needs_pyrvo
def test_orca_drives_a_lone_robot_straight_to_its_target() -> None:
    lone = MapSpec("lone", obstacles=[[8.0, 8.0, 0.5]], starts=[[-2.0, 0.0, 0.0]], targets=[[2.0, 0.0, 0.0]])
    result, _ = _episode("orca", TR, map=lone, n_robots=1, slip="nominal")
    assert result.success
    assert result.path_length[0] < 1.02 * result.straight_distance[0]
    assert np.abs(result.trajectory[:, 0, 1]).max() < 0.1  # keep_right bends it by a few centimetres


def test_dwa_facing_a_wall_within_its_braking_distance_turns_and_keeps_clear() -> None:
    env = gym.make(TR, map=WALL, n_robots=1, slip="nominal")
    ctrl = controllers.make("dwa")
    obs, info = env.reset(seed=0)
    ctrl.reset(env, seed=0)
    ctrl._last[:] = [0.6, 0.0]  # as if it were driving at full speed into the wall
    first = ctrl.act(obs, info)
    assert first[0] < 0.6 or abs(first[1]) > 0.0  # it slows down or turns
    for _ in range(60):
        obs, _, terminated, truncated, info = env.step(ctrl.act(obs, info))
        assert not info["collision"], info["poses"]
        if terminated or truncated:
            break


@pytest.mark.parametrize(
    # slow: DWA's two episodes, about 4 CPU-s (issue 61), when ORCA (0.4 CPU-s) runs by default
    "name",
    [pytest.param(n, marks=pytest.mark.slow) if n == "dwa" and len(NAMES) > 1 else n for n in NAMES],
)
def test_whole_episodes_under_realistic_uncertainty(name: str) -> None:
    """Under the "realistic" preset (noisy poses, lossy radio, one period of command latency) both
    tasks still end in success, and the controller's front end identifies the preset's latency and
    pose noise online."""
    preset = UNCERTAINTY_PRESETS["realistic"]
    for env_id, layout in ((TR, "map1"), (FORMATION, "map3")):
        result, ctrl = _episode(name, env_id, seed=1, map=layout, uncertainty="realistic")
        assert result.success and result.collision is None, (env_id, result.collision, result.final_distance)
        assert np.isfinite(result.trajectory).all()
        counts = ctrl.stats().counts
        assert counts["identified_delay"] == preset.actuation_delay, counts
        # identified from one episode's residuals: within a third of the preset's noise
        assert counts["identified_position_std_mm"] == pytest.approx(1e3 * preset.pose_noise.xy, rel=0.34)
        assert counts["identified_heading_std_mrad"] == pytest.approx(
            1e3 * preset.pose_noise.heading, rel=0.34
        )


@pytest.mark.parametrize("name", NAMES)
def test_the_true_state_changes_no_command(name: str) -> None:
    env = gym.make(FORMATION, map="map3", uncertainty="realistic")
    honest, fooled = controllers.make(name), controllers.make(name)
    obs, info = env.reset(seed=3)
    honest.reset(env, seed=3)
    fooled.reset(env, seed=3)
    for _ in range(15):
        poisoned = {**info, "poses": np.full_like(info["poses"], np.nan), "distances": np.nan}
        if "movers" in info:
            poisoned["movers"] = np.full_like(info["movers"], np.nan)
        command = honest.act(obs, info)
        assert np.array_equal(command, fooled.act(obs, poisoned))
        obs, _, terminated, truncated, info = env.step(command)
        if terminated or truncated:
            break


@pytest.mark.parametrize(
    ("name", "options", "message"),
    [
        ("orca", {"time_horizon": -1.0}, "time_horizon=-1.0"),
        ("orca", {"max_neighbours": 0}, "max_neighbours=0"),
        ("orca", {"keep_right": 2.0}, "keep_right=2.0"),
        ("orca", {"estimator": "kalman"}, "estimator='kalman'"),
        ("orca", {"mover_prediction": "linear"}, "mover_prediction='linear'"),
        ("dwa", {"vx_samples": 0}, "vx_samples=0"),
        ("dwa", {"sim_time": float("nan")}, "sim_time=nan"),
        ("dwa", {"safety_margin": -0.1}, "safety_margin=-0.1"),
        ("dwa", {"ablate": "tightening"}, "ablate='tightening'"),
        ("dwa", {"velocity_window": 1.5}, "velocity_window=1.5"),
    ],
)
def test_bad_options_are_refused_by_name(name: str, options: dict, message: str) -> None:
    if name == "orca" and not HAVE_PYRVO:
        pytest.skip("orca needs pyrvo (the [crowd] extra): it names the extra before any option")
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("[", r"\[")):
        controllers.make(name, **options)


def test_every_option_has_a_spec_with_choices() -> None:
    for name in NAMES:
        spec = controllers.options(name)
        assert spec.option("estimator").choices == ("auto", "realistic", "none")
        assert spec.option("ablate").choices == ("none", "estimation", "delay_compensation")
        assert all(option.doc for option in spec.options), name


def test_orca_without_pyrvo_names_the_extra_and_the_board_skips_it(monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "pyrvo", None)  # import pyrvo now raises ImportError
    with pytest.raises(ImportError, match=r"pip install -e '\.\[crowd\]'"):
        controllers.make("orca")
    from evaluation.execution import runner

    monkeypatch.setattr(runner.registry, "available", lambda **_: ["dwa", "orca"])
    assert runner.usable_controllers(verbose=True) == ["dwa"]
    assert "controller 'orca' skipped" in capsys.readouterr().err


def test_deterministic_across_instances() -> None:
    for name in NAMES:
        first, _ = _episode(name, TR, seed=2, map="map2", slip="high")
        second, _ = _episode(name, TR, seed=2, map="map2", slip="high")
        assert np.array_equal(first.trajectory, second.trajectory), name


def test_team_view_estimates_velocities_from_late_messages_and_carries_them_forward() -> None:
    view = TeamView(window=3)
    view.reset(2, 0.1)
    velocity = np.array([0.5, -0.2])
    for step in range(8):
        true = np.array([[0.0, 0.0], velocity * 0.1 * step])
        late = np.array([[0.0, 0.0], velocity * 0.1 * max(step - 2, 0)])  # robot 1 heard 2 periods late
        known = np.zeros((2, 2, 3))
        known[0, :, :2] = [true[0], late[1]]
        known[1, :, :2] = true
        ages = np.array([[0, 2 if step >= 2 else -1], [0, 0]])
        position, estimate, heard = view.update(known, ages, np.zeros((2, 2)))
    assert heard[0, 1] and np.allclose(estimate[0, 1], velocity)
    assert np.allclose(position[0, 1], true[1])  # the late message carried forward to now


def test_unicycle_tracking_turns_on_the_spot_for_a_velocity_behind_it() -> None:
    command = unicycle_tracking(np.array([[-0.5, 0.0], [0.3, 0.0]]), np.zeros(2), 4.0, 0.6, 0.8)
    assert command[0, 0] == 0.0 and abs(command[0, 1]) == 0.8
    assert np.allclose(command[1], [0.3, 0.0])


def test_dwa_window_stays_within_the_limits() -> None:
    env = gym.make(TR, map="map1")
    ctrl = DWAController()
    env.reset(seed=0)
    ctrl.reset(env, seed=0)
    ctrl._last[:] = [0.55, 0.7]
    samples = ctrl._window()
    scenario = env.unwrapped.scenario
    assert samples[..., 0].min() >= 0.0 and samples[..., 0].max() <= scenario.v_max
    assert np.abs(samples[..., 1]).max() <= scenario.omega_max
    assert samples.shape == (3, ctrl.config.vx_samples * ctrl.config.vth_samples, 2)


@pytest.mark.parametrize("name", NAMES)
def test_a_copy_pickled_mid_episode_commands_the_same(name: str) -> None:
    import pickle

    env = gym.make(TR, map="map1")
    ctrl = controllers.make(name)
    obs, info = env.reset(seed=0)
    ctrl.reset(env, seed=0)
    for _ in range(5):
        obs, _, _, _, info = env.step(ctrl.act(obs, info))
    copy = pickle.loads(pickle.dumps(ctrl))  # orca leaves its RVO2 simulator behind and rebuilds it
    assert np.array_equal(ctrl.act(obs, info), copy.act(obs, info))


def _numpy_wavefront(free, seed, weight=None):
    """The numpy relaxation ``wavefront`` ran before it was compiled (the reference)."""
    import math

    from controllers.classic.plan import _MOVES

    field, start, (rows, cols) = seed.copy(), np.isfinite(seed), free.shape
    cost = np.ones(free.shape) if weight is None else weight
    while True:
        before = field.copy()
        for dx, dy in _MOVES:
            step = math.hypot(dx, dy)
            src = field[max(dx, 0) : rows + min(dx, 0), max(dy, 0) : cols + min(dy, 0)]
            into = (slice(max(-dx, 0), rows + min(-dx, 0)), slice(max(-dy, 0), cols + min(-dy, 0)))
            np.minimum(field[into], src + step * cost[into], out=field[into])
        field[~free] = np.inf
        field[start] = np.minimum(field[start], seed[start])
        if np.array_equal(field, before):
            return field


def test_the_compiled_kernels_give_the_numpy_expressions_bits() -> None:
    from controllers.classic.kernels import closest_approach, unicycle_arcs
    from controllers.classic.plan import polyline_distance, wavefront

    rng = np.random.default_rng(0)
    for trial in range(20):
        shape = tuple(int(v) for v in rng.integers(5, 50, 2))
        free = rng.random(shape) > rng.uniform(0.0, 0.4)
        seed = np.full(shape, np.inf)
        goal = tuple(int(v) for v in rng.integers(0, shape))
        seed[goal], free[goal] = 0.0, True
        weight = 1.0 + rng.random(shape) if trial % 2 else None
        assert np.array_equal(wavefront(free, seed, weight), _numpy_wavefront(free, seed, weight))
    for trial in range(50):  # the polyline distance against its numpy expression
        points = rng.normal(size=(3, 40, 2)) * 3
        line = np.cumsum(rng.normal(size=(int(rng.integers(2, 30)), 2)), axis=0)
        start, along = line[:-1], line[1:] - line[:-1]
        p = points[..., None, :]
        t = ((p - start) * along).sum(axis=-1) / np.maximum((along * along).sum(axis=-1), 1e-12)
        nearest = start + np.clip(t, 0.0, 1.0)[..., None] * along
        reference = np.linalg.norm(p - nearest, axis=-1).min(axis=-1)
        assert np.array_equal(polyline_distance(points, line), reference), trial
    path = rng.normal(size=(3, 40, 12, 3))
    centres = rng.normal(size=(3, 13, 7, 2))
    dx = path[..., 0, None] - centres[:, None, 1:, :, 0]
    dy = path[..., 1, None] - centres[:, None, 1:, :, 1]
    expected = np.sqrt((dx * dx + dy * dy).min(axis=2))
    assert np.array_equal(closest_approach(path, np.ascontiguousarray(centres[:, 1:])), expected)
    for trial in range(50):  # the arcs against the numpy rollout they replaced (np.sinc's chord)
        n, s, k = (int(v) for v in rng.integers(1, 40, 3))
        pose = rng.uniform(-np.pi, np.pi, (n, 3))
        samples = np.stack([rng.uniform(0, 0.5, (n, s)), rng.uniform(-1.5, 1.5, (n, s))], axis=-1)
        samples[:, 0, 1] = 0.0  # a straight sample: the sinc at 0
        times = 1.7 * np.arange(1, k + 1) / k
        v, w, theta0 = samples[..., 0][..., None], samples[..., 1][..., None], pose[:, 2][:, None, None]
        half = 0.5 * w * times
        chord = v * times * np.sinc(half / np.pi)
        x = pose[:, 0][:, None, None] + chord * np.cos(theta0 + half)
        y = pose[:, 1][:, None, None] + chord * np.sin(theta0 + half)
        reference = np.stack([x, y, np.broadcast_to(theta0 + w * times, x.shape)], axis=-1)
        assert np.array_equal(unicycle_arcs(pose, samples, times), reference), trial


def test_dwa_takes_its_settings_as_one_frozen_value_or_as_options() -> None:
    settings = DWASettings(sim_time=2.0, vx_samples=5)
    assert DWAController(settings).config == settings
    # options replace the given settings' fields; the others stay
    built = DWAController(settings, safety_margin=0.05).config
    assert (built.sim_time, built.vx_samples, built.safety_margin) == (2.0, 5, 0.05)
    # the registry's "dwa" applies its tuned preset; the options given stand over it
    made = controllers.make("dwa", sim_time=2.0, vx_samples=5).config
    assert (made.sim_time, made.vx_samples) == (2.0, 5)
    assert DWAController().config == DWASettings()
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.sim_time = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="sim_time=-1.0"):
        DWASettings(sim_time=-1.0)
    with pytest.raises(ValueError, match=r"unknown dwa option 'sim_tim'.*did you mean 'sim_time'"):
        DWAController(sim_tim=2.0)
    with pytest.raises(TypeError, match="is not a DWASettings"):
        DWAController({"sim_time": 2.0})  # type: ignore[arg-type]


def test_the_option_spec_reads_the_settings_fields() -> None:
    # the classes' own specs (the registered names carry their tuned presets' defaults)
    for cls, settings in ((DWAController, DWASettings), (ORCAController, ORCASettings)):
        spec = spec_of(cls.name, cls)
        fields = dataclasses.fields(settings)
        assert spec.names() == [f.name for f in fields]
        assert [spec.default(f.name) for f in fields] == [f.default for f in fields]
        assert all(spec.option(key).bounds is bound for key, bound in settings.RANGES.items())
