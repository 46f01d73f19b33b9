"""What a PPO run of ``python -m baselines.sb3.train`` saves to resume, and how it is put back.

A resume checkpoint (:mod:`baselines.resume`) is taken at the start of a rollout, when PPO's update
of the previous one is done and nothing of the next one is drawn yet. It holds

- the network's weights and Adam's state (``state_dict``\\ s: tensors, restored bit for bit);
- the model's training counters and carried-over rollout state (:data:`MODEL_STATE`: the step
  count, the update count and schedule progress, the last observations and episode starts, the
  episode buffers);
- the vector env whole (the simulator's arrays and every environment's generator, pickled: a
  pickled KoopNav vector env steps bit for bit as the original) and the state of its monitor and
  normalizer (running statistics and the per-env discounted returns);
- the generators of Python, NumPy and torch, and those of the action and observation spaces;
- the trainer's own: the checkpoint-selection table, the eval history, the callback's counters,
  the curriculum stage, the wall time so far.

Restoring builds the model on the restored env without a seed (a seed would reset the env's and
the spaces' generators), loads the tensors and counters, and sets the generators last, after
whatever building the model drew. PPO only: SAC's replay buffer is not saved.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from baselines.resume import RESUME_FILE, global_rng_states, read_resume, set_global_rng_states, write_resume

__all__ = [
    "KIND",
    "MODEL_STATE",
    "capture",
    "chain_of",
    "finished",
    "restore_env",
    "restore_model",
    "resume",
    "resume_identity",
    "save",
]

#: the trainer named in the file's header
KIND = "sb3-ppo"
#: the model's attributes that training changes (beside the network and the optimizer)
MODEL_STATE = (
    "num_timesteps",
    "_episode_num",
    "_n_updates",
    "_current_progress_remaining",
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
)
#: options that may differ between the interrupted and the resumed session (they change where
#: files go or when a resume checkpoint is written, not what is trained)
FREE_OPTIONS = ("out", "resume", "resume_every")
#: options added after resume checkpoints were written: left out of the identity at their default
#: (None), so that a checkpoint of a run from before they existed still fits (they change nothing)
LATER_OPTIONS = ("plant", "slips")
#: a wrapper's attributes rebuilt by its constructor (``class_attributes`` holds the class's
#: members, which do not pickle) or its link to the env below
_REBUILT = ("venv", "class_attributes")


def resume_identity(args: argparse.Namespace) -> dict[str, Any]:
    """The settings a run must share with the run that wrote its resume checkpoint: every option
    but :data:`FREE_OPTIONS` (the thread count too: a run is bit for bit at one thread count)."""
    return {
        k: v
        for k, v in sorted(vars(args).items())
        if k not in FREE_OPTIONS and not (k in LATER_OPTIONS and v is None)
    }


def chain_of(venv: Any) -> list[Any]:
    """``venv`` and the envs it wraps, outermost first (``VecNormalize``, ``VecMonitor``, the
    KoopNav vector env)."""
    chain = [venv]
    while hasattr(chain[-1], "venv") and chain[-1].__class__.__module__.startswith("stable_baselines3"):
        chain.append(chain[-1].venv)
    return chain


def _spaces(model: Any) -> dict[str, Any]:
    """The generators of the model's spaces (None before one was drawn from or seeded)."""
    return {
        "action_space": model.action_space._np_random,
        "observation_space": model.observation_space._np_random,
    }


def capture(model: Any, venv: Any, trainer: dict[str, Any]) -> dict[str, Any]:
    """The state to resume from (see the module docstring); ``trainer`` is the trainer's own."""
    *wrappers, raw = chain_of(venv)
    return {
        "env": raw,
        "wrappers": [{k: v for k, v in vars(w).items() if k not in _REBUILT} for w in wrappers],
        "policy": model.policy.state_dict(),
        "optimizer": model.policy.optimizer.state_dict(),
        "model": {name: getattr(model, name) for name in MODEL_STATE},
        "spaces": _spaces(model),
        "rng": global_rng_states(),
        "trainer": trainer,
    }


def save(run: Any, model: Any, venv: Any, callback: dict[str, Any], where: dict[str, int]) -> Path:
    """Write the resume checkpoint ``OUT/resume.ckpt`` of ``run`` (a
    :class:`baselines.sb3.train.Trainer`) atomically; its path. ``callback``: the callback's
    counters; ``where``: the curriculum stage trained now and the robot-steps at its start."""
    trainer = {
        "callback": callback,
        "where": dict(where),
        "scores": list(run.scores),
        "history": list(run.history),
        "init_source": run.init_source,
        "wall": run.wall_before + time.perf_counter() - run.session_start,
        "resumed_from": list(run.resumed_from),
    }
    state = capture(model, venv, trainer)
    return write_resume(run.out / RESUME_FILE, KIND, resume_identity(run.args), state)


def resume(run: Any) -> tuple[Any, Any, dict[str, Any]]:
    """The env and the model of ``run``'s resume checkpoint, and the trainer's state in it, which
    ``run`` continues from (:class:`baselines.resume.ResumeRefused` naming a file that cannot be
    resumed from: absent, foreign, torn, or of a run with other settings)."""
    if run.args.algo != "ppo":
        raise ValueError(f"--resume: only PPO runs write resume checkpoints, not --algo {run.args.algo}")
    state = read_resume(run.out / RESUME_FILE, KIND, resume_identity(run.args))
    venv = restore_env(state, run.wrap)
    steps = int(state["model"]["num_timesteps"])
    log = run.out / "progress.csv"  # SB3's CSV logger starts its file afresh: the earlier rows kept
    if log.exists():
        log.replace(run.out / f"progress-before-resume-at-{steps}.csv")
    model = run.build_model(venv, resuming=True)
    restore_model(model, state)
    trainer = state["trainer"]
    run.scores, run.history = trainer["scores"], trainer["history"]
    run.init_source, run.wall_before = trainer["init_source"], trainer["wall"]
    run.resumed_from = [*trainer["resumed_from"], steps]
    print(f"resumed from {run.out / RESUME_FILE} after {steps:,} robot-steps", flush=True)
    return model, venv, trainer


def finished(out: Path) -> None:
    """Remove the resume checkpoint of a run that finished in ``out``: nothing is left to resume."""
    (out / RESUME_FILE).unlink(missing_ok=True)


def restore_env(state: dict[str, Any], wrap: Any) -> Any:
    """The saved env wrapped by ``wrap`` (the trainer's monitor and normalizer) with their saved
    statistics."""
    venv = wrap(state["env"])
    wrappers = chain_of(venv)[:-1]
    if len(wrappers) != len(state["wrappers"]):
        raise ValueError(
            f"the resume checkpoint holds {len(state['wrappers'])} env wrappers, the run has {len(wrappers)}"
        )
    for wrapper, saved in zip(wrappers, state["wrappers"], strict=True):
        vars(wrapper).update(saved)
    return venv


def restore_model(model: Any, state: dict[str, Any]) -> None:
    """Put the saved network, optimizer, counters and generators into ``model`` (built on the env
    of :func:`restore_env`, without a seed); the global generators last."""
    model.policy.load_state_dict(state["policy"])
    model.policy.optimizer.load_state_dict(state["optimizer"])
    for name, value in state["model"].items():
        setattr(model, name, value)
    model.action_space._np_random = state["spaces"]["action_space"]
    model.observation_space._np_random = state["spaces"]["observation_space"]
    set_global_rng_states(state["rng"])
