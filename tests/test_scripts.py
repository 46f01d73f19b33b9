"""Every script under bench/ and docs/ starts and finishes on tiny arguments and prints what it
is for (a table row, a verdict, the file it wrote), so that none can rot unseen: a script added
without a row here fails the first test.

The scripts run in this process (``runpy``, as ``python SCRIPT ARGS`` would run them, minus a fresh
interpreter's imports and kernel loading: seconds each); the few that take tens of seconds even on
tiny arguments, or measure fresh processes by design, are marked ``slow`` (``.ci/run`` runs them)."""

from __future__ import annotations

import contextlib
import os
import re
import runpy
import sys
import warnings
from pathlib import Path

import pytest

import evaluate as ev

ROOT = Path(__file__).resolve().parents[1]

#: script -> (its tiny arguments, a regex its output must hold: re.search, multi-line). In the
#: arguments, {tmp} is a fresh folder, {results} a small evaluator run's results.json, {sweep} a
#: small sweep's output directory; every {tmp}/NAME argument must exist after the run.
SMOKE: dict[str, tuple[list[str], str]] = {
    "bench/env_throughput.py": (
        ["--seconds", "0.05", "--repeats", "1"],
        r"(?s)KoopNav-TargetReaching-v0 +gym\.make single env +[\d,]+ steps/s.*"
        r"KoopNav-Formation-v0 +1024, random \+ 2 zones +[\d,]+ env-steps/s",
    ),
    "bench/batched_resets.py": (
        ["--envs", "8", "--batch", "3", "--repeats", "1", "--calls", "2"],
        r"(?s)^8 envs, 3 reset per call.*^8 waypoint walkers +together +[\d.]+ +one at a time +[\d.]+ +\([\d.]+x\)$",
    ),
    "bench/clone_size.py": (  # in place (no clone), one small run split
        ["--no-clone", "--archives", "scale_n3"],
        r"(?s)^history: [\d.]+ MB of objects on disk, data/ [\d.]+ MB \([\d.]+%\)$.*"
        r"^\| data/scale_n3\.tar\.xz \| [\d,]+ \| \d+ \| .* \| 9 \| [\d.]+ \| [\d,]+ \| [\d,]+ \| [\d,]+ \|$.*"
        r"one part \(split\) median [\d,]+ KB",
    ),
    "bench/cold_start.py": (
        ["--settings", "plain", "--repeats", "1"],
        r"(?s)^\| KoopNav plain( \| [\d.]+ s){5} \|$.*first line from empty caches: [\d.]+ s",
    ),
    "bench/batched_evaluation.py": (
        ["--behaviours", "constant", "--counts", "2", "--controllers", "rl-ppo", "--episodes", "2"],
        r"^\| 2 constant \| \d+ \| .* \| yes \|$",  # batched and one-by-one records agree
    ),
    "bench/benchmarl_speed.py": (
        ["--envs", "4", "--frames", "400", "--iters", "1"],
        r"^  PettingZoo env in a SerialEnv +\d+ frames/s +\([\d.]+x slower\)$",
    ),
    "bench/uncertainty_speed.py": (
        ["--seconds", "0.05", "--repeats", "1", "--envs", "16"],
        r"^vector env 16, noise\+comm\+delay +[\d,]+ env-steps/s \([\d.]+x without",
    ),
    "bench/movers_speed.py": (
        ["--seconds", "0.05", "--repeats", "1", "--envs", "16", "--crowd-envs", "4"],
        r"(?s)^vector env 16, 8 constant movers +[\d,]+ env-steps/s.*social force, numba \(comparison\) +[\d,]+",
    ),
    "bench/perception_speed.py": (
        ["--periods", "12", "--json", "{tmp}/perception.json"],
        r"(?s)^   3 robots, map known  : median [\d.]+ ms.*^  16 robots, map unknown: median [\d.]+ ms",
    ),
    "bench/evaluate_wall.py": (
        [
            "--warm",
            "--workers",
            "1",
            "--evaluator-args",
            "--controllers consensus --env KoopNav-TargetReaching-v0 --maps map1 --episodes 1 --max-episode-steps 20",
        ],
        r"^python evaluate\.py \(warm caches\): +[\d.]+ s wall, 1 episodes",
    ),
    "bench/gate_power.py": (
        ["--trials", "50"],
        r"(?s)^  nested: power >= 80% from n = \d+ .*^  independent: power >= 80% from n = \d+",
    ),
    "bench/koopman_fit.py": (
        ["--budget", "2000", "--repeats", "1"],
        r"(?s)^2,000 transitions \(2 x 1000\).*^circle RMSE % +[\d.]+, [\d.]+, [\d.]+$",
    ),
    "bench/nmpc_solve.py": (
        ["--no-do-mpc", "--qp-solvers", "hpipm", "--steps", "5"],
        r"(?s)^  RTI hpipm +median.* failures +0 .*^  koopman-nmpc: [\d.]+x vs IPOPT uncompiled$",
    ),
    "bench/online_update.py": (
        ["--robots", "3", "--steps", "60"],
        r"^N=3 +RLS update +[\d.]+ +[\d.]+ +\(60 updates, 0 rejected",
    ),
    "bench/physics_model_error.py": (
        [
            "--levels",
            "high",
            "--budget",
            "1000",
            "--repetitions",
            "2",
            "--episodes",
            "1",
            "--controller",
            "orca",
        ]
        + ["--horizon", "5", "--max-episode-steps", "30", "--held-out-budget", "1000"],
        r"(?s)^\| high \(ice\) \| [\d.]+ / [\d.]+ \| [\d.]+ \| [\d.]+ / [\d.]+ \|.*"
        r"^\| high \(ice\) \| [\d.]+ / [\d.]+ / [\d.]+ \|",
    ),
    "bench/physics_speed.py": (
        ["--seconds", "0.05", "--repeats", "1", "--envs", "3"],
        r"(?s)^physics: 5 ms steps, 20 per env-step; 3 robots$.*^physics single env +[\d,]+ ",
    ),
    "bench/bench_page_size.py": (  # the test suite's page on a synthetic publication of 3 layouts
        ["--layouts", "3", "--controllers", "orca", "consensus", "--reference", "orca"],
        r"(?s)^page: [\d.]+ KB, \d+ lines$.*^bench_pairs\.csv: [\d.]+ KB, \d+ lines$.*^generator CPU time: \d+ s$",
    ),
    "bench/policy_speed.py": (
        ["--robots", "3", "--seeds", "1", "--controllers", "consensus"],
        r"^consensus +3 +[\d.]+ +[\d.]+ +[\d.]+ +[01]/1",
    ),
    "bench/random_map_resets.py": (
        ["--robots", "2", "24", "--seeds", "2"],
        r"(?s)^KoopNav-Formation-v0 +24 +grid .*^every reset succeeded$",
    ),
    "bench/render_speed.py": (
        ["--seconds", "0.1", "--repeats", "1"],
        r"^speed-up of the renderer over the old redraw: [\d.]+x$",
    ),
    "bench/safety_filter.py": (
        ["--episodes", "1", "--controllers", "consensus", "--workers", "1", "--skip-timing"],
        r"(?s)^\| safe:consensus \| 4 \| .*^consensus: collisions \d/4 -> \d/4 with the filter$",
    ),
    "bench/scaling.py": (
        ["--robots", "3", "--steps", "20", "--seeds", "1", "--controllers", "consensus"],
        r"^consensus +3 +[01]/1 \[\d+-\d+%\] +[01]/1 ",
    ),
    "docs/check_links.py": (["{tmp}"], r"^every relative link resolves$"),
    "docs/make_compute_md.py": (  # the published page's own archives (data/pages.json)
        [
            *(f"data/{run}.tar.xz" for run in ("paper_realistic", "realistic_realtime", "paper")),
            *(f"data/compute_{run}.tar.xz" for run in ("free", "delay", "ipopt_delay")),
            *("--out", "{tmp}/compute.md", "--figures", "{tmp}/figures"),
        ],
        r"^wrote .*/compute\.md and .*/compute_mechanism\.png$",
    ),
    "docs/make_figure.py": (
        ["--steps", "3", "--out", "{tmp}/figure.png"],
        r"^koopman-nmpc-robust: 3 steps, collision=(True|False), success=(True|False)$",
    ),
    "docs/make_bench_figure.py": (["--out", "{tmp}/layouts.png"], r"^wrote .*/layouts\.png$"),
    "docs/make_options_md.py": (["--out", "{tmp}/options.md"], r"^wrote .*/options\.md$"),
    "docs/make_sizing.py": (["--check"], r"^docs/benchmark\.md's bench-sizing block is up to date$"),
    "docs/make_pages.py": (["--check", "docs/lidar_results.md"], r"^every page checked is up to date$"),
    "docs/make_results_md.py": (
        ["{results}", "--out", "{tmp}/results.md", "--figures", "{tmp}/figures"],
        r"^wrote .*/results\.md$",
    ),
    "docs/make_robustness_md.py": (  # no --figures: they go to _static beside the page
        ["{sweep}", "--out", "{tmp}/robustness.md"],
        r"^wrote .*/robustness\.md and 1 sweep\(s\) of figures in .*/_static",
    ),
    "docs/solver_comparison.py": (
        ["{results}"],
        r"(?s)^\| target reaching \| nominal-nmpc \| map1 high, map2 high \| 2 \| .*^Rule \(.*\): \*\*(passes|fails)\*\*",
    ),
}
#: tens of seconds even on tiny arguments (fixed sets of configurations, a training iteration, a
#: page rebuilt from the published archives) or fresh processes by design: run by `-m slow`
SLOW = {
    "bench/batched_evaluation.py",
    "bench/bench_page_size.py",
    "bench/benchmarl_speed.py",
    "bench/cold_start.py",
    "bench/env_throughput.py",
    "bench/evaluate_wall.py",
    "bench/nmpc_solve.py",
    "docs/make_pages.py",
    # slow: seconds each on tiny arguments (issue 61: the default run's time); their siblings keep
    # the benches' and the page generators' path in the default run
    "bench/batched_resets.py",
    "bench/movers_speed.py",
    "bench/physics_model_error.py",
    "bench/render_speed.py",
    "bench/safety_filter.py",
    "docs/make_bench_figure.py",
    "docs/make_compute_md.py",
}
#: scripts run elsewhere, with the reason
ELSEWHERE = {
    "docs/make_ablation_md.py": "its page's generator, run by docs/make_pages.py (tests/test_prose_pages.py runs it on a fixture)",
    "docs/make_bench_md.py": "its page's generator, run by docs/make_pages.py (tests/test_bench_page.py runs it on fixtures)",
    "docs/make_sim2sim_md.py": "its page's generator, run by docs/make_pages.py (tests/test_sim2sim.py runs it on two small real runs)",
    "docs/make_tuning_md.py": "its page's generator, run by docs/make_pages.py (tests/test_tuning_curves.py runs it on the committed studies)",
    "docs/make_seeds_md.py": "its page's generator, run by docs/make_pages.py (tests/test_seeds_page.py runs it on a real 9-episode validation publication)",
    "docs/page_writer.py": "a module of docs/make_ablation_md.py and docs/make_seeds_md.py, not a script (tests/test_prose_pages.py, tests/test_seeds_page.py)",
    "docs/bench_headline.py": "a module of docs/make_bench_md.py (README's headline block), not a script (tests/test_bench_page.py)",
    "bench/nmpc_build_time.py": "a module of bench/nmpc_solve.py (its --cache-timing), not a script",
    "docs/make_prose_md.py": "docs/paper.md's generator, run by docs/make_pages.py (tests/test_prose_pages.py)",
    "docs/prose_numbers.py": "a module of docs/make_prose_md.py, not a script (tests/test_prose_pages.py)",
    "docs/policy_budgets.py": "a module of docs/make_results_md.py, not a script (tests/test_results_page.py)",
    "docs/prose_tables.py": "a module of docs/make_prose_md.py, not a script (tests/test_prose_pages.py)",
    "docs/prose_span.py": "a module of docs/prose_numbers.py, not a script (tests/test_prose_intros.py)",
    "docs/prose_sweeps.py": "a module of docs/prose_numbers.py, not a script (tests/test_prose_intros.py)",
    "docs/conf.py": "Sphinx's configuration: .ci/run builds the site with it (bash docs/build.sh)",
    "docs/build.sh": "the site build itself: the docs step of .ci/run",
}


