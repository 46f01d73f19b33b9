"""The slip settings of a run as text: the one reader of ``"high"``, ``"0,0.1,0.2"`` and
``["nominal,high", "0,0.1,0.2"]`` for the command line, run specs and episode cells.

A cell's slip is a setting name of :data:`koopman_envs.params.SLIP_NAMES` or comma-separated
per-robot lambdas; :func:`slip_value` turns it into what the env takes (the env's own checks then
apply: :func:`koopman_envs.params.slip_lambdas`). A listed schedule of levels over time is an env
keyword only, not a cell.
"""

from __future__ import annotations

from koopman_envs.checks import choice_message
from koopman_envs.params import SLIP_NAMES

__all__ = ["is_lambda", "slip_value", "split_slips"]


def is_lambda(text: str) -> bool:
    """Whether one comma-separated piece of a slip text is a number (a per-robot lambda) rather
    than a setting name: the one rule for reading ``"0,0.1,0.2"`` (cells and the CLI alike)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def slip_value(slip: str) -> str | list[float]:
    """A slip cell name as the env takes it: a setting name, ``"random"``, ``"drift"`` or per-robot
    lambdas (a listed schedule of levels over time is an env keyword only, not a cell)."""
    if slip in SLIP_NAMES:
        return slip
    pieces = slip.split(",")
    if not all(is_lambda(piece) for piece in pieces):
        raise ValueError(choice_message("slip", slip, SLIP_NAMES, " nor comma-separated per-robot lambdas"))
    return [float(piece) for piece in pieces]


def split_slips(words: list[str] | None) -> list[str] | None:
    """Slip words -> settings: names split at commas, a run of numbers stays one lambda vector.

    ``["nominal,high", "0,0.1,0.2"]`` -> ``["nominal", "high", "0,0.1,0.2"]``.
    """
    if words is None:
        return None
    slips: list[str] = []
    for word in words:
        numbers: list[str] = []
        for piece in [p.strip() for p in word.split(",") if p.strip()]:
            if is_lambda(piece):
                numbers.append(piece)
                continue
            if numbers:
                slips.append(",".join(numbers))
                numbers = []
            slips.append(piece)
        if numbers:
            slips.append(",".join(numbers))
    return slips
