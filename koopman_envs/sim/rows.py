"""Which environments of a batch an operation touches, as the cheapest numpy index."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["rows_index"]


def rows_index(rows: Sequence[int]) -> slice | NDArray[np.int64]:
    """``rows`` (ascending or not) as an index of the batch axis: a slice when they are
    consecutive and ascending (one environment, or every one: a view, no gather or scatter of
    numpy's advanced indexing, which costs microseconds per array at a reset), else an array.
    Either selects the same rows in the same order, so writes through it are the same."""
    if len(rows) and all(b - a == 1 for a, b in zip(rows, rows[1:])):
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return np.asarray(rows, dtype=np.int64)
