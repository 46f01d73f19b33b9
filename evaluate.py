"""KoopNav evaluator: run every controller on every cell, report success rates and final distances.

``python evaluate.py`` runs the quick default leaderboard (both tasks, their maps, three slip
settings, every registered controller, a few episodes each), prints the tables and writes
Markdown, JSON, CSV and figures to ``results/``. ``python evaluate.py --paper`` runs the paper's
protocol (SPEC section 5: 10 trials per cell) and prints tables 1-5. From Python::

    from evaluate import evaluate
    results = evaluate("KoopNav-Formation-v0", ["koopman-nmpc", "consensus"], maps=["map3"],
                       slips=["nominal", "high"], episodes=5, seed=0)
    print(results.to_markdown())

Episodes run in worker processes; each episode's seed depends only on the base seed and its
index in the cell, so results do not depend on the worker count. Each finished episode is
appended to ``OUT/episodes.jsonl`` at once; ``--resume`` continues an interrupted run. An
episode that raises is recorded with its error, the others go on, and the exit code is the
number of failed episodes (capped at 100); a failed ``--check`` exits with 101.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import multiprocessing as mp
import os
import sys
import time
import traceback
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

import controllers
import koopman_envs
from koopman_envs.params import PARAMS, SLIP_SETTINGS, slip_lambdas
from koopman_envs.sim.maps import BUILTIN_MAPS, load_map

__all__ = ["Cell", "EpisodeSpec", "Results", "evaluate", "main", "paper_protocol", "quick_protocol"]

SCHEMA_VERSION = 1
TASK_MAPS = {
    "KoopNav-TargetReaching-v0": ("map1", "map2"),
    "KoopNav-Formation-v0": ("map3", "map4"),
}
TASK_LABEL = {"KoopNav-TargetReaching-v0": "target reaching", "KoopNav-Formation-v0": "formation"}
FAILED_CHECK_EXIT = 101


# --------------------------------------------------------------------------- the plan
@dataclass(frozen=True)
class EpisodeSpec:
    """One episode to run: a cell plus the trial index (which fixes the seed)."""

    env_id: str
    controller: str
    map: str
    slip: str  # a setting name, or comma-separated lambdas
    trial: int
    seed: int
    tolerance: float
    max_episode_steps: int

    @property
    def key(self) -> str:
        """Unique id of the episode within a run."""
        return f"{self.env_id}|{self.controller}|{self.map}|{self.slip}|{self.trial}"

    @property
    def cell(self) -> tuple[str, str, str, str]:
        """(env, controller, map, slip)."""
        return (self.env_id, self.controller, self.map, self.slip)


def _slip_value(slip: str) -> str | list[float]:
    return slip if slip in SLIP_SETTINGS else [float(v) for v in slip.split(",")]


def plan_episodes(
    env_ids: Sequence[str],
    controller_names: Sequence[str],
    maps: dict[str, Sequence[str]],
    slips: Sequence[str],
    episodes: int,
    seed: int,
    tolerance: float,
    max_episode_steps: int,
) -> list[EpisodeSpec]:
    """Every episode of a run, in a fixed order. Trial i of every cell uses seed ``seed + i``,
    so all controllers face the same slip draws on the same map (paired comparison)."""
    plan = []
    for env_id in env_ids:
        for name in controller_names:
            for map_name in maps[env_id]:
                for slip in slips:
                    for trial in range(episodes):
                        plan.append(EpisodeSpec(env_id, name, map_name, slip, trial, seed + trial,
                                                tolerance, max_episode_steps))  # fmt: skip
    return plan


def validate_arguments(
    env_ids: Sequence[str],
    controller_names: Sequence[str],
    maps: dict[str, Sequence[str]],
    slips: Sequence[str],
    episodes: int,
    workers: int,
) -> None:
    """Raise ``ValueError`` naming the bad value and what exists."""
    for env_id in env_ids:
        if env_id not in koopman_envs.ENV_IDS:
            raise ValueError(f"env {env_id!r} is not one of {list(koopman_envs.ENV_IDS)}")
        for map_name in maps[env_id]:
            if map_name != "random":
                try:
                    load_map(map_name)
                except ValueError as exc:
                    raise ValueError(f"map {map_name!r}: {exc}") from None
    available = controllers.available()
    for name in controller_names:
        if name not in available:
            raise ValueError(f"controller {name!r} is not one of {available}")
    for slip in slips:
        try:
            slip_lambdas(_slip_value(slip), PARAMS.n_robots)
        except ValueError as exc:
            raise ValueError(f"slip {slip!r}: {exc}") from None
    if not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes={episodes!r} must be an integer >= 1")
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r} must be an integer >= 1")


def usable_controllers(verbose: bool = True) -> list[str]:
    """Registered controllers that can be built here; the others are named on stderr.

    An optional controller (``rl-ppo`` without the ``[rl]`` extra or without trained policies)
    is skipped by the default run instead of failing every episode.
    """
    usable = []
    for name in controllers.available():
        try:
            controllers.make(name)
        except (ImportError, ValueError) as exc:
            if verbose:
                print(f"note: controller {name!r} skipped ({exc})", file=sys.stderr)
            continue
        usable.append(name)
    return usable


# --------------------------------------------------------------------------- one episode
_CONTROLLER_CACHE: dict[tuple, Any] = {}


def _controller_for(spec: EpisodeSpec):
    """Controllers are reused within a worker (their NLPs are built once per structure)."""
    options: dict[str, Any] = {}
    if controllers.accepts_option(spec.controller, "slip"):
        # the deployment setting selects the data a learned model comes from, never lambda itself
        options["slip"] = _slip_value(spec.slip)
    key = (spec.controller, json.dumps(options, sort_keys=True))
    if key not in _CONTROLLER_CACHE:
        _CONTROLLER_CACHE[key] = controllers.make(spec.controller, **options)
    return _CONTROLLER_CACHE[key]


def run_episode(spec: EpisodeSpec) -> dict[str, Any]:
    """Run one episode and return its record (never raises: errors are recorded)."""
    import gymnasium as gym

    start = time.perf_counter()
    record: dict[str, Any] = {"key": spec.key, **asdict(spec)}
    try:
        env = gym.make(
            spec.env_id,
            map=spec.map,
            slip=_slip_value(spec.slip),
            goal_tolerance=spec.tolerance,
            max_episode_steps=spec.max_episode_steps,
        )
        ctrl = _controller_for(spec)
        obs, info = env.reset(seed=spec.seed)
        scenario = env.unwrapped.scenario
        ctrl.reset(scenario, seed=spec.seed)
        poses = [info["poses"].copy()]
        effort = np.zeros(scenario.n_robots)
        formation_sq, steps = [], 0
        first_within: int | None = None
        while True:
            action = np.asarray(ctrl.act(obs, info), dtype=np.float64).reshape(-1, 2)
            obs, _, terminated, truncated, info = env.step(action.reshape(-1))
            steps += 1
            applied = np.clip(action, [-scenario.v_max, -scenario.omega_max], [scenario.v_max, scenario.omega_max])
            effort += (applied**2).sum(axis=1) * scenario.dt
            poses.append(info["poses"].copy())
            if "formation_error" in info:
                formation_sq.append(info["formation_error"][1:] ** 2)
            if first_within is None and np.all(info["distances"] <= spec.tolerance):
                first_within = steps
            if terminated or truncated:
                break
        trajectory = np.asarray(poses)
        path = np.linalg.norm(np.diff(trajectory[:, :, :2], axis=0), axis=2).sum(axis=0)
        stats = ctrl.stats().summary()
        record.update(
            status="ok",
            success=bool(info["is_success"]),
            collision=info["collision_kind"] if info["collision"] else None,
            truncated=bool(truncated and not terminated),
            steps=steps,
            time_to_goal=(first_within * scenario.dt) if info["is_success"] else None,
            final_poses=info["poses"].tolist(),
            targets=info["targets"].tolist(),
            final_distance=info["distances"].tolist(),
            path_length=path.tolist(),
            control_effort=effort.tolist(),
            formation_rms=float(np.sqrt(np.mean(formation_sq))) if formation_sq else None,
            solve_ms_median=stats["solve_ms_median"],
            solve_ms_p95=stats["solve_ms_p95"],
            solver_failures=stats["failures"],
            trajectory=np.round(trajectory[:, :, :2], 4).tolist() if spec.trial == 0 else None,
            obstacles=scenario.obstacles.tolist() if spec.trial == 0 else None,
        )
    except Exception as exc:  # noqa: BLE001 - one bad episode must not lose the others
        record.update(status="error", error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
    record["wall_seconds"] = time.perf_counter() - start
    return record


# --------------------------------------------------------------------------- aggregation
def _nan_reduce(reduce, values: list[float]) -> float:
    """``reduce`` over the finite values, NaN when there are none (without numpy's warning)."""
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return float(reduce(finite)) if finite else float("nan")


def _mean_sd(values: list[float]) -> tuple[float, float]:
    if not values:
        return float("nan"), float("nan")
    arr = np.asarray(values, dtype=float)
    return float(arr.mean()), float(arr.std(ddof=1)) if len(arr) > 1 else 0.0


@dataclass
class Cell:
    """Aggregated metrics of one (env, controller, map, slip) cell."""

    env_id: str
    controller: str
    map: str
    slip: str
    episodes: int
    successes: int
    collision_free: int
    errors: int
    final_distance_cm: list[tuple[float, float]]  # per robot (mean, SD) over successful runs
    time_to_goal_s: float
    path_length_m: float
    control_effort: float
    formation_rms_cm: float
    solve_ms_median: float
    solve_ms_p95: float
    solver_failures: int

    @property
    def success_rate(self) -> float:
        """Fraction of episodes that ended in success."""
        valid = self.episodes - self.errors
        return self.successes / valid if valid else float("nan")

    @property
    def collision_free_rate(self) -> float:
        """The paper's SR: fraction of episodes without collision."""
        valid = self.episodes - self.errors
        return self.collision_free / valid if valid else float("nan")


def aggregate(records: Iterable[dict[str, Any]]) -> list[Cell]:
    """Cells from episode records, in the order they first appear."""
    by_cell: dict[tuple, list[dict]] = {}
    for rec in records:
        by_cell.setdefault((rec["env_id"], rec["controller"], rec["map"], rec["slip"]), []).append(rec)
    cells = []
    for (env_id, name, map_name, slip), recs in by_cell.items():
        ok = [r for r in recs if r["status"] == "ok"]
        won = [r for r in ok if r["success"]]
        n_robots = len(ok[0]["final_distance"]) if ok else 0
        distances = [_mean_sd([100 * r["final_distance"][i] for r in won]) for i in range(n_robots)]
        cells.append(
            Cell(
                env_id=env_id,
                controller=name,
                map=map_name,
                slip=slip,
                episodes=len(recs),
                successes=len(won),
                collision_free=sum(1 for r in ok if r["collision"] is None),
                errors=len(recs) - len(ok),
                final_distance_cm=distances,
                time_to_goal_s=_mean_sd([r["time_to_goal"] for r in won])[0],
                path_length_m=_mean_sd([float(np.mean(r["path_length"])) for r in ok])[0],
                control_effort=_mean_sd([float(np.mean(r["control_effort"])) for r in ok])[0],
                formation_rms_cm=_mean_sd([100 * r["formation_rms"] for r in ok if r["formation_rms"] is not None])[0],
                solve_ms_median=_nan_reduce(np.median, [r["solve_ms_median"] for r in ok]),
                solve_ms_p95=_nan_reduce(np.max, [r["solve_ms_p95"] for r in ok]),
                solver_failures=sum(r["solver_failures"] for r in ok),
            )
        )
    return cells


def _fmt_distance(mean: float, sd: float, successes: int) -> str:
    if successes == 0 or math.isnan(mean):
        return "-"
    return f"{mean:.1f}" if successes == 1 else f"{mean:.1f}+-{sd:.1f}"


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


@dataclass
class Results:
    """Everything a run produced: episode records, cells, and the run configuration."""

    records: list[dict[str, Any]]
    config: dict[str, Any]
    cells: list[Cell] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.cells:
            self.cells = aggregate(self.records)

    @property
    def failed_episodes(self) -> list[dict[str, Any]]:
        """Records of episodes that raised."""
        return [r for r in self.records if r["status"] != "ok"]

    def cell(self, env_id: str, controller: str, map_name: str, slip: str) -> Cell:
        """One cell by its coordinates."""
        for c in self.cells:
            if (c.env_id, c.controller, c.map, c.slip) == (env_id, controller, map_name, slip):
                return c
        raise KeyError((env_id, controller, map_name, slip))

    # ------------------------------------------------------------------ tables
    def paper_table(self, env_id: str, controller: str) -> str:
        """The paper-style table (Map, Slip, SR, Robot 1..N final distance in cm)."""
        cells = [c for c in self.cells if c.env_id == env_id and c.controller == controller]
        if not cells:
            return ""
        n = max(len(c.final_distance_cm) for c in cells)
        head = "| Map | Slip | Success | SR (collision-free) | " + " | ".join(f"Robot {i + 1} [cm]" for i in range(n)) + " |"
        lines = [f"**{controller}, {TASK_LABEL.get(env_id, env_id)}**", "", head,
                 "|" + "---|" * (4 + n)]  # fmt: skip
        for c in cells:
            valid = c.episodes - c.errors
            dists = " | ".join(_fmt_distance(m, s, c.successes) for m, s in c.final_distance_cm)
            lines.append(f"| {c.map} | {c.slip} | {c.successes}/{valid} | {c.collision_free}/{valid} | {dists} |")
        return "\n".join(lines)

    def leaderboard(self) -> list[dict[str, Any]]:
        """One row per (task, controller), ranked by success rate, then mean final distance."""
        rows = []
        for env_id in dict.fromkeys(c.env_id for c in self.cells):
            for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id):
                cells = [c for c in self.cells if c.env_id == env_id and c.controller == name]
                episodes = sum(c.episodes - c.errors for c in cells)
                successes = sum(c.successes for c in cells)
                free = sum(c.collision_free for c in cells)
                dists = [m for c in cells for m, _ in c.final_distance_cm if not math.isnan(m)]
                rows.append({
                    "env_id": env_id,
                    "controller": name,
                    "episodes": episodes,
                    "success_rate": successes / episodes if episodes else float("nan"),
                    "collision_free_rate": free / episodes if episodes else float("nan"),
                    "final_distance_cm": float(np.mean(dists)) if dists else float("nan"),
                    "solve_ms_median": _nan_reduce(np.median, [c.solve_ms_median for c in cells]),
                    "solver_failures": sum(c.solver_failures for c in cells),
                    "errors": sum(c.errors for c in cells),
                })  # fmt: skip
        def rank_key(row):
            dist = row["final_distance_cm"]
            return (row["env_id"], -row["success_rate"], dist if not math.isnan(dist) else 1e9)

        return sorted(rows, key=rank_key)

    def to_markdown(self) -> str:
        """Leaderboard plus every paper-style table, as Markdown."""
        out = ["## Leaderboard", ""]
        out.append("| Rank | Task | Controller | Episodes | Success | Collision-free | Final dist. [cm] | Solve median [ms] | Solver failures |")
        out.append("|---|---|---|---|---|---|---|---|---|")
        rank, last_env = 0, None
        for row in self.leaderboard():
            rank = 1 if row["env_id"] != last_env else rank + 1
            last_env = row["env_id"]
            dist = "-" if math.isnan(row["final_distance_cm"]) else f"{row['final_distance_cm']:.1f}"
            solve = "-" if math.isnan(row["solve_ms_median"]) else f"{row['solve_ms_median']:.1f}"
            out.append(
                f"| {rank} | {TASK_LABEL.get(row['env_id'], row['env_id'])} | {row['controller']} | {row['episodes']} | "
                f"{100 * row['success_rate']:.0f}% | {100 * row['collision_free_rate']:.0f}% | {dist} | {solve} | "
                f"{row['solver_failures']} |"
            )
        out += ["", "## Per-controller tables", "",
                "Success: every robot settled within tolerance without collision. SR: the paper's success rate "
                "(no collision). Distances: mean+-SD over successful runs.", ""]  # fmt: skip
        for env_id in dict.fromkeys(c.env_id for c in self.cells):
            for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id):
                out += [self.paper_table(env_id, name), ""]
        if self.failed_episodes:
            out += ["## Episodes that raised", ""]
            out += [f"- `{r['key']}`: {r['error']}" for r in self.failed_episodes]
        return "\n".join(out)

    def to_json(self) -> str:
        """Versioned JSON document (see ``docs/results.schema.json``)."""
        doc = {
            "schema_version": SCHEMA_VERSION,
            "package_version": koopman_envs.__version__,
            "config": self.config,
            "leaderboard": self.leaderboard(),
            "cells": [
                {**asdict(c), "success_rate": c.success_rate, "collision_free_rate": c.collision_free_rate}
                for c in self.cells
            ],
            "episodes": [
                {k: v for k, v in r.items() if k not in ("trajectory", "obstacles", "traceback")} for r in self.records
            ],
        }
        return json.dumps(_json_safe(doc), indent=1)

    def to_csv(self) -> str:
        """One row per episode."""
        buffer = io.StringIO()
        fields = ["key", "env_id", "controller", "map", "slip", "trial", "seed", "status", "success", "collision",
                  "steps", "time_to_goal", "final_distance", "path_length", "control_effort", "formation_rms",
                  "solve_ms_median", "solve_ms_p95", "solver_failures", "error"]  # fmt: skip
        writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        for rec in self.records:
            row = dict(rec)
            for key in ("final_distance", "path_length", "control_effort"):
                if isinstance(row.get(key), list):
                    row[key] = ";".join(f"{v:.5f}" for v in row[key])
            writer.writerow(row)
        return buffer.getvalue()

    # ------------------------------------------------------------------ figures
    def save_figures(self, out_dir: Path) -> list[Path]:
        """One sample trajectory per cell and success rate by slip level per controller."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Circle

        out_dir.mkdir(parents=True, exist_ok=True)
        written = []
        samples = [r for r in self.records if r["status"] == "ok" and r.get("trajectory")]
        for rec in samples:
            fig = Figure(figsize=(4, 4), dpi=100)
            FigureCanvasAgg(fig)
            ax = fig.add_subplot(1, 1, 1)
            for x, y, rad in rec["obstacles"]:
                ax.add_patch(Circle((x, y), rad, color="0.5"))
            traj = np.asarray(rec["trajectory"])
            for i in range(traj.shape[1]):
                line = ax.plot(traj[:, i, 0], traj[:, i, 1], lw=1.5)[0]
                ax.plot(*rec["targets"][i][:2], "x", color=line.get_color(), ms=8)
                ax.plot(*traj[0, i], "s", color=line.get_color(), ms=4)
            ax.set_aspect("equal")
            ax.grid(alpha=0.3)
            outcome = "success" if rec["success"] else (rec["collision"] or "time limit")
            ax.set_title(f"{rec['controller']} | {rec['map']} | {rec['slip']} | {outcome}", fontsize=8)
            path = out_dir / f"traj_{rec['controller']}_{rec['map']}_{rec['slip'].replace(',', '-')}.png"
            fig.tight_layout()
            fig.savefig(path)
            written.append(path)
        for env_id in dict.fromkeys(c.env_id for c in self.cells):
            fig = Figure(figsize=(5, 3.5), dpi=100)
            FigureCanvasAgg(fig)
            ax = fig.add_subplot(1, 1, 1)
            slips = list(dict.fromkeys(c.slip for c in self.cells if c.env_id == env_id))
            for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id):
                rates = []
                for slip in slips:
                    cells = [c for c in self.cells if (c.env_id, c.controller, c.slip) == (env_id, name, slip)]
                    total = sum(c.episodes - c.errors for c in cells)
                    rates.append(100 * sum(c.successes for c in cells) / total if total else float("nan"))
                ax.plot(slips, rates, marker="o", label=name)
            ax.set_ylim(-5, 105)
            ax.set_ylabel("success rate [%]")
            ax.set_xlabel("slip setting")
            ax.set_title(TASK_LABEL.get(env_id, env_id), fontsize=9)
            ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
            fig.tight_layout()
            path = out_dir / f"success_by_slip_{env_id}.png"
            fig.savefig(path)
            written.append(path)
        return written

    def write(self, out_dir: str | os.PathLike) -> dict[str, Path]:
        """Write results.md, results.json, results.csv and figures/ under ``out_dir``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"markdown": out / "results.md", "json": out / "results.json", "csv": out / "results.csv"}
        paths["markdown"].write_text(self.to_markdown() + "\n", encoding="utf-8")
        paths["json"].write_text(self.to_json() + "\n", encoding="utf-8")
        paths["csv"].write_text(self.to_csv(), encoding="utf-8")
        self.save_figures(out / "figures")
        return paths


