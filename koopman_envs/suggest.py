"""Did-you-mean hints for names that are not among the allowed ones (as Gymnasium's registry gives):
the one helper every error message of the package uses."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = ["closest", "did_you_mean"]


def closest(name: object, allowed: Iterable[str]) -> str | None:
    """The allowed name closest to ``name``, or None.

    The same name in another case first (``'HARSH'`` -> ``'harsh'``), then difflib's closest
    match (ratio cut-off 0.6) compared without case: difflib's ratio alone is case-sensitive, so
    an upper-case name matched nothing.
    """
    if not isinstance(name, str):
        return None
    folded: dict[str, str] = {}  # case-folded -> the first allowed name that folds to it
    for choice in allowed:
        if isinstance(choice, str):
            folded.setdefault(choice.casefold(), choice)
    key = name.casefold()
    if key in folded:
        return folded[key]
    close = difflib.get_close_matches(key, list(folded), n=1)
    return folded[close[0]] if close else None


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
