"""What a one-stage run of ``python -m baselines.marl.benchmarl_train`` saves to resume
(``--resume-every N``, ``--resume``), and how it is put back (issue 60).

BenchMARL's own checkpoint (``ExperimentConfig.checkpoint_interval``, ``restore_file``) restores the
networks, the replay buffer and the counters, but not enough to continue bit for bit: it leaves out
Adam's moments and step counts (``Experiment.state_dict`` saves the losses' parameters, not the
optimizers), the environments' episodes in progress and their generators (the collector's
``state_dict`` of a plain env is empty, and building the collector resets every environment), the
observation the collector carries to its next step, the trajectory counter, and the global
generators (``Experiment.run`` seeds them again from the seed). A resumed run from it starts new
episodes with fresh moments: another run.

The resume checkpoint (:mod:`baselines.resume`'s format, kind :data:`KIND`, the run's folder's
``resume.ckpt``) is taken where BenchMARL takes its checkpoints, at the end of an iteration (the
training, the evaluation and the logging done; nothing of the next batch drawn), and holds

- BenchMARL's ``Experiment.state_dict()`` (parameters, buffer, counters, the collector's counters);
- every optimizer's ``state_dict``;
- the training and evaluation envs' state (:data:`ENV_STATE`: the KoopNav vector env whole, with
  its simulator arrays and every environment's generator, the reward shaping's state, the
  pending first observations) and the collector's carried tensordict and trajectory counter;
- the generators of Python, NumPy and torch;
- the callbacks' own state (a suite run's checkpoint table) and the run's BenchMARL folder name
  (the resumed run logs into the same folder).

Restoring builds the experiment as a fresh run does, then puts all of that back and enters
BenchMARL's collection loop with the generators set (not through ``Experiment.run``, which seeds
them again).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from baselines.resume import RESUME_FILE, global_rng_states, read_resume, set_global_rng_states, write_resume

__all__ = [
    "ENV_STATE",
    "FREE_OPTIONS",
    "KIND",
    "MARKER",
    "capture",
    "Session",
    "marker",
    "read",
    "restore",
    "resume_identity",
    "save",
]

#: the trainer named in the file's header
KIND = "benchmarl-ppo"
#: options that may differ between the interrupted and the resumed session (where files go, when
#: a resume checkpoint is written), not what is trained
FREE_OPTIONS = ("out", "resume", "resume_every")
#: the attributes of a :class:`baselines.marl.torchrl_env.KoopNavMultiAgentEnv` that stepping changes
ENV_STATE = ("_venv", "shaping", "_seed", "_pending", "_ended")
#: the name of the ``restore_file`` given to BenchMARL by a resumed run (:func:`marker`): its
#: folder's name is the run's (BenchMARL logs into it); :class:`baselines.marl.benchmarl_resumable.ResumableExperiment`
#: loads nothing from it
MARKER = "koopnav-resume"


def resume_identity(args: argparse.Namespace) -> dict[str, Any]:
    """The settings a run must share with the run that wrote its resume checkpoint: every option
    but :data:`FREE_OPTIONS` (the thread count too: a run is bit for bit at one thread count)."""
    return {k: v for k, v in sorted(vars(args).items()) if k not in FREE_OPTIONS}


def marker(folder: Path, name: str) -> Path:
    """The ``restore_file`` of a resumed run whose BenchMARL run folder is ``folder/name``."""
    return folder / name / "checkpoints" / MARKER


class Session:
    """A one-stage run's sessions: the resume checkpoint's extras (the frames every resumed
    session began at, the earlier sessions' wall time) and this session's start."""

    def __init__(self, resumed: dict[str, Any] | None) -> None:
        self.start = time.perf_counter()
        self.resumed_from: list[int] = []
        self.wall_before = 0.0
        if resumed is not None:
            self.resumed_from = [
                *resumed["resumed_from"],
                int(resumed["experiment"]["state"]["total_frames"]),
            ]
            self.wall_before = float(resumed["wall_before"])

    def extras(self) -> dict[str, Any]:
        return {
            "resumed_from": list(self.resumed_from),
            "wall_before": self.wall_before + time.perf_counter() - self.start,
        }


def _base(env: Any) -> Any:
    """The KoopNav env below BenchMARL's transforms."""
    return getattr(env, "base_env", env)


def capture(run: Any, callbacks: list[Any], extra: dict[str, Any]) -> dict[str, Any]:
    """The state of the experiment ``run`` at the end of an iteration (module docstring)."""
    collector = run.collector
    return {
        "experiment": run.state_dict(),
        "optimizers": {
            group: {name: optimizer.state_dict() for name, optimizer in optimizers.items()}
            for group, optimizers in run.optimizers.items()
        },
        "env": {key: getattr(_base(collector.env), key) for key in ENV_STATE},
        "test_env": {key: getattr(_base(run.test_env), key) for key in ENV_STATE},
        "carrier": collector._carrier.clone(),
        "traj_id": collector._traj_pool._traj_id.clone(),
        "rng": global_rng_states(),
        "callbacks": [callback.resume_state() for callback in callbacks],
        "name": run.name,
        **extra,
    }


def save(out: Path, args: argparse.Namespace, run: Any, callbacks: list[Any], extra: dict[str, Any]) -> Path:
    """Write ``OUT/resume.ckpt`` of ``run`` (atomically)."""
    return write_resume(out / RESUME_FILE, KIND, resume_identity(args), capture(run, callbacks, extra))


def read(out: Path, args: argparse.Namespace) -> dict[str, Any]:
    """The state in ``OUT/resume.ckpt``, checked (:func:`baselines.resume.read_resume`:
    :class:`baselines.resume.ResumeRefused` naming what is wrong)."""
    state: dict[str, Any] = read_resume(out / RESUME_FILE, KIND, resume_identity(args))
    return state


def restore(run: Any, state: dict[str, Any], callbacks: list[Any]) -> None:
    """Put ``state`` (:func:`capture`) back into the freshly built experiment ``run`` and set the
    generators: the next thing to do is ``run._collection_loop()``."""
    run.load_state_dict(state["experiment"])
    for group, optimizers in state["optimizers"].items():
        for name, optimizer_state in optimizers.items():
            run.optimizers[group][name].load_state_dict(optimizer_state)
    collector = run.collector
    for env, saved in ((_base(collector.env), state["env"]), (_base(run.test_env), state["test_env"])):
        env._venv.close()  # the one building made, replaced by the saved one
        for key, value in saved.items():
            setattr(env, key, value)
    collector._carrier = state["carrier"]
    collector._traj_pool._traj_id.copy_(state["traj_id"])
    for callback, saved in zip(callbacks, state["callbacks"], strict=True):
        callback.set_resume_state(saved)
    set_global_rng_states(state["rng"])
