"""Many episodes at once: one episode in every sub-environment of the native vector env, each
measured as :func:`~koopman_envs.episodes.single.run_episode` measures a lone one.

A sub-environment seeded ``s`` is the lone env seeded ``s`` (the vector env's per-environment
generators; tests/test_determinism.py), and its row of the vector env's info is the lone env's
info (:func:`info_row`), so a policy that acts on the same observations gives the same episode,
bit for bit (tests/test_batch_episodes.py). The environments step together in the compiled
kernels; a controller class that decides for many teams at once (``acts_in_batch``, its
``act_many``: the learned policies' one forward pass) acts for all running environments in one
call, every other policy on its own environment's observation and info. The results stay those
of the per-episode path.

The vector env must run Gymnasium's ``"NextStep"`` autoreset (its default): the step that ends
an episode returns that episode's own last observation and info; an environment whose episode
has ended keeps stepping (its next episode is not recorded, and its generator is its own, so it
changes nothing for the others). Compute-aware charging and rendering are the one-env runner's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from koopman_envs.episodes.single import EpisodeRecorder, EpisodeResult, Policy

__all__ = ["info_row", "info_rows", "run_episodes_in_batch"]


def info_row(info: dict[str, Any], index: int) -> dict[str, Any]:
    """Sub-environment ``index``'s info as the lone env gives it: its row of every array (per
    environment flags and counters as Python scalars), without the vector env's ``_key`` masks."""
    row = {}
    for key, value in info.items():
        if key.startswith("_") or key in ("final_obs", "final_info"):
            continue
        value = np.asarray(value)
        row[key] = value[index].item() if value.ndim == 1 else value[index]
    return row


def info_rows(info: dict[str, Any], indices: Sequence[int]) -> list[dict[str, Any]]:
    """:func:`info_row` of each of ``indices``, each array split once for all of them."""
    columns = {}
    for key, value in info.items():
        if key.startswith("_") or key in ("final_obs", "final_info"):
            continue
        value = np.asarray(value)
        columns[key] = value.tolist() if value.ndim == 1 else value  # Python scalars, as .item()
    return [{key: column[i] for key, column in columns.items()} for i in indices]


def _act_many(policies: Sequence[Policy]) -> Any:
    """The policies' common ``act_many`` (a controller class deciding for many teams at once,
    :meth:`controllers.base.BaseController.act_many`), or None: each policy acts alone."""
    kinds = {type(policy) for policy in policies}
    if len(kinds) != 1:
        return None
    kind = kinds.pop()
    return getattr(kind, "act_many", None) if getattr(kind, "acts_in_batch", False) else None


def run_episodes_in_batch(
    venv: Any, policies: Sequence[Policy], seeds: Sequence[int], options: dict[str, Any] | None = None
) -> list[EpisodeResult]:
    """Run one episode in every sub-environment of ``venv``, sub-environment ``i`` seeded
    ``seeds[i]`` and driven by ``policies[i]`` (reset with its scenario and seed first, as
    :func:`~koopman_envs.episodes.single.run_episode` does), and measure each.

    Parameters
    ----------
    venv : KoopNavVectorEnv
        ``gym.make_vec(env_id, num_envs=K, ...)`` of a KoopNav id, NextStep autoreset.
    policies : sequence of Policy
        One per sub-environment (their own objects: a controller keeps state over an episode).
    seeds : sequence of int
        One per sub-environment.
    options : dict, optional
        The vector env's reset options (e.g. ``{"layout": [i0, i1, ...]}``, one suite layout per
        sub-environment; ``docs/reset_options.md``).

    Returns
    -------
    list of EpisodeResult
        In the order of the sub-environments, equal to ``run_episode(gym.make(env_id, ...),
        policies[i], seed=seeds[i])``.
    """
    base = venv.unwrapped
    k = int(base.num_envs)
    if len(policies) != k or len(seeds) != k:
        raise ValueError(
            f"{len(policies)} policies and {len(seeds)} seeds for {k} environments: one of each per environment"
        )
    if str(getattr(base.autoreset_mode, "value", base.autoreset_mode)) != "NextStep":
        raise ValueError(
            f"autoreset_mode={base.autoreset_mode!r}: run_episodes_in_batch needs 'NextStep' (the default), "
            "whose ending step returns the episode's own last info"
        )
    obs, info = venv.reset(seed=[int(s) for s in seeds], options=options)
    recorders = []
    for i, policy in enumerate(policies):
        scenario = base.scenario(i)
        reset = getattr(policy, "reset", None)
        if callable(reset):
            reset(scenario, seed=int(seeds[i]))
        recorders.append(EpisodeRecorder(scenario, info_row(info, i)))
    actions = np.zeros(venv.action_space.shape)
    results: list[EpisodeResult | None] = [None] * k
    running = list(range(k))
    act_many = _act_many(policies)
    rows = info_rows(info, range(k))  # each running environment's info, as a lone env's
    while running:
        if act_many is not None:
            decided = act_many(
                [policies[i] for i in running], [obs[i] for i in running], [rows[i] for i in running]
            )
        else:
            decided = [policies[i].act(obs[i], rows[i]) for i in running]
        commands = {}
        for i, command in zip(running, decided, strict=True):
            commands[i] = np.asarray(command, dtype=np.float64)
            actions[i] = commands[i].reshape(-1)
        obs, reward, terminated, truncated, info = venv.step(actions)
        for i, row in zip(running, info_rows(info, running), strict=True):
            rows[i] = row
            recorders[i].record(commands[i].reshape(-1, 2), float(reward[i]), row)
            if terminated[i] or truncated[i]:
                result = recorders[i].result(row, bool(truncated[i] and not terminated[i]))
                result.decisions = recorders[i].steps
                results[i] = result
        running = [i for i in running if results[i] is None]
    return [result for result in results if result is not None]
