"""Shared fixtures (small hand-made maps for exact scenarios) and the suite's own temporary caches."""

from __future__ import annotations

import ctypes
import os
import shutil
import sys
import tempfile
import warnings
from collections.abc import Callable, Generator, Iterator
from pathlib import Path

import numpy as np
import pytest

# NMPC solvers run uncompiled in the tests: the suite builds dozens of one-off problem structures,
# and compiling each once (30-60 s on a fresh machine) would dominate its run time. The compiled
# path and its cache have their own tests (tests/test_solver_cache.py), which set jit explicitly.
# Set before any controller is built; worker processes and subprocesses inherit it.
os.environ.setdefault("KOOPNAV_NMPC_JIT", "0")

# The suite writes nothing under the user's HOME: calibrations and compiled solvers go to a
# KOOPNAV_CACHE of its own, so that its run time and results never depend on what an earlier run
# left in ~/.cache/koopnav (a cold cache every run), and matplotlib's font cache and Selenium
# Manager's driver metadata go there too. Numba's kernel cache stays where numba puts it, in the
# checkout's __pycache__ folders. The directory is made once per session by the process that runs
# pytest and removed when it ends (pytest_unconfigure below); pytest-xdist workers and every
# subprocess inherit these variables (set here, before anything imports koopman_envs or
# controllers), and each xdist worker takes a cache of its own below the session's directory.
# A test that sets KOOPNAV_CACHE itself (monkeypatch.setenv) still wins.
SESSION_VARIABLE = "KOOPNAV_TEST_SESSION_DIR"
#: where the library's cache lives when KOOPNAV_CACHE is unset (controllers.disk_cache.cache_root;
#: tests/test_suite_hygiene.py holds the two together)
HOME_CACHE = Path(os.path.expanduser("~")) / ".cache" / "koopnav"

_worker = os.environ.get("PYTEST_XDIST_WORKER")
_owner = not (_worker and os.environ.get(SESSION_VARIABLE))
if _owner:
    os.environ[SESSION_VARIABLE] = tempfile.mkdtemp(prefix="koopnav-tests-")
SESSION_DIR = Path(os.environ[SESSION_VARIABLE])
_home = SESSION_DIR / (_worker if not _owner and _worker else "main")
os.environ["KOOPNAV_CACHE"] = str(_home / "koopnav")
os.environ["MPLCONFIGDIR"] = str(_home / "matplotlib")
os.environ["SE_CACHE_PATH"] = str(_home / "selenium")
# the headless browser of the HTML report tests keeps its profile under XDG_CONFIG_HOME and dconf
# its cache under XDG_CACHE_HOME: in the session folder, not the user's HOME
os.environ["XDG_CONFIG_HOME"] = str(_home / "config")
os.environ["XDG_CACHE_HOME"] = str(_home / "cache")


def tree_state(root: Path) -> dict[str, tuple[bool, int, int]] | None:
    """Every entry below ``root`` (``root`` included) with (is a directory, size, mtime in ns);
    None when ``root`` does not exist. Two states differ when anything was created, removed or
    written below ``root`` between them (a removed file changes its directory's mtime)."""
    if not root.exists():
        return None
    state = {}
    for path in [root, *root.rglob("*")]:
        st = path.lstat()
        state[str(path.relative_to(root))] = (path.is_dir(), st.st_size, st.st_mtime_ns)
    return state


def describe_change(
    before: dict[str, tuple[bool, int, int]] | None, after: dict[str, tuple[bool, int, int]] | None
) -> str:
    """What changed between two :func:`tree_state` results, in a few words ("" when nothing)."""
    if before == after:
        return ""
    if after is None:
        return "removed"
    was = before or {}
    changed = sorted(k for k in was.keys() | after.keys() if was.get(k) != after.get(k))
    listed = ", ".join(changed[:10]) + (" ..." if len(changed) > 10 else "")
    return ("created: " if before is None else "changed: ") + listed


_HOME_CACHE_BEFORE = tree_state(HOME_CACHE)

