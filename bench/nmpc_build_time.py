"""The build time to the first command of bench/nmpc_solve.py's ``--cache-timing``: compiled IPOPT
with an empty and a filled solver cache, and the real-time iteration (nothing compiled, nothing
cached), each in a fresh process. A module of bench/nmpc_solve.py, not a script.
"""

from __future__ import annotations

import time
from typing import Any

BUILD = """
import time, gymnasium as gym, koopman_envs, controllers
env = gym.make("{env_id}", map="{map}")
start = time.perf_counter()
ctrl = controllers.make("{name}", **{options!r})
controllers.calibration.calibrate_controller(ctrl, env)
obs, info = env.reset(seed=0); ctrl.reset(env); ctrl.act(obs, info)
print(time.perf_counter() - start)
"""


def build_seconds(
    env_id: str, map_name: str, name: str, cache: str, options: dict[str, Any], jit: bool
) -> float:
    """Seconds from ``controllers.make(name, **options)`` to the first command, in a fresh process
    with cache ``cache`` and compiled ``nlpsol`` solvers on (``jit``) or off."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from controllers.mpc.config import JIT_ENV

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "KOOPNAV_CACHE": cache, "PYTHONPATH": str(root), JIT_ENV: "1" if jit else "0"}
    code = "import controllers.calibration\n" + BUILD.format(
        env_id=env_id, map=map_name, name=name, options=options
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout
    return float(out.strip().splitlines()[-1])


def cache_timing(env_id: str, map_name: str) -> None:
    """Print the build time to the first command of compiled IPOPT (empty and filled cache) and of the RTI."""
    import shutil
    import tempfile
    from pathlib import Path

    for name in ("nominal-nmpc", "koopman-nmpc"):
        cache = tempfile.mkdtemp(prefix="koopnav-bench-cache-")
        try:
            start = time.perf_counter()
            # empty cache: the solver runs uncompiled while it compiles in the background
            cold = build_seconds(env_id, map_name, name, cache, {"solver": "ipopt"}, jit=True)
            while list(Path(cache, "solvers").glob("*.c")):
                time.sleep(0.5)
            compile_s = time.perf_counter() - start
            warm = build_seconds(env_id, map_name, name, cache, {"solver": "ipopt"}, jit=True)
            rti = build_seconds(env_id, map_name, name, cache, {"solver": "rti"}, jit=False)
        finally:
            shutil.rmtree(cache, ignore_errors=True)
        print(
            f"{name:14s} build to first command: IPOPT compiled, empty cache {cold:5.1f} s (uncompiled; the "
            f"background compile took {compile_s:5.0f} s), filled cache {warm:5.1f} s; RTI {rti:5.1f} s"
        )