# --------------------------------------------------------------------------- running
class _Progress:
    """A one-line progress bar on stderr (no dependency)."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.done, self.enabled = total, 0, enabled
        self.start = time.perf_counter()

    def update(self, record: dict[str, Any]) -> None:
        self.done += 1
        if not self.enabled:
            return
        width = 30
        filled = int(width * self.done / max(self.total, 1))
        elapsed = time.perf_counter() - self.start
        mark = "ok" if record["status"] == "ok" and record.get("success") else record.get("collision") or (
            "error" if record["status"] != "ok" else "fail")  # fmt: skip
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} "
                         f"{elapsed:5.0f}s  {record['controller']:<14s} {record['map']:<6s} {record['slip']:<8s} {mark:<10s}")  # fmt: skip
        if self.done == self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _config_signature(config: dict[str, Any]) -> dict[str, Any]:
    """The parts of a configuration that must match for a resume."""
    keys = ("env_ids", "controllers", "maps", "slips", "episodes", "seed", "tolerance", "max_episode_steps")
    return {k: config[k] for k in keys}


def _read_log(log: Path, config: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Finished episodes of a previous run with the same configuration (key -> record)."""
    lines = log.read_text(encoding="utf-8").splitlines()
    if not lines:
        return {}
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError:
        raise ValueError(f"{log} is not a KoopNav episode log (bad first line); nothing was overwritten") from None
    if header.get("kind") != "koopnav-run" or header.get("config") != _config_signature(config):
        raise ValueError(
            f"{log} belongs to a run with another configuration ({header.get('config')}); "
            "use another --out directory or the same options to resume; nothing was overwritten"
        )
    done = {}
    for line in lines[1:]:
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by the interruption: that episode simply runs again
        done[rec["key"]] = rec
    return done


