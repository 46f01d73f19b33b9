"""NMPC solve time per control step over a closed-loop episode (Map 1, 3 robots, horizon 20).

Usage::

    python bench/nmpc_solve.py [--slip nominal] [--map map1] [--cache-timing] [--no-do-mpc]

For Koopman-NMPC and nominal NMPC it prints median / p95 / max solve time per step with the
default setup (IPOPT with the NLP compiled to C, the compiled code cached on disk by
:mod:`controllers.solver_cache`), IPOPT uncompiled (the same closed loop, bit for bit) and fatrop
compiled (faster, not always the same closed loop), plus each episode's outcome so that "same
closed-loop result" can be read off. The first run on a
machine compiles (30-60 s per problem structure, not in the per-step times); ``--cache-timing``
prints the build time to the first command in fresh processes with an empty and a filled cache. When ``do-mpc`` is installed it also solves the same nominal problem (same model, horizon,
weights, hard obstacle and inter-robot constraints, IPOPT) with do-mpc in the same run and
prints the ratio of medians.
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

import controllers
from koopman_envs.tasks.base import env_id_for_map
import koopman_envs  # noqa: F401
from controllers.calibration import calibrate_controller
from controllers.nmpc import IPOPT_OPTIONS, NMPCConfig
from controllers.unicycle import UnicycleModel
from koopman_envs.episode import run_episode



def closed_loop(env_id: str, map_name: str, slip: str, make_controller) -> dict:
    """Run one episode; returns outcome and per-step solve times [s]."""
    env = gym.make(env_id, map=map_name, slip=slip)
    ctrl = make_controller()
    calibrate_controller(ctrl, env)
    result = run_episode(env, ctrl, seed=0)
    stats = ctrl.stats()
    return {"times": np.asarray(stats.solve_times), "result": result, "failures": stats.failures}


def do_mpc_closed_loop(env_id: str, map_name: str, slip: str, horizon: int) -> dict | None:
    """The nominal problem in do-mpc: discrete RK4 unicycle model, hard constraints, IPOPT."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import do_mpc
    except ImportError:
        return None
    import casadi as ca

    if hasattr(ca.GlobalOptions, "setNumpyMode"):
        ca.GlobalOptions.setNumpyMode(-1)  # do-mpc calls numpy on casadi values; keep it quiet
    env = gym.make(env_id, map=map_name, slip=slip)
    obs, info = env.reset(seed=0)
    sc = env.unwrapped.scenario
    n = sc.n_robots
    model = do_mpc.model.Model("discrete")
    x = model.set_variable("_x", "x", (3 * n, 1))
    u = model.set_variable("_u", "u", (2 * n, 1))
    model.set_rhs("x", UnicycleModel(n, sc.dt).casadi_step()(x, u))
    model.setup()
    mpc = do_mpc.controller.MPC(model)
    mpc.settings.n_horizon = horizon
    mpc.settings.t_step = sc.dt
    mpc.settings.store_full_solution = False
    mpc.settings.nlpsol_opts = {k: v for k, v in IPOPT_OPTIONS.items() if not k.startswith("ipopt.warm")}
    cfg = NMPCConfig()
    cost = 0
    for i in range(n):
        tx, ty, tth = sc.targets[i]
        qx, qy, qc, qs = cfg.q_leader
        th = x[3 * i + 2]
        cost += qx * (x[3 * i] - tx) ** 2 + qy * (x[3 * i + 1] - ty) ** 2
        cost += qc * (ca.cos(th) - np.cos(tth)) ** 2 + qs * (ca.sin(th) - np.sin(tth)) ** 2
    r = np.tile(cfg.r_input, n)
    mpc.set_objective(lterm=cost + ca.dot(r, u * u), mterm=cost)
    mpc.set_rterm(u=np.zeros(2 * n))
    lower = np.tile([-sc.v_max, -sc.omega_max], n)
    mpc.bounds["lower", "_u", "u"] = lower
    mpc.bounds["upper", "_u", "u"] = -lower
    mpc.bounds["lower", "_x", "x"] = np.tile([sc.workspace[0], sc.workspace[2], -np.inf], n)
    mpc.bounds["upper", "_x", "x"] = np.tile([sc.workspace[1], sc.workspace[3], np.inf], n)
    for i in range(n):
        px, py = x[3 * i], x[3 * i + 1]
        for k, (ox, oy, orad) in enumerate(sc.obstacles):
            gap = (sc.robot_radius[i] + orad + cfg.obstacle_offset) ** 2 - (px - ox) ** 2 - (py - oy) ** 2
            mpc.set_nl_cons(f"obs_{i}_{k}", gap, ub=0.0)
        for j in range(i + 1, n):
            gap = (sc.robot_radius[i] + sc.robot_radius[j]) ** 2 - (px - x[3 * j]) ** 2 - (py - x[3 * j + 1]) ** 2
            mpc.set_nl_cons(f"rob_{i}_{j}", gap, ub=0.0)
    mpc.setup()
    mpc.x0 = info["poses"].reshape(-1, 1)
    mpc.set_initial_guess()

    class DoMPCPolicy:
        """do-mpc behind the runner's act(), timed per step."""

        times: list[float] = []

        def act(self, observation, step_info):
            start = time.perf_counter()
            action = np.asarray(mpc.make_step(step_info["poses"].reshape(-1, 1))).reshape(-1)
            self.times.append(time.perf_counter() - start)
            return action

    policy = DoMPCPolicy()
    result = run_episode(env, policy, seed=0)
    return {"times": np.asarray(policy.times), "result": result, "failures": 0}


