"""The on-disk cache is optional (issue 41, item 7): a cache that cannot be written warns once per
process and the run goes on with what it computed in memory; reads stay checked.

The tests may run as root, where ``chmod`` does not stop a write: an unwritable cache is made
either by a cache path whose parent is a regular file (refused to root too) or by a write that
raises the ``OSError`` a read-only or full file system raises. A real read-only directory is
tested as well when the tests do not run as root.
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the envs
from controllers import disk_cache
from controllers.calibration import CacheWarning, cache_path, calibrate_controller
from controllers.koopman.model import KoopmanModel
from controllers.solvers import compiled as solver_cache
from koopman_envs import files as koopman_files
from koopman_envs.engine.plant import make_plant

ROOT = Path(__file__).resolve().parents[1]
ENV = "KoopNav-TargetReaching-v0"
BUDGET = 2000  # not the shipped models' budget: the Koopman model is fitted and written


def _write_warning() -> type[Warning]:
    # looked up at call time: before the fix the class does not exist, and the tests fail on that
    return getattr(disk_cache, "CacheWriteWarning", Warning)


@pytest.fixture(autouse=True)
def fresh_process(monkeypatch) -> None:
    """Each test is a fresh process for the warn-once rule."""
    monkeypatch.setattr(disk_cache, "_unwritable_warned", False, raising=False)


@pytest.fixture
def blocked_cache(tmp_path, monkeypatch) -> Path:
    """``KOOPNAV_CACHE`` below a regular file: no directory can be made there, root or not."""
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("a file where the cache should be\n")
    monkeypatch.setenv("KOOPNAV_CACHE", str(blocker / "cache"))
    return blocker / "cache"


def _calibrated(name: str, **options) -> tuple[object, dict, list[warnings.WarningMessage]]:
    ctrl = controllers.make(name, **options)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = calibrate_controller(ctrl, make_plant(ENV, slip="high", budget=BUDGET, seed=0), seed=0)
    assert summary is not None
    return ctrl, summary, list(caught)


def _steps(ctrl, steps: int = 1) -> None:
    env = gym.make(ENV, map="map1", slip="high")
    obs, info = env.reset(seed=0)
    ctrl.reset(env)
    for _ in range(steps):
        action = ctrl.act(obs, info)
        assert np.all(np.isfinite(action))
        obs, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated)


def _of(caught: list[warnings.WarningMessage], category: type[Warning]) -> list[warnings.WarningMessage]:
    return [w for w in caught if issubclass(w.category, category)]


# ---------------------------------------------------------------------------- write_atomic itself


@pytest.mark.parametrize(
    "failure",
    [
        PermissionError(errno.EACCES, "Permission denied"),
        OSError(errno.EROFS, "Read-only file system"),
        OSError(errno.ENOSPC, "No space left on device"),
    ],
    ids=["permission", "read-only-fs", "disk-full"],
)
def test_a_failed_write_warns_once_and_leaves_nothing_behind(tmp_path, failure) -> None:
    def write(tmp: str) -> None:
        Path(tmp).write_bytes(b"half an entr")  # the torn part a full disk leaves
        raise failure

    with pytest.warns(_write_warning()) as caught:
        assert disk_cache.write_atomic(tmp_path / "entry.json", write, ".json") is False
    (warning,) = caught
    text = str(warning.message)
    assert str(tmp_path) in text and failure.strerror in text and "without caching" in text
    assert list(tmp_path.iterdir()) == []  # neither the entry nor the temporary file
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per process: the second failure is silent
        assert disk_cache.write_atomic(tmp_path / "other.json", write, ".json") is False


def test_a_cache_below_a_file_warns_once_naming_the_directory(blocked_cache) -> None:
    entry = blocked_cache / "calibration" / "x.json"
    with pytest.warns(_write_warning(), match="Not a directory") as caught:
        assert disk_cache.write_atomic(entry, lambda tmp: Path(tmp).write_text("{}"), ".json") is False
    assert len(caught) == 1 and str(entry.parent) in str(caught[0].message)


def test_a_successful_write_says_so(tmp_path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert disk_cache.write_atomic(tmp_path / "a" / "b.txt", lambda t: Path(t).write_text("ok"), ".txt")
    assert (tmp_path / "a" / "b.txt").read_text() == "ok"


@pytest.mark.usefixtures("permission_bits_bind")  # root (CI) too
def test_a_read_only_directory(tmp_path) -> None:
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o555)
    try:
        with pytest.warns(_write_warning(), match="Permission denied"):
            assert not disk_cache.write_atomic(cache / "x.json", lambda t: Path(t).write_text("{}"), ".json")
    finally:
        cache.chmod(0o755)


# ------------------------------------------------------------------- calibrations and controllers


@pytest.mark.parametrize(
    ("name", "source"), [("koopman-nmpc", "fitted"), ("nominal-nmpc-robust", "measured")]
)
def test_a_calibration_goes_on_without_its_cache(blocked_cache, name, source) -> None:
    """The issue's reproduction: the calibration succeeded, the failed write raised."""
    ctrl, summary, caught = _calibrated(name)
    assert summary["source"] == source
    (warning,) = caught  # exactly one warning, the cache's
    assert issubclass(warning.category, _write_warning()) and "without caching" in str(warning.message)
    assert str(blocked_cache) in str(warning.message)
    _steps(ctrl)
    # the next calibration in the same process recomputes, silently: warned once per process
    ctrl, again, caught = _calibrated(name)
    assert again["source"] == source and caught == []
    _steps(ctrl)


