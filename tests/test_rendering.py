"""Matplotlib rendering and episode export; nothing imports pygame."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

from koopman_envs import formation_v0
from koopman_envs.rendering import save_episode


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
