"""Fine-tuning a trained policy (``python -m baselines.sb3.train --init-from DIR``): what the source
must share with the run, and how its weights are carried over.

A source fits when its task, policy kind, features and network are the run's. One difference is
allowed: a set policy without mover slots may seed a run with them (the movers' third set of
:mod:`baselines.sb3.set_encoder`). Its weights are then copied where the shapes agree, and the first
layers of the actor and critic heads, which read the features and grew by the movers' pooled
encoding at the end, keep the source's columns with zeros for the new ones: the fine-tune starts
from exactly the source's policy, blind to movers, and learns to read them.
"""

from __future__ import annotations

from typing import Any

__all__ = ["copy_weights", "mismatches"]


def mismatches(metadata: dict[str, Any], required: dict[str, Any]) -> list[str]:
    """What keeps the policy of ``metadata`` from seeding a run that needs ``required`` (metadata
    key -> value), one phrase per key; empty when it fits (module docstring)."""
    wrong = []
    for key, wanted in required.items():
        got = metadata.get(key)
        if key == "set_config" and isinstance(got, dict) and isinstance(wanted, dict):
            # a policy without mover slots grows them (the module docstring)
            got = {**got, "movers": got.get("movers", 0) or wanted.get("movers", 0)}
        if got != wanted:
            wrong.append(f"{key} is {metadata.get(key)!r}, this run needs {wanted!r}")
    return wrong


def copy_weights(target: Any, source: Any) -> list[str]:
    """Copy the parameters of torch module ``source`` into ``target``; returns the names of the
    grown ones (module docstring). A parameter the source lacks keeps its fresh initialization.

    Raises
    ------
    ValueError
        A parameter whose shapes differ otherwise than by added input columns.
    """
    import torch

    mine, theirs = target.state_dict(), source.state_dict()
    grown = []
    with torch.no_grad():
        for name, value in mine.items():
            if name not in theirs:
                continue
            old = theirs[name]
            if old.shape == value.shape:
                value.copy_(old)
            elif (
                value.dim() == 2
                and old.dim() == 2
                and value.shape[0] == old.shape[0]
                and value.shape[1] > old.shape[1]
            ):
                value.zero_()
                value[:, : old.shape[1]] = old
                grown.append(name)
            else:
                raise ValueError(
                    f"parameter {name} has shape {tuple(old.shape)} in the source, {tuple(value.shape)} here"
                )
    target.load_state_dict(mine)
    return grown