# the asserts of the shared test code (tests/helpers/) report their values as a test file's do;
# registered before any test module imports it
pytest.register_assert_rewrite("helpers")

from koopman_envs.sim.maps.map_spec import MapSpec  # noqa: E402  (after the environment above is set)

#: the thread pools of the numerical libraries (OpenBLAS, MKL, OpenMP: numpy, torch), one thread each
#: in an xdist worker
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def pytest_configure(config: pytest.Config) -> None:
    """With pytest-xdist workers (one per core), each numerical library gets one thread per worker:
    their default, a thread per core in every worker, oversubscribes the cores, and OpenBLAS's
    threads spin while they wait. Set in the
    process that starts the workers, before it starts them: a library reads its variable when it
    loads. A variable the user set is kept."""
    if _owner and (getattr(config.option, "numprocesses", None) or 0) > 1:
        for variable in THREAD_VARIABLES:
            os.environ.setdefault(variable, "1")
        if os.environ.get(WARM_VARIABLE, "1") != "0":
            try:
                warm_kernel_cache()
            except Exception as exc:  # the tests that run the same code report it, one by one
                warnings.warn(
                    f"the numba warm-up failed, each worker compiles its kernels: {exc!r}", stacklevel=1
                )


#: "0": the process that starts the xdist workers leaves numba's kernel cache as it finds it
WARM_VARIABLE = "KOOPNAV_TEST_WARM_KERNELS"
#: the environments whose kernels the warm-up compiles (the settings of tests/test_batched_reset.py:
#: fixed and random maps, slip zones, faults, constant, tracked and walking movers, lidar)
WARM_SETTINGS: tuple[tuple[str, dict[str, object]], ...] = (
    ("KoopNav-TargetReaching-v0", {"uncertainty": "harsh", "map": "random", "start_noise": 0.1}),
    ("KoopNav-Formation-v0", {"map": "random", "slip": "random"}),
    ("KoopNav-TargetReaching-v0", {"movers": {"count": 6}}),
    ("KoopNav-Formation-v0", {"movers": {"count": 5, "behaviour": "waypoints"}, "map": "random"}),
    ("KoopNav-TargetReaching-v0", {"sensing": "lidar", "movers": {"count": 4}, "map": "map5"}),
)
#: the controllers driving them: dwa's kernels, and the CBF filter's barriers and two-variable QP
WARM_CONTROLLERS = ("dwa", "safe:consensus")


def warm_kernel_cache() -> None:
    """Compile the numba kernels most tests use, once, in the process that starts the xdist workers
    and before it starts them, so that the workers load them from numba's cache (the checkout's
    ``__pycache__``) instead of each compiling the same kernels at the same time. On a fresh clone
    the kernels cost each process about 35 CPU-s to compile; with the cache written, the warm-up
    loads them in about 1 CPU-s. A kernel compiled later for a signature not seen here is compiled
    by the worker that needs it, as before. Set KOOPNAV_TEST_WARM_KERNELS=0 to skip it."""
    import gymnasium as gym

    import controllers
    from koopman_envs.episodes.single import run_episode

    for k, (env_id, kwargs) in enumerate(WARM_SETTINGS):
        env = gym.make(env_id, max_episode_steps=3, **kwargs)
        run_episode(env, controllers.make(WARM_CONTROLLERS[k % len(WARM_CONTROLLERS)]), seed=k)
        env.close()


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(
    collector: pytest.Collector,
) -> Generator[None, pytest.CollectReport, pytest.CollectReport]:
    """Import a test module with bytecode writing on, so that pytest caches the module's rewritten
    asserts in ``__pycache__`` (a ``-pytest-`` .pyc) and the next run, or the other xdist worker,
    reads it instead of rewriting again (5.9 CPU-s per process for the test modules).
    ``PYTHONDONTWRITEBYTECODE=1`` would otherwise make every process of every run rewrite them all;
    a project module the test module imports first is cached as well. The user's setting is
    restored after each module."""
    if not isinstance(collector, pytest.Module):
        return (yield)
    previous, sys.dont_write_bytecode = sys.dont_write_bytecode, False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = previous


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the run when the user's own cache was written while it ran (checked by the process that
    owns the session, whose lifetime covers every xdist worker's)."""
    if not _owner:
        return
    change = describe_change(_HOME_CACHE_BEFORE, tree_state(HOME_CACHE))
    if change:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        message = (
            f"the user's cache {HOME_CACHE} was written during the test session ({change}); the suite "
            f"must only write to its own KOOPNAV_CACHE below {SESSION_DIR} (or another process wrote there "
            "meanwhile)"
        )
        if reporter is not None:
            reporter.write_sep("!", message, red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_unconfigure(config: pytest.Config) -> None:
    """Remove the session's caches (the owner only: the workers' caches live below its directory)."""
    if _owner:
        shutil.rmtree(SESSION_DIR, ignore_errors=True)


@pytest.fixture
def open_map() -> MapSpec:
    """Three robots in an obstacle-free area, targets 1 m ahead."""
    return MapSpec(
        "open",
        obstacles=np.zeros((0, 3)),
        starts=np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]),
        targets=np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.0, 0.0]]),
    )


