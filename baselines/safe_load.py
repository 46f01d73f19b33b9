"""Load a stable-baselines3 model from its zip without running any of the pickles inside it.

An SB3 zip stores its weights as tensors (``policy.pth``, read by ``torch.load(weights_only=True)``,
which runs no code) and its settings as JSON, except a dozen fields that it pickles with
cloudpickle (the policy class, the spaces, the schedules, the extractor class...).
``cloudpickle.loads`` runs whatever code the file's author put there, so loading an untrusted zip
the plain way is running an untrusted program.

SB3's ``load(custom_objects=...)`` takes a value for a field instead of unpickling it. This module
rebuilds every pickled field of a policy that KoopNav trains (``python -m baselines.train``) from
the readable text SB3 writes beside each pickle, against an allow-list of classes, and refuses a
zip that holds any other pickled field. The shipped policies load this way (tested bit-identical
to the pickled load); ``allow_pickle=True`` loads any zip the plain way, for files you trust.
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from typing import Any

import numpy as np

__all__ = ["UnsafePolicyFile", "load_model"]

#: the extractor classes a KoopNav policy may name (by the text SB3 writes beside the pickle)
_EXTRACTORS = {"<class 'baselines.set_encoder.SetEncoder'>": ("baselines.set_encoder", "SetEncoder")}
#: pickled fields that only matter for training (rollout state, episode buffers): left out
_TRAINING_STATE = (
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
)


class UnsafePolicyFile(ValueError):
    """A policy zip holds a pickled field this loader cannot rebuild without running it."""


def _box(field: dict[str, Any], name: str) -> Any:
    """A ``Box`` from SB3's readable text of one; the bounds must read as what we rebuild."""
    from gymnasium import spaces

    if field.get(":type:") != "<class 'gymnasium.spaces.box.Box'>":
        raise UnsafePolicyFile(f"{name} is a {field.get(':type:')}, not a Box")
    shape = tuple(int(v) for v in field["_shape"])
    dtype = np.dtype(field["dtype"])
    low, high = (np.array(str(field[k]).strip("[]").split(), dtype=dtype) for k in ("low", "high"))
    if low.size != int(np.prod(shape)) or high.size != int(np.prod(shape)):
        # a long vector is cut short in the text: an unbounded observation box (float32 limits)
        limit = np.finfo(dtype).max
        low, high = np.full(shape, -limit, dtype=dtype), np.full(shape, limit, dtype=dtype)
    return spaces.Box(low.reshape(shape), high.reshape(shape), shape=shape, dtype=dtype)


def _constant(field: dict[str, Any], name: str) -> float:
    match = re.fullmatch(r"ConstantSchedule\(val=([-+0-9.eE]+)\)", str(field.get("value_schedule", "")))
    if match is None:
        raise UnsafePolicyFile(f"{name} is not a constant schedule ({field.get('value_schedule')!r})")
    return float(match.group(1))


def _policy_kwargs(field: dict[str, Any]) -> dict[str, Any]:
    import importlib

    kwargs = {k: v for k, v in field.items() if not k.startswith(":")}
    extractor = kwargs.get("features_extractor_class")
    if extractor is not None:
        if extractor not in _EXTRACTORS:
            raise UnsafePolicyFile(
                f"policy_kwargs names the extractor {extractor}, not one of {list(_EXTRACTORS)}"
            )
        module, attribute = _EXTRACTORS[extractor]
        kwargs["features_extractor_class"] = getattr(importlib.import_module(module), attribute)
    return kwargs


def _replacements(data: dict[str, Any], algorithm: Any) -> dict[str, Any]:
    """A value for every pickled field of ``data`` (SB3's ``data`` JSON of the zip)."""
    from stable_baselines3.common.buffers import RolloutBuffer
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.utils import ConstantSchedule, FloatSchedule

    pickled = [k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v]
    out: dict[str, Any] = {}
    for key in pickled:
        field = data[key]
        if key in _TRAINING_STATE:
            out[key] = None
        elif key == "policy_class":
            if field.get(
                "__module__"
            ) != "stable_baselines3.common.policies" or "ActorCriticPolicy" not in str(field.get("__init__")):
                raise UnsafePolicyFile("policy_class is not stable-baselines3's ActorCriticPolicy")
            out[key] = ActorCriticPolicy
        elif key in ("observation_space", "action_space"):
            out[key] = _box(field, key)
        elif key in ("clip_range", "lr_schedule"):
            out[key] = FloatSchedule(ConstantSchedule(_constant(field, key)))
        elif key == "rollout_buffer_class":
            if "RolloutBuffer.__init__" not in str(field.get("__init__")):
                raise UnsafePolicyFile("rollout_buffer_class is not stable-baselines3's RolloutBuffer")
            out[key] = RolloutBuffer
        elif key == "policy_kwargs":
            out[key] = _policy_kwargs(field)
        else:
            raise UnsafePolicyFile(f"the pickled field {key!r} cannot be rebuilt without running it")
    return out


def load_model(path: str | os.PathLike[str], algorithm: Any, *, allow_pickle: bool = False) -> Any:
    """Load an SB3 model of class ``algorithm`` (e.g. ``PPO``) on the CPU.

    Parameters
    ----------
    path : path
        The ``policy.zip``.
    algorithm : type
        The SB3 algorithm class.
    allow_pickle : bool
        False (default): rebuild every pickled field from its text (see the module docstring) and
        run none of them; a zip with a field that cannot be rebuilt raises
        :class:`UnsafePolicyFile`. True: SB3's plain load, which unpickles them (trusted files only).

    Raises
    ------
    UnsafePolicyFile
        Without ``allow_pickle``, a field that cannot be rebuilt (named).
    """
    if allow_pickle:
        return algorithm.load(path, device="cpu")
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    try:
        replacements = _replacements(data, algorithm)
    except UnsafePolicyFile as exc:
        raise UnsafePolicyFile(
            f"{os.fspath(path)}: {exc}; loading it would run code stored in the file. If you trust "
            "the file, load it with allow_pickle=True"
        ) from None
    return algorithm.load(path, device="cpu", custom_objects=replacements)
