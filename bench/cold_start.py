"""A newcomer's first seconds: the first step of an env and the evaluator's first line, from
empty caches, beside VMAS's first step in the same run.

Usage::

    python bench/cold_start.py [--repeats 3] [--settings plain lidar movers crowd harsh]

Each measurement is a fresh process whose compiled-kernel cache (``NUMBA_CACHE_DIR``),
``KOOPNAV_CACHE`` and ``HOME`` point into a new temporary directory, as on a fresh machine (the
package install is not timed). For every setting it prints the seconds from the interpreter's
start to the end of ``import koopman_envs``, ``gym.make``, ``reset`` and the first ``step``
(target reaching, 3 robots), then the same once the cache is warm (a second process on the same
cache). ``evaluator`` is the time from launching README's first command (``python evaluate.py``)
to its first line on the terminal. When ``vmas`` is importable (VMAS 1.5.2 in a venv of its own:
``python -m venv --system-site-packages /tmp/vmas && /tmp/vmas/bin/pip install vmas==1.5.2``,
then run this script with ``/tmp/vmas/bin/python``) its ``navigation`` scenario's first step
(3 agents, CPU) is timed the same way. Medians over ``--repeats`` fresh caches. Targets (issue
47): the first step of a plain env <= 5 s, the evaluator's first line <= 2 s.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SETTINGS: dict[str, dict] = {
    "plain": {},
    "lidar": {"sensing": "lidar"},
    "movers": {"movers": {"count": 4}},
    "crowd": {"movers": {"count": 8, "behaviour": "crowd"}},
    "harsh": {"uncertainty": "harsh"},
}

_KOOPNAV = """
import time, json, sys
t0 = float(sys.argv[2])
import gymnasium as gym, koopman_envs
t_import = time.time() - t0
env = gym.make("KoopNav-TargetReaching-v0", **json.loads(sys.argv[1]))
t_make = time.time() - t0
env.reset(seed=0)
t_reset = time.time() - t0
env.step(env.action_space.sample())
print(json.dumps([t_import, t_make, t_reset, time.time() - t0]))
"""

_VMAS = """
import time, sys
t0 = float(sys.argv[1])
import torch, vmas
torch.set_num_threads(1)
t_import = time.time() - t0
env = vmas.make_env("navigation", num_envs=1, device="cpu", continuous_actions=True, n_agents=3)
t_make = time.time() - t0
env.reset()
t_reset = time.time() - t0
env.step([torch.zeros(1, 2) for _ in range(3)])
print(__import__("json").dumps([t_import, t_make, t_reset, time.time() - t0]))
"""


def _cache_env(home: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        KOOPNAV_CACHE=str(home / "koopnav-cache"), HOME=str(home), NUMBA_CACHE_DIR=str(home / "numba-cache")
    )
    return env


def _timed(code: str, args: list[str], env: dict[str, str]) -> list[float]:
    """[import, make, reset, first step] seconds from the launch of a fresh interpreter."""
    launch = time.time()
    out = subprocess.run(
        [sys.executable, "-c", code, *args, repr(launch)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def first_line(env: dict[str, str]) -> float:
    """Seconds from launching ``python evaluate.py`` to its first line on stderr or stdout."""
    with tempfile.TemporaryDirectory() as out:
        launch = time.perf_counter()
        proc = subprocess.Popen(
            [sys.executable, "-u", "evaluate.py", "--out", out],
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        assert proc.stdout is not None
        proc.stdout.readline()
        seconds = time.perf_counter() - launch
        proc.kill()
        proc.wait()
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    args = parser.parse_args()
    rows = []
    for name in args.settings:
        cold, warm = [], []
        for _ in range(args.repeats):
            with tempfile.TemporaryDirectory(prefix="koopnav-cold-") as home:
                env = _cache_env(Path(home))
                cold.append(_timed(_KOOPNAV, [json.dumps(SETTINGS[name])], env))
                warm.append(_timed(_KOOPNAV, [json.dumps(SETTINGS[name])], env))
        rows.append((f"KoopNav {name}", cold, warm))
    try:
        import vmas  # noqa: F401

        cold = []
        for _ in range(args.repeats):
            with tempfile.TemporaryDirectory(prefix="vmas-cold-") as home:
                cold.append(_timed(_VMAS, [], _cache_env(Path(home))))
        rows.append(("VMAS 1.5.2 navigation", cold, cold))
    except ImportError:
        print("(vmas not importable: no competitor row; see the module docstring)")
    print("| setup | import | make | reset | first step (cold) | first step (warm) |")
    print("|---|---|---|---|---|---|")
    for name, cold, warm in rows:
        median = [statistics.median(c[i] for c in cold) for i in range(4)]
        warm_step = statistics.median(w[3] for w in warm)
        print(
            f"| {name} | {median[0]:.2f} s | {median[1]:.2f} s | {median[2]:.2f} s | {median[3]:.2f} s | {warm_step:.2f} s |"
        )
    lines = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory(prefix="koopnav-cold-") as home:
            lines.append(first_line(_cache_env(Path(home))))
    print(
        f"\n`python evaluate.py`, first line from empty caches: {statistics.median(lines):.2f} s (median of {args.repeats})"
    )


if __name__ == "__main__":
    main()
