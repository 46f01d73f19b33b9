"""What the two single-env fronts share, the Gymnasium env (gym_env.py) and the PettingZoo
parallel env (parallel_env.py): both run env 0 of an engine, name its observation layout and
scenario the same way, keep the trail of the robots' poses while rendering, draw the frame and
close the engine and the renderer. Internal."""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.layout import ObservationLayout
from koopman_envs.scenario import Scenario

if TYPE_CHECKING:  # pragma: no cover - typing only (rendering imports matplotlib when first used)
    from koopman_envs.rendering.renderer import Renderer

__all__ = ["SingleEnvFront"]


class SingleEnvFront:
    """Env 0 of ``engine`` rendered in ``render_mode``, for a front that sets both in its
    ``__init__`` and calls :meth:`_start_trail` after a reset and :meth:`_extend_trail` after a
    step. Listed before the API's base class, whose ``render`` and ``close`` it provides."""

    engine: NavigationEngine
    render_mode: str | None
    _renderer: Renderer | None = None
    _trail: list[NDArray[np.float64]]

    @property
    def observation_layout(self) -> ObservationLayout:
        """One robot's observation block by name (:class:`koopman_envs.layout.ObservationLayout`),
        known before the first reset."""
        return self.engine.observation_layout

    @property
    def scenario(self) -> Scenario:
        """Obstacles, radii, starts, targets, formation offsets, limits and dt of this episode."""
        return self.engine.scenario(0)

    def _start_trail(self) -> None:
        """After a reset: the trail drawn is the robots' start poses (only while rendering)."""
        if self.render_mode is not None:
            self._trail = [self.engine.poses[0].copy()]

    def _extend_trail(self) -> None:
        """After a step: the poses reached join the trail; ``"human"`` shows the frame."""
        if self.render_mode is not None:
            self._trail.append(self.engine.poses[0].copy())
            if self.render_mode == "human":
                self.render()

    def render(self) -> NDArray[np.uint8] | None:
        """The frame of env 0 (movers, lidar beams and a collision's mark included), with the trail;
        None with a warning without a render mode, a ``RuntimeError`` before the first reset."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' or 'human' to the "
                "env's constructor (gym.make, parallel_env)"
            )
            return None
        from koopman_envs.rendering.renderer import Renderer, draw_engine_env

        if self._renderer is None:
            self._renderer = Renderer(human=self.render_mode == "human")
        self.scenario  # noqa: B018 - a RuntimeError before the first reset()
        return draw_engine_env(self._renderer, self.engine, 0, self._trail)

    def close(self) -> None:
        """Closes the engine and the renderer (a later ``render`` opens a new one)."""
        self.engine.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
