"""New episodes: where each starts, how a batch of environments is reset, and what a
model-based controller is told of it.

**The layout.** A reset of the engine first decides the episode's layout
(:func:`episode_layout`), then installs it. The decision draws from the reset's generator in the
one order a seed fixes: a new layout with ``map="random"``
(:func:`~koopman_envs.sim.maps.generator.generate_random_map`) or a layout index with
``map="suite:<name>/<split>"`` (one ``rng.integers`` draw, made even when ``options["layout"]``
picks the layout, so that every later draw is the same either way), then the ``start_noise``
perturbation when it is asked for (:func:`~koopman_envs.sim.starts.perturbed_starts`), nothing
else. ``reset(options=...)`` replacements (:class:`~koopman_envs.settings.reset_options.ResetOptions`) are
checked against the episode's map before anything changes.

**The reset, one pass for many** (:func:`reset_episodes`). A vector env resets the environments
that end in the same step together
(:meth:`~koopman_envs.engine.engine.NavigationEngine.reset_envs`). Each environment still draws
only from its own generator, in the order a lone environment draws (the layout, the start noise,
the slip level, then the children of the perception, the movers, the people tracker and the
physics plant's frictions), so sub-environment i of a batch reproduces a lone environment with
the same seed; what the batch shares is the bookkeeping: the episode's arrays are written once
for all of them, and the movers are placed in one compiled call
(:meth:`~koopman_envs.sim.movers.field.MoverField.reset_envs`).

**The scenario** (:func:`engine_scenario`): what a model-based controller may know of its
episode (:class:`~koopman_envs.scenario.Scenario`), from the episode's layout and the config.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from koopman_envs.engine.config import EngineConfig
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario
from koopman_envs.settings.reset_options import ResetOptions
from koopman_envs.sim.maps.generator import generate_random_map
from koopman_envs.sim.maps.map_spec import MapSpec
from koopman_envs.sim.rows import rows_index
from koopman_envs.sim.slip.sampling import draw_random_lambdas
from koopman_envs.sim.starts import perturbed_starts

__all__ = ["EpisodeLayout", "engine_scenario", "episode_layout", "reset_episodes"]

#: no replacements: the map's starts and targets
_NO_OPTIONS = ResetOptions()


class EpisodeLayout(NamedTuple):
    """The map, start poses and targets of one new episode (N robots)."""

    spec: MapSpec
    starts: NDArray[np.float64]  # (N, 3): x [m], y [m], heading [rad]
    targets: NDArray[np.float64]  # (N, 3)


def episode_layout(
    config: EngineConfig,
    current: MapSpec | None,
    rng: np.random.Generator,
    options: ResetOptions,
) -> EpisodeLayout:
    """The layout of an environment's next episode, drawing only from ``rng``.

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    current : MapSpec or None
        The environment's map now (the fixed map of ``config``; ignored with ``map="random"``,
        which draws a new one).
    rng : numpy.random.Generator
        The environment's generator: the random layout's draws, then the start noise's.
    options : ResetOptions
        Start poses and/or targets replacing the map's for this episode; the suite layout to run.

    Returns
    -------
    EpisodeLayout
        The episode's map, start poses (the options', the map's perturbed by ``start_noise``, or
        the map's) and targets (the options' or the map's).

    Raises
    ------
    ValueError
        A start pose or target of ``options`` that is outside the workspace, overlaps an
        obstacle or another robot's; a ``layout`` outside the suite, or without a suite map.
    """
    n = config.n_robots
    radius = float(config.robot_radius[0])
    spec = current
    if config.suite is not None:
        drawn = int(rng.integers(len(config.suite)))
        spec = config.suite.layout(drawn if options.layout is None else options.layout).spec
    elif options.layout is not None:
        raise ValueError(
            f"options['layout']={options.layout!r} needs a suite map; this env's map is {config.map_name!r}; "
            "allowed: map='suite:<name>/<split>' (koopman_envs.suites), or no 'layout' option"
        )
    elif config.map_spec is None:
        spec = generate_random_map(rng, n, config.random_map, radius)
    # with a fixed map, the engine installed it in every environment (and nothing removes it)
    assert spec is not None
    targets = spec.targets[:n] if options.targets is None else options.targets
    if options.targets is not None:
        _check_placement(spec, targets, "targets", radius)
    if options.start_poses is not None:
        _check_placement(spec, options.start_poses, "start_poses", radius)
        starts = options.start_poses
    elif config.start_noise > 0:
        # the noise is drawn after the map and before the slip level, and only when asked
        # for, so that start_noise=0 consumes nothing and replays earlier rollouts bit for bit
        starts = perturbed_starts(spec, rng, n, config.start_noise, radius)
    else:
        starts = spec.starts[:n]
    return EpisodeLayout(spec, starts, targets)


def _check_placement(spec: MapSpec, poses: NDArray[np.float64], key: str, radius: float) -> None:
    """Raise ValueError naming ``options[key]`` if the team cannot stand at ``poses`` on ``spec``."""
    label = "start" if key == "start_poses" else "target"
    problem = spec.pose_problem(poses, radius, PARAMS.workspace, label)
    if problem is not None:
        raise ValueError(
            f"options[{key!r}]: {problem} (map {spec.name!r}); allowed: (x, y, heading) rows whose "
            f"robot discs of radius {radius} lie inside the workspace {PARAMS.workspace}, clear of "
            "every obstacle and of each other"
        )


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


def engine_scenario(
    config: EngineConfig,
    spec: MapSpec | None,
    obstacles: NDArray[np.float64],
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    offsets: NDArray[np.float64],
    settle_steps: int,
) -> Scenario:
    """The scenario of one environment: its map ``spec``, obstacles (M, 3), planned starts
    (N, 3), targets (3, N) and formation offsets (2, N) as the engine holds them.

    Raises
    ------
    RuntimeError
        The environment has not been reset (``spec`` is None).
    """
    if spec is None:
        raise RuntimeError("call reset() before reading the scenario")
    layout = config.observation_layout
    return Scenario(
        task=config.task.name,
        map_name=spec.name,
        n_robots=config.n_robots,
        obstacles=obstacles.copy(),
        robot_radius=config.robot_radius.copy(),
        starts=starts.copy(),
        targets=targets.T.copy(),
        formation_offsets=offsets.T.copy(),
        leader=0,
        v_max=PARAMS.v_max,
        omega_max=PARAMS.omega_max,
        workspace=PARAMS.workspace,
        dt=PARAMS.dt,
        goal_tolerance=config.goal_tolerance,
        settle_steps=settle_steps,
        lidar_beams=layout.beams,
        message_ages=layout.comm,
        n_movers=config.movers.count,
        mover_radius=config.movers.radius,
        mover_slots=layout.movers,
        observation_layout=layout,
        **config.lidar_datasheet,
    )