def _run_ray(todo: list[EpisodeSpec], workers: int):
    """Episodes as Ray tasks: on a local Ray instance, or on the cluster at ``RAY_ADDRESS``."""
    try:
        import ray
    except ImportError:
        raise ValueError("--backend ray needs Ray: pip install -e '.[ray]'") from None
    started_here = not ray.is_initialized()
    if started_here:
        address = os.environ.get("RAY_ADDRESS")
        ray.init(address=address, num_cpus=None if address else workers, include_dashboard=False,
                 log_to_driver=False)  # fmt: skip
    try:
        remote = ray.remote(num_cpus=1)(run_episode)
        pending = [remote.remote(spec) for spec in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started_here:
            ray.shutdown()


def evaluate(
    env_ids: str | Sequence[str] = tuple(TASK_MAPS),
    controller_names: Sequence[str] | None = None,
    maps: Sequence[str] | dict[str, Sequence[str]] | None = None,
    slips: Sequence[str] = SLIP_SETTINGS,
    episodes: int = 2,
    seed: int = 0,
    workers: int | None = None,
    backend: str = "process",
    out: str | os.PathLike | None = None,
    resume: bool = False,
    tolerance: float = PARAMS.goal_tolerance,
    max_episode_steps: int = PARAMS.max_episode_steps,
    progress: bool = False,
) -> Results:
    """Run every controller on every (env, map, slip) cell.

    Parameters
    ----------
    env_ids : str or sequence of str
        Environment ids.
    controller_names : sequence of str, optional
        Registered controller names (default: all of :func:`controllers.available`).
    maps : sequence or dict, optional
        Maps for every env, or a dict env id -> maps (default: each task's paper maps).
    slips : sequence of str
        Setting names or comma-separated per-robot lambdas.
    episodes : int
        Trials per cell (trial i uses seed ``seed + i``).
    seed : int
        Base seed.
    workers : int, optional
        Worker processes (default: all cores).
    backend : str
        ``"process"`` or ``"ray"``.
    out : path, optional
        Directory for the JSONL episode log (and, from the CLI, the reports).
    resume : bool
        Continue the run logged in ``out``.
    tolerance : float
        Goal tolerance [m].
    max_episode_steps : int
        Time limit [periods].
    progress : bool
        Show a progress bar on stderr.

    Returns
    -------
    Results
    """
    env_ids = [env_ids] if isinstance(env_ids, str) else list(env_ids)
    names = list(controller_names) if controller_names else usable_controllers(progress)
    if maps is None:
        map_table = {e: list(TASK_MAPS.get(e, BUILTIN_MAPS)) for e in env_ids}
    elif isinstance(maps, dict):
        map_table = {e: list(maps[e]) for e in env_ids}
    else:
        map_table = {e: list(maps) for e in env_ids}
    slips = [s if isinstance(s, str) else ",".join(str(v) for v in s) for s in slips]
    workers = (os.cpu_count() or 1) if workers is None else workers
    if backend not in ("process", "ray"):
        raise ValueError(f"backend={backend!r} is not one of ['process', 'ray']")
    validate_arguments(env_ids, names, map_table, slips, episodes, workers)
    config = {
        "env_ids": env_ids, "controllers": names, "maps": map_table, "slips": slips, "episodes": episodes,
        "seed": seed, "tolerance": tolerance, "max_episode_steps": max_episode_steps, "workers": workers,
        "backend": backend,
    }  # fmt: skip
    plan = plan_episodes(env_ids, names, map_table, slips, episodes, seed, tolerance, max_episode_steps)
    done: dict[str, dict[str, Any]] = {}
    log_file = None
    if out is not None:
        out_dir = Path(out)
        out_dir.mkdir(parents=True, exist_ok=True)
        log = out_dir / "episodes.jsonl"
        if log.exists() and log.stat().st_size > 0:
            if not resume:
                raise ValueError(f"{log} exists: pass --resume to continue that run, or choose another --out")
            done = _read_log(log, config)
            log_file = open(log, "a", encoding="utf-8")  # noqa: SIM115 - closed below
        else:
            log_file = open(log, "w", encoding="utf-8")  # noqa: SIM115
            log_file.write(json.dumps({"kind": "koopnav-run", "config": _config_signature(config)}) + "\n")
            log_file.flush()
    # longest episodes first (the learned-model NMPC, then the other optimizers) so that no worker
    # idles at the end of the run; records are put back in plan order below
    cost = {"koopman-nmpc": 0, "nominal-nmpc": 1}
    todo = sorted((spec for spec in plan if spec.key not in done), key=lambda spec: cost.get(spec.controller, 2))
    bar = _Progress(len(todo), progress)
    records = dict(done)
    try:
        if backend == "ray":
            stream = _run_ray(todo, workers)
        elif workers == 1 or len(todo) <= 1:
            stream = (run_episode(spec) for spec in todo)
        else:
            pool = mp.get_context("spawn").Pool(min(workers, len(todo)), maxtasksperchild=None)
            stream = pool.imap_unordered(run_episode, todo, chunksize=1)
        for record in stream:
            records[record["key"]] = record
            if log_file is not None:
                log_file.write(json.dumps(_json_safe(record)) + "\n")
                log_file.flush()
            bar.update(record)
        if backend == "process" and workers > 1 and len(todo) > 1:
            pool.close()
            pool.join()
    finally:
        if log_file is not None:
            log_file.close()
    ordered = [records[spec.key] for spec in plan]
    return Results(ordered, config)


# --------------------------------------------------------------------------- protocols
def quick_protocol() -> dict[str, Any]:
    """The default leaderboard: both tasks, their maps, three slips, 2 episodes per cell."""
    return {"env_ids": list(TASK_MAPS), "maps": {e: list(m) for e, m in TASK_MAPS.items()}, "episodes": 2}


def paper_protocol() -> dict[str, Any]:
    """SPEC section 5: maps 1-2 (target reaching), 3-4 (formation), 3 slips, 10 trials per cell,
    Koopman-NMPC, nominal NMPC and (formation) consensus with collision avoidance."""
    return {
        "env_ids": list(TASK_MAPS),
        "maps": {e: list(m) for e, m in TASK_MAPS.items()},
        "episodes": 10,
        "controllers": ["koopman-nmpc", "nominal-nmpc", "consensus"],
    }


# --------------------------------------------------------------------------- checks
def check_thresholds(results: Results, path: str | os.PathLike) -> list[str]:
    """Cells below the committed thresholds (empty list = pass).

    The TOML file holds ``[[cell]]`` tables with any of ``env``, ``controller``, ``map``,
    ``slip`` (omitted = any) and limits ``min_success_rate`` (0-1) and/or
    ``max_final_distance_cm`` (mean over robots and successful runs).
    """
    import tomllib

    try:
        with open(path, "rb") as fh:
            spec = tomllib.load(fh)
    except OSError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} cannot be read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} is not valid TOML: {exc}") from None
    rules = spec.get("cell")
    if not isinstance(rules, list) or not rules:
        raise ValueError(f"thresholds file {os.fspath(path)!r} has no [[cell]] tables")
    problems = []
    for rule in rules:
        unknown = set(rule) - {"env", "controller", "map", "slip", "min_success_rate", "max_final_distance_cm"}
        if unknown:
            raise ValueError(f"thresholds file {os.fspath(path)!r}: unknown keys {sorted(unknown)}")
        matched = [
            c for c in results.cells
            if all(rule.get(k) in (None, v) for k, v in (("env", c.env_id), ("controller", c.controller),
                                                          ("map", c.map), ("slip", c.slip)))
        ]  # fmt: skip
        if not matched:
            problems.append(f"no evaluated cell matches {rule}")
        for c in matched:
            name = f"{c.env_id} / {c.controller} / {c.map} / {c.slip}"
            if "min_success_rate" in rule and not c.success_rate >= rule["min_success_rate"]:
                problems.append(f"{name}: success rate {c.success_rate:.2f} < {rule['min_success_rate']:.2f}")
            if "max_final_distance_cm" in rule:
                dists = [m for m, _ in c.final_distance_cm if not math.isnan(m)]
                mean = float(np.mean(dists)) if dists else float("inf")
                if not mean <= rule["max_final_distance_cm"]:
                    problems.append(f"{name}: final distance {mean:.1f} cm > {rule['max_final_distance_cm']:.1f} cm")
    return problems


