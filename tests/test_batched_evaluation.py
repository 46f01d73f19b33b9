"""The evaluator's batched path (evaluation.execution.worker.run_batch): a controller that decides for many
teams at once has its episodes run together in the vector env, and every record equals the
record of the same episode run alone, field for field and bit for bit, but for the timing fields;
one failing episode never costs the others of its batch their results."""

from __future__ import annotations

import pytest

from evaluation import RunSpec, evaluate
from evaluation.execution.backends import work_units
from evaluation.execution.worker import runs_in_batch

#: what a batch may change: decision and wall times (measured, never the same twice)
TIMING = {"solve_ms", "solve_ms_median", "solve_ms_p95", "wall_seconds"}
#: trials per cell: a batch of 3 holds a first trial (its paths recorded) and two others
EPISODES = 3
MOVERS = {"movers": {"count": 3, "behaviour": "constant", "speed": 0.3}}


def _untimed(record: dict) -> dict:
    extra = {k: v for k, v in (record.get("controller_extra") or {}).items() if "_ms" not in k}
    return {k: v for k, v in record.items() if k not in TIMING} | {"controller_extra": extra or None}


def _spec(controllers: list[str], **env_kwargs) -> RunSpec:
    return RunSpec(
        envs="KoopNav-TargetReaching-v0",
        controllers=controllers,
        maps=["random", "map1"],
        slips=["nominal"],
        episodes=EPISODES,
        env_kwargs={"max_episode_steps": 100, "start_noise": 0.05, **env_kwargs},
    )


@pytest.mark.parametrize(
    ("controllers", "env_kwargs", "workers"),
    [
        # the learned policies' batches in this process: a worker process that runs them starts
        # an interpreter and loads torch and the policies, about 9 CPU-s each
        # slow: the movers' case and the 2 worker processes' case, 3-4 CPU-s each (issue 61); the
        # realistic case keeps the batched evaluation's path in the default run
        pytest.param(["rl-ppo", "rl-ppo-set-movers"], MOVERS, 1, marks=pytest.mark.slow),
        (["rl-ppo-set", "rl-ppo-set-realistic"], {"uncertainty": "realistic"}, 1),
        # the same batches in 2 worker processes (spawned: a batch crosses to them and its records
        # back), run by a controller that acts in batch without torch
        pytest.param(["plugin_controllers:BatchedConsensus"], MOVERS, 2, marks=pytest.mark.slow),
        # the learned policies in 2 worker processes: the lidar case, which takes a minute (20
        # episodes of a set policy reading beams): -m slow
        pytest.param(
            ["rl-ppo-set-movers"],
            {"sensing": "lidar", "movers": {"count": 2, "behaviour": "constant"}},
            2,
            marks=pytest.mark.slow,
        ),
    ],
    ids=["movers", "realistic", "workers", "lidar"],
)
def test_a_batched_evaluation_records_what_the_one_by_one_evaluation_records(
    controllers, env_kwargs, workers
) -> None:
    if any(name.startswith("rl-") for name in controllers):
        pytest.importorskip("stable_baselines3")
    spec = _spec(controllers, **env_kwargs)
    plan = spec.resolved().episodes_plan("")
    units = work_units(plan)
    batched_units = [unit for unit in units if len(unit) > 1]
    # every cell's trials run together (trial 0 keeps its paths, the movers' too)
    assert len(batched_units) == 2 * len(controllers) and {len(u) for u in batched_units} == {EPISODES}
    together = evaluate(spec, workers=workers)  # batched (the default), in workers or here
    alone = evaluate(spec, workers=1, batch=1)
    assert [r["key"] for r in together.records] == [r["key"] for r in alone.records]
    for first, second in zip(together.records, alone.records, strict=True):
        assert first["status"] == "ok", first.get("error")
        assert _untimed(first) == _untimed(second), first["key"]
    first_trials = [r for r in together.records if r["trial"] == 0]
    assert first_trials and all(r["trajectory"] and r["obstacles"] is not None for r in first_trials)
    assert all(bool(r.get("mover_trajectory")) == ("movers" in env_kwargs) for r in first_trials)
    for name in controllers:  # distinct episodes (perturbed starts, random layouts)
        poses = [str(r["final_poses"]) for r in together.records if r["controller"] == name]
        assert len(set(poses)) == len(poses) == 2 * EPISODES


def test_one_failing_episode_of_a_batch_is_its_own_error(monkeypatch) -> None:
    """The planned failure of one episode fails its batch; the evaluator then runs the batch's
    episodes alone: that one is recorded as an error naming the failure, the others as run."""
    spec = RunSpec(
        envs="KoopNav-TargetReaching-v0",
        controllers=["plugin_controllers:BatchedFailingOnce"],
        maps=["map1"],
        slips=["nominal"],
        episodes=5,
        env_kwargs={"max_episode_steps": 20},
    )
    plan = spec.resolved().episodes_plan("")
    assert all(runs_in_batch(spec) for spec in plan)
    monkeypatch.setenv("KOOPNAV_TEST_FAILING_SEED", str(plan[2].seed))
    records = {r["trial"]: r for r in evaluate(spec, workers=1).records}
    assert records[2]["status"] == "error" and "planned failure" in records[2]["error"]
    assert all(records[t]["status"] == "ok" and records[t]["steps"] == 20 for t in (0, 1, 3, 4))


def test_controllers_that_act_alone_are_not_batched() -> None:
    pytest.importorskip("stable_baselines3")
    spec = _spec(["consensus", "rl-ppo"])
    units = work_units(spec.resolved().episodes_plan(""))
    for unit in units:
        if len(unit) > 1:
            assert {s.controller for s in unit} == {"rl-ppo"}
            assert len({(s.map, s.slip) for s in unit}) == 1  # one cell per batch
    assert all(len(u) == 1 for u in work_units(spec.resolved().episodes_plan(""), batch=1))
    with pytest.raises(ValueError, match="batch"):
        evaluate(spec, workers=1, batch=0)
