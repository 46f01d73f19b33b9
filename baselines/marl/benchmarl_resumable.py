"""BenchMARL's ``Experiment`` as a resumable run builds it (:mod:`baselines.marl.benchmarl_resume`):
a module of its own, imported only with BenchMARL, whose class pickles by name (BenchMARL pickles
the callbacks, and with them the experiment, into its run folder's ``config.pkl``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from benchmarl.experiment import Experiment

from baselines.marl.benchmarl_resume import MARKER

__all__ = ["ResumableExperiment"]


class ResumableExperiment(Experiment):  # type: ignore[misc]  # BenchMARL is untyped
    """With ``on_checkpoint`` set, the checkpoints BenchMARL takes every ``checkpoint_interval``
    frames before the end are ``on_checkpoint(self)`` (a resume checkpoint) instead of its own;
    a ``restore_file`` named :data:`MARKER` loads nothing."""

    on_checkpoint: Any = None

    def _save_experiment(self) -> None:
        if self.on_checkpoint is not None and self.total_frames < self.config.get_max_n_frames(
            self.on_policy
        ):
            self.on_checkpoint(self)
            return
        super()._save_experiment()

    def _load_experiment(self) -> Any:
        if Path(self.config.restore_file).name == MARKER:
            return self
        return super()._load_experiment()
