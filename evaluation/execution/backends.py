"""Where episodes run: in this process, a pool of worker processes, or Ray; plus progress display
and clean interruption."""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from typing import Any

from evaluation.episodes.records import is_degraded, ran
from evaluation.execution.worker import batch_cell, episode_record, run_batch, runs_in_batch
from evaluation.run.plan import EpisodeSpec
from koopman_envs.checks import check_choice, import_optional

__all__ = [
    "BACKENDS",
    "BATCH",
    "Progress",
    "RunInterrupted",
    "run_episodes",
    "sigterm_stops_the_run",
    "stop_on_sigterm",
    "work_units",
]

BACKENDS = ("process", "ray")
#: the most episodes of a cell run together (a controller that acts in batch, worker.run_batch)
BATCH = 64


def announce(message: str, enabled: bool = True) -> None:
    """One line on stderr saying what the run is doing before its first episode ends (a cold
    start prepares for tens of seconds: a newcomer must not mistake it for a hang)."""
    if enabled:
        print(f"koopnav: {message}", file=sys.stderr, flush=True)


class Progress:
    """Progress on stderr: a tqdm bar on a terminal, one line per episode otherwise (CI logs)."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.done, self.enabled = total, 0, enabled
        self.start = time.perf_counter()
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, file=sys.stderr, unit="episode", dynamic_ncols=True)

    def update(self, record: dict[str, Any]) -> None:
        """Count one finished episode and show its outcome."""
        self.done += 1
        if not self.enabled:
            return
        mark = (
            "ok"
            if ran(record) and record.get("success")
            else record.get("collision") or ("error" if not ran(record) else "fail")
        ) + (" (degraded)" if is_degraded(record) else "")
        what = f"{record['controller']} {record['map']} {record['slip']} #{record['trial']}: {mark}"
        if self.bar is not None:
            self.bar.set_postfix_str(what, refresh=False)
            self.bar.update()
        else:
            elapsed = time.perf_counter() - self.start
            print(f"[{self.done}/{self.total} {elapsed:.0f}s] {what}", file=sys.stderr, flush=True)

    def close(self) -> None:
        """Finish the bar (if any)."""
        if self.bar is not None:
            self.bar.close()


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: the episodes finished so far are in the log; ``--resume`` continues."""

    def __init__(self, finished: int, total: int) -> None:
        super().__init__(f"interrupted after {finished}/{total} episodes")
        self.finished, self.total = finished, total


def stop_on_sigterm(signum: int, frame: Any) -> None:
    """SIGTERM (``kill``, a CI timeout) stops a run like Ctrl-C: the worker pool is terminated
    (no orphan workers keep computing) and the log stays resumable."""
    raise KeyboardInterrupt


@contextlib.contextmanager
def sigterm_stops_the_run() -> Iterator[None]:
    """Within the block, SIGTERM stops a run like Ctrl-C (:func:`stop_on_sigterm`); the handler
    that was there before is put back afterwards, so a program or test that calls
    ``evaluate.main`` keeps its own SIGTERM behaviour. Only the main thread can set a handler;
    elsewhere the block changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGTERM, stop_on_sigterm)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C is the main process's to handle (it stops the pool cleanly)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def work_units(todo: Sequence[EpisodeSpec], batch: int = BATCH) -> list[tuple[EpisodeSpec, ...]]:
    """What the workers get: one episode, or up to ``batch`` episodes of one cell that run
    together (:func:`~evaluation.execution.worker.runs_in_batch`), in ``todo``'s order of first episodes.
    ``batch`` 1 runs every episode alone."""
    units: list[list[EpisodeSpec]] = []
    open_batches: dict[EpisodeSpec, list[EpisodeSpec]] = {}
    for spec in todo:
        if batch <= 1 or not runs_in_batch(spec):
            units.append([spec])
            continue
        cell = batch_cell(spec)
        members = open_batches.get(cell)
        if members is None or len(members) >= batch:
            members = open_batches[cell] = []
            units.append(members)
        members.append(spec)
    return [tuple(unit) for unit in units]


def _run_unit(unit: tuple[EpisodeSpec, ...]) -> list[dict[str, Any]]:
    return run_batch(unit) if len(unit) > 1 else [episode_record(unit[0])]


def _run_ray(todo: Sequence[tuple[EpisodeSpec, ...]], workers: int) -> Iterator[dict[str, Any]]:
    """Episodes as Ray tasks: on a local Ray instance, or on the cluster at ``RAY_ADDRESS``."""
    ray = import_optional("ray", "--backend ray needs Ray: pip install -e '.[ray]'", ValueError)
    started_here = not ray.is_initialized()
    if started_here:
        address = os.environ.get("RAY_ADDRESS")
        ray.init(
            address=address,
            num_cpus=None if address else workers,
            include_dashboard=False,
            log_to_driver=False,
        )
    try:
        remote = ray.remote(num_cpus=1)(_run_unit)
        pending = [remote.remote(unit) for unit in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield from ray.get(ready[0])
    finally:
        if started_here:
            ray.shutdown()


@contextlib.contextmanager
def run_episodes(
    todo: Sequence[EpisodeSpec], workers: int, backend: str = "process", batch: int = BATCH
) -> Iterator[Iterator[dict[str, Any]]]:
    """Context manager yielding the episodes' records as they finish (in any order).

    Episodes of a controller that acts in batch run ``batch`` at a time per cell
    (:func:`work_units`; their records equal the one-by-one records but for the timing fields).
    The worker pool is terminated on every exit: success, error or Ctrl-C. Workers ignore
    SIGINT, so Ctrl-C reaches only this process, which stops the pool without tracebacks.
    """
    check_choice("backend", backend, BACKENDS)
    units = work_units(todo, batch)
    if backend == "ray":
        yield _run_ray(units, workers)
    elif workers == 1 or len(units) <= 1:
        yield (record for unit in units for record in _run_unit(unit))
    else:
        with mp.get_context("spawn").Pool(min(workers, len(units)), initializer=_ignore_sigint) as pool:
            yield (
                record for records in pool.imap_unordered(_run_unit, units, chunksize=1) for record in records
            )
