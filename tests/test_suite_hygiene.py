"""The suite's own caches (tests/conftest.py): nothing it runs writes to the user's ~/.cache/koopnav."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import conftest
import pytest

from controllers.disk_cache import cache_root

ROOT = Path(__file__).resolve().parents[1]


def test_the_guarded_directory_is_the_librarys_default_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    """The session-end check watches the directory the library writes to without KOOPNAV_CACHE, so
    it cannot watch a directory nothing would write to."""
    monkeypatch.delenv("KOOPNAV_CACHE")
    assert cache_root() == conftest.HOME_CACHE


def test_tests_and_their_subprocesses_cache_in_the_sessions_directory() -> None:
    here = cache_root()
    child = subprocess.run(
        [sys.executable, "-c", "from controllers.disk_cache import cache_root; print(cache_root())"],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout.strip()
    assert Path(child) == here
    assert here.is_relative_to(conftest.SESSION_DIR)
    assert not here.is_relative_to(conftest.HOME_CACHE)


def test_the_tree_state_changes_with_every_write(tmp_path: Path) -> None:
    root = tmp_path / "koopnav"
    states = [conftest.tree_state(root)]
    assert states[0] is None
    root.mkdir()
    states.append(conftest.tree_state(root))
    (root / "calibration").mkdir()
    states.append(conftest.tree_state(root))
    entry = root / "calibration" / "entry.npz"
    entry.write_bytes(b"one")
    states.append(conftest.tree_state(root))
    os.utime(entry, ns=(1, 1))  # the same size, another write
    states.append(conftest.tree_state(root))
    entry.unlink()
    os.utime(root / "calibration", ns=(2, 2))  # a removal changes its directory's mtime
    states.append(conftest.tree_state(root))
    for before, after in zip(states, states[1:], strict=False):
        assert conftest.describe_change(before, after)
    assert conftest.describe_change(states[-1], conftest.tree_state(root)) == ""


def test_a_session_that_writes_to_the_home_cache_fails(tmp_path: Path) -> None:
    """A copy of the suite's conftest over one test that writes to ~/.cache/koopnav (HOME pointed
    at a temporary directory): the run fails and names the file."""
    shutil.copy(ROOT / "tests" / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "test_stray.py").write_text(
        "import os\n"
        "from pathlib import Path\n\n\n"
        "def test_writes_home():\n"
        "    path = Path(os.path.expanduser('~')) / '.cache' / 'koopnav' / 'calibration'\n"
        "    path.mkdir(parents=True)\n"
        "    (path / 'stray.npz').write_bytes(b'x')\n"
    )
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTEST_XDIST_WORKER", conftest.SESSION_VARIABLE)}
    env.update(HOME=str(home), PYTHONPATH=str(ROOT))
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-c",
            str(tmp_path / "pytest.ini"),
            str(tmp_path),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert "1 passed" in run.stdout, run.stdout + run.stderr
    assert run.returncode == pytest.ExitCode.TESTS_FAILED, run.stdout + run.stderr
    assert f"the user's cache {home / '.cache' / 'koopnav'} was written" in run.stdout
    assert "calibration/stray.npz" in run.stdout


def test_a_test_module_is_imported_with_bytecode_writing_on_and_the_setting_restored(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """pytest caches a module's rewritten asserts only when bytecode may be written: the collection
    hook turns writing on for the module's import (PYTHONDONTWRITEBYTECODE=1 or not) and gives the
    user's setting back, and leaves other collectors (the session, a directory) alone."""
    module = request.node.parent
    assert isinstance(module, pytest.Module)
    for setting in (True, False):
        monkeypatch.setattr(sys, "dont_write_bytecode", setting)
        hook = conftest.pytest_make_collect_report(module)
        next(hook)
        assert sys.dont_write_bytecode is False
        report = pytest.CollectReport(module.nodeid, "passed", None, [])
        with pytest.raises(StopIteration) as done:
            hook.send(report)
        assert done.value.value is report and sys.dont_write_bytecode is setting
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    hook = conftest.pytest_make_collect_report(request.session)
    next(hook)
    assert sys.dont_write_bytecode is True
