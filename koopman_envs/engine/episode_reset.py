"""New episodes for a batch of environments: the engine's reset, one pass for many.

A vector env resets the environments that end in the same step together
(:meth:`~koopman_envs.engine.engine.NavigationEngine.reset_envs`). Each environment still
draws only from its own generator, in the order a lone environment draws (the layout, the start
noise, the slip level, then the children of the perception, the movers, the people tracker
and the physics plant's frictions), so sub-environment i of a batch reproduces a lone environment with the same seed; what
the batch shares is the bookkeeping: the episode's arrays are written once for all of them, and
the movers are placed in one compiled call (:meth:`~koopman_envs.sim.movers.MoverField.reset_envs`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from koopman_envs.engine.episode_layout import episode_layout
from koopman_envs.reset_options import ResetOptions
from koopman_envs.sim.rows import rows_index
from koopman_envs.sim.slip import draw_random_lambdas

__all__ = ["reset_episodes"]

_NO_OPTIONS = ResetOptions()


def reset_episodes(
    engine: Any,
    rows: Sequence[int],
    rngs: Sequence[np.random.Generator],
    options: Sequence[ResetOptions | None] | None = None,
) -> None:
    """Start a new episode in each environment of ``rows`` of ``engine`` (a
    :class:`~koopman_envs.engine.engine.NavigationEngine`, which calls this: typed ``Any`` so
    that the two modules do not import each other), environment ``rows[b]`` drawing only from
    ``rngs[b]`` with ``options[b]`` (default: the map's starts and targets).

    Every layout is drawn and checked before anything changes, so a rejected option leaves
    every environment of the batch in its previous episode.

    Raises
    ------
    ValueError
        A start pose or target of ``options`` that is outside the workspace, overlaps an
        obstacle or another robot's.
    """
    cfg = engine.config
    n = cfg.n_robots
    rows = [int(index) for index in rows]
    opts = [_NO_OPTIONS] * len(rows) if options is None else [o or _NO_OPTIONS for o in options]
    layouts = [episode_layout(cfg, engine.maps[i], rng, o) for i, rng, o in zip(rows, rngs, opts)]
    for index, layout in zip(rows, layouts):
        if layout.spec is not engine.maps[index]:
            engine._set_map(index, layout.spec)
    where = rows_index(rows)
    starts = np.array([layout.starts for layout in layouts]).reshape(-1, n, 3)
    targets = np.array([layout.targets for layout in layouts]).reshape(-1, n, 3)
    engine.target[where] = targets.transpose(0, 2, 1)
    # each team's formation_offsets(targets): its targets relative to its leader's
    engine.offset[where] = (targets[:, :, :2] - targets[:, :1, :2]).transpose(0, 2, 1)
    engine.starts[where] = starts
    engine.nominal_starts[where] = [
        layout.spec.starts[:n] if o.start_poses is None else o.start_poses for layout, o in zip(layouts, opts)
    ]
    engine.state[where] = starts.transpose(0, 2, 1)
    engine.settled[where] = 0
    engine.elapsed[where] = 0
    engine.collision[where] = 0
    engine.success[where] = False
    dx = engine.target[where, 0] - engine.state[where, 0]
    dy = engine.target[where, 1] - engine.state[where, 1]
    engine.distances[where] = np.sqrt(dx * dx + dy * dy)  # the formula of FeatureBuilder
    random_slip = cfg.random_slip
    for index, rng in zip(rows, rngs):
        if engine.slip_clock is not None:
            # the last draws of a reset (drift only), so that every other setting draws as before
            lambdas = engine.slip_clock.reset_env(index, rng)
        else:
            lambdas = draw_random_lambdas(rng, n) if random_slip else cfg.lambdas
        engine.slip.reset_env(index, rng, lambdas)
        if engine.perception is not None:  # draws from a child of rng: the env's own stream is untouched
            engine.perception.reset_env(index, rng)  # its first readings: at the next features() or step()
    if engine.movers is not None:  # another child of rng: placed clear of this episode's starts and targets
        obstacles = [layout.spec.obstacles for layout in layouts]
        engine.movers.reset_envs(rows, list(rngs), obstacles, starts, targets, float(cfg.robot_radius[0]))
    if engine.mover_tracker is not None:  # another child of rng: every earlier stream is as before
        for index, rng in zip(rows, rngs):
            engine.mover_tracker.reset_env(index, rng)
    if engine.physics is not None:  # the last child of rng: the episode's frictions
        for index, rng, layout, start in zip(rows, rngs, layouts, starts):
            engine.physics.reset_env(index, rng, start, layout.spec.obstacles, layout.spec.slip_zones)