def test_both_calibrations_in_one_process_warn_once(blocked_cache) -> None:
    _, _, first = _calibrated("koopman-nmpc")
    _, _, second = _calibrated("nominal-nmpc-robust")
    assert len(first) == 1 and second == []


def _no_new_files(monkeypatch, refuse) -> None:
    """Every way the cache creates a file raises as ``refuse`` does: the writability probe's
    :func:`tempfile.mkstemp` and the atomic writer's temporary file
    (:func:`koopman_envs.files._make_temporary`, an ``os.open`` with ``O_CREAT | O_EXCL``)."""
    monkeypatch.setattr(disk_cache.tempfile, "mkstemp", refuse)
    monkeypatch.setattr(koopman_files, "_make_temporary", refuse)


def test_a_read_only_file_system_as_root(tmp_path, monkeypatch) -> None:
    """The directory exists and is readable, but creating a file in it raises EROFS."""
    monkeypatch.setenv("KOOPNAV_CACHE", str(tmp_path / "cache"))
    (tmp_path / "cache" / "calibration").mkdir(parents=True)

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", str(tmp_path / "cache" / "calibration"))

    _no_new_files(monkeypatch, read_only)
    ctrl, summary, caught = _calibrated("koopman-nmpc")
    assert summary["source"] == "fitted"
    assert [w.category for w in caught] == [_write_warning()] and "Read-only" in str(caught[0].message)
    assert list((tmp_path / "cache" / "calibration").iterdir()) == []
    _steps(ctrl, steps=3)


