"""Compute-aware episodes (koopman_envs/episodes/single.py ComputeCharge, ``--realtime``): a controller's
decision time is charged to its robots. Timed with a clock of the test's own, so nothing here
depends on how busy the machine is."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import controllers
import evaluate as ev
import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.episodes.single import ComputeCharge, run_episode


class _Clock:
    """Seconds that pass only when a controller says it thought."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class _Thinker:
    """Consensus that takes ``seconds`` per decision on ``clock``; logs each decision's period."""

    def __init__(self, clock: _Clock, seconds: float) -> None:
        self.inner = controllers.make("consensus")
        self.clock, self.seconds = clock, seconds
        self.decided_at: list[int] = []
        self.commands: list[np.ndarray] = []

    def reset(self, scenario, seed=None):
        self.inner.reset(scenario, seed=seed)
        self.period = 0

    def act(self, observation, info):
        self.clock.now += self.seconds
        command = np.asarray(self.inner.act(observation, info))
        self.commands.append(command.reshape(-1, 2))
        return command


def _run(seconds: float, charge: bool, steps: int = 60):
    env = gym.make("KoopNav-TargetReaching-v0", map="map1", max_episode_steps=steps)
    clock = _Clock()
    thinker = _Thinker(clock, seconds)
    applied = []
    result = run_episode(
        env,
        thinker,
        seed=0,
        compute=ComputeCharge(clock=clock) if charge else None,
        on_step=lambda step, action, info: applied.append(np.array(action)),
    )
    return result, thinker, applied


def test_a_controller_that_thinks_250_ms_acts_3_periods_late_and_misses_every_deadline() -> None:
    result, thinker, applied = _run(0.25, charge=True)
    # it decides at periods 0, 3, 6, ... and each command acts 3 periods after its measurement
    decisions = -(-result.steps // 3)  # periods 0, 3, 6, ... of the episode
    assert result.steps >= 20 and result.decisions == len(thinker.commands) == decisions
    assert result.deadline_misses == decisions and result.late_periods == 3.0
    for period, command in enumerate(applied):
        if period < 3:
            np.testing.assert_array_equal(command, np.zeros((3, 2)))  # nothing ready yet: standing
        else:
            np.testing.assert_array_equal(command, thinker.commands[period // 3 - 1])


def test_a_controller_that_returns_at_once_is_unchanged_from_free_compute_bit_for_bit() -> None:
    charged, _, applied_charged = _run(0.0, charge=True)
    free, _, applied_free = _run(0.0, charge=False)
    assert charged.decisions == free.decisions == free.steps and charged.deadline_misses == 0
    for a, b in zip(applied_charged, applied_free, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(charged.trajectory, free.trajectory)


@pytest.mark.parametrize(
    "seconds, scale, late",
    [(0.0005, 1.0, 0), (0.002, 1.0, 1), (0.1, 1.0, 1), (0.1001, 1.0, 2), (0.03, 5.0, 2), (0.0001, 20.0, 1)],
)
def test_periods_late_by_hand(seconds: float, scale: float, late: int) -> None:
    """Within the 1 ms grace a command acts in its own period; else from the next boundary after
    it is ready (the scale emulates a slower computer: 30 ms x 5 = 150 ms, two periods)."""
    assert ComputeCharge(scale=scale).periods_late(seconds, 0.1) == late


class _Ticks:
    """A clock that moves ``seconds`` every time it is read: each decision, timed by two reads,
    takes exactly ``seconds``."""

    def __init__(self, seconds: float) -> None:
        self.now, self.seconds = 0.0, seconds

    def __call__(self) -> float:
        self.now += self.seconds
        return self.now


@pytest.mark.parametrize(
    "scale, decisions, misses, late",
    [
        (1.0, 20, 0, 1),  # 50 ms: the next period, every period, within the deadline
        (3.0, 10, 10, 2),  # 150 ms: two periods late, every other period, every deadline missed
    ],
)
def test_the_evaluator_charges_the_scaled_decision_time_and_names_the_machine(
    tmp_path, monkeypatch: pytest.MonkeyPatch, scale: float, decisions: int, misses: int, late: int
) -> None:
    """``--compute-scale`` end to end: each decision takes 50 ms on the run's clock, the scale
    multiplies it, and the records and the report show what the charge did."""
    import functools
    import json

    import evaluation.run.spec

    # the one place a run makes its charge, which reaches the episode runner as it is
    monkeypatch.setattr(
        evaluation.run.spec, "ComputeCharge", functools.partial(ComputeCharge, clock=_Ticks(0.05))
    )
    code = ev.main(
        [
            "--env", "KoopNav-TargetReaching-v0", "--maps", "map1", "--episodes", "1",
            "--controllers", "consensus", "--env-kwargs", "max_episode_steps=20", "--workers", "1",
            "--compute-scale", str(scale), "--out", str(tmp_path), "--quiet",
        ]
    )  # fmt: skip
    assert code == 0
    doc = json.loads((tmp_path / "results.json").read_text())
    assert doc["config"]["compute"]["scale"] == scale and "cores" in doc["config"]["compute"]["machine"]
    (record,) = doc["episodes"]
    assert record["compute_scale"] == scale and record["steps"] == 20
    assert (record["decisions"], record["deadline_misses"], record["late_periods"]) == (
        decisions,
        misses,
        late,
    )
    text = (tmp_path / "results.md").read_text()
    assert f"| {misses} ({100 * misses // decisions}%) |" in text
    assert f"every decision's wall time, times {scale:.1f}, was charged to the robots" in text


@pytest.mark.parametrize("value", ["0", "-1", "nan", "5000"])
def test_a_bad_compute_scale_is_refused_before_any_work(tmp_path, capsys, value: str) -> None:
    code = ev.main(["--episodes", "1", "--compute-scale", value, "--out", str(tmp_path / "run"), "--quiet"])
    assert code == 2 and "compute_scale" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
