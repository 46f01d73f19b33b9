"""The one episode runner: reset, the act/step loop, and the compute charge.

The evaluator, both demos, the benchmark scripts and the tests all run episodes through
:func:`run_episode`, so an outcome means the same thing everywhere. It needs nothing of a
controller but ``act(observation, info)`` (and calls ``reset(scenario, seed=...)`` when the
object has one: the episode's :class:`~koopman_envs.scenario.Scenario`, never the env, so that a
controller learns nothing at reset that the observed info does not tell it), so it lives beside
the environments and imports no controller. The per-episode metrics are measured by
:class:`~koopman_envs.episodes.metrics.EpisodeRecorder` (re-exported here with the result).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from koopman_envs.episodes.metrics import EpisodeRecorder, EpisodeResult, path_ratio, smallest_clearance
from koopman_envs.scenario import scenario_of

__all__ = [
    "ComputeCharge",
    "EpisodeRecorder",
    "EpisodeResult",
    "Policy",
    "path_ratio",
    "run_episode",
    "smallest_clearance",
]


class Policy(Protocol):
    """Anything that maps (observation, info) to a joint command (2N,)."""

    def act(self, observation: NDArray[np.float64], info: dict[str, Any]) -> NDArray[np.float64]: ...


@dataclass(frozen=True)
class ComputeCharge:
    """Compute-aware episodes: a controller's decision time is charged to its robots.

    The pose of period t is measured at its start; the decision computed from it takes L
    seconds (the CPU time ``act`` takes in this process, times ``scale``: a scale of 5 emulates a
    computer five times slower, a small ARM board beside the machine the run is on). CPU time
    rather than wall time, so that other processes on a shared machine (a second worker, a test
    run) do not lengthen a decision; threads a solver starts are summed, as if they ran on one
    core. The robots hold the last
    command applied until the period boundary after the decision is ready: a decision ready
    within ``grace`` seconds of the measurement acts in period t, as without the charge; one of
    L seconds otherwise acts from period t + ceil(L / dt). The controller decides again at the
    period its command starts to act (it was busy until then), so a decision of 250 ms at a
    100 ms period acts 3 periods late, every third period. A decision longer than the period
    misses its deadline (counted). Timing varies from run to run, so compute-aware episodes are
    not bit-reproducible; everything else about them is.

    Attributes
    ----------
    scale : float
        Factor on the measured decision time (> 0; 1: this machine).
    grace : float
        Decision time [s] within which a command still acts in the period it was computed for
        (the actuator's own input latency; default 1 ms).

    The third field, ``clock``, gives the seconds now (``time.process_time``, this process's CPU
    time; a test may give a clock of its own).
    """

    scale: float = 1.0
    grace: float = 1e-3
    clock: Callable[[], float] = time.process_time

    def periods_late(self, seconds: float, dt: float) -> int:
        """Periods until a decision of ``seconds`` (before the scale) acts."""
        charged = seconds * self.scale
        return 0 if charged <= self.grace else math.ceil(charged / dt - 1e-9)


def run_episode(
    env: Any,
    policy: Policy,
    *,
    seed: int | None = None,
    options: dict[str, Any] | None = None,
    render: bool = False,
    on_step: Callable[[int, NDArray[np.float64], dict[str, Any]], None] | None = None,
    compute: ComputeCharge | None = None,
) -> EpisodeResult:
    """Reset ``env``, drive it with ``policy`` until the episode ends, and measure it.

    Parameters
    ----------
    env : gymnasium.Env
        A KoopNav Gymnasium env (wrapped or not).
    policy : Policy
        Its ``reset(scenario, seed=seed)`` is called after ``env.reset`` when it has one, with
        the episode's scenario (the planned starts, the targets, the map's obstacles, limits).
    seed : int, optional
        Seed of ``env.reset`` (and handed to the policy).
    options : dict, optional
        ``env.reset`` options.
    render : bool
        Collect ``env.render()`` frames (the env needs ``render_mode="rgb_array"``).
    on_step : callable, optional
        ``on_step(step, action, info)`` after every step (for logging or recording).
    compute : ComputeCharge, optional
        Charge the controller's decision time to its robots (see :class:`ComputeCharge`);
        None (default): the env waits for the controller, as the paper's evaluation does.
    """
    obs, info = env.reset(seed=seed, options=options)
    scenario = scenario_of(env)
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset(scenario, seed=seed)
    recorder = EpisodeRecorder(scenario, info)
    frames = [env.render()] if render else []
    decider = _Decider(policy, compute, scenario.dt, scenario.n_robots)
    while True:
        action = decider.command(recorder.steps, obs, info)
        obs, reward, terminated, truncated, info = env.step(action.reshape(-1))
        recorder.record(action, float(reward), info)
        if render:
            frames.append(env.render())
        if on_step is not None:
            on_step(recorder.steps, action, info)
        if terminated or truncated:
            break
    result = recorder.result(info, bool(truncated and not terminated))
    result.decisions, result.deadline_misses = decider.decisions, decider.misses
    result.late_periods = decider.late / decider.decisions if decider.decisions else 0.0
    result.frames = frames
    return result


class _Decider:
    """When the controller decides and which command the robots hold (:class:`ComputeCharge`;
    without one, a decision every period that acts at once)."""

    def __init__(self, policy: Policy, compute: ComputeCharge | None, dt: float, n: int) -> None:
        self.policy, self.compute, self.dt = policy, compute, dt
        self.held = np.zeros((n, 2))
        self.pending: tuple[int, NDArray[np.float64]] | None = None
        self.next_decision = 0
        self.decisions = self.misses = self.late = 0

    def command(self, step: int, obs: Any, info: dict[str, Any]) -> NDArray[np.float64]:
        compute = self.compute
        if compute is None:
            self.decisions += 1
            return np.asarray(self.policy.act(obs, info), dtype=np.float64).reshape(self.held.shape)
        if self.pending is not None and self.pending[0] <= step:
            self.held, self.pending = self.pending[1], None
        if step >= self.next_decision:
            start = compute.clock()
            command = np.asarray(self.policy.act(obs, info), dtype=np.float64).reshape(self.held.shape)
            seconds = compute.clock() - start
            late = compute.periods_late(seconds, self.dt)
            self.decisions += 1
            self.late += late
            self.misses += seconds * compute.scale > self.dt
            if late == 0:
                self.held = command
            else:
                self.pending = (step + late, command)
            self.next_decision = step + max(late, 1)
        return self.held