def test_every_script_has_a_smoke_run() -> None:
    assert SLOW <= set(SMOKE)
    scripts = {
        str(path.relative_to(ROOT))
        for folder in ("bench", "docs")
        for path in (ROOT / folder).iterdir()
        if path.suffix in (".py", ".sh")
    }
    assert not set(SMOKE) & set(ELSEWHERE), (
        f"both run and run elsewhere: {sorted(set(SMOKE) & set(ELSEWHERE))}"
    )
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
    """A results.json with both tasks (their two paper maps, high slip), consensus and an NMPC under
    two solver labels; 10 periods per episode (IPOPT uncompiled takes most of the run: 20 periods
    took 4.3-4.6 CPU-s, 10 take 2.4-2.8)."""
    out = tmp_path_factory.mktemp("run")
    spec = ev.RunSpec(
        envs=["KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"],
        controllers=[
            "consensus",
            "nominal-nmpc:solver=rti,label=nominal-nmpc@rti",
            "nominal-nmpc:solver=ipopt,label=nominal-nmpc@ipopt",
        ],
        episodes=1,
        slips=["high"],
        env_kwargs={"max_episode_steps": 10},
    )
    results = ev.evaluate(spec, workers=1)
    # results.json alone, as Results.write writes it: the scripts read nothing else of a run, and
    # the rest of the report (figures, index.html) took 4.6 CPU-s of this fixture's 9.1
    path = out / "results.json"
    path.write_text(results.to_json() + "\n")
    return path


