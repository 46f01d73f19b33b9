"""Koopman learning speed: data generation and fit of 1M transitions, peak memory.

Usage::

    python bench/koopman_fit.py [--slip high] [--budget 1000000] [--pykoopman-python /path/to/venv/bin/python]

Prints the wall time of generating the calibration data set (by default the paper's 1000
trajectories x 1000 periods, drawn on the calibration plant as every controller's calibration
draws it: :func:`controllers.calibration.collect_data`), of
the bilinear fit (SPEC eq. 9) on them, the peak memory of both (traced numpy allocations and
the process high-water mark), and the circle-test RMSE of the fitted model. With
``--pykoopman-python`` it also runs pykoopman's (linear) EDMDc on the same data in that
interpreter (a virtual environment with ``pykoopman`` installed) and prints both fit times and
both RMSEs side by side.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from typing import Any

import numpy as np

from controllers.calibration import collect_data, data_spec_for
from controllers.koopman.accuracy import CIRCLE_OMEGA, CIRCLE_STEPS, CIRCLE_V, circle_starts, circle_test
from controllers.koopman.dictionary import get_dictionary
from controllers.koopman.fit import fit_bilinear
from controllers.koopman.model import KoopmanModel
from koopman_envs import make_plant, rollout
from koopman_envs.params import PARAMS, slip_lambdas

PYKOOPMAN_SCRIPT = r"""
import json, sys, time
import numpy as np
import pykoopman as pk
from pykoopman.regression import EDMDc
from pykoopman.observables import CustomObservables

data = np.load(sys.argv[1])
X, U, Y = data["X"], data["U"], data["Y"]          # (S, 3N) poses, (S, 2N), next poses
n = X.shape[1] // 3
idx = [[3 * i, 3 * i + 1] for i in range(n)]
def lift(x):                                        # the same 1 + 4N observables
    cols = [np.ones((x.shape[0], 1))]
    for i in range(n):
        th = x[:, 3 * i + 2]
        cols += [x[:, 3 * i : 3 * i + 2], np.cos(th)[:, None], np.sin(th)[:, None]]
    return np.hstack(cols)
Z, Zn = lift(X), lift(Y)
times = []
for _ in range(int(sys.argv[2])):                  # best of N, as for KoopNav
    start = time.perf_counter()
    model = pk.Koopman(observables=pk.observables.Identity(), regressor=EDMDc())
    model.fit(Z, y=Zn, u=U)
    times.append(time.perf_counter() - start)
fit_seconds = min(times)
A = model.A if hasattr(model, "A") else model.ur @ model._regressor_A  # noqa
B = model.B
# circle test with re-lifting through the position / heading rows
c = data["circle_commands"]; truth = data["circle_truth"]
state = truth[0].copy()
pred = [state.copy()]
for t in range(c.shape[0]):
    z = lift(state.reshape(1, -1))
    zn = (z @ np.asarray(A).T + c[t].reshape(1, -1) @ np.asarray(B).T)[0]
    new = []
    for i in range(n):
        base = 1 + 4 * i
        new += [zn[base], zn[base + 1], np.arctan2(zn[base + 3], zn[base + 2])]
    state = np.array(new)
    pred.append(state.copy())
