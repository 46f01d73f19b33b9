"""What the evaluator reads from a controller's class without building it (issue 61): the order
its workers get the episodes in (``episode_cost``, evaluation.execution.runner.schedule) and
whether a cell's episodes run together (``acts_in_batch``, evaluation.execution.worker.runs_in_batch).
A controller of the user's own declares both on its class; the evaluator names no controller."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest

import controllers
from controllers import registry
from controllers.consensus import ConsensusController
from evaluation.execution.runner import schedule
from evaluation.execution.worker import runs_in_batch
from evaluation.run.plan import EpisodeSpec
from evaluation.run.spec import RunSpec

#: the order before the classes declared their cost: the evaluator's own table (_COST), lowest first
_TABLE_BEFORE = {"koopman-nmpc": 0, "koopman-nmpc-robust": 0, "nominal-nmpc": 1, "nominal-nmpc-robust": 1}
#: the built-ins of those two classes that the table left out (at 2, with the cheap controllers):
#: ranked with their class now, as the table's own comment meant ("then the other optimizers")
_RANKED_BY_THEIR_CLASS = {
    "adaptive-koopman-nmpc": 0,
    "koopman-nmpc-v0": 0,
    "mpc-cbf": 1,
    "mpc-cbf-v0": 1,
    "nominal-nmpc-v0": 1,
}


def _episode(name: str, trial: int = 0, factory: Any = None) -> EpisodeSpec:
    return EpisodeSpec(
        "KoopNav-Formation-v0",
        name,
        "map3",
        "high",
        trial,
        trial,
        controller_name=name,
        controller_factory=factory,
    )


class Costly(ConsensusController):
    """A controller of the user's own that declares its episodes the longest of all."""

    name = "costly"
    episode_cost = 5


class NeverBuilt(ConsensusController):
    """Acts in batch; building it fails the test: the evaluator must decide from the class."""

    name = "never-built"
    acts_in_batch = True

    def __init__(self, **options: Any) -> None:
        raise AssertionError("the evaluator built a controller to read what its class declares")


class CalibratingBatch(ConsensusController):
    """Acts in batch but calibrates: its episodes run alone (a batch hands its teams no plant)."""

    name = "calibrating-batch"
    acts_in_batch = True

    def calibrate(self, plant: Any, *, seed: int = 0) -> dict[str, Any]:
        return {"transitions": 0}


def make_costly() -> Costly:
    """A factory function that declares its class by its return annotation."""
    return Costly()


def test_the_builtins_keep_their_order() -> None:
    """The Koopman-NMPC's episodes first, then the nominal NMPC's (wrapped or not), then the
    others in plan order, as the evaluator's table had them, read from the classes now."""
    names = [*registry.available(), "safe:koopman-nmpc", "ekf:nominal-nmpc", "safe:consensus"]
    plan = [_episode(name, trial) for name in names for trial in range(2)]
    rank = {**_TABLE_BEFORE, **_RANKED_BY_THEIR_CLASS}
    expected = sorted(plan, key=lambda e: rank.get(registry.split_name(e.controller)[1], 2))
    assert [e.key for e in schedule(plan)] == [e.key for e in expected]
    assert [e.controller for e in schedule(plan)][:8] == [
        "adaptive-koopman-nmpc", "adaptive-koopman-nmpc", "koopman-nmpc", "koopman-nmpc",
        "koopman-nmpc-robust", "koopman-nmpc-robust", "koopman-nmpc-v0", "koopman-nmpc-v0",
    ]  # fmt: skip


@pytest.mark.parametrize("how", ["registered", "import path", "factory class", "factory function"])
def test_a_controller_of_the_users_own_declares_its_cost_without_an_edit_of_the_evaluator(how: str) -> None:
    if how == "registered":
        controllers.register("costly", Costly, overwrite=True)
        costly = _episode("costly")
    elif how == "import path":
        costly = _episode(f"{__name__}:Costly")
    else:
        factory = Costly if how == "factory class" else make_costly
        costly = _episode("costly", factory=factory)
    plan = [_episode("consensus"), _episode("koopman-nmpc"), costly, _episode("nominal-nmpc")]
    assert [e.controller_name for e in schedule(plan)][0] == costly.controller_name
    assert [e.controller for e in schedule(plan)][1:] == ["koopman-nmpc", "nominal-nmpc", "consensus"]


def test_a_factory_that_names_no_class_costs_nothing_and_runs_alone() -> None:
    """A partial says nothing about its class without a call: the evaluator builds nothing to
    find out; the episode keeps its place and runs alone (its record is the same either way)."""
    controllers.register("costly-partial", functools.partial(Costly), overwrite=True)
    plan = [_episode("consensus"), _episode("costly-partial")]
    assert schedule(plan) == plan
    assert not runs_in_batch(plan[1])
    # declared at registration, as the presets are: read from that class
    controllers.register("costly-partial", functools.partial(Costly), overwrite=True, builds=Costly)
    assert schedule(plan) == plan[::-1]


def test_whether_a_cell_runs_in_batch_is_read_from_the_class_without_building() -> None:
    controllers.register("never-built", NeverBuilt, overwrite=True)
    assert runs_in_batch(_episode("never-built"))
    assert runs_in_batch(_episode("never-built-api", factory=NeverBuilt))
    assert not runs_in_batch(_episode(f"{__name__}:CalibratingBatch"))
    assert not runs_in_batch(_episode("safe:never-built"))  # the safety filter decides team by team
    assert not runs_in_batch(_episode("consensus"))
    # an animation or charged compute: the one-env runner's
    spec = RunSpec(envs="KoopNav-Formation-v0", controllers=["never-built"], maps=["map3"], slips=["high"])
    assert all(runs_in_batch(e) for e in spec.resolved().episodes_plan(""))
    charged = spec.replace(compute_scale=2.0).resolved().episodes_plan("")
    assert not any(runs_in_batch(e) for e in charged)
    assert np.all(
        [not runs_in_batch(e) for e in spec.replace(gifs=True).resolved().episodes_plan("/x") if e.animation]
    )
