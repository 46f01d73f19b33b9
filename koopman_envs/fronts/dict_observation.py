"""An opt-in ``Dict`` observation built from the named layout (as VMAS's ``dict_spaces``).

``DictObservation(gym.make("KoopNav-Formation-v0"))`` turns the flat ``Box(N * F)`` team
observation into a ``Dict`` of the block's parts (:class:`koopman_envs.layout.ObservationLayout`),
each an array of shape (N, width): ``obs["team"][i]`` is robot i's team-mate entries. The values
are the flat observation's, re-sliced (no copy of the simulator's work, no other arithmetic), and
the bounds are the flat space's, so a policy can move from one to the other without retraining
its scaling.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from koopman_envs.layout import ObservationLayout

__all__ = ["DictObservation", "split_observation"]


def split_observation(
    flat: NDArray[Any], layout: ObservationLayout, n_robots: int
) -> dict[str, NDArray[Any]]:
    """The parts of a team observation (..., N * F) as (..., N, width) arrays, by name."""
    blocks = np.asarray(flat).reshape(np.shape(flat)[:-1] + (n_robots, layout.size))
    return {name: blocks[..., layout[name]] for name, _ in layout.parts}


class DictObservation(gym.ObservationWrapper):
    """A KoopNav Gymnasium env whose observation is a ``Dict`` of the layout's parts.

    Parameters
    ----------
    env : gymnasium.Env
        A KoopNav env (``gym.make`` of a KoopNav id, wrapped or not).
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        flat = env.observation_space
        if not isinstance(flat, spaces.Box):
            raise TypeError(f"DictObservation needs a KoopNav env's Box observation, got {flat!r}")
        layout = getattr(env.unwrapped, "observation_layout", None)
        if not isinstance(layout, ObservationLayout):
            raise TypeError(
                f"DictObservation needs a KoopNav env; {env.unwrapped!r} has no observation layout"
            )
        self.layout, self.n_robots = layout, layout.n_robots
        low = split_observation(flat.low, layout, self.n_robots)
        high = split_observation(flat.high, layout, self.n_robots)
        self.observation_space = spaces.Dict(
            {name: spaces.Box(low[name], high[name], dtype=flat.dtype) for name in low}
        )

    def observation(self, observation: NDArray[Any]) -> dict[str, Any]:
        """The flat observation's parts, by name."""
        return split_observation(observation, self.layout, self.n_robots)
