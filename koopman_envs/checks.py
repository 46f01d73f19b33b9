"""Number checks with one wording everywhere: ``name=value must be an integer >= 1``.

Every public function and keyword of KoopNav checks its numbers before any work starts; these
helpers make the messages the same across the package, so that a user (and a test) reads the
bad value and what is allowed in one form.
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any

__all__ = ["check_int", "check_number"]


def check_int(name: str, value: Any, minimum: int | None = None, *, note: str = "") -> int:
    """``value`` as an ``int``, or ``ValueError`` naming it and the allowed range.

    Parameters
    ----------
    name : str
        The argument's name, as the user wrote it.
    value : object
        The value to check: an integer (Python or NumPy; ``bool`` is refused).
    minimum : int, optional
        Smallest allowed value.
    note : str
        Appended to the message in parentheses (e.g. the unit).
    """
    ok = isinstance(value, Integral) and not isinstance(value, bool)
    if not ok or (minimum is not None and value < minimum):
        allowed = "an integer" + (f" >= {minimum}" if minimum is not None else "")
        raise ValueError(f"{name}={value!r} must be {allowed}" + (f" ({note})" if note else ""))
    return int(value)


def check_number(
    name: str,
    value: Any,
    *,
    above: float | None = None,
    at_least: float | None = None,
    at_most: float | None = None,
    note: str = "",
) -> float:
    """``value`` as a finite ``float``, or ``ValueError`` naming it and the allowed range.

    Parameters
    ----------
    name : str
        The argument's name, as the user wrote it.
    value : object
        A real number (``bool``, text, NaN and infinities are refused).
    above, at_least, at_most : float, optional
        Bounds: ``value > above``, ``value >= at_least``, ``value <= at_most``.
    note : str
        Appended to the message in parentheses (e.g. the unit).
    """
    bounds = [
        f"> {above}" if above is not None else "",
        f">= {at_least}" if at_least is not None else "",
        f"<= {at_most}" if at_most is not None else "",
    ]
    allowed = "a finite number" + "".join(f" {b}" for b in bounds if b)
    ok = isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        ok = not (
            (above is not None and value <= above)
            or (at_least is not None and value < at_least)
            or (at_most is not None and value > at_most)
        )
    if not ok:
        raise ValueError(f"{name}={value!r} must be {allowed}" + (f" ({note})" if note else ""))
    return float(value)
