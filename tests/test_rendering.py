"""Matplotlib rendering and episode export; nothing imports pygame."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from koopman_envs import formation_v0
from koopman_envs.rendering.renderer import Renderer, frame_title, save_episode

DATA = Path(__file__).parent / "data"


def _mean_abs_difference(a: np.ndarray, b: np.ndarray) -> float:
    assert a.shape == b.shape
    return float(np.abs(a.astype(np.int16) - b.astype(np.int16)).mean())


def test_rgb_array_frames_show_the_scene() -> None:
    env = gym.make("KoopNav-Formation-v0", render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    for _ in range(5):
        env.step(np.array([0.6, 0.0] * 3))
    later = env.render()
    assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3
    assert len(np.unique(first.reshape(-1, 3), axis=0)) > 20  # obstacles, robots, targets drawn
    assert not np.array_equal(first, later)  # the robots moved and left trails
    env.close()


def test_save_gif(tmp_path) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frames = [env.render()]
    for _ in range(3):
        env.step(np.array([0.5, 0.1] * 3))
        frames.append(env.render())
    path = save_episode(frames, tmp_path / "episode.gif")
    from PIL import Image

    with Image.open(path) as gif:
        assert gif.n_frames == 4


def test_save_rejects_unknown_format(tmp_path) -> None:
    with pytest.raises(ValueError, match="must end in '.gif' or '.mp4'"):
        save_episode([np.zeros((4, 4, 3), np.uint8)], tmp_path / "x.avi")


def test_parallel_env_renders() -> None:
    env = formation_v0.parallel_env(render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().shape[2] == 3


def test_no_pygame_import() -> None:
    code = (
        "import sys, gymnasium as gym, koopman_envs; "
        "e = gym.make('KoopNav-Formation-v0', render_mode='rgb_array'); e.reset(seed=0); e.render(); "
        "from koopman_envs import formation_v0; print('pygame' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_frame_matches_the_full_redraw_renderer() -> None:
    """tests/data/render_formation_map3_seed0_step20.png was written by the renderer before
    blitting (commit 3431aeb: clear the axes, create every artist, tight_layout and a full draw
    per frame) for this very state; the blitting renderer draws the same picture (exactly, with
    the fonts of the project machine)."""
    from PIL import Image

    env = gym.make("KoopNav-Formation-v0", render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.array([0.6, 0.1] * 3))
    frame = env.render()
    with Image.open(DATA / "render_formation_map3_seed0_step20.png") as png:
        reference = np.asarray(png.convert("RGB"))
    assert _mean_abs_difference(frame, reference) < 0.5  # a spread of font versions
    env.close()


def test_blitting_matches_a_full_redraw_every_frame(open_map) -> None:
    """The blitting renderer against the same renderer redrawing the whole figure per frame,
    through the cases that redraw the background: the first frame, robots leaving the map's view
    (the view widens), the clock growing a digit (the title moves), and a new episode's map."""
    env = gym.make("KoopNav-TargetReaching-v0", map=open_map, render_mode="rgb_array")
    env.reset(seed=0)
    base = env.unwrapped
    fast, full = Renderer(), Renderer(blit=False)
    shown = {0, 1, 2, 25, 40, 60, 99, 100, 101, 104}
    limits = set()
    for step in range(105):
        if step in shown:
            trail, scenario = np.asarray(base._trail), base.scenario
            args = (scenario, trail, frame_title(base.config), step * 0.1)
            assert _mean_abs_difference(fast.draw(*args), full.draw(*args)) < 0.1, step
            limits.add(fast._scene.limits)
        env.step(np.array([0.6, 0.0] * 3))
    assert len(limits) >= 3  # the robots drove out of the map's view, which widened twice
    other = gym.make("KoopNav-Formation-v0", map="random", render_mode="rgb_array")
    other.reset(seed=3)
    for _ in range(3):
        other.step(np.array([0.3, 0.2] * 3))
    args = (other.unwrapped.scenario, np.asarray(other.unwrapped._trail), "random", 0.3)
    assert _mean_abs_difference(fast.draw(*args), full.draw(*args)) < 0.1


def test_a_frame_takes_at_most_10_ms() -> None:
    """Only the robots, trails and clock are drawn per frame (the static background is kept as a
    bitmap): >= 100 frames/s, where redrawing the whole figure took ~100 ms a frame.

    Measured in CPU time of this process, the best of 5 windows: on the shared 2-core machine
    wall time also counts the waits for a core that other jobs take (bench/render_speed.py
    reports wall-clock frames/s)."""
    env = gym.make("KoopNav-Formation-v0", render_mode="rgb_array")
    env.reset(seed=0)
    env.render()
    action = np.array([0.3, 0.05] * 3)
    best = np.inf
    for _ in range(5):
        spent = 0.0
        for _ in range(10):
            env.step(action)
            start = time.process_time()
            env.render()
            spent += time.process_time() - start
        best = min(best, spent / 10)
    assert best <= 0.010, f"{best * 1e3:.1f} ms a frame"
    env.close()


# slow: 130 frames drawn by the original and its copies, about 6 CPU-s (issue 61); the blitting
# and full-redraw tests keep the frames' checks in the default run
@pytest.mark.slow
def test_a_copy_renders_what_the_original_renders_over_a_whole_episode() -> None:
    """A frame depends on the state only: copies made after the original has drawn (at several
    points, one just before the clock reaches 10 s and the title is laid out again) draw every
    later frame pixel for pixel as the original, to the end of the episode."""
    import copy

    env = gym.make(
        "KoopNav-Formation-v0", map="random", n_robots=5, render_mode="rgb_array", max_episode_steps=130
    )
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    copies = {}
    done = False
    step = 0
    while not done:
        frame = env.render()
        for made_at, clone in copies.items():
            assert np.array_equal(clone.render(), frame), (
                f"copy made at step {made_at} differs at step {step}"
            )
        if step in (0, 37, 99):
            copies[step] = copy.deepcopy(env)
        action = rng.uniform(-0.3, 0.3, env.action_space.shape)
        _, _, terminated, truncated, _ = env.step(action)
        for clone in copies.values():
            clone.step(action)
        done = terminated or truncated
        step += 1
    assert step == 130 and len(copies) == 3
