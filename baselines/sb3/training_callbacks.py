"""The training run's stable-baselines3 callback (a module of its own: it imports SB3 at load,
and :mod:`baselines.sb3.train` loads it only once SB3 is known to be installed)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

__all__ = ["PeriodicCheckpoints"]


class PeriodicCheckpoints(BaseCallback):
    """Every ``every`` steps, ``checkpoint(timesteps)`` (score and save the policy; it returns a
    line that is printed); every ``resume_every`` rollouts (0: never), ``save_resume()`` at the
    start of the next rollout (write the resume checkpoint: the previous update is done and nothing
    of the next rollout is drawn yet)."""

    def __init__(
        self,
        every: int,
        checkpoint: Callable[[int], str],
        resume_every: int = 0,
        save_resume: Callable[[], object] | None = None,
    ) -> None:
        super().__init__()
        self.next_at = every
        self.every = every
        self.checkpoint = checkpoint
        self.resume_every = resume_every
        self.save_resume = save_resume
        #: rollouts collected so far, and the count at the last resume checkpoint
        self.rollouts = 0
        self.saved_at = 0

    def state(self) -> dict[str, Any]:
        """The counters a resumed run continues from."""
        return {"next_at": self.next_at, "rollouts": self.rollouts}

    def set_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state` (its rollout count is the one just saved)."""
        self.next_at, self.rollouts = state["next_at"], state["rollouts"]
        self.saved_at = self.rollouts

    def _on_rollout_start(self) -> None:
        due = self.resume_every and self.rollouts % self.resume_every == 0
        if due and self.rollouts != self.saved_at and self.save_resume is not None:
            self.saved_at = self.rollouts
            self.save_resume()

    def _on_rollout_end(self) -> None:
        self.rollouts += 1

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_at:
            self.next_at += self.every
            print(self.checkpoint(self.num_timesteps), flush=True)
        return True
