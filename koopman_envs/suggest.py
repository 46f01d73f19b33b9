"""Did-you-mean hints for names that are not among the allowed ones (as Gymnasium's registry gives):
the one helper every error message of the package uses."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = ["closest", "did_you_mean"]


def closest(name: object, allowed: Iterable[str]) -> str | None:
    """The allowed name closest to ``name`` (difflib's ratio, cut-off 0.6), or None."""
    if not isinstance(name, str):
        return None
    close = difflib.get_close_matches(name, list(allowed), n=1)
    return close[0] if close else None


def did_you_mean(name: object, allowed: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest allowed name, or ``""`` when none is close.

    Parameters
    ----------
    name : object
        The value that is not allowed (only a string can have a close match).
    allowed : iterable of str
        The allowed names.
    """
    match = closest(name, allowed)
    return f" (did you mean {match!r}?)" if match is not None else ""
