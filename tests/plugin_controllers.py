"""Controllers the tests name by import path (``plugin_controllers:Name``; tests/ is on the path of
pytest and, through PYTHONPATH, of the evaluator subprocesses the tests start)."""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

from controllers.base import BaseController
from controllers.consensus import ConsensusController

#: the file whose existence lets :class:`GatedConsensus` episodes start
GATE_VARIABLE = "KOOPNAV_TEST_GATE"


class GatedConsensus(ConsensusController):
    """Consensus whose episodes wait at reset until the file named by ``$KOOPNAV_TEST_GATE``
    exists (at most 10 minutes): a run with it cannot finish before the test opens the gate, so an
    interruption lands mid-run on a busy machine as on an idle one. Each waiting episode first
    leaves a file ``<gate>.waiting-<pid>``, so that a test can wait until every worker is past its
    start-up and waiting before it interrupts (a signal during a worker's start-up is another
    scenario, whose outcome depends on where the start-up is)."""

    name = "gated-consensus"

    def _reset(self, scenario: Any, seed: int | None) -> None:
        gate = os.environ.get(GATE_VARIABLE)
        if gate:
            open(f"{gate}.waiting-{os.getpid()}", "w").close()
        deadline = time.monotonic() + 600
        while gate and not os.path.exists(gate) and time.monotonic() < deadline:
            time.sleep(0.02)
        super()._reset(scenario, seed)


class AlwaysFailing(BaseController):
    """Stands still and reports a solver failure in every period (an episode that must be degraded)."""

    name = "always-failing"

    def _act(self, observation: Any, info: dict[str, Any]) -> Any:
        assert self.scenario is not None
        self._stats.failures += 1
        return np.zeros(2 * self.scenario.n_robots)


class PlainTimed(BaseController):
    """A plugin that records no time of its own: the base class times its decisions."""

    name = "plain-timed"

    def _act(self, observation: Any, info: dict[str, Any]) -> Any:
        assert self.scenario is not None
        return np.zeros(2 * self.scenario.n_robots)


class NotAController:
    """Has ``act`` but neither ``reset`` nor ``stats``: ``controllers.make`` must refuse it."""

    def act(self, observation: Any, info: dict[str, Any]) -> Any:
        return observation


class AlwaysRaising(BaseController):
    """Raises in every decision: every episode of it is an error record."""

    name = "always-raising"

    def _act(self, observation: Any, info: dict[str, Any]) -> Any:
        raise RuntimeError("this controller always raises")


class BatchedConsensus(ConsensusController):
    """Consensus declared to act in batch (the base class's ``act_many``: each team's own
    ``act``): an evaluation runs its episodes together, as it runs the learned policies', without
    loading torch, so that worker processes that run batches start in seconds."""

    name = "batched-consensus"
    acts_in_batch = True


def make_plain_timed() -> PlainTimed:
    """A factory function that declares the contract by its return annotation."""
    return PlainTimed()


def make_anything():  # noqa: ANN201 - undeclared on purpose: must be refused without a call
    """A factory without a return annotation: refused, never called."""
    raise AssertionError("an undeclared factory was called")


class BatchedFailingOnce(BaseController):
    """Acts in batch (``act_many``) and stands still, but raises in the episode of seed
    ``$KOOPNAV_TEST_FAILING_SEED``: a batch holding that episode fails, and the evaluator must
    still record every other episode of the batch as run, and that one as an error."""

    name = "batched-failing-once"
    acts_in_batch = True

    def _reset(self, scenario: Any, seed: int | None) -> None:
        self.seed = seed

    def _act(self, observation: Any, info: dict[str, Any]) -> Any:
        assert self.scenario is not None
        if str(self.seed) == os.environ.get("KOOPNAV_TEST_FAILING_SEED"):
            raise RuntimeError(f"planned failure in the episode of seed {self.seed}")
        return np.zeros(2 * self.scenario.n_robots)
