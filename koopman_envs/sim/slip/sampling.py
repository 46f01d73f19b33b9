"""Per-environment slip sampling with block-buffered draws.

Each environment owns one ``numpy.random.Generator``; slip coefficients are drawn from it only.
Drawing a block of periods at once is what makes 1024 environments cheap to step, and because a
single environment uses exactly the same block logic, sub-environment ``i`` of a batch consumes
its generator exactly as a lone environment with the same seed does.

The blocks hold unit-mean draws; the step scales them by each robot's slip mean of the period.
That mean may come from slip zones (:mod:`koopman_envs.sim.slip.zones`) or change with a schedule
(:mod:`koopman_envs.sim.slip.schedule`), but the unit draws are the same stream whatever the
means are: zones never change what is drawn, only how it is scaled.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import RANDOM_SLIP_MAX

__all__ = ["SlipSampler", "draw_random_lambdas"]


def draw_random_lambdas(rng: np.random.Generator, n_robots: int) -> NDArray[np.float64]:
    """One episode's slip means under ``slip="random"``: robot 1 slip-free, the others spaced linearly.

    Draws exactly one uniform number from ``rng`` (none for a single robot).
    """
    top = rng.uniform(0.0, RANDOM_SLIP_MAX)
    return np.zeros(1) if n_robots == 1 else np.linspace(0.0, top, n_robots)


class SlipSampler:
    """Slip coefficients alpha, beta, gamma ~ Exponential(mean lambda_i), i.i.d. per robot and period.

    Parameters
    ----------
    num_envs : int
        Batch size K.
    n_robots : int
        Robots per environment N.
    block : int
        Periods drawn per generator call (ours: 128).
    """

    def __init__(self, num_envs: int, n_robots: int, block: int = 128) -> None:
        self.block = int(block)
        self.n_robots = int(n_robots)
        self.rngs: list[np.random.Generator | None] = [None] * num_envs
        #: (K, N) base slip mean of every robot: the setting, the episode's draw or the schedule's
        #: level of the coming period (slip zones act on top of it)
        self.lambdas = np.zeros((num_envs, n_robots))
        #: (K, block, 3, N) unit-mean draws; one period of env k is a (3, N) slab: alpha, beta, gamma rows
        self.unit = np.zeros((num_envs, self.block, 3, n_robots))
        #: (K,) next unread period of each environment's block
        self.cursor = np.full(num_envs, self.block, dtype=np.int64)
        # periods every env can still draw from its buffer; 0 forces the refill check
        self._headroom = 0

    def reset_env(self, index: int, rng: np.random.Generator, lambdas: NDArray[np.float64]) -> None:
        """Attach env ``index`` to its generator and slip means.

        Draws already buffered from the same generator carry over into the next episode (an
        auto-reset wastes nothing); a new generator, as after ``reset(seed=...)``, drops them.
        """
        if self.rngs[index] is not rng:
            self.rngs[index] = rng
            self.cursor[index] = self.block
            self._headroom = 0
        self.lambdas[index] = lambdas

    def prepare(self, active: NDArray[np.bool_] | None = None) -> None:
        """Refill the block of every environment about to step past its buffer.

        Call once before each step; the step itself then reads row ``cursor[k]`` of
        :attr:`unit` for every active environment k, scales it by the robots' slip means
        (:attr:`lambdas`, the base levels, or what the slip zones make of them) and advances
        ``cursor[k]`` (see :func:`koopman_envs.sim.dynamics.advance_teams`).

        Parameters
        ----------
        active : ndarray of bool, shape (K,), optional
            Environments that actually step; the others consume nothing.
        """
        if active is None and self._headroom > 0:
            self._headroom -= 1
            return
        need = self.cursor >= self.block
        if active is not None:
            need &= active
        for k in np.flatnonzero(need):
            rng = self.rngs[k]
            if rng is None:
                raise RuntimeError(f"environment {k} was stepped before reset()")
            rng.standard_exponential(out=self.unit[k])
            self.cursor[k] = 0
        # rows every environment can still read after this step, counted conservatively
        self._headroom = int(self.block - self.cursor.max()) - 1
