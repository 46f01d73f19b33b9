"""The memory of a batched engine, bounded before it is allocated.

Every env keyword is bounded on its own (:data:`~koopman_envs.params.LIMITS`), but a batch
multiplies them: :func:`engine_array_bytes` estimates from above the bytes of the arrays a
:class:`~koopman_envs.engine.engine.NavigationEngine` of a config holds and builds in a step, from the
settings alone, and :func:`check_engine_memory` refuses a batch over ``LIMITS.engine_bytes``
naming what to reduce. The engine runs the check first thing in its constructor.
"""

from __future__ import annotations

import numpy as np

from koopman_envs.engine.config import EngineConfig
from koopman_envs.params import LIMITS
from koopman_envs.sim.mover_motion import DRAW_SIZE
from koopman_envs.sim.perception import BLOCK_NUMBERS
from koopman_envs.sim.physics.model import world_bytes

__all__ = ["check_engine_memory", "engine_array_bytes"]


def engine_array_bytes(config: EngineConfig, num_envs: int) -> int:
    """An estimate from above of the bytes of the arrays a
    :class:`~koopman_envs.engine.engine.NavigationEngine` of
    ``num_envs`` environments of ``config`` holds and builds in a step, computed before any is
    allocated: every keyword is bounded on its own (:data:`~koopman_envs.params.LIMITS`), but
    their product over a batch is bounded here (``LIMITS.engine_bytes``).

    Each term is an array (or a step's copies of it) of the engine's parts, in 8-byte numbers
    unless said; the exact allocations are those parts' constructors.

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    num_envs : int
        Batch size K.

    Returns
    -------
    int
        Bytes [B], at least what the engine allocates.
    """
    n, m, k = config.n_robots, config.n_obstacles, int(num_envs)
    comm, movers, layout = config.comm, config.movers, config.observation_layout
    beams, width = layout.beams, layout.size
    words = (
        40 * n  # poses, targets, starts, offsets, distances and the step's copies of them
        + 3 * 128 * n  # the slip draws' block (SlipSampler: 128 periods)
        + n * (n + m)
        + 3 * m  # radius sums, obstacle discs
        + n * n  # the builder's message ages
        + 4 * n * width  # the features, their clipped copy, the observation and the info's
        + 6 * config.n_slip_zones * (n + 1)  # zone table
    )
    if config.perceives:
        numbers = 6 * n + n * (n - 1) + 2 * n * beams  # per period at most (Perception.__init__)
        block = int(np.clip(BLOCK_NUMBERS // max(1, numbers), 8, 256))
        words += (
            8 * n * n  # known poses, message ages, their info copies
            + 4 * n * beams  # readings, the exact scan, the info's copy
            + 5 * n * (comm.latency + 1)  # the radio's sent poses and positions
            + 2 * n * max(config.actuation_delay, 1)  # the command queue
            + block * numbers  # single-precision normals and uniforms: two halves of one block
        )
    if movers.active:
        c = movers.count
        words += max(4096, 8 * c * DRAW_SIZE) + 16 * c + 6 * n  # the uniforms' pool, states, goals, hits
    if config.plant == "mujoco":
        words += world_bytes(n, m) // 8  # every environment's MuJoCo model copy, data and arena
    return 8 * k * words


def check_engine_memory(config: EngineConfig, num_envs: int) -> None:
    """Refuse a batch whose arrays would exceed ``LIMITS.engine_bytes`` (before allocating).

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    num_envs : int
        Batch size K.

    Raises
    ------
    ValueError
        :func:`engine_array_bytes` is over the limit: naming the batch, the sizes that drive it,
        the estimate and the limit, and what to reduce.
    """
    need = engine_array_bytes(config, num_envs)
    if need > LIMITS.engine_bytes:
        per_env = need / num_envs / 2**20
        raise ValueError(
            f"num_envs={num_envs} environments of n_robots={config.n_robots} (lidar.beams="
            f"{0 if config.lidar is None else config.lidar.beams}, comm.latency={config.comm.latency}, "
            f"movers.count={config.movers.count}) need about {need / 2**30:.1f} GiB of arrays "
            f"({per_env:.1f} MiB each); the limit is {LIMITS.engine_bytes / 2**30:g} GiB "
            "(koopman_envs.params.LIMITS): use fewer environments, robots or lidar beams"
        )