def line(label: str, result: dict) -> str:
    t = 1e3 * result["times"]
    episode = result["result"]
    outcome = episode.outcome
    dist = ", ".join(f"{100 * d:.1f}" for d in episode.final_distance)
    return (f"{label:34s} median {np.median(t):6.1f} ms  p95 {np.percentile(t, 95):6.1f} ms  max {t.max():6.1f} ms  "
            f"steps {len(t):3d}  failures {result['failures']:2d}  {outcome:9s} final [{dist}] cm")  # fmt: skip


BUILD = """
import time, gymnasium as gym, koopman_envs, controllers
env = gym.make("{env_id}", map="{map}")
start = time.perf_counter()
ctrl = controllers.make("{name}")
controllers.calibration.calibrate_controller(ctrl, env)
obs, info = env.reset(seed=0); ctrl.reset(env); ctrl.act(obs, info)
print(time.perf_counter() - start)
"""


def build_seconds(env_id: str, map_name: str, name: str, cache: str) -> float:
    """Seconds from ``controllers.make`` to the first command, in a fresh process with cache ``cache``."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "KOOPNAV_CACHE": cache, "PYTHONPATH": str(root)}
    env.pop("KOOPNAV_NMPC_JIT", None)
    code = "import controllers.calibration\n" + BUILD.format(env_id=env_id, map=map_name, name=name)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    return float(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", default="map1")
    parser.add_argument("--slip", default="nominal")
    parser.add_argument("--cache-timing", action="store_true",
                        help="also time building the default solvers with an empty and a filled cache")
    parser.add_argument("--no-do-mpc", action="store_true")
    args = parser.parse_args()
    env_id = env_id_for_map(args.map)
    print(f"{env_id} {args.map} slip={args.slip}, 3 robots, horizon {NMPCConfig().horizon}, one closed-loop episode")
    if args.cache_timing:
        import shutil
        import tempfile

        for name in ("nominal-nmpc", "koopman-nmpc"):
            import time
            from pathlib import Path

            cache = tempfile.mkdtemp(prefix="koopnav-bench-cache-")
            try:
                start = time.perf_counter()
                cold = build_seconds(env_id, args.map, name, cache)  # uncompiled; compiles in the background
                while list(Path(cache, "solvers").glob("*.c")):
                    time.sleep(0.5)
                compile_s = time.perf_counter() - start
                warm = build_seconds(env_id, args.map, name, cache)
            finally:
                shutil.rmtree(cache, ignore_errors=True)
            print(f"{name:14s} build to first command: empty cache {cold:5.1f} s (uncompiled; the background "
                  f"compile took {compile_s:5.0f} s), filled cache {warm:5.1f} s")  # fmt: skip
    results = {}
    setups = [("default: IPOPT, compiled", {"jit": True}), ("IPOPT, uncompiled", {"solver": "ipopt", "jit": False}),
              ("fatrop, compiled", {"solver": "fatrop", "jit": True})]  # fmt: skip
    for name in ("nominal-nmpc", "koopman-nmpc"):
        for label, setup in setups:
            kwargs = dict(setup)
            result = closed_loop(env_id, args.map, args.slip, lambda: controllers.make(name, **kwargs))
            results[(name, label)] = result
            print(line(f"{name} / {label}", result), flush=True)
    if not args.no_do_mpc:
        reference = do_mpc_closed_loop(env_id, args.map, args.slip, NMPCConfig().horizon)
        if reference is None:
            print("do-mpc not installed: `pip install do-mpc` to compare on the same nominal problem")
        else:
            print(line("do-mpc (nominal, IPOPT)", reference))
            for label, _ in setups:
                ours = results[("nominal-nmpc", label)]["times"]
                print(f"median ratio do-mpc / nominal-nmpc {label}: {np.median(reference['times']) / np.median(ours):.1f}x")


if __name__ == "__main__":
    main()