# --------------------------------------------------------------------------- CLI
def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="evaluate.py", description=__doc__.split("\n")[0])
    parser.add_argument("--env", nargs="+", help=f"environment ids (default: {list(TASK_MAPS)})")
    parser.add_argument("--maps", nargs="+", help="maps (default: each task's: map1 map2 / map3 map4)")
    parser.add_argument("--slips", nargs="+", help="nominal low high, or per-robot lambdas like 0,0.1,0.2")
    parser.add_argument("--controllers", nargs="+", help=f"default: every registered one ({controllers.available()})")
    parser.add_argument("--episodes", type=int, help="trials per cell (default 2; 10 with --paper)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    parser.add_argument("--backend", choices=["process", "ray"], default="process")
    parser.add_argument("--out", default="results", help="output directory (default: results)")
    parser.add_argument("--resume", action="store_true", help="continue the run logged in --out")
    parser.add_argument("--tolerance", type=float, default=PARAMS.goal_tolerance, help="goal tolerance [m]")
    parser.add_argument("--max-episode-steps", type=int, default=PARAMS.max_episode_steps)
    parser.add_argument("--paper", action="store_true", help="the paper's protocol (SPEC section 5)")
    parser.add_argument("--check", metavar="THRESHOLDS", help="TOML thresholds; exit 101 if a cell falls below")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    protocol = paper_protocol() if args.paper else quick_protocol()
    env_ids = args.env or protocol["env_ids"]
    if args.maps:
        maps: dict[str, list[str]] = {e: args.maps for e in env_ids}
    else:
        maps = {e: protocol["maps"].get(e, list(BUILTIN_MAPS)) for e in env_ids}
    try:
        start = time.perf_counter()
        results = evaluate(
            env_ids,
            args.controllers or protocol.get("controllers"),
            maps,
            args.slips or list(SLIP_SETTINGS),
            args.episodes or protocol["episodes"],
            args.seed,
            args.workers,
            args.backend,
            args.out,
            args.resume,
            args.tolerance,
            args.max_episode_steps,
            progress=not args.quiet,
        )
        wall = time.perf_counter() - start
        paths = results.write(args.out)
        problems = check_thresholds(results, args.check) if args.check else []
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(results.to_markdown())
    print(f"\n{len(results.records)} episodes in {wall:.1f} s; wrote {', '.join(str(p) for p in paths.values())} "
          f"and {Path(args.out) / 'figures'}/")  # fmt: skip
    failed = results.failed_episodes
    if failed:
        print(f"{len(failed)} episode(s) raised; see {paths['markdown']}", file=sys.stderr)
    if problems:
        print("threshold check failed:\n" + "\n".join(f"  - {p}" for p in problems), file=sys.stderr)
        return FAILED_CHECK_EXIT
    if args.check:
        print(f"threshold check passed ({args.check})")
    return min(len(failed), 100)


if __name__ == "__main__":
    raise SystemExit(main())
