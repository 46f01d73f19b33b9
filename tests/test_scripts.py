"""Every script under bench/ and docs/ starts and finishes on tiny arguments (seconds each), so
that none can rot unseen: a script added without a row here fails the first test."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import evaluate as ev

ROOT = Path(__file__).resolve().parents[1]

#: script -> its tiny arguments ({tmp}: a fresh folder, {results}: a small evaluator run's results.json,
#: {sweep}: a small sweep's output directory)
SMOKE: dict[str, list[str]] = {
    "bench/env_throughput.py": ["--seconds", "0.05", "--repeats", "1"],
    "bench/batched_resets.py": ["--envs", "8", "--batch", "3", "--repeats", "1", "--calls", "2"],
    "bench/cold_start.py": ["--settings", "plain", "--repeats", "1"],
    "bench/batched_evaluation.py": [
        "--behaviours",
        "constant",
        "--counts",
        "2",
        "--controllers",
        "rl-ppo",
        "--episodes",
        "2",
    ],
    "bench/benchmarl_speed.py": ["--envs", "4", "--frames", "400", "--iters", "1"],
    "bench/uncertainty_speed.py": ["--seconds", "0.05", "--repeats", "1", "--envs", "16"],
    "bench/movers_speed.py": ["--seconds", "0.05", "--repeats", "1", "--envs", "16", "--crowd-envs", "4"],
    "bench/perception_speed.py": ["--periods", "12", "--json", "{tmp}/perception.json"],
    "bench/evaluate_wall.py": [
        "--warm",
        "--workers",
        "1",
        "--evaluator-args",
        "--controllers consensus --env KoopNav-TargetReaching-v0 --maps map1 --episodes 1 --max-episode-steps 20",
    ],
    "bench/gate_power.py": ["--trials", "50"],
    "bench/koopman_fit.py": ["--budget", "2000", "--repeats", "1"],
    "bench/nmpc_solve.py": ["--no-do-mpc", "--qp-solvers", "hpipm", "--steps", "5"],
    "bench/online_update.py": ["--robots", "3", "--steps", "60"],
    "bench/physics_speed.py": ["--seconds", "0.05", "--repeats", "1", "--envs", "3"],
    "bench/policy_speed.py": ["--robots", "3", "--seeds", "1", "--controllers", "consensus"],
    "bench/random_map_resets.py": ["--robots", "2", "24", "--seeds", "2"],
    "bench/render_speed.py": ["--seconds", "0.1", "--repeats", "1"],
    "bench/safety_filter.py": [
        "--episodes",
        "1",
        "--controllers",
        "consensus",
        "--workers",
        "1",
        "--skip-timing",
    ],
    "bench/scaling.py": ["--robots", "3", "--steps", "20", "--seeds", "1", "--controllers", "consensus"],
    "docs/check_links.py": ["{tmp}"],
    "docs/make_figure.py": ["--steps", "3", "--out", "{tmp}/figure.png"],
    "docs/make_options_md.py": ["--out", "{tmp}/options.md"],
    "docs/make_pages.py": ["--check", "docs/lidar_results.md"],
    "docs/make_results_md.py": ["{results}", "--out", "{tmp}/results.md", "--figures", "{tmp}/figures"],
    "docs/make_robustness_md.py": ["{sweep}", "--out", "{tmp}/robustness.md", "--figures", "{tmp}/figures"],
    "docs/solver_comparison.py": ["{results}"],
}
#: scripts run elsewhere, with the reason
ELSEWHERE = {
    "docs/conf.py": "Sphinx's configuration: .ci/run builds the site with it (bash docs/build.sh)",
    "docs/build.sh": "the site build itself: the docs step of .ci/run",
}


def test_every_script_has_a_smoke_run() -> None:
    scripts = {
        str(path.relative_to(ROOT))
        for folder in ("bench", "docs")
        for path in (ROOT / folder).iterdir()
        if path.suffix in (".py", ".sh")
    }
    assert scripts == set(SMOKE) | set(ELSEWHERE), (
        f"without a smoke run: {sorted(scripts - set(SMOKE) - set(ELSEWHERE))}; "
        f"listed but gone: {sorted((set(SMOKE) | set(ELSEWHERE)) - scripts)}"
    )


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory) -> Path:
    """A finished two-level sweep of one cheap controller."""
    out = tmp_path_factory.mktemp("sweep") / "out"
    args = ["--controllers", "consensus-free", "--env", "KoopNav-TargetReaching-v0", "--maps", "map1"]
    args += ["--episodes", "1", "--max-episode-steps", "20", "--workers", "1", "--quiet"]
    assert ev.main([*args, "--sweep", "actuation_delay=0,1", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def small_run(tmp_path_factory) -> Path:
    """A results.json with both tasks, consensus and an NMPC under two solver labels."""
    out = tmp_path_factory.mktemp("run")
    spec = ev.RunSpec(
        envs=["KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"],
        controllers=[
            "consensus",
            "nominal-nmpc:solver=rti,label=nominal-nmpc@rti",
            "nominal-nmpc:solver=ipopt,label=nominal-nmpc@ipopt",
        ],
        episodes=1,
        env_kwargs={"max_episode_steps": 20},
    )
    results = ev.evaluate(spec, workers=1)
    return results.write(out)["json"]


#: scripts whose tiny run needs an extra (the module it imports): skipped on a core install, as
#: README's test command runs on `pip install -e '.[test]'` alone
SMOKE_NEEDS = {
    "bench/batched_evaluation.py": "stable_baselines3",  # it times the rl-ppo policy
    "bench/benchmarl_speed.py": "benchmarl",  # it trains MAPPO
}


@pytest.mark.parametrize("script", sorted(SMOKE))
def test_script_runs_on_tiny_arguments(
    script: str, small_run: Path, small_sweep: Path, tmp_path: Path
) -> None:
    if script in SMOKE_NEEDS:
        pytest.importorskip(SMOKE_NEEDS[script])
    (tmp_path / "index.html").write_text('<html><body><a href="index.html">self</a></body></html>')
    args = [a.format(tmp=tmp_path, results=small_run, sweep=small_sweep) for a in SMOKE[script]]
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, script, *args],
        cwd=ROOT,
        env={**os.environ, "MPLBACKEND": "Agg"},
        capture_output=True,
        text=True,
        timeout=600,
    )
    seconds = time.monotonic() - start
    assert run.returncode == 0, (
        f"{script} exited {run.returncode}:\n{run.stdout[-1500:]}\n{run.stderr[-3000:]}"
    )
    assert run.stdout.strip(), f"{script} printed nothing"
    print(f"{script}: {seconds:.1f} s")


def _robustness_page(*args: str) -> subprocess.CompletedProcess:
    """``python docs/make_robustness_md.py ARGS...`` from the checkout, output captured."""
    return subprocess.run(
        [sys.executable, "docs/make_robustness_md.py", *args],
        cwd=ROOT,
        env={**os.environ, "MPLBACKEND": "Agg"},
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_robustness_page_names_parts_and_opens_with_their_overview(small_sweep: Path, tmp_path: Path) -> None:
    intro = tmp_path / "intro.md"
    intro.write_text("Our own intro.\n")
    out = tmp_path / "crowd.md"
    args = [str(small_sweep), str(small_sweep), "--out", str(out), "--figures", str(tmp_path / "fig")]
    args += ["--names", "First part", "Second part", "--intro", str(intro), "--figure-prefix", "crowd"]
    run = _robustness_page(*args)
    assert run.returncode == 0, run.stderr[-3000:]
    page = out.read_text()
    assert (
        page.index("Our own intro.") < page.index("## Overview of every part") < page.index("## First part")
    )
    assert "| First part: actuation_delay AUC [%] | Second part: actuation_delay AUC [%] |" in page
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == [
        "crowd1_robustness_actuation_delay.png",
        "crowd2_robustness_actuation_delay.png",
    ]
    wrong = _robustness_page(str(small_sweep), "--names", "a", "b", "--out", str(out))
    assert wrong.returncode == 2 and "--names gives 2 name(s) for 1 sweep(s)" in wrong.stderr
    stranger = _robustness_page(str(small_sweep), "--reference", "nobody", "--out", str(out))
    assert stranger.returncode == 2 and "--reference 'nobody' is not one of" in stranger.stderr


def test_the_actor_timing_of_the_batched_evaluation_bench_runs() -> None:
    """``bench/batched_evaluation.py --actors``: one row per shipped policy, with both timings."""
    pytest.importorskip("stable_baselines3")
    run = subprocess.run(
        [sys.executable, "bench/batched_evaluation.py", "--actors", "--rows", "2"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    rows = [line for line in run.stdout.splitlines() if line.startswith("| ") and "x |" in line]
    assert len(rows) >= 6 and all(line.split("|")[2].strip() == "2" for line in rows)
