"""Commands that must not depend on the BLAS kernels OpenBLAS picks for the CPU.

OpenBLAS chooses its kernels when it loads, by CPU, and they round differently: the SkylakeX
kernels (AVX-512 Intel) fuse a dot product's multiply-adds where the Haswell ones (AMD Zen) do
not, and the Nehalem ones fuse none in a matrix-vector product either. ``OPENBLAS_CORETYPE``
forces one, so one machine can run the kernels of several: every kernel this CPU can run must
give the same commands (of the kernels of CPUs with AVX2 and FMA, which the gate pins: see
CORES). Consensus' closed loop was the one the gate saw move (2.44 m of final pose
on an episode whose first 100 steps are replayed here) until its products were written out.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

#: OpenBLAS core types and the CPU flags their kernels need
#: (Nehalem's pre-AVX2 kernels are left out: they fuse no matrix-vector product, so the estimator
#: front-end's filter rounds differently under them; the tuned consensus's episode shows it at step 14)
CORES = {"Haswell": ("avx2", "fma"), "SkylakeX": ("avx512f", "avx512bw", "avx512vl")}

#: the first 100 commands of the gate's consensus episode target reaching / map2 / high / trial 2
SCRIPT = """
import hashlib
import gymnasium as gym
import numpy as np
import controllers
import koopman_envs  # noqa: F401
from koopman_envs.episodes.single import run_episode
env = gym.make("KoopNav-TargetReaching-v0", map="map2", slip="high", goal_tolerance=0.1, max_episode_steps=100,
               start_noise=0.05)
digest = hashlib.sha256()
run_episode(env, controllers.make("consensus"), seed=2, on_step=lambda step, action, info: digest.update(action.tobytes()))
print(digest.hexdigest())
"""


def _runnable_cores() -> list[str]:
    """The core types this machine's CPU can run (none off x86-64 Linux or without OpenBLAS)."""
    blas = str(np.__config__.CONFIG["Build Dependencies"]["blas"].get("name", ""))
    cpuinfo = Path("/proc/cpuinfo")
    if platform.machine() != "x86_64" or "openblas" not in blas.lower() or not cpuinfo.is_file():
        return []
    flags = set(cpuinfo.read_text().split())
    return [core for core, needs in CORES.items() if flags.issuperset(needs)]


def test_consensus_commands_are_the_same_under_every_blas_kernel() -> None:
    cores = _runnable_cores()
    if len(cores) < 2:
        pytest.skip(f"needs OpenBLAS on an x86-64 CPU that runs two of {sorted(CORES)}")
    digests = {}
    for core in cores:
        env = {**os.environ, "OPENBLAS_CORETYPE": core, "PYTHONPATH": str(ROOT)}
        run = subprocess.run(
            [sys.executable, "-c", SCRIPT], env=env, cwd=ROOT, capture_output=True, text=True
        )
        assert run.returncode == 0, run.stderr[-3000:]
        digests[core] = run.stdout.strip()
    assert len(set(digests.values())) == 1, digests


@pytest.mark.parametrize(("given", "expected"), [(None, "Haswell"), ("Nehalem", "Nehalem")])
@pytest.mark.parametrize("script", [".ci/leaderboard.sh", "data/publish.sh"])
def test_the_gate_and_the_publications_pin_the_haswell_kernels_unless_told_otherwise(
    tmp_path: Path, script: str, given, expected
) -> None:
    """.ci/leaderboard.sh and data/publish.sh run the evaluator under OPENBLAS_CORETYPE=Haswell
    where the CPU has AVX2 and FMA (the kernels the committed baseline was recorded with; a
    publication resumed on another machine goes on with the same arithmetic); a value set wins.
    A stand-in ``python`` on PATH prints what the evaluator would see, and nothing is evaluated."""
    if "Haswell" not in _runnable_cores():
        pytest.skip("the pin applies to x86-64 CPUs with AVX2 and FMA")
    stand_in = tmp_path / "python"
    stand_in.write_text('#!/bin/sh\necho "OPENBLAS_CORETYPE=${OPENBLAS_CORETYPE:-unset}"\n')
    stand_in.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    env["PATH"] = f"{tmp_path}{os.pathsep}{env['PATH']}"
    if given is not None:
        env["OPENBLAS_CORETYPE"] = given
    # publish.sh: one of its runs (the stand-in runs nothing and writes nothing)
    arguments = [str(tmp_path / "out")] if script.startswith(".ci") else ["bench_test"]
    run = subprocess.run(
        ["bash", str(ROOT / script), *arguments],
        env=env,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().splitlines()[-1] == f"OPENBLAS_CORETYPE={expected}"
