"""Which weights a run's learned controllers play: a digest of the policy files each one loads.

A learned controller's options (``policy_root``) name a folder, not the weights in it: if a
shipped policy is replaced while a run is paused (``python -m evaluation.experiments.seeds --ship``,
a retrained seed), a resume would play the new weights for the rest of the run under the same
row. So a run's configuration records, for every controller whose class declares the files it
loads (``weight_files(options, task)``: ``rl-ppo``, ``rl-ppo-set`` and its variants, ``ippo``,
``mappo``), the SHA-256 of those files per task (:func:`run_weights`), and the run's log header
keeps it (:data:`evaluation.episodes.log_weights.WEIGHTS_KEY`); :func:`evaluation.episodes.runlog.read_log` refuses a resume whose controller would load
other weights than its logged episodes did, naming it.

A tuned controller's defaults are the same kind of hole: ``koopman-nmpc``, ``nominal-nmpc``,
``consensus``, ``mpc-cbf`` take theirs from ``controllers/tuned/NAME.json``
(:func:`controllers.tuning.presets.tuned_file`), which ``python -m evaluation.tune adopt`` or a
pull may replace while a run is paused. So the configuration also records, per controller whose
defaults come from such a file (its ``-v0`` variant has none), the SHA-256 of that file
(:func:`run_presets`, the key :data:`evaluation.episodes.log_weights.PRESETS_KEY`), checked on a
resume the same way as the weights.

A log written before the digests were recorded has none: it still resumes (nothing can be
checked for it, and its header stays without digests) and every page still reads it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from controllers.registry import split_name
from controllers.tuning.presets import tuned_file
from evaluation.run.configs import ControllerConfig
from koopman_envs import TASKS

__all__ = ["files_digest", "run_presets", "run_weights"]

#: bytes read at a time
_CHUNK = 1 << 20


def files_digest(paths: Iterable[Path]) -> str | None:
    """The SHA-256 of the files ``paths`` that exist, each as its name, its size and its bytes, in
    the order given (a file renamed, grown or edited changes it); None when none exists (the
    controller names what is missing when it loads)."""
    digest = hashlib.sha256()
    found = False
    for path in paths:
        if not path.is_file():
            continue
        found = True
        digest.update(f"{path.name}\0{path.stat().st_size}\0".encode())
        with open(path, "rb") as handle:
            while chunk := handle.read(_CHUNK):
                digest.update(chunk)
    return digest.hexdigest() if found else None


def _task_of(env_id: str) -> str | None:
    return next((name for name, spec in TASKS.items() if spec.env_id == env_id), None)


def run_weights(controllers: Sequence[ControllerConfig], env_ids: Sequence[str]) -> dict[str, dict[str, str]]:
    """Per controller label that loads a policy (its class, behind any wrapper prefix, declares
    ``weight_files``), the digest of the files it loads for each task of ``env_ids``
    (:func:`files_digest`; a task without its files is left out)."""
    tasks = [task for task in map(_task_of, env_ids) if task is not None]
    weights: dict[str, dict[str, str]] = {}
    for config in controllers:
        cls: Any = config.controller_class(wrapped=True)
        files = getattr(cls, "weight_files", None)
        if not callable(files):
            continue
        options = dict(config.options)
        digests = {task: files_digest(files(options, task)) for task in tasks}
        found = {task: digest for task, digest in digests.items() if digest is not None}
        if found:
            weights[config.label] = found
    return weights


def run_presets(controllers: Sequence[ControllerConfig]) -> dict[str, dict[str, str]]:
    """Per controller label whose defaults a tuned preset file sets (its registered name, behind
    any wrapper prefix: :func:`controllers.tuning.presets.tuned_file`), the digest of that file
    (:func:`files_digest`) under its name in the package, ``{"tuned/NAME.json": sha256}``; a
    controller given as a factory, and a preset file that is missing, are left out."""
    presets: dict[str, dict[str, str]] = {}
    for config in controllers:
        path = None if config.factory is not None else tuned_file(split_name(config.name)[1])
        digest = None if path is None else files_digest([path])
        if path is not None and digest is not None:
            presets[config.label] = {f"{path.parent.name}/{path.name}": digest}
    return presets
