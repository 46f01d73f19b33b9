"""The tuning objective and the expected best score of n configurations (Dodge et al. 2019)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from koopman_envs.checks import check_int
from koopman_envs.params import PARAMS

#: the objective, as the header records it
OBJECTIVE = (
    "score = S/n + (1 - u)/(n + 1) if S > 0 else 0: S successes of n validation episodes, u the mean "
    "over the successes of time to goal / the episode's time limit (max_episode_steps x T_s)"
)


@dataclass(frozen=True)
class Score:
    """A configuration's result on its episodes (:func:`objective`)."""

    value: float
    successes: int
    episodes: int
    errors: int
    mean_time_to_goal: float | None


def objective(records: Sequence[Mapping[str, Any]]) -> Score:
    """The tuning objective of a configuration's episode records.

    ``score = S / n + (1 - u) / (n + 1)`` when S > 0, else 0: S successes of n episodes, u the
    mean over the successes of t_i / T_i, t_i an episode's time to goal [s] and T_i its time
    limit (``max_episode_steps`` x T_s [s]), each ratio clipped to [0, 1]. Normalised per episode,
    so that the two tasks' episodes weigh alike when their limits differ.

    The success rate S / n comes first; the tie-break is in [0, 1 / (n + 1)], less than the
    1 / n between two success counts, so a faster configuration wins only among equal success.
    An episode that raised counts as a failure (and in ``errors``).

    Parameters
    ----------
    records : sequence of dict
        Episode records (``status``, ``success``, ``time_to_goal``, ``max_episode_steps``).
    """
    n = len(records)
    if n == 0:
        raise ValueError("objective: no episodes to score; allowed: at least one record")
    won = [r for r in records if r.get("success") and r.get("time_to_goal") is not None]
    successes = sum(1 for r in records if r.get("success"))
    errors = sum(1 for r in records if r.get("status") == "error")
    times = [float(r["time_to_goal"]) for r in won]
    shares = [min(max(t / (int(r["max_episode_steps"]) * PARAMS.dt), 0.0), 1.0) for t, r in zip(times, won)]
    value = successes / n
    if successes and shares:
        value += (1.0 - float(np.mean(shares))) / (n + 1)
    return Score(value, successes, n, errors, float(np.mean(times)) if times else None)


def expected_max(scores: Sequence[float], n: int) -> float:
    """The expected best score of ``n`` configurations drawn from a study's trials (Dodge et al.
    2019, "Show Your Work", eq. 1 with the empirical distribution).

    With the N trial scores sorted, v_(1) <= ... <= v_(N), and F(v) = #{i : v_i <= v} / N their
    empirical distribution, n configurations drawn independently from it (with replacement)
    have a best score of distribution F(v)^n, so

        E[max of n] = sum_{i=1..N} v_(i) * ((i / N)^n - ((i - 1) / N)^n).

    n = 1 gives the mean of the scores; as n grows it rises to their maximum.

    Parameters
    ----------
    scores : sequence of float
        The N >= 1 trial scores.
    n : int
        Configurations drawn (>= 1).
    """
    check_int("n", n, 1)
    values = np.sort(np.asarray(scores, dtype=np.float64))
    if values.size == 0:
        raise ValueError("expected_max: no scores; allowed: at least one trial score")
    cdf = np.arange(values.size + 1, dtype=np.float64) / values.size
    weights = cdf[1:] ** n - cdf[:-1] ** n
    return float(np.dot(values, weights))


def expected_max_curve(scores: Sequence[float]) -> list[float]:
    """:func:`expected_max` for n = 1 .. N (N = ``len(scores)``)."""
    return [expected_max(scores, n) for n in range(1, len(scores) + 1)]
