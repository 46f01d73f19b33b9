"""The training driver, data/training/run.sh, as the tests run it, and the tiny training runs they
share (tests/test_ippo_resume.py, tests/test_training_resume.py, tests/test_learned_seeds.py,
tests/test_physics_policy.py)."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Callable
from pathlib import Path

from baselines.resume import RESUME_FILE

ROOT = Path(__file__).resolve().parents[2]

#: a tiny set-policy PPO run: 2 envs x 3 robots x 64 steps = 384 robot-steps per rollout
TINY_SB3 = ["--n-envs", "2", "--n-steps", "64", "--batch-size", "128", "--set-width", "8", "--net", "16,16"]
#: the batches of a tiny IPPO run: 2 envs, iterations of 200 frames, one epoch of 2 minibatches each
TINY_IPPO_BATCHES = ["--envs", "2", "--frames-per-batch", "200", "--minibatch-size", "100", "--epochs", "1"]


def one_seed_driver(
    policy: str, task: str, training_root: Path, timeout: float, **variables: str
) -> Callable[[], subprocess.CompletedProcess[str]]:
    """A call of ``bash data/training/run.sh POLICY`` on one seed of one task (SEEDS=1,
    TASKS=``task``), each checkpoint validated on one layout (VALIDATION_LAYOUTS=1), with this
    checkout on PYTHONPATH, the seed folders below ``training_root`` and the driver's other
    ``variables`` (TIMESTEPS, SB3_ARGS, ...); its environment is this process's as it is now, when
    the call is made. Each call runs the driver once, to its end (or ``timeout`` seconds), and
    returns what it printed and its code."""
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "TRAINING_ROOT": str(training_root),
        "SEEDS": "1",
        "TASKS": task,
        "VALIDATION_LAYOUTS": "1",
        **variables,
    }

    def driver() -> subprocess.CompletedProcess[str]:
        command = ["bash", str(ROOT / "data/training/run.sh"), policy]
        return subprocess.run(command, env=env, capture_output=True, text=True, timeout=timeout, check=False)

    return driver


def restart_after_a_torn_checkpoint(
    seed_dir: Path, driver: Callable[[], subprocess.CompletedProcess[str]]
) -> subprocess.CompletedProcess[str]:
    """A finished seed made unfinished again with a torn resume checkpoint, and the driver run on
    it: the checkpoint refused by name, removed, and the seed trained from the start."""
    (seed_dir / "finished.json").unlink()
    (seed_dir / RESUME_FILE).write_bytes(b"KOOPNAV-RESUME 1\n{}\n")  # torn
    restarted = driver()
    assert restarted.returncode == 0, restarted.stderr
    assert "has no readable header" in restarted.stderr
    assert "removed; training again" in restarted.stdout
    return restarted
