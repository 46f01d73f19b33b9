"""Did-you-mean hints for names that are not among the allowed ones (as Gymnasium's registry gives)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = ["did_you_mean"]


def did_you_mean(name: object, allowed: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest allowed name, or ``""`` when none is close.

    Parameters
    ----------
    name : object
        The value that is not allowed (only a string can have a close match).
    allowed : iterable of str
        The allowed names.
    """
    if not isinstance(name, str):
        return ""
    close = difflib.get_close_matches(name, list(allowed), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""
