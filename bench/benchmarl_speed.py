"""BenchMARL's MAPPO on a KoopNav task: frames per second with the batched vector env against the
PettingZoo env batched by a ``SerialEnv``, same settings, same run.

Usage::

    python bench/benchmarl_speed.py [--envs 600] [--frames 60000] [--iters 2]

Target reaching, 3 robots, random layouts, nominal slip, 200-step episodes; MAPPO with
BenchMARL's default networks, ``--iters`` iterations of ``--frames`` frames collected from
``--envs`` environments, 2 PPO epochs of minibatches of 6,000 (the training share small, so the
figure is mostly collection); torch on one thread. ``vectorized=True`` is
:class:`baselines.marl.torchrl_env.KoopNavMultiAgentEnv` (the task's default), ``False`` the
``PettingZooWrapper`` path.
"""

from __future__ import annotations

import argparse
import tempfile
import time


def frames_per_second(vectorized: bool, envs: int, frames: int, iters: int) -> float:
    import torch
    from benchmarl.experiment import ExperimentConfig

    from baselines import KoopNavTask
    from baselines.marl.benchmarl_train import experiment

    torch.set_num_threads(1)
    task = KoopNavTask.TARGET_REACHING.get_task()
    task.config.update({"n_robots": 3, "slip": "nominal", "max_cycles": 200, "vectorized": vectorized})
    config = ExperimentConfig.get_from_yaml()
    config.max_n_iters, config.max_n_frames, config.render, config.loggers = iters, None, False, []
    config.on_policy_collected_frames_per_batch, config.on_policy_n_envs_per_worker = frames, envs
    config.on_policy_n_minibatch_iters, config.on_policy_minibatch_size = 2, min(6000, frames)
    config.evaluation, config.checkpoint_interval = False, 0
    with tempfile.TemporaryDirectory() as folder:
        config.save_folder = folder
        run = experiment(task, config, "mappo")
        start = time.perf_counter()
        run.run()
        return iters * frames / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", type=int, default=600)
    parser.add_argument("--frames", type=int, default=60000)
    parser.add_argument("--iters", type=int, default=2)
    args = parser.parse_args()
    fast = frames_per_second(True, args.envs, args.frames, args.iters)
    slow = frames_per_second(False, args.envs, args.frames, args.iters)
    print(f"MAPPO, {args.envs} envs, {args.iters} x {args.frames} frames:")
    print(f"  vector env (KoopNavMultiAgentEnv)   {fast:10,.0f} frames/s")
    print(f"  PettingZoo env in a SerialEnv       {slow:10,.0f} frames/s  ({fast / slow:.1f}x slower)")


if __name__ == "__main__":
    main()
