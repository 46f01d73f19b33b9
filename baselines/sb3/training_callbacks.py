"""The training run's stable-baselines3 callback (a module of its own: it imports SB3 at load,
and :mod:`baselines.sb3.train` loads it only once SB3 is known to be installed)."""

from __future__ import annotations

from collections.abc import Callable

from stable_baselines3.common.callbacks import BaseCallback

__all__ = ["PeriodicCheckpoints"]


class PeriodicCheckpoints(BaseCallback):
    """Every ``every`` steps, ``checkpoint(timesteps)`` (score and save the policy; it returns a
    line that is printed)."""

    def __init__(self, every: int, checkpoint: Callable[[int], str]) -> None:
        super().__init__()
        self.next_at = every
        self.every = every
        self.checkpoint = checkpoint

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_at:
            self.next_at += self.every
            print(self.checkpoint(self.num_timesteps), flush=True)
        return True