#: scripts whose tiny run needs an extra (the module it imports): skipped on a core install, as
#: README's test command runs on `pip install -e '.[test]'` alone
SMOKE_NEEDS = {
    "bench/batched_evaluation.py": "stable_baselines3",  # it times the rl-ppo policy
    "bench/benchmarl_speed.py": "benchmarl",  # it trains MAPPO
    "bench/movers_speed.py": "pyrvo",  # it times the ORCA crowd (the [crowd] extra)
    "bench/physics_model_error.py": "mujoco",  # the physics plant (the [physics] extra)
    "bench/physics_speed.py": "mujoco",  # the physics plant (the [physics] extra)
}


@contextlib.contextmanager
def _as_main(script: str, args: list[str]):
    """Run ``script`` as ``python script args`` would, in this process: its own ``sys.argv``, its
    folder first on ``sys.path``, the checkout as working directory; what it changes of the
    process (``sys.path``, warning filters, torch's thread count) is put back afterwards."""
    saved_argv, saved_path, saved_cwd = sys.argv[:], sys.path[:], os.getcwd()
    torch = sys.modules.get("torch")
    threads = torch.get_num_threads() if torch is not None else None
    sys.argv = [script, *args]
    sys.path.insert(0, str((ROOT / script).parent))
    os.chdir(ROOT)
    try:
        with warnings.catch_warnings():
            yield
    finally:
        sys.argv[:], sys.path[:] = saved_argv, saved_path
        os.chdir(saved_cwd)
        torch = sys.modules.get("torch")
        if torch is not None:
            torch.set_num_threads(threads or torch.get_num_threads())


