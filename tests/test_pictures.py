"""Pictures that show what happened (issue 43): the env's frames draw the lidar beams (and hide
them on request), keep every mover in view and mark a collision where it happens with its kind
and time; the evaluator's trajectory figures draw the movers' paths, and its success chart keeps
the legend off the bars with one colour per controller."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.rendering.layers import Overlay, collision_marks, engine_frame, view_limits
from koopman_envs.rendering.renderer import Renderer, draw_engine_env, frame_title
from koopman_envs.scenario import Scenario
from koopman_envs.sim.collision import CollisionKind
from koopman_envs.sim.movers.placement import mover_arena

ROOT = Path(__file__).resolve().parents[1]
TR = "KoopNav-TargetReaching-v0"


def _lidar_env() -> gym.Env:
    env = gym.make(TR, sensing="lidar", movers=dict(count=4, behaviour="waypoints"), render_mode="rgb_array")
    env.reset(seed=1)
    for _ in range(5):
        env.step(np.tile([0.3, 0.2], 3))
    return env


def test_lidar_beams_are_drawn_and_can_be_hidden(monkeypatch: pytest.MonkeyPatch) -> None:
    env = _lidar_env()
    base = env.unwrapped
    shown = env.render()
    hidden = draw_engine_env(Renderer(show_beams=False), base.engine, 0, base._trail)
    assert np.abs(shown.astype(int) - hidden.astype(int)).sum(axis=-1).astype(bool).mean() > 0.01
    monkeypatch.setattr(Renderer, "show_beams", False)  # the class default: every env's frames
    fresh = gym.make(
        TR, sensing="lidar", movers=dict(count=4, behaviour="waypoints"), render_mode="rgb_array"
    )
    fresh.reset(seed=1)
    for _ in range(5):
        fresh.step(np.tile([0.3, 0.2], 3))
    np.testing.assert_array_equal(fresh.render(), hidden)
    # one segment per beam, from each robot's centre to its reading (the info's lidar_ranges)
    ranges = env.unwrapped.engine.info(0)["lidar_ranges"]
    segments = np.asarray(env.unwrapped._renderer._scene.layers.beams.get_segments())
    assert segments.shape == (ranges.size, 2, 2)
    lengths = np.hypot(*(segments[:, 1] - segments[:, 0]).T)
    np.testing.assert_allclose(lengths, ranges.reshape(-1), atol=1e-9)
    np.testing.assert_allclose(segments[:: ranges.shape[1], 0], base.engine.poses[0][:, :2])
    # the blitted frame is the full redraw's
    frame = engine_frame(base.engine, 0)
    args = (base.scenario, np.asarray(base._trail))
    fast, full = Renderer().draw(*args, **frame), Renderer(blit=False).draw(*args, **frame)
    assert np.abs(fast.astype(int) - full.astype(int)).mean() < 0.1


def test_a_state_sensing_env_draws_no_beams() -> None:
    env = gym.make(TR, render_mode="rgb_array")
    env.reset(seed=0)
    env.render()
    assert len(env.unwrapped._renderer._scene.layers.beams.get_segments()) == 0


def _crash_into_an_obstacle() -> gym.Env:
    env = gym.make("KoopNav-Formation-v0", render_mode="rgb_array")  # map3: robot 0 drives into a disc
    env.reset(seed=0)
    for _ in range(200):
        _, _, terminated, truncated, info = env.step(np.tile([0.6, 0.0], 3))
        if terminated or truncated:
            break
    assert info["collision_code"] == CollisionKind.OBSTACLE
    return env


def test_a_collision_is_marked_where_and_when_it_happens() -> None:
    env = _crash_into_an_obstacle()
    frame = env.render()
    base = env.unwrapped
    layers = base._renderer._scene.layers
    (x, y), = layers.marks.get_xydata()  # fmt: skip
    label = layers.labels[0]
    elapsed = base.engine.elapsed[0] * base.scenario.dt
    assert label.get_visible() and label.get_text() == f"collision: obstacle at t = {elapsed:.1f} s"
    # on robot 0's rim, toward the obstacle it touches
    robot = base.engine.poses[0][0]
    obstacles = base.scenario.obstacles
    touched = obstacles[np.argmin(np.hypot(*(obstacles[:, :2] - robot[:2]).T) - obstacles[:, 2])]
    assert np.hypot(x - robot[0], y - robot[1]) <= base.scenario.robot_radius[0] + 1e-9
    assert np.hypot(x - touched[0], y - touched[1]) <= touched[2] + 1e-9
    # the cross is there in the picture: red at its pixel
    ax = layers.ax
    px, py = ax.transData.transform((x, y))
    red = frame[frame.shape[0] - int(round(py)) - 2 : frame.shape[0] - int(round(py)) + 3,
                int(round(px)) - 2 : int(round(px)) + 3].reshape(-1, 3).astype(int)  # fmt: skip
    assert ((red[:, 0] > 180) & (red[:, 1] < 90) & (red[:, 2] < 90)).any()
    # the blitted frame is the full redraw's
    args = (base.scenario, np.asarray(base._trail), frame_title(base.config), elapsed)
    overlay = Overlay(collision=CollisionKind.OBSTACLE)
    fast, full = Renderer().draw(*args, overlay=overlay), Renderer(blit=False).draw(*args, overlay=overlay)
    assert np.abs(fast.astype(int) - full.astype(int)).mean() < 0.1
    # a new episode clears the mark
    env.reset(seed=0)
    env.render()
    assert len(layers.marks.get_xydata()) == 0 and not any(t.get_visible() for t in layers.labels)


def _scenario(**kw) -> Scenario:
    values = dict(
        task="target_reaching",
        map_name="test",
        n_robots=3,
        obstacles=np.array([[0.0, 0.0, 0.5]]),
        robot_radius=np.full(3, 0.2),
        starts=np.zeros((3, 3)),
        targets=np.zeros((3, 3)),
        formation_offsets=np.zeros((3, 2)),
        leader=0,
        v_max=0.6,
        omega_max=1.0,
        workspace=(-10.0, 10.0, -10.0, 10.0),
        dt=0.1,
        goal_tolerance=0.1,
        settle_steps=1,
        n_movers=1,
        mover_radius=0.3,
    )
    values.update(kw)
    return Scenario(**values)


def test_collision_marks_name_each_kind_at_the_contact() -> None:
    scenario = _scenario()
    poses = np.array([[0.6, 0.0, 0.0], [3.0, 0.0, 0.0], [3.3, 0.0, 0.0]])
    marks = collision_marks(scenario, poses, CollisionKind.OBSTACLE | CollisionKind.ROBOT)
    # inside the overlap, on the robot's rim scaled by distance / radius sum; each pair once
    assert marks == [
        (pytest.approx(0.6 - 0.2 * 0.6 / 0.7), 0.0, "obstacle"),
        (pytest.approx(3.15), 0.0, "robot"),
    ]
    poses = np.array([[10.1, 5.0, 0.0], [3.0, 0.0, 0.0], [-5.0, -5.0, 0.0]])
    movers = np.array([[-5.0, -4.6]])
    marks = collision_marks(scenario, poses, CollisionKind.WORKSPACE | CollisionKind.MOVER, movers)
    assert marks == [(10.0, 5.0, "workspace"), (-5.0, pytest.approx(-5.0 + 0.2 * 0.4 / 0.5), "mover")]
    # a flag whose contact is gone is still named, at the team's centre
    (mark,) = collision_marks(scenario, poses, CollisionKind.MOVER, np.array([[9.0, 9.0]]))
    assert mark[2] == "mover"


# slow: 150 rendered frames of an ORCA crowd, about 2 CPU-s (issue 61)
@pytest.mark.slow
def test_every_mover_stays_in_view_over_an_episode() -> None:
    pytest.importorskip("pyrvo", reason="the ORCA crowd needs the [crowd] extra")
    env = gym.make(
        TR,
        movers=dict(count=8, behaviour="crowd", aware=True, speed=1.0),  # they avoid the robots
        render_mode="rgb_array",
        max_episode_steps=150,
    )
    env.reset(seed=4)
    base = env.unwrapped
    arena = mover_arena(
        base.scenario.starts, base.scenario.targets, base.scenario.obstacles, base.scenario.workspace
    )
    radius = base.scenario.mover_radius
    done, steps = False, 0
    while not done:
        env.render()
        ax = base._renderer.ax
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert x0 <= arena[0] and x1 >= arena[1] and y0 <= arena[2] and y1 >= arena[3]
        movers = base.engine.movers.position[0]
        assert (movers[:, 0] - radius >= x0).all() and (movers[:, 0] + radius <= x1).all(), steps
        assert (movers[:, 1] - radius >= y0).all() and (movers[:, 1] + radius <= y1).all(), steps
        # stand still: the pedestrians walk around the robots to the episode's limit
        _, _, terminated, truncated, _ = env.step(np.zeros(6))
        done, steps = terminated or truncated, steps + 1
    assert steps == 150


def test_a_mover_outside_the_arena_widens_the_view() -> None:
    scenario = _scenario(starts=np.array([[0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.0, 3.0, 0.0]]))
    current = scenario.starts
    inside = view_limits(scenario, current, movers=np.array([[0.0, 0.0]]))
    outside = view_limits(scenario, current, movers=np.array([[inside[1] + 0.5, 0.0]]))
    assert outside[1] >= inside[1] + 0.5 + scenario.mover_radius and outside[1] - inside[1] == int(
        outside[1] - inside[1]
    )


# ------------------------------------------------------------------------------- the evaluator
def _baseline_records() -> list[dict]:
    return json.loads((ROOT / ".ci" / "baseline" / "results.json").read_text())["episodes"]


def test_the_worker_records_the_movers_paths_and_the_figure_draws_them(tmp_path: Path) -> None:
    jsonschema = pytest.importorskip("jsonschema")
    from evaluation.episodes.records import record_problem
    from evaluation.reports.figures import _trajectory_figure, save_figures
    from evaluation.stats.run_data import RunData
    from koopman_envs.episodes.demo import NaiveGoToTarget
    from koopman_envs.episodes.single import run_episode

    env = gym.make(TR, movers=dict(count=3, behaviour="waypoints"), max_episode_steps=40)
    result = run_episode(env, NaiveGoToTarget(), seed=0)
    assert result.mover_trajectory is not None
    paths = np.round(result.mover_trajectory, 4).tolist()  # as the worker records them
    assert np.shape(paths) == (result.steps + 1, 3, 2)
    np.testing.assert_allclose(paths[-1], env.unwrapped.engine.movers.position[0], atol=1e-4)
    np.testing.assert_array_equal(result.obstacles, env.unwrapped.scenario.obstacles)
    rec = copy.deepcopy(next(r for r in _baseline_records() if r["env_id"] == TR))
    rec.update(
        key="with-movers",
        trajectory=np.round(result.trajectory[:, :, :2], 4).tolist(),
        obstacles=env.unwrapped.scenario.obstacles.tolist(),
        mover_trajectory=paths,
    )
    assert record_problem(rec) is None
    schema = json.loads((ROOT / "docs" / "results.schema.json").read_text())
    episode_schema = schema["properties"]["episodes"]["items"]
    jsonschema.validate({k: v for k, v in rec.items() if k != "trajectory"}, episode_schema)
    for bad in ([[[0.0, 0.0, 0.0]]], [[["0", 1.0]]], [[0.0, 1.0]]):
        assert record_problem({**rec, "mover_trajectory": bad}) is not None
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate({**rec, "mover_trajectory": bad}, episode_schema)
    written = save_figures(RunData([rec], {}), tmp_path)
    assert [p.name for p in written if p.name.startswith("traj_")] and all(
        p.stat().st_size > 0 for p in written
    )
    fig = _trajectory_figure(rec, tmp_path / "again.png")
    dotted = [line for line in fig.axes[0].get_lines() if line.get_linestyle() == ":"]
    assert len(dotted) == 3  # one path per mover
    np.testing.assert_allclose(dotted[0].get_xydata(), np.asarray(paths)[:, 0])
    without = gym.make(TR, max_episode_steps=5)
    assert run_episode(without, NaiveGoToTarget(), seed=0).mover_trajectory is None  # no movers: no field


def test_the_success_chart_keeps_its_legend_off_the_bars(tmp_path: Path) -> None:
    from evaluation.reports.figures import _success_figure, colour_of
    from evaluation.stats.run_data import RunData

    records = []
    for slip in ("nominal", "high"):
        for r in _baseline_records():
            records.append({**r, "slip": slip, "key": r["key"] + slip})
    fig = _success_figure(RunData(records, {}), TR, tmp_path / "chart.png")
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    legend = ax.get_legend().get_window_extent(renderer)
    assert legend.x0 >= ax.get_window_extent(renderer).x1  # beside the axes, not over them
    assert legend.x1 <= fig.bbox.x1 + 1  # and inside the picture
    names = [t.get_text() for t in ax.get_legend().get_texts()]
    colours = {c.get_label(): c.lines[0].get_color() for c in ax.containers}
    assert len(names) == len({r["controller"] for r in _baseline_records()}) and sorted(colours) == sorted(
        names
    )
    assert len({tuple(np.round(c, 6)) for c in colours.values()}) == len(names)  # one colour each
    for name, colour in colours.items():
        np.testing.assert_allclose(colour, colour_of(name))  # the same in every figure
