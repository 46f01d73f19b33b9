"""Where a new episode starts: its map, its targets and its start poses.

A reset of the engine first decides the episode's layout, then installs it. This module is
that decision, and it draws from the reset's generator in the one order a seed fixes: a new
layout with ``map="random"`` (:func:`~koopman_envs.sim.random_maps.generate_random_map`) or a
layout index with ``map="suite:<name>/<split>"`` (one ``rng.integers`` draw, made even when
``options["layout"]`` picks the layout, so that every later draw is the same either way), then
the ``start_noise`` perturbation when it is asked for
(:func:`~koopman_envs.sim.starts.perturbed_starts`), nothing else. ``reset(options=...)``
replacements (:class:`~koopman_envs.reset_options.ResetOptions`) are checked against the
episode's map before anything changes.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from koopman_envs.engine.config import EngineConfig
from koopman_envs.params import PARAMS
from koopman_envs.reset_options import ResetOptions
from koopman_envs.sim.maps import MapSpec
from koopman_envs.sim.random_maps import generate_random_map
from koopman_envs.sim.starts import perturbed_starts

__all__ = ["EpisodeLayout", "episode_layout"]


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
