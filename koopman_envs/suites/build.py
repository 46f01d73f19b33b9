"""Build the suites' data from the generator, or check that the stored data is what it builds.

``python -m koopman_envs.suites.build --check`` (the default) regenerates every split of every
suite, the tier thresholds from the train splits and the reference-rollout digests, and exits 101
naming each difference from the stored files, the manifest and the declared thresholds;
``--write`` writes the split files and the manifest of a suite that has no data yet (a new
version: it refuses, exit 2, to change a published suite, whose layouts never change); it prints
the train splits' tier cuts, to be declared in the suite's definition before ``--check`` passes.
``--suite NAME`` limits it to one suite.

This module rolls episodes on the Gymnasium front for the digests, so it sits on top of the
environment package's layers (tests/test_architecture.py places it with the fronts).
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from koopman_envs.files import write_atomic
from koopman_envs.params import PARAMS
from koopman_envs.suites.families import FAMILIES, draw_layout, family_of_seed
from koopman_envs.suites.measures import measure_layout, tier_of
from koopman_envs.suites.suite import (
    SPLITS,
    SUITES,
    SuiteDefinition,
    content_hash,
    load_suite,
    read_manifest,
    read_split_document,
)

__all__ = [
    "ROLLOUT_LAYOUTS",
    "ROLLOUT_STEPS",
    "build_records",
    "PROTOCOL_ROLLOUT_LAYOUTS",
    "main",
    "protocol_rollout_digest",
    "reference_rollout_digest",
    "split_document",
]

#: test layouts per task in the reference-rollout digest, and the steps rolled on each
ROLLOUT_LAYOUTS = 4
ROLLOUT_STEPS = 40
#: layouts per task of the protocol digest (:func:`protocol_rollout_digest`): one per family, as
#: a split's layouts cycle through the families
PROTOCOL_ROLLOUT_LAYOUTS = 3
_DATA = Path(__file__).resolve().parent / "data"


def build_records(
    definition: SuiteDefinition, task: str, split: str, limit: int | None = None
) -> list[dict[str, Any]]:
    """The layout records of a split, tiers aside: the first accepted seeds of its range, each
    family up to its share (``size // 3``, the first ``size % 3`` families one more), in seed
    order; ``limit``: only the first that many (a quick check of a stored prefix).

    A seed is accepted when its draw fits (:func:`~koopman_envs.suites.families.draw_layout`)
    and every robot reaches its target (:func:`~koopman_envs.suites.measures.measure_layout`).
    """
    plan = definition.split(split)
    quota = {
        family: plan.size // len(FAMILIES) + (k < plan.size % len(FAMILIES))
        for k, family in enumerate(FAMILIES)
    }
    count = dict.fromkeys(FAMILIES, 0)
    wanted = plan.size if limit is None else min(limit, plan.size)
    records: list[dict[str, Any]] = []
    for seed in range(*plan.seeds):
        if len(records) == wanted:
            break
        family = family_of_seed(seed)
        if count[family] == quota[family]:
            continue
        drawn = draw_layout(task, seed, definition.n_obstacles, definition.n_robots)
        measures = None if drawn is None else measure_layout(drawn.obstacles, drawn.starts, drawn.targets)
        if drawn is None or measures is None:
            continue
        count[family] += 1
        records.append(
            {
                "id": f"{split}-{len(records):03d}",
                "family": family,
                "seed": seed,
                "obstacles": drawn.obstacles.tolist(),
                "starts": drawn.starts.tolist(),
                "targets": drawn.targets.tolist(),
                "measures": measures.to_dict(),
            }
        )
    if len(records) < wanted:
        raise RuntimeError(
            f"{definition.name}/{task}/{split}: only {len(records)} layouts in seeds {plan.seeds}"
        )
    return records


def train_thresholds(records: Sequence[dict[str, Any]]) -> tuple[float, float]:
    """The 1/3 and 2/3 quantiles of the records' difficulties, rounded to 4 decimals."""
    difficulty = np.array([r["measures"]["difficulty"] for r in records])
    low, high = np.quantile(difficulty, [1.0 / 3.0, 2.0 / 3.0])
    return round(float(low), 4), round(float(high), 4)


def split_document(
    definition: SuiteDefinition,
    task: str,
    split: str,
    records: list[dict[str, Any]],
    thresholds: tuple[float, float],
) -> dict[str, Any]:
    """The stored document of a split: its header and the records with their tiers."""
    plan = definition.split(split)
    layouts = [{**r, "tier": tier_of(r["measures"]["difficulty"], thresholds)} for r in records]
    return {
        "suite": definition.name,
        "version": definition.version,
        "task": task,
        "split": split,
        "seed_range": list(plan.seeds),
        "n_obstacles": definition.n_obstacles,
        "n_robots": definition.n_robots,
        "families": list(FAMILIES),
        "tier_thresholds": list(thresholds),
        "layouts": layouts,
    }


def _go_to_goal(observation: np.ndarray, target: slice, n_robots: int) -> np.ndarray:
    """A fixed rule from the observation alone: drive at the target in the body frame."""
    block = observation.reshape(n_robots, -1)[:, target].astype(np.float64)
    v = np.clip(0.5 * block[:, 0], -PARAMS.v_max, PARAMS.v_max)
    omega = np.clip(2.0 * np.arctan2(block[:, 1], block[:, 0]), -PARAMS.omega_max, PARAMS.omega_max)
    return np.column_stack([v, omega]).reshape(-1).astype(np.float32)


def _shuttle(step: int, n_robots: int) -> np.ndarray:
    """A fixed open-loop action of period ``step``: every robot drives forward, then back, 10
    periods at a time at a fifth of ``v_max`` while turning at half ``omega_max`` (the turn
    reversing with the drive). Every slip component moves the robots (side and traction slip act
    on the drive, turn slip on the turn) while they stay near their starts, clear of the
    obstacles, so an episode runs to its time limit."""
    sign = 1.0 if (step // 10) % 2 == 0 else -1.0
    action = [sign * 0.2 * PARAMS.v_max, sign * 0.5 * PARAMS.omega_max]
    return np.tile(np.asarray(action, dtype=np.float32), n_robots)


def _rollouts_digest(
    env: Any, layouts: int, action: Callable[[np.ndarray, int], np.ndarray], steps: int | None
) -> str:
    """sha256 of episode i = ``reset(seed=i, options={"layout": i})`` for i below ``layouts``,
    each stepped with ``action(observation, step)`` for ``steps`` steps (None: no limit) or
    until it ends: every pose, reward and end flag, rounded to 1e-9."""
    digest = hashlib.sha256()
    for index in range(layouts):
        observation, info = env.reset(seed=index, options={"layout": index})
        digest.update(np.round(info["poses"], 9).tobytes())
        step = 0
        while steps is None or step < steps:
            observation, reward, terminated, truncated, info = env.step(action(observation, step))
            digest.update(np.round(info["poses"], 9).tobytes())
            digest.update(np.round([reward, float(terminated), float(truncated)], 9).tobytes())
            step += 1
            if terminated or truncated:
                break
    env.close()
    return digest.hexdigest()


def reference_rollout_digest(
    name: str, task: str, layouts: int = ROLLOUT_LAYOUTS, steps: int = ROLLOUT_STEPS
) -> str:
    """sha256 of reference rollouts on the first ``layouts`` test layouts of a suite's task.

    Episode i: ``reset(seed=i, options={"layout": i})`` on the Gymnasium front with
    ``map="suite:<name>/test"`` and default keywords, then ``steps`` steps of a go-to-goal rule
    computed from the observation (no controller), until the episode ends. The digest covers
    every pose, reward and end flag, rounded to 1e-9: any change to the dynamics, the tasks or
    the layouts that changes a test episode changes it. The benchmark's own keywords (high
    slip, start noise, the time limit) are :func:`protocol_rollout_digest`'s.
    """
    from koopman_envs.fronts.gym_env import FormationEnv, TargetReachingEnv

    env_class = FormationEnv if task == "formation" else TargetReachingEnv
    env = env_class(map=f"suite:{name}/test")
    target = env.observation_layout["target"]
    n_robots = env.config.n_robots
    return _rollouts_digest(env, layouts, lambda obs, _: _go_to_goal(obs, target, n_robots), steps)


def protocol_rollout_digest(
    env_id: str, make_kwargs: Mapping[str, Any], layouts: int = PROTOCOL_ROLLOUT_LAYOUTS
) -> str:
    """sha256 of rollouts of the first ``layouts`` layouts of a suite split under a run's own
    ``gym.make`` keywords, each to the episode's end.

    Episode i: ``gym.make(env_id, **make_kwargs)`` (the keywords an evaluator's episode is made
    with: its ``map="suite:<name>/<split>"``, slip, start noise and time limit), then
    ``reset(seed=i, options={"layout": i})``, as a suite run's first episode on layout i, then a
    fixed open-loop action sequence (:func:`_shuttle`, no controller) until the episode ends (the
    time limit). The digest covers every pose, reward and end flag, rounded to 1e-9: a change to
    the slip draws, the start perturbation or the time limit that changes the benchmark's
    episodes changes it, where :func:`reference_rollout_digest` (default keywords, 40 steps)
    does not see them. It is pinned by a test, not stored in the suite's data.
    """
    import gymnasium as gym

    env = gym.make(env_id, **dict(make_kwargs))
    core: Any = env.unwrapped  # the KoopNav env under gym.make's wrappers
    n_robots = core.config.n_robots
    return _rollouts_digest(env, layouts, lambda _, step: _shuttle(step, n_robots), None)


def build_suite(definition: SuiteDefinition) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """Every split document of a suite (keyed ``task/split``) and its manifest, digests aside."""
    records = {(t, s): build_records(definition, t, s) for t in definition.tasks for s in SPLITS}
    thresholds = {t: train_thresholds(records[t, "train"]) for t in definition.tasks}
    documents = {
        f"{t}/{s}": split_document(definition, t, s, records[t, s], thresholds[t]) for t, s in records
    }
    manifest = {
        "suite": definition.name,
        "version": definition.version,
        "generator": "koopman_envs.suites.families.draw_layout",
        "tier_thresholds": {t: list(v) for t, v in thresholds.items()},
        "splits": {
            key: {
                "file": f"{key}.json.gz",
                "sha256": content_hash(doc),
                "layouts": len(doc["layouts"]),
                "seed_range": doc["seed_range"],
                "last_seed": doc["layouts"][-1]["seed"],
            }
            for key, doc in documents.items()
        },
        "reference_rollouts": {"layouts": ROLLOUT_LAYOUTS, "steps": ROLLOUT_STEPS, "sha256": {}},
    }
    return documents, manifest


def _differences(
    definition: SuiteDefinition, documents: dict[str, dict[str, Any]], manifest: dict[str, Any]
) -> list[str]:
    """What the stored data, manifest and declared thresholds of a suite do not share with a build."""
    name, found = definition.name, []
    for task, pair in definition.tier_thresholds.items():
        built = tuple(manifest["tier_thresholds"][task])
        if tuple(pair) != built:
            found.append(f"{name}: TIER_THRESHOLDS[{task!r}] = {pair} but its train split gives {built}")
    stored = read_manifest(name)
    for key, document in documents.items():
        try:
            old, path = read_split_document(name, *key.split("/"))
        except ValueError as exc:
            found.append(str(exc))
            continue
        if old != document:
            found.append(f"{path}: differs from what the generator builds (a new suite version is needed)")
        if stored["splits"].get(key) != manifest["splits"][key]:
            found.append(f"{name} manifest entry {key!r} differs from the build")
    for task in definition.tasks:
        digest = reference_rollout_digest(name, task)
        if stored["reference_rollouts"]["sha256"].get(task) != digest:
            found.append(f"{name} manifest: the reference rollouts of {task} now hash to {digest}")
    return found


def _write(
    definition: SuiteDefinition, documents: dict[str, dict[str, Any]], manifest: dict[str, Any]
) -> None:
    """Write the split files and the manifest (digests of the written data), each whole or not at
    all (:func:`koopman_envs.files.write_atomic`): the manifest is read back (the reference
    rollouts load the suite through it) and then written again with their digests, and a torn
    manifest or split would be read as a published suite."""
    root = _DATA / definition.name
    for key, document in documents.items():
        text = json.dumps(document, separators=(",", ":"), allow_nan=False)
        write_atomic(root / f"{key}.json.gz", gzip.compress(text.encode("utf-8"), compresslevel=9, mtime=0))
    write_atomic(root / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    load_suite.cache_clear()
    for task in definition.tasks:
        manifest["reference_rollouts"]["sha256"][task] = reference_rollout_digest(definition.name, task)
    write_atomic(root / "manifest.json", json.dumps(manifest, indent=1) + "\n")


#: the exit codes of ``evaluation.exit_codes`` this command uses (the environments import nothing
#: from the evaluator; tests/test_suites_build_exit.py checks that they agree): 2 bad input,
#: 101 a check that found differences
BAD_INPUT_EXIT = 2
CHECK_DIFFERS_EXIT = 101


def main(argv: Sequence[str] | None = None) -> int:
    """The command line (module docstring); returns the exit code."""
    parser = argparse.ArgumentParser(
        prog="python -m koopman_envs.suites.build", description=__doc__.split("\n\n")[0]
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true", help="compare the stored data with a build (default)")
    mode.add_argument("--write", action="store_true", help="write the data of a new suite version")
    parser.add_argument("--suite", choices=sorted(SUITES), help="only this suite")
    args = parser.parse_args(argv)
    names = [args.suite] if args.suite else sorted(SUITES)
    published = [name for name in names if (_DATA / name / "manifest.json").exists()]
    if args.write and published:  # the versioning rule: stored layouts never change under a name
        print(
            f"--write refused: {published} already have data, and a published suite never changes; "
            "add a new version to koopman_envs.suites.suite.SUITES (e.g. koopnav-bench-v2) and write that",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    failed = False
    for name in names:
        definition = SUITES[name]
        documents, manifest = build_suite(definition)
        if args.write:
            _write(definition, documents, manifest)
            print(f"{name}: wrote {len(documents)} splits; tier thresholds {manifest['tier_thresholds']}")
            continue
        found = _differences(definition, documents, manifest)
        failed = failed or bool(found)
        print("\n".join(found) if found else f"{name}: the stored data is what the generator builds")
    return CHECK_DIFFERS_EXIT if failed else 0


if __name__ == "__main__":  # pragma: no cover - the command line
    sys.exit(main())
