"""Checks with one wording everywhere: ``name=value must be an integer >= 1``, and the commands.

Every public function and keyword of KoopNav checks its numbers before any work starts; these
helpers make the messages the same across the package, so that a user (and a test) reads the
bad value and what is allowed in one form.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from numbers import Integral, Real
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.suggest import did_you_mean

__all__ = ["check_choice", "check_commands", "check_flag", "check_int", "check_number", "checked_options"]


def check_choice(name: str, value: Any, allowed: Iterable[Any], also: str = "") -> Any:
    """``value`` if it is one of ``allowed``, else ``ValueError``: ``name=value is not one of
    [...]`` with ``also`` (e.g. ``" or None"``) and, for a near miss, a did-you-mean; the one
    wording of every choice check in KoopNav.

    Parameters
    ----------
    name : str
        The option's name, as the user wrote it (e.g. ``"movers.behaviour"``).
    value : object
        The value given.
    allowed : iterable
        The allowed values, in the order the message lists them.
    also : str
        Appended after the list (what else is allowed, or a hint).
    """
    options = list(allowed)
    try:
        ok = any(value == option and type(value) is not bool for option in options)
    except (TypeError, ValueError):  # an array or another value without a plain ==
        ok = False
    if ok:
        return value
    words = [option for option in options if isinstance(option, str)]
    raise ValueError(f"{name}={value!r} is not one of {options}{also}{did_you_mean(value, words)}")


def checked_options(
    cls: Any, what: str, prefix: str, options: dict[str, Any], check: Callable[[str, Any, str], None]
) -> Any:
    """``cls(**options)`` for an options dataclass, after every key is checked: an unknown one is a
    ``ValueError`` naming it as given (with ``prefix``, e.g. ``"safety_"``), with a did-you-mean and
    the allowed keys; a known one goes through ``check(key, value, prefix)``. The one routine behind
    the option dataclasses' ``from_options``."""
    import dataclasses

    allowed = [f.name for f in dataclasses.fields(cls)]
    for key, value in options.items():
        if key not in allowed:
            raise ValueError(
                f"unknown {what} option {prefix + key!r}{did_you_mean(prefix + key, [prefix + a for a in allowed])}; "
                f"allowed: {[prefix + a for a in allowed]}"
            )
        check(key, value, prefix)
    return cls(**options)


def check_int(
    name: str, value: Any, minimum: int | None = None, *, maximum: int | None = None, note: str = ""
) -> int:
    """``value`` as an ``int``, or ``ValueError`` naming it and the allowed range.

    Parameters
    ----------
    name : str
        The argument's name, as the user wrote it.
    value : object
        The value to check: an integer (Python or NumPy; ``bool`` is refused).
    minimum : int, optional
        Smallest allowed value.
    maximum : int, optional
        Largest allowed value (the sizes' bounds, :data:`koopman_envs.params.LIMITS`): checked
        before the caller allocates anything of that size.
    note : str
        Appended to the message in parentheses (e.g. the unit).
    """
    ok = isinstance(value, Integral) and not isinstance(value, bool)
    if not ok or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        bounds = [
            f">= {minimum}" if minimum is not None else "",
            f"<= {maximum}" if maximum is not None else "",
        ]
        allowed = "an integer" + (" " if any(bounds) else "") + " and ".join(b for b in bounds if b)
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


def check_flag(name: str, value: Any) -> bool:
    """``value`` as a ``bool`` (``True``/``False``, or numpy's), or ``ValueError`` naming it."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ValueError(f"{name}={value!r} is not a flag; allowed: true or false")


def check_commands(commands: Any, num_envs: int, n_robots: int) -> NDArray[np.float64]:
    """A batch of joint commands as float64 (K, N, 2): (v [m/s], omega [rad/s]) per robot.

    Also accepted: (K, 2N), and for K = 1 (2N,) or (N, 2).

    Raises
    ------
    ValueError
        Another shape, or a NaN or infinite entry (named by its index).
    """
    k, n = num_envs, n_robots
    arr = np.asarray(commands, dtype=np.float64)
    if arr.shape != (k, n, 2):
        if arr.size == k * n * 2 and arr.shape in ((k, 2 * n), (2 * n,), (n, 2)):
            arr = arr.reshape(k, n, 2)
        else:
            allowed = f"({2 * n},) or ({n}, 2)" if k == 1 else f"({k}, {2 * n}) or ({k}, {n}, 2)"
            raise ValueError(
                f"action has shape {arr.shape}; expected {allowed}: (v [m/s], omega [rad/s]) per robot"
            )
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0].tolist()
        raise ValueError(
            f"action contains a non-finite value at index {bad} ({arr[tuple(bad)]}); "
            "allowed: finite (v, omega), saturated to the actuation limits"
        )
    return arr
