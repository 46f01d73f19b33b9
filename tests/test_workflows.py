"""The GitHub Action and the example workflows work by construction: their run steps are scripts
under .ci/, which .ci/run (the repository's leaderboard gate) and these tests run.

The action's script runs here in a fresh virtual environment (on top of the packages this
interpreter sees, its own venv's included, so that nothing is downloaded) with a user's package that adds a controller by import path."""

from __future__ import annotations

import json
import os
import site
import subprocess
import venv
from pathlib import Path

import pytest

yaml = pytest.importorskip("yaml")

ROOT = Path(__file__).resolve().parents[1]
WORKFLOWS = sorted(
    [*(ROOT / ".github" / "workflows").glob("*.yml"), *(ROOT / "examples" / "workflows").glob("*.yml")]
)


def _steps(path: Path) -> list[dict]:
    doc = yaml.safe_load(path.read_text())
    return [step for job in doc["jobs"].values() for step in job["steps"]]


def test_there_are_workflows_for_both_uses() -> None:
    names = {p.name for p in WORKFLOWS}
    assert {"leaderboard.yml", "my-controller-leaderboard.yml"} <= names


@pytest.mark.parametrize("path", WORKFLOWS, ids=lambda p: p.name)
def test_every_run_step_is_a_script_that_ci_runs(path: Path) -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    for step in _steps(path):
        if "run" in step:
            command = step["run"].strip()
            assert command.startswith("bash .ci/"), f"{path.name}: step {step.get('name')!r} runs {command!r}"
            script = command.split()[1]
            assert (ROOT / script).is_file()
            assert f"bash {script}" in ci, f"{script} is not run by .ci/run"
        else:
            assert step["uses"].split("@")[0] in {
                "actions/checkout",
                "actions/setup-python",
                "actions/upload-artifact",
                "koopnav/koopnav",  # this repository's action.yml
            }


def test_the_user_workflow_passes_only_inputs_the_action_declares() -> None:
    action = yaml.safe_load((ROOT / "action.yml").read_text())
    (step,) = [
        s
        for s in _steps(ROOT / "examples" / "workflows" / "my-controller-leaderboard.yml")
        if "koopnav" in s.get("uses", "")
    ]
    assert set(step["with"]) <= set(action["inputs"])
    required = {name for name, spec in action["inputs"].items() if spec.get("required")}
    assert required <= set(step["with"])
    # the action's run step is the script tested below, with every input passed on
    (run,) = [s for s in action["runs"]["steps"] if "run" in s]
    assert run["run"].endswith('.ci/action.sh"')
    assert {f"${{{{ inputs.{name} }}}}" for name in action["inputs"] if name != "python-version"} <= set(
        run["env"].values()
    )


USER_CONTROLLER = '''
import numpy as np
from controllers.base import BaseController


class Forward(BaseController):
    """Drive straight at a constant speed: a user's controller, packaged outside KoopNav."""

    def __init__(self, speed: float = 0.1) -> None:
        super().__init__()
        self.speed = speed

    def _act(self, observation, info):
        return np.tile([self.speed, 0.0], len(info["poses"]))
'''


@pytest.fixture(scope="module")
def user_venv(tmp_path_factory) -> tuple[Path, Path]:
    """A fresh venv (seeing this environment's packages) and a user's package beside it."""
    # the installs below build from local sources without an index: they need a setuptools that
    # builds wheels by itself (>= 70.1) or the wheel package
    setuptools = pytest.importorskip("setuptools")
    version = tuple(int(part) for part in setuptools.__version__.split(".")[:2] if part.isdigit())
    if version < (70, 1):
        pytest.importorskip(
            "wheel", reason="building the user package offline needs setuptools >= 70.1 or wheel"
        )
    root = tmp_path_factory.mktemp("user")
    package = root / "my-controller"
    (package / "my_package").mkdir(parents=True)
    (package / "my_package" / "__init__.py").write_text("")
    (package / "my_package" / "control.py").write_text(USER_CONTROLLER)
    (package / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=61"]\nbuild-backend = "setuptools.build_meta"\n\n'
        '[project]\nname = "my-package"\nversion = "0.0.1"\n'
    )
    env_dir = root / "venv"
    venv_seeing_this_interpreter(env_dir)
    return env_dir, package