def _run_script(script: str, args: list[str], capfd: pytest.CaptureFixture[str]) -> tuple[object, str, str]:
    """``python script args`` in this process: (exit code, 0 or None for success; stdout; stderr)."""
    code: object = 0
    capfd.readouterr()  # what came before is not the script's
    with _as_main(script, args):
        try:
            runpy.run_path(str(ROOT / script), run_name="__main__")
        except SystemExit as exc:
            code = exc.code
    out, err = capfd.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    "script", [pytest.param(s, marks=pytest.mark.slow) if s in SLOW else s for s in sorted(SMOKE)]
)
def test_script_runs_on_tiny_arguments_and_prints_its_result(
    script: str,
    small_run: Path,
    small_sweep: Path,
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if script in SMOKE_NEEDS:
        pytest.importorskip(SMOKE_NEEDS[script])
    monkeypatch.setenv("MPLBACKEND", "Agg")
    (tmp_path / "index.html").write_text('<html><body><a href="index.html">self</a></body></html>')
    raw, expected = SMOKE[script]
    args = [a.format(tmp=tmp_path, results=small_run, sweep=small_sweep) for a in raw]
    code, out, err = _run_script(script, args, capfd)
    assert code in (0, None), f"{script} exited {code}:\n{out[-1500:]}\n{err[-3000:]}"
    assert re.search(expected, out, re.MULTILINE), (
        f"{script} printed:\n{out[-3000:]}\nnot matching {expected!r}"
    )
    for a in raw:
        if a.startswith("{tmp}/"):
            assert Path(a.format(tmp=tmp_path)).exists(), f"{script} did not write {a}"


#: the generators of docs/'s pages and pictures: each output is a tracked file, so none has a default
GENERATORS = [
    "docs/make_bench_figure.py",
    "docs/make_compute_md.py",
    "docs/make_figure.py",
    "docs/make_options_md.py",
    "docs/make_results_md.py",
    "docs/make_robustness_md.py",
    "docs/make_sim2sim_md.py",
]


@pytest.mark.parametrize("script", GENERATORS)
def test_a_docs_generator_writes_nothing_until_told_where(
    script: str, capfd: pytest.CaptureFixture[str]
) -> None:
    code, _, err = _run_script(script, [], capfd)
    assert code == 2 and re.search(r"the following arguments are required: .*--out", err), err


def test_robustness_page_names_parts_and_opens_with_their_overview(
    small_sweep: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    def make_page(*args: str) -> tuple[object, str, str]:
        return _run_script("docs/make_robustness_md.py", list(args), capfd)

    intro = tmp_path / "intro.md"
    intro.write_text("Our own intro.\n")
    out = tmp_path / "crowd.md"
    args = [str(small_sweep), str(small_sweep), "--out", str(out), "--figures", str(tmp_path / "fig")]
    args += ["--names", "First part", "Second part", "--intro", str(intro), "--figure-prefix", "crowd"]
    code, _, err = make_page(*args)
    assert code in (0, None), err[-3000:]
    page = out.read_text()
    assert (
        page.index("Our own intro.") < page.index("## Overview of every part") < page.index("## First part")
    )
    assert "| First part: actuation_delay AUC [%] | Second part: actuation_delay AUC [%] |" in page
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == [
        "crowd1_robustness_actuation_delay.png",
        "crowd2_robustness_actuation_delay.png",
    ]
    code, _, err = make_page(str(small_sweep), "--names", "a", "b", "--out", str(out))
    assert code == 2 and "--names gives 2 name(s) for 1 sweep(s)" in err
    code, _, err = make_page(str(small_sweep), "--reference", "nobody", "--out", str(out))
    assert code == 2 and "--reference 'nobody' is not one of" in err


def test_the_actor_timing_of_the_batched_evaluation_bench_runs(capfd: pytest.CaptureFixture[str]) -> None:
    """``bench/batched_evaluation.py --actors``: one row per shipped policy, with both timings."""
    pytest.importorskip("stable_baselines3")
    code, out, err = _run_script("bench/batched_evaluation.py", ["--actors", "--rows", "2"], capfd)
    assert code in (0, None), err[-3000:]
    rows = [line for line in out.splitlines() if line.startswith("| ") and "x |" in line]
    assert len(rows) >= 6 and all(line.split("|")[2].strip() == "2" for line in rows)
