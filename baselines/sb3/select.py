"""Pick the policy of a training run by its success on held-out random maps.

``python -m baselines.sb3.select --run runs/formation --out baselines/policies/formation``

PPO's deterministic policy swings from one checkpoint to the next, so the last one is not
necessarily the best. This command scores the final policy and every checkpoint of a run
(``baselines.sb3.train`` writes them) on a fixed validation set: ``--episodes`` random layouts of
the run's training distribution (same generator settings, random slip) with seeds far from any
training seed, never the paper maps that the evaluator reports on. The best (ties: the later
one) is written to ``--out`` with the run's metadata plus the whole validation table.
"""

from __future__ import annotations

import argparse
import functools
import json
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

from baselines.curriculum import VALIDATION
from baselines.features.set_features import SetFeatureConfig
from baselines.sb3.policy import PolicyFiles, load_policy, success_rate
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from koopman_envs import TASKS
from koopman_envs.checks import parse_json
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic

__all__ = [
    "EVAL_MAPS",
    "VALIDATION_SEED",
    "candidates",
    "evaluate_policy_on_maps",
    "main",
    "set_validation_success",
    "validation_success",
]

#: first seed of the validation layouts (training seeds run from ``--seed`` upward, by ones)
VALIDATION_SEED = 1_000_000


#: the paper maps an mlp policy's checkpoints are scored on, by env id
EVAL_MAPS = {spec.env_id: spec.paper_maps for spec in TASKS.values()}


def evaluate_policy_on_maps(
    model, norm, env_id: str, layout: str, features: str, episodes_per_map: int = 2, slip: str = "nominal"
) -> float:
    """Success rate of the deterministic policy on the task's paper maps (seeds 0, 1, ...)."""
    rates = [
        success_rate(model, norm, layout, features, env_id, episodes_per_map, 0, map=map_name, slip=slip)
        for map_name in EVAL_MAPS[env_id]
    ]
    return float(np.mean(rates))


def set_validation_success(
    model: Any, norm: dict, metadata: dict, episodes_per_cell: int, seed: int = VALIDATION_SEED
) -> float:
    """Mean success of a set policy over its task's validation cells (:data:`baselines.curriculum.VALIDATION`).

    Cell c plays ``episodes_per_cell`` layouts seeded from ``seed + 1000 c``: held out, since
    training seeds stay below 100_000.
    """
    config = SetFeatureConfig(**metadata["set_config"])
    rates = [
        success_rate(
            model,
            norm,
            "robot",
            "set",
            metadata["env_id"],
            episodes_per_cell,
            seed + 1000 * cell,
            set_config=config,
            n_robots=n,
            map="random",
            slip=slip,
            random_map=random_map,
            max_episode_steps=400,
            uncertainty=metadata.get("uncertainty", "nominal"),
            **({"movers": metadata["movers"]} if metadata.get("movers") else {}),
        )
        for cell, (n, random_map, slip) in enumerate(VALIDATION[metadata["task"]])
    ]
    return float(np.mean(rates))


def validation_success(directory: Path, metadata: dict, episodes: int, seed: int = VALIDATION_SEED) -> float:
    """Success rate of the policy in ``directory`` on ``episodes`` held-out random layouts.

    A set policy plays its task's validation cells (``episodes`` split evenly between them).
    """
    model, norm, _ = load_policy(directory, metadata["task"], metadata["algo"])
    if "set_config" in metadata:
        cells = len(VALIDATION[metadata["task"]])
        return set_validation_success(model, norm, metadata, max(1, episodes // cells), seed)
    return success_rate(
        model,
        norm,
        metadata["layout"],
        metadata.get("features", "bearing"),
        metadata["env_id"],
        episodes,
        seed,
        map="random",
        slip="random",
        random_map=metadata.get("random_map") or None,
    )


def read_metadata(run: Path) -> dict[str, Any]:
    """A training run's ``metadata.json``, read bounded (a regular file of at most
    :data:`koopman_envs.files.MAX_TEXT_BYTES`) and parsed with its nesting bounded; anything but a
    JSON object is refused by name."""
    path = PolicyFiles(run).metadata
    metadata = parse_json(read_text(path, MAX_TEXT_BYTES, what="training metadata"), str(path))
    if not isinstance(metadata, dict):
        raise ValueError(f"{path}: a training run's metadata is a JSON object, not {type(metadata).__name__}")
    return metadata


def candidates(run: Path) -> list[tuple[int, Path]]:
    """(timesteps, directory) of every checkpoint of a run and of its final policy, in order."""
    found = []
    for path in (run / "checkpoints").glob("step_*"):
        if PolicyFiles(path).model.exists():
            found.append((int(path.name.split("_")[1]), path))
    final = read_metadata(run)
    found.append((int(final.get("trained_timesteps", final["timesteps"])), run))
    return sorted(found, key=lambda item: item[0])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m baselines.sb3.select", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--run", required=True, help="output directory of python -m baselines.sb3.train")
    parser.add_argument("--out", required=True, help="where to write the selected policy")
    parser.add_argument("--episodes", type=int, default=100, help="validation layouts")
    args = parser.parse_args(argv)
    run = Path(args.run)
    if not PolicyFiles(run).metadata.exists():
        print(f"error: {run} holds no finished training run (metadata.json missing)", file=sys.stderr)
        return BAD_INPUT_EXIT
    metadata = read_metadata(run)
    table = []
    for steps, directory in candidates(run):
        rate = validation_success(directory, metadata, args.episodes)
        table.append({"timesteps": steps, "validation_success_rate": rate})
        print(f"{steps:>12,d} steps  validation success {rate:.2f}", flush=True)
    best = max(range(len(table)), key=lambda i: (table[i]["validation_success_rate"], i))
    chosen = candidates(run)[best][1]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    source, target = PolicyFiles(chosen), PolicyFiles(out)
    # each file whole or not at all: a later evaluation loads the selected policy
    write_atomic(target.model, functools.partial(shutil.copyfile, source.model))
    write_atomic(target.norm, functools.partial(shutil.copyfile, source.norm))
    selected = dict(metadata)
    selected["selection"] = {
        "command": "python -m baselines.sb3.select " + " ".join(argv if argv is not None else sys.argv[1:]),
        "rule": (
            f"best mean success on {args.episodes} held-out random layouts split over the validation "
            f"cells of baselines.curriculum.VALIDATION (seeds {VALIDATION_SEED}+); ties go to the later policy"
            if "set_config" in metadata
            else f"best success on {args.episodes} held-out random layouts (seeds {VALIDATION_SEED}+, "
            "random slip, the training generator settings); ties go to the later policy"
        ),
        "selected_timesteps": table[best]["timesteps"],
        "validation": table,
    }
    write_atomic(target.metadata, json.dumps(selected, indent=1) + "\n")
    print(
        f"selected the policy after {table[best]['timesteps']:,} steps "
        f"(validation success {table[best]['validation_success_rate']:.2f}); wrote {out}"
    )
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
