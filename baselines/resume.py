"""Resume checkpoints of a training run: a file that lets an interrupted seed continue as if it had
never stopped (issue 60, docs/benchmark.md#learned-policies).

A trainer writes its resume checkpoint every few rollouts with :func:`write_resume` (atomically: a
temporary file renamed over the previous one) and reads it back with :func:`read_resume`. The file is

- a first line ``KOOPNAV-RESUME <FORMAT>``;
- a JSON header line: the trainer (``kind``), the run's ``identity`` (the settings that fix what a
  seed trains: env, seed, budget, network...), and the payload's size and SHA-256;
- the payload: a pickle of the trainer's state (the model, its optimizer, the vector env with its
  generators, every global random generator, the checkpoint table).

Reading checks all of it before anything is unpickled and refuses by name (:class:`ResumeRefused`,
a ``ValueError``): a file that is not a resume checkpoint, of another format, of another trainer,
cut short or altered (size or hash), or written by a run with other settings. The payload is a
pickle, and unpickling runs code: a resume checkpoint is the run's own file in its own folder, to
be trusted as the run's code is, never a file received from elsewhere (the policies a run exports
load without any pickle, :mod:`baselines.safe_load`).

Run as ``python -m baselines.resume FILE [KIND]`` it checks a file's header and hash without
unpickling it (exit 0 and one line, or exit 2 and the reason): ``data/training/run.sh`` asks this
before it resumes a seed folder.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import random
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from koopman_envs.checks import differing_settings
from koopman_envs.files import read_bounded, write_atomic

__all__ = [
    "FORMAT",
    "MAGIC",
    "MAX_RESUME_BYTES",
    "RESUME_FILE",
    "ResumeRefused",
    "check_resume",
    "global_rng_states",
    "read_resume",
    "set_global_rng_states",
    "write_resume",
]

#: the resume checkpoint's name in a run's folder
RESUME_FILE = "resume.ckpt"
#: the file's first bytes
MAGIC = b"KOOPNAV-RESUME"
#: the layout of the file and of its payload; a file of another format is refused
FORMAT = 1
#: the largest header line [bytes] (read before the payload)
_MAX_HEADER = 1 << 20
#: the largest resume checkpoint read [bytes]: a real rl-ppo-set run's is 2.8 MiB (384 sub-envs)
MAX_RESUME_BYTES = 1 << 30


class ResumeRefused(ValueError):
    """A resume checkpoint that cannot be resumed from; the message names the file and why."""


def write_resume(path: str | os.PathLike[str], kind: str, identity: dict[str, Any], state: Any) -> Path:
    """Write ``state`` as the resume checkpoint ``path`` of a ``kind`` run with ``identity``.

    Parameters
    ----------
    path : str or path-like
        The file (replaced whole or not at all: a temporary file renamed over it).
    kind : str
        The trainer, e.g. ``"sb3-ppo"``.
    identity : dict
        JSON-serializable settings that must be equal for a run to resume from the file.
    state : object
        Whatever the trainer needs to continue (pickled).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    payload = pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    header = {
        "kind": kind,
        "identity": identity,
        "payload_bytes": len(payload),
        "sha256": hashlib.sha256(payload).hexdigest(),
    }
    first = MAGIC + b" " + str(FORMAT).encode() + b"\n"
    line = json.dumps(header, sort_keys=True).encode() + b"\n"
    return write_atomic(path, first + line + payload)


def _split(path: Path, kind: str | None) -> tuple[dict[str, Any], bytes]:
    """The header and the payload of ``path``, checked (magic, format, kind, size, hash)."""
    name = f"resume checkpoint {os.fspath(path)!r}"
    try:
        blob = read_bounded(path, MAX_RESUME_BYTES, what="resume checkpoint")
    except (OSError, ValueError) as exc:  # missing, not a regular file, over the cap
        raise ResumeRefused(str(exc)) from None
    first, _, rest = blob.partition(b"\n")
    words = first.split(b" ")
    if len(words) != 2 or words[0] != MAGIC:
        raise ResumeRefused(f"{name} is not a KoopNav resume checkpoint (its first line is {first[:40]!r})")
    if words[1] != str(FORMAT).encode():
        raise ResumeRefused(
            f"{name} has format {words[1].decode(errors='replace')!r}; this KoopNav reads {FORMAT}"
        )
    line, newline, payload = rest.partition(b"\n")
    try:
        if not newline or len(line) > _MAX_HEADER:
            raise ValueError("no header line")
        header = json.loads(line)
        if not isinstance(header, dict) or not {"kind", "identity", "payload_bytes", "sha256"} <= set(header):
            raise ValueError("fields missing")
    except ValueError:
        raise ResumeRefused(f"{name} has no readable header (cut short or not written by KoopNav)") from None
    if kind is not None and header["kind"] != kind:
        raise ResumeRefused(f"{name} was written by a {header['kind']!r} run; this is a {kind!r} run")
    if len(payload) != header["payload_bytes"]:
        raise ResumeRefused(
            f"{name} is torn: its payload has {len(payload)} bytes, its header says {header['payload_bytes']}"
        )
    if hashlib.sha256(payload).hexdigest() != header["sha256"]:
        raise ResumeRefused(f"{name} is altered: its payload's SHA-256 differs from its header's")
    return header, payload


def check_resume(path: str | os.PathLike[str], kind: str | None = None) -> dict[str, Any]:
    """The header of the resume checkpoint ``path`` once its format, kind, size and hash are checked
    (nothing is unpickled); :class:`ResumeRefused` naming what is wrong."""
    return _split(Path(path), kind)[0]


def read_resume(path: str | os.PathLike[str], kind: str, identity: dict[str, Any]) -> Any:
    """The state in the resume checkpoint ``path`` of a ``kind`` run with ``identity``.

    Raises
    ------
    ResumeRefused
        The file is not a resume checkpoint, is of another format or trainer, is torn or altered,
        or was written by a run whose identity differs (the differing settings are named).
    """
    header, payload = _split(Path(path), kind)
    # a JSON round trip: the header holds the identity as JSON gave it back (lists for tuples)
    expected = json.loads(json.dumps(identity, sort_keys=True))
    if header["identity"] != expected:
        raise ResumeRefused(
            f"resume checkpoint {os.fspath(path)!r} was written by a run with other settings "
            f"({differing_settings(header['identity'], expected)})"
        )
    return pickle.loads(payload)


def global_rng_states() -> dict[str, Any]:
    """The states of the process's global generators: Python's, NumPy's and torch's (CPU)."""
    import torch

    return {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}


def set_global_rng_states(states: dict[str, Any]) -> None:
    """Set the process's global generators to ``states`` (:func:`global_rng_states`)."""
    import torch

    random.setstate(states["python"])
    np.random.set_state(states["numpy"])
    torch.set_rng_state(states["torch"])


def main(argv: list[str] | None = None) -> int:
    """``python -m baselines.resume FILE [KIND]``: exit 0 when FILE is a sound resume checkpoint
    (of KIND), 2 with the reason when not."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) not in (1, 2):
        print("usage: python -m baselines.resume FILE [KIND]", file=sys.stderr)
        return BAD_INPUT_EXIT
    try:
        header = check_resume(args[0], args[1] if len(args) == 2 else None)
    except ResumeRefused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    print(f"{args[0]}: a {header['kind']} resume checkpoint of {header['payload_bytes']:,} bytes, sound")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