def venv_seeing_this_interpreter(env_dir: Path) -> None:
    """Create a venv at ``env_dir`` that sees the packages this interpreter sees, in its order.

    No pip of its own: this environment's pip and setuptools install into it (``sys.prefix`` is the
    new venv). ``system_site_packages=True`` is not enough: it shows the *base* interpreter's
    site-packages, so when this interpreter is itself a venv (a newcomer's, with setuptools
    upgraded over the base Python's older one) the new venv would build with the base's packages
    while the skip guard of :func:`user_venv` read this one's. A ``.pth`` file adds this
    interpreter's site directories instead, with ``site.addsitedir`` so that their own ``.pth``
    files (editable installs) are read as well.
    """
    venv.create(env_dir, system_site_packages=False, with_pip=False)
    seen = [site.getusersitepackages()] if site.ENABLE_USER_SITE else []
    seen += site.getsitepackages()
    python = env_dir / "bin" / "python"
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout.strip()
    lines = "; ".join(f"site.addsitedir({d!r})" for d in seen if os.path.isdir(d))
    (Path(purelib) / "koopnav_tests_outer.pth").write_text(f"import site; {lines}\n")


def test_a_nested_venv_sees_the_packages_of_the_venv_that_made_it(tmp_path: Path) -> None:
    """The newcomer's setup: this interpreter is a venv over a base Python, with a package of its own
    (here a probe module) that the base lacks; the venv the action's tests make from it sees it."""
    outer = tmp_path / "outer"
    venv.create(outer, system_site_packages=True, with_pip=False)
    outer_python = outer / "bin" / "python"
    purelib = subprocess.run(
        [str(outer_python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout.strip()
    (Path(purelib) / "koopnav_probe.py").write_text("")
    make = f"import sys; sys.path.insert(0, {str(ROOT / 'tests')!r}); import test_workflows as t; "
    make += f"t.venv_seeing_this_interpreter(t.Path({str(tmp_path / 'nested')!r}))"
    subprocess.run(
        [str(outer_python), "-c", make], check=True, timeout=120, env={**os.environ, "PYTHONPATH": ""}
    )
    where = subprocess.run(
        [
            str(tmp_path / "nested" / "bin" / "python"),
            "-c",
            "import koopnav_probe; print(koopnav_probe.__file__)",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": ""},
    )
    assert where.returncode == 0, where.stderr[-2000:]
    assert Path(where.stdout.strip()) == Path(purelib) / "koopnav_probe.py"
    # and the venv this interpreter makes builds with the setuptools that user_venv's guard reads
    import setuptools

    venv_seeing_this_interpreter(tmp_path / "ours")
    seen = subprocess.run(
        [str(tmp_path / "ours" / "bin" / "python"), "-c", "import setuptools; print(setuptools.__file__)"],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": ""},
    )
    assert Path(seen.stdout.strip()) == Path(setuptools.__file__), seen.stderr[-2000:]


#: the evaluator options of the action's test runs (one small cell)
ACTION_ARGS = "--env KoopNav-TargetReaching-v0 --maps map1 --slips nominal --max-episode-steps 20 --workers 1"


def _run_action(env_dir: Path, package: Path, out: Path, **inputs: str) -> subprocess.CompletedProcess:
    environment = {
        **os.environ,
        "PATH": f"{env_dir / 'bin'}{os.pathsep}{os.environ['PATH']}",
        "VIRTUAL_ENV": str(env_dir),
        # installs from local sources only: no index (CI machines reach none), no build isolation
        "PIP_NO_INDEX": "1",
        "PIP_NO_BUILD_ISOLATION": "0",  # pip reads this negated: 0 turns isolation off
        "PIP_NO_DEPS": "1",
        "KOOPNAV_SOURCE": str(ROOT),
        "KOOPNAV_PACKAGE": str(package),
        "KOOPNAV_CONTROLLERS": "my_package.control:Forward:speed=0.2 consensus",
        "KOOPNAV_EPISODES": "1",
        "KOOPNAV_ARGS": ACTION_ARGS,
        "KOOPNAV_OUT": str(out),
        **inputs,
    }
    environment.pop("PYTHONPATH", None)
    return subprocess.run(
        ["bash", str(ROOT / ".ci" / "action.sh")],
        env=environment,
        capture_output=True,
        text=True,
        cwd=out.parent,
    )


@pytest.mark.slow  # three whole runs of the action, each installing KoopNav into the venv (about a minute)
def test_the_action_ranks_a_users_controller_and_gates_a_rerun(user_venv, tmp_path) -> None:
    env_dir, package = user_venv
    first = _run_action(env_dir, package, tmp_path / "base")
    assert first.returncode == 0, first.stderr[-3000:]
    results = json.loads((tmp_path / "base" / "results.json").read_text())
    assert results["config"]["controllers"] == ["my_package.control:Forward:speed=0.2", "consensus"]
    assert all(r["status"] == "ok" for r in results["episodes"]), [
        r.get("error") for r in results["episodes"]
    ]
    badge = (tmp_path / "base" / "badge.svg").read_text()
    assert badge.startswith("<svg") and "my_package.control:Forward:speed=0.2" in badge
    # the rerun against the first run as baseline: one pair per controller is fewer than the gate's
    # default minimum of 10, so the gate fails closed (exit 2, before any episode) ...
    closed = _run_action(env_dir, package, tmp_path / "closed", KOOPNAV_BASELINE=str(tmp_path / "base"))
    assert closed.returncode == 2, closed.stderr[-3000:]
    assert "consensus: 1 episode(s) pair with the baseline, fewer than the minimum 10" in closed.stderr
    assert "baseline gate passed" not in closed.stdout
    # ... and with the minimum lowered: the same seeds, the same outcomes, the gate passes
    again = _run_action(
        env_dir,
        package,
        tmp_path / "again",
        KOOPNAV_BASELINE=str(tmp_path / "base"),
        KOOPNAV_ARGS=ACTION_ARGS + " --min-pairs 1",
    )
    assert again.returncode == 0, again.stderr[-3000:]
    assert "baseline gate passed" in again.stdout
    assert (tmp_path / "again" / "baseline_comparison.md").is_file()


def test_the_action_refuses_a_missing_controller_input(user_venv, tmp_path) -> None:
    env_dir, package = user_venv
    run = _run_action(env_dir, package, tmp_path / "out", KOOPNAV_CONTROLLERS="")
    assert run.returncode != 0 and "at least one controller configuration" in run.stderr


@pytest.mark.slow
def test_the_repository_gate_passes_on_its_own_baseline(tmp_path) -> None:
    """.ci/leaderboard.sh against the committed baseline, on a subset: seed 0 of every quick-board
    cell for two controllers, 4 pairs each (the full gate is the last step of .ci/run). Slow (15
    CPU-s): the default run holds the gate's pass in tests/test_baseline.py (an identical rerun
    passes) and runs this script there (test_the_ci_leaderboard_script_fails_closed_on_other_seeds)."""
    environment = {
        **os.environ,
        "KOOPNAV_GATE_EPISODES": "1",
        "KOOPNAV_GATE_ARGS": "--controllers consensus nominal-nmpc --solver rti --min-pairs 4",
    }
    run = subprocess.run(
        ["bash", str(ROOT / ".ci" / "leaderboard.sh"), str(tmp_path / "gate")],
        env=environment,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    assert "baseline gate passed" in run.stdout
    comparison = json.loads((tmp_path / "gate" / "baseline_comparison.json").read_text())
    assert {row["controller"] for row in comparison["rows"]} == {"consensus", "nominal-nmpc"}
    assert all(row["only_a"] == row["only_b"] == 0 for row in comparison["rows"])


def _action_words(cwd: Path, **inputs: str) -> subprocess.CompletedProcess:
    """The action's checks and the evaluator words it would run (KOOPNAV_PRINT_ONLY: no install)."""
    environment = {
        **os.environ,
        "KOOPNAV_SOURCE": str(ROOT),
        "KOOPNAV_CONTROLLERS": "consensus",
        "KOOPNAV_PRINT_ONLY": "true",
        **inputs,
    }
    for name in ("KOOPNAV_BASELINE", "KOOPNAV_FAIL_IF_WORSE", "KOOPNAV_BASELINE_MAY_BE_ABSENT"):
        if name not in inputs:
            environment.pop(name, None)
    return subprocess.run(
        ["bash", str(ROOT / ".ci" / "action.sh")], env=environment, capture_output=True, text=True, cwd=cwd
    )


def test_the_action_fails_on_a_missing_baseline_unless_told_it_may_be_absent(tmp_path) -> None:
    missing = _action_words(tmp_path, KOOPNAV_BASELINE="leaderboard/baseline.json")
    assert missing.returncode == 2
    assert "input baseline='leaderboard/baseline.json' does not exist" in missing.stderr
    assert "baseline-may-be-absent: true" in missing.stderr
    first = _action_words(
        tmp_path, KOOPNAV_BASELINE="leaderboard/baseline.json", KOOPNAV_BASELINE_MAY_BE_ABSENT="True"
    )
    assert first.returncode == 0, first.stderr
    assert "does not exist yet" in first.stderr and "--baseline" not in first.stdout.split()


@pytest.mark.parametrize(
    ("value", "gated"),
    [("true", True), ("TRUE", True), ("True", True), ("", True), ("false", False), ("FALSE", False)],
)
def test_the_action_reads_fail_if_worse_in_any_case(tmp_path, value, gated) -> None:
    (tmp_path / "base.json").write_text("{}")
    run = _action_words(tmp_path, KOOPNAV_BASELINE="base.json", KOOPNAV_FAIL_IF_WORSE=value)
    assert run.returncode == 0, run.stderr
    words = run.stdout.split("\n")
    assert words[words.index("--baseline") + 1] == "base.json"
    assert ("--fail-if-worse" in words) is gated


@pytest.mark.parametrize(
    ("inputs", "message"),
    [
        ({"KOOPNAV_FAIL_IF_WORSE": "yes"}, "input fail-if-worse='yes' is not a boolean"),
        ({"KOOPNAV_FAIL_IF_WORSE": "ture"}, "input fail-if-worse='ture' is not a boolean"),
        ({"KOOPNAV_BASELINE_MAY_BE_ABSENT": "1"}, "input baseline-may-be-absent='1' is not a boolean"),
        ({"KOOPNAV_EPISODES": "0"}, "input episodes='0' is not a whole number from 1 to 10000"),
        ({"KOOPNAV_EPISODES": "ten"}, "input episodes='ten' is not a whole number from 1 to 10000"),
        ({"KOOPNAV_EPISODES": "10001"}, "input episodes='10001' is not a whole number from 1 to 10000"),
        (
            {"KOOPNAV_EPISODES": "99999999999999999999999"},
            "input episodes='99999999999999999999999' is not a whole number from 1 to 10000",
        ),
        ({"KOOPNAV_CONTROLLERS": "  "}, "input controllers is empty"),
    ],
)
def test_the_action_refuses_bad_inputs_before_installing(tmp_path, inputs, message) -> None:
    (tmp_path / "base.json").write_text("{}")
    run = _action_words(tmp_path, KOOPNAV_BASELINE="base.json", **inputs)
    assert run.returncode == 2 and message in run.stderr and run.stdout == ""


def test_the_action_and_the_evaluator_share_the_episode_bound(tmp_path) -> None:
    """The action checks its inputs before KoopNav is installed, so it states the bound itself:
    the same number as koopman_envs.params.MAX_EPISODES_PER_CELL, and the largest value passes."""
    from koopman_envs.params import MAX_EPISODES_PER_CELL

    script = (ROOT / ".ci" / "action.sh").read_text()
    assert f"max_episodes={MAX_EPISODES_PER_CELL}\n" in script
    run = _action_words(tmp_path, KOOPNAV_EPISODES=str(MAX_EPISODES_PER_CELL))
    assert run.returncode == 0, run.stderr


def test_the_action_never_expands_globs_against_workspace_files(tmp_path) -> None:
    for name in ("consensus-notes.txt", "map1", "mapX", "ab"):
        (tmp_path / name).write_text("")
    run = _action_words(
        tmp_path, KOOPNAV_CONTROLLERS="consensus consens* a[b]", KOOPNAV_ARGS="--maps map? --slips *"
    )
    assert run.returncode == 0, run.stderr
    words = run.stdout.split("\n")
    assert words[words.index("--controllers") + 1 : words.index("--controllers") + 4] == [
        "consensus",
        "consens*",
        "a[b]",
    ]
    assert "map?" in words and "*" in words and "map1" not in words
