"""The size of docs/bench_results.md (and of the pairwise file beside it) on a synthetic
full-size publication of the test suite, and the CPU time its generator takes (issue 60).

Usage::

    python bench/bench_page_size.py [--controllers LABEL ...] [--layouts 200] [--reference NAME] [--keep DIR]

It writes two publications as ``bash data/publish.sh pack`` would (``bench_test_realtime`` and
``bench_test``) into a temporary folder: per mode, every controller of that mode's run in
data/publish.sh (or the ``--controllers`` given, in both modes) on ``--layouts`` layouts of each
task's test split, one episode each. The records are the committed fixtures' real records
(tests/data/bench_test*_layouts0-2.tar.xz) with their outcomes and metrics drawn from a seeded
generator (a success rate per controller and a difficulty per layout), so the statistics run on
a full-size sample; no controller runs. Then it runs docs/make_bench_md.py on them and prints the
page's size, the pairwise file's (when the generator writes one), and the generator's CPU time.
Nothing in the repository is written.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import pack_run

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_bench_md import option_values, published_runs  # noqa: E402  (docs/ is no package)

FIXTURES = {
    "bench_test_realtime": ROOT / "tests" / "data" / "bench_test_realtime_layouts0-2.tar.xz",
    "bench_test": ROOT / "tests" / "data" / "bench_test_layouts0-2.tar.xz",
}
#: fields a synthetic record leaves out (heavy, and read by no table of the page)
_DROPPED = ("trajectory", "obstacles", "final_poses", "decisions")


def published_controllers(run: str) -> list[str]:
    """The ``--controllers`` of data/publish.sh's run ``run``, as bash expands them."""
    return option_values(published_runs()[run], "--controllers")


def _synthetic(
    template: dict[str, Any], label: str, layout: int, rng: np.random.Generator, rate: float
) -> dict:
    record = {k: v for k, v in template.items() if k not in _DROPPED}
    env_id, _, map_name, slip, _ = template["key"].split("|")
    success = bool(rng.random() < rate)
    close = float(rng.uniform(-0.01, 0.2))
    robots = len(template["straight_distance"])
    record.update(
        key=f"{env_id}|{label}|{map_name}|{slip}|{layout}",
        controller=label,
        controller_name=label,
        controller_options="{}",
        trial=layout,
        seed=layout,
        layout=layout,
        layout_tier=("easy", "medium", "hard")[layout % 3],
        layout_family=("clutter", "passages", "rooms")[(layout // 3) % 3],
        success=success,
        strict_success=success and close > 0.05,
        success_excusing_unavoidable=success or bool(rng.random() < 0.03),
        time_to_goal=float(rng.uniform(10, 50)) if success else None,
        min_clearance={"obstacle": close, "robot": float(rng.uniform(0.02, 0.5)), "mover": None},
        path_length=[float(d * rng.uniform(1.0, 1.6)) for d in template["straight_distance"]],
        # an episode's own end (what tells two episodes of a cell apart: distinct_records)
        final_distance=rng.uniform(0.0, 0.1 if success else 3.0, robots).tolist(),
        steps=int(rng.integers(100, 600)) if success else 600,
        jerk_rms=rng.uniform(0.1, 4.0, robots).tolist(),
        near_obstacle_share=rng.uniform(0.0, 0.6, robots).tolist(),
    )
    return record


def write_publication(run: str, labels: list[str], layouts: int, folder: Path, seed: int) -> Path:
    """A synthetic publication of ``run`` with ``labels`` on ``layouts`` layouts per task."""
    with extracted_archive(FIXTURES[run]) as fixture:
        lines = (fixture / "episodes.jsonl").read_text(encoding="utf-8").splitlines()
    header = json.loads(lines[0])
    templates: dict[str, dict[str, Any]] = {}
    for line in lines[1:]:
        record = json.loads(line)
        templates.setdefault(record["env_id"], record)
    header["config"]["controller_configs"] = [{"label": c, "name": c, "options": {}} for c in labels]
    suite = header["config"]["suite"]
    full = all(task["size"] == layouts for task in suite["tasks"].values())
    suite["layouts"] = None if full else [0, layouts]
    rng = np.random.default_rng(seed)
    rates = {c: float(rng.uniform(0.3, 0.95)) for c in labels}
    hardness = rng.uniform(-0.25, 0.25, layouts)
    out = [json.dumps(header)]
    for template in templates.values():
        for label in labels:
            for layout in range(layouts):
                rate = float(np.clip(rates[label] - hardness[layout], 0.0, 1.0))
                out.append(json.dumps(_synthetic(template, label, layout, rng, rate)))
    run_dir = folder / "runs" / run
    run_dir.mkdir(parents=True)
    (run_dir / "episodes.jsonl").write_text("\n".join(out) + "\n", encoding="utf-8")
    return pack_run(run_dir, folder / f"{run}.tar.xz")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--controllers", nargs="+", help="both modes' labels (default: data/publish.sh's)")
    parser.add_argument("--layouts", type=int, default=200, help="layouts per task (default 200)")
    parser.add_argument(
        "--reference", default="koopman-nmpc", help="the page's reference (default koopman-nmpc)"
    )
    parser.add_argument("--keep", type=Path, help="write into this folder and keep it")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.keep or Path(scratch)
        paths = {}
        for index, run in enumerate(FIXTURES):
            labels = args.controllers or published_controllers(run)
            paths[run] = write_publication(run, labels, args.layouts, folder, seed=index)
            print(f"{run}: {len(labels)} controllers x {2 * args.layouts} units", flush=True)
        page = folder / "docs" / "bench_results.md"
        page.parent.mkdir(parents=True, exist_ok=True)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        command = [sys.executable, str(ROOT / "docs" / "make_bench_md.py"), "--out", str(page)]
        command += ["--reference", args.reference]
        command += ["--charged", str(paths["bench_test_realtime"]), "--free", str(paths["bench_test"])]
        subprocess.run(command, check=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        print(f"page: {page.stat().st_size / 1000:.1f} KB, {len(page.read_text().splitlines())} lines")
        for extra in sorted(page.parent.glob("*.csv")):
            print(
                f"{extra.name}: {extra.stat().st_size / 1000:.1f} KB, {len(extra.read_text().splitlines())} lines"
            )
        print(f"generator CPU time: {cpu:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