def test_a_full_disk_while_saving_a_model(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("KOOPNAV_CACHE", str(tmp_path / "cache"))

    def full(self, path) -> None:
        Path(path).write_bytes(b"PK\x03\x04")  # a torn start, then the disk is full
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(KoopmanModel, "save", full)
    ctrl, summary, caught = _calibrated("koopman-nmpc")
    assert summary["source"] == "fitted" and len(_of(caught, _write_warning())) == 1
    assert list((tmp_path / "cache" / "calibration").iterdir()) == []  # no torn entry left
    _steps(ctrl)


def test_reads_stay_checked_when_the_cache_cannot_be_repaired(tmp_path, monkeypatch) -> None:
    """A torn entry in a read-only cache is refused by name (never used) and the fit stays in memory."""
    monkeypatch.setenv("KOOPNAV_CACHE", str(tmp_path / "cache"))
    _, first, _ = _calibrated("koopman-nmpc")
    path = cache_path("koopman", first["key"], ".npz")
    path.write_bytes(path.read_bytes()[:200])  # torn
    torn = path.read_bytes()

    def read_only(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(path.parent))

    _no_new_files(monkeypatch, read_only)
    ctrl, again, caught = _calibrated("koopman-nmpc")
    assert again["source"] == "fitted"
    (bad,) = _of(caught, CacheWarning)
    assert str(path) in str(bad.message)
    assert len(_of(caught, _write_warning())) == 1 and len(caught) == 2, [str(w.message) for w in caught]
    assert path.read_bytes() == torn  # left as it was: it could not be replaced
    _steps(ctrl)


def test_a_unicycle_residual_entry_stays_checked_in_a_read_only_cache(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("KOOPNAV_CACHE", str(tmp_path / "cache"))
    _, first, _ = _calibrated("nominal-nmpc-robust")
    path = cache_path("unicycle-residual", first["key"], ".json")
    good = json.loads(path.read_text())["position_residual"]
    path.write_text('{"position_residual": [NaN, NaN, NaN]}')

    def read_only(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(path.parent))

    _no_new_files(monkeypatch, read_only)
    ctrl, again, caught = _calibrated("nominal-nmpc-robust")
    assert again["source"] == "measured" and ctrl.position_residual.tolist() == good
    assert len(_of(caught, CacheWarning)) == 1 and len(_of(caught, _write_warning())) == 1


# ------------------------------------------------------------------------------ compiled solvers

BUILD = """
import sys
import casadi as ca
from controllers.solvers.compiled import jit_options, nlpsol
x = ca.SX.sym("x", 3)
nlp = {"x": x, "f": ca.sumsqr(x - 1.0) + x[0] * x[1], "g": x[0] + x[1]}
options = jit_options(background=sys.argv[1] == "background")
print("compiled" if options else "uncompiled")
solver = nlpsol("s", "ipopt", nlp, {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, **options})
print(float(solver(x0=0, lbg=0, ubg=1)["x"][2]))
"""


@pytest.mark.skipif(solver_cache.compiler() is None, reason="no C compiler (gcc) on this machine")
@pytest.mark.parametrize("mode", ["foreground", "background"])
def test_a_solver_builds_without_its_cache(blocked_cache, tmp_path, mode) -> None:
    """Foreground: compiled, not cached. Background: uncompiled at once, and no compile is promised."""
    proc = subprocess.run(
        [sys.executable, "-c", BUILD, mode],
        env={**os.environ, "PYTHONPATH": str(ROOT), "KOOPNAV_CACHE": str(blocked_cache)},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    kind, value = proc.stdout.split()[-2:]
    assert float(value) == pytest.approx(1.0, abs=1e-6)
    assert kind == ("compiled" if mode == "foreground" else "uncompiled")
    assert proc.stderr.count("without caching") == 1, proc.stderr
    assert "in the background" not in proc.stderr


# ------------------------------------------------------------------------------------- evaluator


# slow: a fitted calibration and two controllers' episodes through the CLI, about 6 CPU-s (issue
# 61); the calibration and solver tests above keep the unwritable cache's paths in the default run
@pytest.mark.slow
def test_the_evaluator_runs_every_episode_with_an_unwritable_cache(blocked_cache, tmp_path) -> None:
    """The CLI as a user runs it, with a calibration that is fitted (not shipped) and written."""
    out = tmp_path / "run"
    args = ["--controllers", "consensus", "koopman-nmpc", "--env", ENV, "--maps", "map1", "--episodes", "1"]
    args += ["--calibration-budget", str(BUDGET), "--max-episode-steps", "20", "--quiet", "--out", str(out)]
    proc = subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), *args],
        env={**os.environ, "PYTHONPATH": str(ROOT), "KOOPNAV_CACHE": str(blocked_cache)},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    episodes = json.loads((out / "results.json").read_text())["episodes"]
    assert {e["controller"]: e["status"] for e in episodes} == {"consensus": "ok", "koopman-nmpc": "ok"}
    koopman = next(e for e in episodes if e["controller"] == "koopman-nmpc")
    assert koopman["calibration"]["source"] == "fitted"
    # one process calibrates koopman-nmpc (a pool worker, or this one): one warning
    assert proc.stderr.count("without caching") == 1, proc.stderr
