"""Where ``python -m evaluation.experiments.seeds --ship`` ships a chosen seed, and when it refuses.

A learned controller loads its shipped policies from ``baselines/policies/<folder>/<task>/``
(its class's ``shipped``). Shipping a training seed chosen on validation
(:func:`evaluation.experiments.seeds.ship`) keeps the policies shipped before: the first time, the
folder is copied to ``<folder>_v0`` (:func:`keep_former`, never written again), which the registered
``<policy>-v0`` plays (``rl-ppo-set-v0``, as the tuned presets keep their defaults as
``<name>-v0``). :func:`check_shippable` refuses, by name and before anything moves, while a seed
the driver plans for the policy and task is unfinished (the chosen seed is chosen among every
planned one), or when no ``<policy>-v0`` plays ``<folder>_v0``.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from koopman_envs import TASKS
from koopman_envs.files import write_atomic

__all__ = ["V0_FOLDER_SUFFIX", "check_shippable", "keep_former", "shipped_folder"]

#: the suffix of the folder that keeps a controller's policies shipped before its chosen seeds
#: (``baselines/policies/set`` -> ``set_v0``), played by the registered ``<policy>-v0``
V0_FOLDER_SUFFIX = "_v0"


def shipped_folder(policy: str, policies: str | os.PathLike[str] | None = None) -> Path:
    """The folder ``policy``'s controller loads its shipped policies from (``<folder>/<task>/``):
    ``baselines/policies/<shipped>``, or ``<policies>/<shipped>`` under another ``policies``
    directory. Found without building the controller (which refuses a folder without policies).

    Raises
    ------
    ValueError
        ``policy`` is not a controller with a shipped folder of its own (``shipped``): ``rl-ppo``
        loads ``baselines/policies`` itself, which holds the other controllers' folders too.
    """
    from controllers.registry import controller_class

    cls: Any = controller_class(policy)
    shipped = getattr(cls, "shipped", None)
    if not shipped or not callable(getattr(cls, "weight_files", None)):
        raise ValueError(
            f"{policy} has no shipped folder of its own (its class {getattr(cls, '__name__', cls)!r} "
            f"declares shipped={shipped!r}): --ship ships a controller whose policies live in "
            "baselines/policies/<folder>/, with a <policy>-v0 controller to keep the former ones"
        )
    if policies is None:
        # the parent of a task folder its default options load (weight_files: no controller built)
        return Path(cls.weight_files({}, next(iter(TASKS)))[0]).parent.parent
    return Path(policies) / shipped


def check_shippable(
    policy: str,
    task: str,
    seeds: str | os.PathLike[str],
    plan: Sequence[tuple[str, str, int]],
    finished: str = "finished.json",
) -> None:
    """Refuse (``ValueError``, naming what is wrong) to ship a seed of ``policy`` on ``task``
    unless every seed ``plan`` (``(policy, task, seed)`` triples: the driver's) names for them is
    finished (``seed<k>/<finished>`` under ``seeds``, the task's seed folders), so that the chosen
    seed is chosen among all of them, and unless a registered ``<policy>-v0`` plays the folder
    the former policies move to (``<folder>_v0``)."""
    from controllers.registry import controller_class

    planned = sorted(k for p, t, k in plan if (p, t) == (policy, task))
    missing = [k for k in planned if not Path(seeds, f"seed{k}", finished).is_file()]
    if missing:
        raise ValueError(
            f"{policy} {task}: planned seeds {missing} of {planned} are not finished (no "
            f"seed<k>/{finished} under {seeds}); the shipped seed is chosen among every planned one: "
            "ship when they have finished"
        )
    folder = shipped_folder(policy)
    variant, former = policy + "-v0", folder.name + V0_FOLDER_SUFFIX
    try:
        keeper: Any = controller_class(variant)
    except ValueError:
        keeper = None
    if getattr(keeper, "shipped", None) != former:
        raise ValueError(
            f"{policy}: no registered controller {variant!r} plays {former}/ (its shipped folder: "
            f"{getattr(keeper, 'shipped', None)!r}): shipping a seed would leave {policy}'s former "
            f"policies reachable by no name; register {variant} with shipped = {former!r} (as "
            "rl-ppo-set-v0, baselines/sb3/policy.py) first"
        )


def keep_former(shipped: Path) -> Path:
    """Copy ``shipped`` (a controller's shipped folder) to ``<shipped>_v0`` unless that exists
    (once: the policies shipped before the seeds, every task's, kept for ``<policy>-v0``; an
    existing ``_v0`` is never written to); ``shipped``.

    A copy, not a move: a task not shipped yet keeps playing its former policy under the
    controller's own name (shipping one task must not leave the other without a policy)."""
    former = shipped.with_name(shipped.name + V0_FOLDER_SUFFIX)
    if not former.exists() and shipped.exists():
        scratch = former.with_name(former.name + ".partial")
        shutil.rmtree(scratch, ignore_errors=True)
        for path in sorted(shipped.rglob("*")):
            if path.is_file():
                write_atomic(scratch / path.relative_to(shipped), path.read_bytes())
        scratch.rename(former)  # whole or absent: a copy cut short is never read as the former policies
    return shipped