@pytest.fixture
def parked_map() -> MapSpec:
    """Every robot starts on its target: success after the settling time with zero commands."""
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    return MapSpec("parked", obstacles=np.array([[3.0, 3.0, 0.5]]), starts=poses, targets=poses)


@pytest.fixture(autouse=True)
def _restore_controller_registry():
    """Undo the controllers a test registers (``controllers.register(..., overwrite=True)``): a
    registration left behind joins ``registry.available()`` for every later test of the same xdist
    worker, so which tests saw it would depend on how the run was split (the quick plan's count in
    tests/test_prose_checks.py once read 15 controllers in CI and 14 locally)."""
    from controllers import registry

    tables = (registry._REGISTRY, registry._BUILDS, registry._WRAPPERS, registry._WRAPPER_OPTIONS)
    saved = [dict(table) for table in tables]
    yield
    for table, before in zip(tables, saved, strict=True):
        table.clear()
        table.update(before)


# Root writes through permission bits, and CI runs as root: without this the tests of a read-only
# directory would skip there and check nothing. Linux keeps the bypass in capabilities, per
# thread: lowering them in the effective set (the permitted set keeps them, so they come back
# after) makes this thread meet permission bits as any user does, in the directories it has.
_CAP_VERSION_3 = 0x20080522
#: CAP_DAC_OVERRIDE (1), CAP_DAC_READ_SEARCH (2), CAP_FOWNER (3): what lets root past the bits
_PERMISSION_OVERRIDES = (1 << 1) | (1 << 2) | (1 << 3)


class _CapHeader(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint32), ("pid", ctypes.c_int)]


class _CapData(ctypes.Structure):
    _fields_ = [
        ("effective", ctypes.c_uint32),
        ("permitted", ctypes.c_uint32),
        ("inheritable", ctypes.c_uint32),
    ]


def _capabilities(change: Callable[[int], int]) -> int:
    """Set this thread's effective capabilities (the first 32) to ``change(effective)``; the old."""
    libc = ctypes.CDLL(None, use_errno=True)
    header, data = _CapHeader(_CAP_VERSION_3, 0), (_CapData * 2)()
    if libc.capget(ctypes.byref(header), data) != 0:
        raise OSError(ctypes.get_errno(), "capget failed")
    old = data[0].effective
    data[0].effective = change(old)
    if libc.capset(ctypes.byref(header), data) != 0:
        raise OSError(ctypes.get_errno(), "capset failed")
    return old


@pytest.fixture
def permission_bits_bind() -> Iterator[None]:
    """Within the test, permission bits bind this process as they bind a user: for root, its
    permission overrides are off (Linux capabilities, this thread only) and restored after."""
    if os.geteuid() != 0:
        yield
        return
    if not sys.platform.startswith("linux"):
        pytest.skip("root's permission override is lowered through Linux capabilities")
    old = _capabilities(lambda effective: effective & ~_PERMISSION_OVERRIDES)
    try:
        yield
    finally:
        _capabilities(lambda _: old)