pred = np.array(pred).reshape(len(pred), n, 3)
truth = truth.reshape(len(truth), n, 3)
d = truth[1:, :, :2] - pred[1:, :, :2]
rmse = (100 * np.sqrt((d * d).sum(-1).mean(0))).tolist()
print(json.dumps({"fit_seconds": fit_seconds, "rmse": rmse, "version": pk.__version__}))
"""


def time_runs(plant, spec, dic, repeats: int) -> tuple[list[float], list[float]]:
    """The data generation's and the fit's times of ``repeats`` runs, without tracemalloc (it hooks
    every allocation and inflates the times); the best is printed, as timeit does, because shared
    machines only ever add time."""
    gen_times, fit_times = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        data = collect_data(plant, spec)
        gen_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        fit_bilinear(data.states, data.commands, dic)
        fit_times.append(time.perf_counter() - start)
    return gen_times, fit_times


def measure_memory(plant, spec, dic) -> tuple[Any, Any, int, int]:
    """A separate pass that measures the peak traced memory: the data, the fit and their peaks."""
    tracemalloc.start()
    data = collect_data(plant, spec)
    gen_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.reset_peak()
    fit = fit_bilinear(data.states, data.commands, dic)
    fit_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return data, fit, gen_peak, fit_peak


def print_fit(args, spec, dic, times: tuple[list[float], list[float]], peaks: tuple[int, int], rmse) -> None:
    """The data set, the times and memory of generating it and fitting it, and the circle test."""
    gen_times, fit_times = times
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB -> MiB on Linux
    print(
        f"{spec.transitions:,} transitions ({spec.trajectories} x {spec.steps}), slip {args.slip}, "
        f"{args.dictionary} dictionary ({dic.size(3)} observables), {os.cpu_count()} cores"
    )
    print(
        f"data generation   {min(gen_times):6.3f} s   peak traced memory {peaks[0] / 2**20:7.1f} MiB  "
        f"(best of {args.repeats}: " + ", ".join(f"{t:.3f}" for t in gen_times) + ")"
    )
    print(
        f"bilinear fit      {min(fit_times):6.3f} s   peak traced memory {peaks[1] / 2**20:7.1f} MiB  "
        f"(best of {args.repeats}: " + ", ".join(f"{t:.3f}" for t in fit_times) + ") "
        "(data included)"
    )
    print(f"process peak RSS  {rss:7.1f} MiB")
    print("circle RMSE %     " + ", ".join(f"{v:.2f}" for v in rmse))


def run_pykoopman(python: str, data, lambdas, repeats: int) -> subprocess.CompletedProcess:
    """pykoopman's EDMDc fitted on the same data in ``python`` (a venv with pykoopman), with its
    circle test: the finished process, its last line the JSON figures."""
    start_poses = circle_starts(3)
    commands = np.tile([CIRCLE_V, CIRCLE_OMEGA], (CIRCLE_STEPS, 3, 1))
    truth = rollout(start_poses[None], commands[:, None], lambdas, np.random.default_rng(0))[:, 0]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "data.npz")
        states = data.states
        np.savez(
            path,
            X=states[:-1].reshape(-1, 9),
            Y=states[1:].reshape(-1, 9),
            U=data.commands.reshape(-1, 6),
            circle_commands=commands.reshape(CIRCLE_STEPS, 6),
            circle_truth=truth.reshape(-1, 9),
        )
        script = os.path.join(tmp, "run_pykoopman.py")
        with open(script, "w") as fh:
            fh.write(PYKOOPMAN_SCRIPT)
        return subprocess.run([python, script, path, str(repeats)], capture_output=True, text=True)


def print_comparison(other: dict, fit_seconds: float, rmse) -> None:
    print(f"\n{'':24s} {'fit [s]':>8s}  circle RMSE % (robots 1..3)")
    print(f"{'KoopNav bilinear EDMDc':24s} {fit_seconds:8.3f}  " + ", ".join(f"{v:.2f}" for v in rmse))
    print(
        f"{'pykoopman ' + other['version'] + ' EDMDc':24s} {other['fit_seconds']:8.3f}  "
        + ", ".join(f"{v:.2f}" for v in other["rmse"])
    )
    print(f"fit-time ratio pykoopman / KoopNav: {other['fit_seconds'] / fit_seconds:.2f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--slip", default="nominal")
    parser.add_argument("--dictionary", default="minimal")
    parser.add_argument("--pykoopman-python", help="python of a venv with pykoopman installed")
    parser.add_argument("--repeats", type=int, default=3, help="timing runs (the best is printed)")
    parser.add_argument(
        "--budget",
        type=int,
        default=PARAMS.calibration_budget,
        help="team-transitions of the data set (default: the paper's 1,000,000)",
    )
    args = parser.parse_args()
    lambdas = slip_lambdas(args.slip, 3)
    plant = make_plant("KoopNav-TargetReaching-v0", slip=args.slip, budget=10**12, seed=0)
    spec = data_spec_for(args.budget)
    dic = get_dictionary(args.dictionary)
    collect_data(plant, data_spec_for(100))  # warm-up (imports, compiled kernels)
    times = time_runs(plant, spec, dic, args.repeats)
    data, fit, gen_peak, fit_peak = measure_memory(plant, spec, dic)
    model = KoopmanModel(fit.A, fit.N, fit.B, fit.C, dic, 3, plant.dt)
    report, _, _ = circle_test(model, lambdas, repetitions=30)
    print_fit(args, spec, dic, times, (gen_peak, fit_peak), report.rmse_fixed_seed)
    if args.pykoopman_python:
        out = run_pykoopman(args.pykoopman_python, data, lambdas, args.repeats)
        if out.returncode != 0:
            print("pykoopman run failed:\n" + out.stderr[-2000:])
            return
        other = json.loads(out.stdout.strip().splitlines()[-1])
        print_comparison(other, min(times[1]), report.rmse_fixed_seed)


if __name__ == "__main__":
    sys.exit(main())
