"""Command line of the Koopman models.

``python -m controllers.koopman fit --slip high --out model.npz``
``python -m controllers.koopman accuracy --slip high [--model model.npz] [--json] [--plot fig.png]``
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from controllers.calibration import DataSpec
from controllers.koopman.accuracy import circle_test
from controllers.koopman.dictionary import DICTIONARIES
from controllers.koopman.model import KoopmanModel
from controllers.koopman.store import calibrated_model, fit_on_plant
from koopman_envs import make_plant
from koopman_envs.checks import choice_message
from koopman_envs.files import write_atomic
from koopman_envs.params import PARAMS, SLIP_SETTINGS, slip_lambdas


def _slip_arg(text: str) -> str | list[float]:
    """A setting name, or comma-separated per-robot lambdas ("0,0.1,0.2")."""
    if text in SLIP_SETTINGS:
        return text
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            choice_message("slip", text, SLIP_SETTINGS, " nor comma-separated numbers")
        ) from None


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--slip", type=_slip_arg, default="nominal", help="nominal, low, high or 0,0.1,0.2")
    parser.add_argument("--n-robots", type=int, default=PARAMS.n_robots)
    parser.add_argument("--dictionary", choices=sorted(DICTIONARIES), default="minimal")
    parser.add_argument("--seed", type=int, default=0, help="seed of the calibration data (inputs and slip)")
    parser.add_argument("--trajectories", type=int, default=PARAMS.koopman_trajectories)
    parser.add_argument("--steps", type=int, default=PARAMS.koopman_steps)


def _plant_and_spec(args: argparse.Namespace):
    """The calibration plant of the setting (its budget = the data set) and the data set."""
    spec = DataSpec(args.trajectories, args.steps, seed=args.seed)
    plant = make_plant(
        "KoopNav-TargetReaching-v0",
        slip=args.slip,
        n_robots=args.n_robots,
        budget=spec.transitions,
        seed=args.seed,
    )
    return plant, spec


def cmd_fit(args: argparse.Namespace) -> int:
    plant, spec = _plant_and_spec(args)
    start = time.perf_counter()
    model = fit_on_plant(plant, spec, args.dictionary, ridge=args.ridge)
    model.save(args.out)
    print(
        f"fitted {args.dictionary} model: {args.n_robots} robots, slip {args.slip}, "
        f"{spec.transitions:,} transitions, residual {model.metadata['fit_residual']:.3e}, "
        f"rank {model.metadata['rank']}, {time.perf_counter() - start:.2f} s -> {args.out}"
    )
    return 0


def cmd_accuracy(args: argparse.Namespace) -> int:
    # the test compares the model with the simulator it was calibrated on: it knows lambda, the model does not
    lambdas = slip_lambdas(args.slip, args.n_robots)
    if args.model:
        model = KoopmanModel.load(args.model, n_robots=args.n_robots)
    else:
        plant, spec = _plant_and_spec(args)
        model = calibrated_model(plant, args.seed, args.dictionary, spec)[0]
    report, prediction, truths = circle_test(model, lambdas, args.repetitions, args.truth_seed)
    if args.json:
        print(json.dumps({"dictionary": model.dictionary.name, **report.to_dict()}, indent=1))
    else:
        print(
            f"circle test: {model.dictionary.name} model, lambda = {lambdas.tolist()}, "
            f"{report.repetitions} slip realizations (seed {report.seed})"
        )
        print(
            f"{'robot':>5} {'RMSE % (seed)':>14} {'RMSE % mean+-SD':>17} {'Hausdorff [m]':>14} "
            f"{'floor [m]':>10} {'RMSE % vs mean truth':>21}"
        )
        for i in range(model.n_robots):
            print(
                f"{i + 1:>5} {report.rmse_fixed_seed[i]:>14.2f} "
                f"{report.rmse_mean[i]:>9.2f} +- {report.rmse_sd[i]:<5.2f} {report.hausdorff_mean[i]:>14.3f} "
                f"{report.hausdorff_floor[i]:>10.3f} {report.rmse_vs_mean_truth[i]:>21.2f}"
            )
    if args.plot:
        _plot(args.plot, prediction, truths, report, model.dictionary.name)
        print(f"saved {args.plot}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _plot(path: str, prediction: np.ndarray, truths: np.ndarray, report, name: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 6), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")
    for i in range(prediction.shape[1]):
        color = colors[i % len(colors)]
        for r in range(truths.shape[1]):
            ax.plot(truths[:, r, i, 0], truths[:, r, i, 1], color=color, alpha=0.12, lw=0.8)
        ax.plot(
            truths[:, 0, i, 0], truths[:, 0, i, 1], color=color, lw=1.5, label=f"robot {i + 1} true (seed)"
        )
        ax.plot(
            prediction[:, i, 0],
            prediction[:, i, 1],
            "--",
            color="k",
            lw=1.2,
            label="Koopman prediction" if i == 0 else None,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    rmse = ", ".join(f"{v:.2f}" for v in report.rmse_fixed_seed)
    ax.set_title(f"{name} model, lambda={report.lambdas}: RMSE [{rmse}] %", fontsize=9)
    fig.tight_layout()
    write_atomic(path, fig.savefig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m controllers.koopman", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    fit = sub.add_parser(
        "fit", help="collect data on the calibration plant of a slip setting and fit a model"
    )
    _common(fit)
    fit.add_argument("--ridge", type=float, default=0.0, help="Tikhonov term (0 = least squares)")
    fit.add_argument("--out", required=True, help="output .npz")
    fit.set_defaults(func=cmd_fit)
    acc = sub.add_parser("accuracy", help="the paper's circle test")
    _common(acc)
    acc.add_argument("--model", help="a model file (default: shipped or cached model of --slip)")
    acc.add_argument("--repetitions", type=int, default=30)
    acc.add_argument("--truth-seed", type=int, default=0, help="seed of the slip realizations")
    acc.add_argument("--json", action="store_true", help="print JSON instead of a table")
    acc.add_argument("--plot", help="save predicted vs true trajectories to this image")
    acc.set_defaults(func=cmd_accuracy)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:  # bad settings or model files: one clear line, no traceback
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
