"""Episodes per second of the crowd protocol's learned-policy rows, batched against one by one.

Usage::

    python bench/batched_evaluation.py [--behaviours constant waypoints crowd] [--counts 0 4 8 16]
                                       [--controllers rl-ppo ...] [--episodes 20] [--batch 64]
    python bench/batched_evaluation.py --actors [--rows 3 48]

Plans the crowd protocol (``python evaluate.py --crowd BEHAVIOUR``: both tasks on their paper maps
and random layouts, perturbed starts, nominal slip) for the learned policies at each mover count
and runs it twice in this process on one worker: with ``--batch`` (a cell's episodes together in
the vector env, :func:`evaluation.execution.worker.run_batch`) and with ``batch=1`` (every episode alone, the
path every controller took before), alternating which goes first. Prints the wall time and
episodes per second of each, the ratio, and whether every record is the same (all fields but the
timing ones). A short warm-up run first compiles the kernels and loads the policies, so that
neither side pays for them.

``--actors`` times instead one forward pass of each shipped policy's actor, compiled
(:mod:`baselines.sb3.actor`) and torch's (the actor's mean as ``predict`` computes it, one torch
thread), on ``--rows`` random observations, in alternation (median of 200 calls each).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from evaluation import RunSpec, evaluate
from evaluation.experiments.protocols import CROWD_COUNTS, crowd_protocol
from evaluation.run.configs import parse_controller

POLICIES = ["rl-ppo", "rl-ppo-set", "rl-ppo-set-movers", "rl-ppo-set-realistic"]
TIMING = {"solve_ms", "solve_ms_median", "solve_ms_p95", "wall_seconds"}


def untimed(record: dict) -> dict:
    """A record without its timing fields (decision and wall times)."""
    extra = {k: v for k, v in (record.get("controller_extra") or {}).items() if "_ms" not in k}
    return {k: v for k, v in record.items() if k not in TIMING} | {"controller_extra": extra or None}


def protocol(behaviour: str, count: int, controllers: list[str], episodes: int) -> RunSpec:
    """The crowd protocol's run of ``controllers`` at ``count`` movers of ``behaviour``."""
    spec = crowd_protocol(behaviour)
    env_kwargs = {**spec.env_kwargs, "movers": {**spec.env_kwargs["movers"], "count": count}}
    return dataclasses.replace(
        spec,
        env_kwargs=env_kwargs,
        episodes=episodes,
        controllers=[parse_controller(name) for name in controllers],
    )


def timed(spec: RunSpec, batch: int) -> tuple[float, list[dict]]:
    start = time.perf_counter()
    records = evaluate(spec, workers=1, batch=batch).records
    return time.perf_counter() - start, records


def actor_speed(rows: list[int]) -> None:
    """Print the compiled and the torch forward pass of every shipped policy's actor."""
    import numpy as np
    import torch

    from baselines import SHIPPED, compile_actor, load_policy

    torch.set_num_threads(1)
    print("| policy | rows | compiled [us] | torch [us] | torch / compiled |")
    print("|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    for directory in sorted(p.parent for p in SHIPPED.rglob("policy.zip")):
        model, _, _ = load_policy(directory)
        actor, policy = compile_actor(model), model.policy
        assert actor is not None
        for n in rows:
            obs = rng.normal(size=(n, policy.observation_space.shape[0])).astype(np.float32)
            for pool in actor.sets:  # mask entries 0 or 1, as the set features give them
                masks = np.arange(pool.columns.start + pool.slot_size, pool.columns.stop, pool.slot_size + 1)
                obs[:, masks] = rng.random((n, len(masks))) < 0.6

            def torch_forward(obs=obs, policy=policy) -> None:
                with torch.inference_mode():
                    features = policy.extract_features(torch.as_tensor(obs), policy.pi_features_extractor)
                    policy.action_net(policy.mlp_extractor.forward_actor(features)).numpy()

            times: dict[str, list[float]] = {"compiled": [], "torch": []}
            for _ in range(200):
                for name, call in (
                    ("compiled", lambda obs=obs, actor=actor: actor(obs)),
                    ("torch", torch_forward),
                ):
                    start = time.perf_counter()
                    call()
                    times[name].append(time.perf_counter() - start)
            compiled, torch_time = (1e6 * float(np.median(times[k])) for k in ("compiled", "torch"))
            policy_name = directory.relative_to(SHIPPED)
            print(
                f"| {policy_name} | {n} | {compiled:.0f} | {torch_time:.0f} | {torch_time / compiled:.2f}x |"
            )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--behaviours", nargs="+", default=["constant", "waypoints", "crowd"])
    parser.add_argument("--counts", nargs="+", type=int, default=list(CROWD_COUNTS))
    parser.add_argument("--controllers", nargs="+", default=POLICIES)
    parser.add_argument("--episodes", type=int, default=20, help="trials per cell (the protocol's 20)")
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--actors", action="store_true", help="time the actors' forward pass instead")
    parser.add_argument("--rows", nargs="+", type=int, default=[3, 48], help="--actors: rows per call")
    args = parser.parse_args(argv)
    if args.actors:
        actor_speed(args.rows)
        return 0
    timed(protocol(args.behaviours[0], max(args.counts), args.controllers, 2), args.batch)  # warm-up
    print(
        "| movers | episodes | one by one [s] | batched [s] | episodes/s one by one | batched | ratio | same records |"
    )
    print("|---|---|---|---|---|---|---|---|")
    seconds_alone = seconds_together = 0.0
    episodes = 0
    for index, (behaviour, count) in enumerate((b, c) for b in args.behaviours for c in args.counts):
        spec = protocol(behaviour, count, args.controllers, args.episodes)
        order = (1, args.batch) if index % 2 == 0 else (args.batch, 1)
        runs = {batch: timed(spec, batch) for batch in order}
        (alone, alone_records), (together, batched_records) = runs[1], runs[args.batch]
        same = [untimed(r) for r in alone_records] == [untimed(r) for r in batched_records]
        n = len(alone_records)
        seconds_alone, seconds_together, episodes = (
            seconds_alone + alone,
            seconds_together + together,
            episodes + n,
        )
        print(
            f"| {count} {behaviour} | {n} | {alone:.1f} | {together:.1f} | {n / alone:.1f} | "
            f"{n / together:.1f} | {alone / together:.2f}x | {'yes' if same else 'NO'} |"
        )
    print(
        f"| all | {episodes} | {seconds_alone:.1f} | {seconds_together:.1f} | {episodes / seconds_alone:.1f} | "
        f"{episodes / seconds_together:.1f} | {seconds_alone / seconds_together:.2f}x | |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
