"""The values the tuner tries for one option of a controller (:class:`Search`).

A leaf module: the controllers' ``TUNABLE`` tables, :mod:`controllers.option_spec` and
:mod:`controllers.tuning.presets` import it, and it imports nothing of theirs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from koopman_envs.checks import Range

__all__ = ["Search"]


@dataclass(frozen=True)
class Search:
    """The values the tuner tries for one option: a numeric interval or a list of choices.

    Declared beside the option's :class:`~koopman_envs.checks.Range`, in the controller's
    ``TUNABLE`` table: the range says what the controller accepts, the search what is worth
    trying (``tests/test_tune.py`` checks that every search lies inside its range).

    Attributes
    ----------
    low, high : float, optional
        The interval searched (both ends included); None for a search over ``choices``.
    log : bool
        Sample uniformly in log(value) (gains and weights whose scale, not offset, matters).
    integer : bool
        Integers only.
    choices : tuple, optional
        The values tried instead of an interval (e.g. ``(True, False)`` for a flag).
    entries : int, optional
        For an option that is a tuple of numbers (a weight per input): one number is searched
        and given to every one of its ``entries`` entries, so that only the weight's scale is
        tuned, not the ratios between its entries.
    """

    low: float | None = None
    high: float | None = None
    log: bool = False
    integer: bool = False
    choices: tuple[Any, ...] | None = None
    entries: int | None = None

    def __post_init__(self) -> None:
        if self.choices is not None:
            if self.low is not None or self.high is not None or not self.choices:
                raise ValueError(f"{self!r}: give either a non-empty choices or low and high, not both")
            return
        if self.low is None or self.high is None or not self.low < self.high:
            raise ValueError(f"{self!r}: low and high must be numbers with low < high")
        if self.log and self.low <= 0:
            raise ValueError(f"{self!r}: a log search needs low > 0")
        if self.entries is not None and self.entries < 1:
            raise ValueError(f"{self!r}: entries must be an integer >= 1")

    def value(self, sampled: Any) -> Any:
        """The option's value for a sampled point (a tuple of ``entries`` equal numbers, or the
        point itself)."""
        return sampled if self.entries is None else tuple(sampled for _ in range(self.entries))

    def point(self, name: str, value: Any) -> Any:
        """The sampled point that gives option ``name`` its ``value`` (the inverse of
        :meth:`value`); ``ValueError`` naming it when the value is not a point of the search
        (a weight tuple of unequal entries, a number outside the interval, another choice)."""
        if self.entries is not None:
            if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(set(value)) != 1:
                raise ValueError(f"{name}={value!r} is not {self.entries} equal numbers, as {self} searches")
            value = value[0]
        if not self.contains(value):
            raise ValueError(f"{name}={value!r} is not in the searched {self}")
        return value

    def contains(self, value: Any) -> bool:
        """Whether ``value`` is a sampled point of this search."""
        if self.choices is not None:
            return any(value == c and type(value) is type(c) for c in self.choices)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        if self.integer and value != int(value):
            return False
        assert self.low is not None and self.high is not None  # __post_init__
        return bool(self.low <= value <= self.high)

    def check_within(self, name: str, bounds: Range | None, choices: Sequence[str] | None) -> None:
        """``ValueError`` naming option ``name`` when a searched value is one the option refuses:
        an end of the interval outside ``bounds`` (an integer search of a real option is fine,
        a real search of an integer option is not), or a choice outside ``choices``."""
        if self.choices is not None:
            bad = [c for c in self.choices if choices is not None and c not in choices]
            if bad:
                raise ValueError(f"{name}: searched choices {bad} are not among {list(choices or ())}")
            return
        if bounds is None:
            raise ValueError(f"{name}: a numeric search needs the option's declared Range")
        if bounds.integer and not self.integer:
            raise ValueError(f"{name}: the option takes integers ({bounds}); its search must be integer=True")
        assert self.low is not None and self.high is not None  # __post_init__
        for end in (self.low, self.high):
            try:
                bounds.check(name, int(end) if self.integer else end)
            except ValueError as exc:
                raise ValueError(f"{name}: the searched {self} leaves the option's range: {exc}") from None

    def __str__(self) -> str:
        """``[0.5, 5] log``, ``integers in [10, 40]``, ``{True, False}``, ``[0.01, 1] log, x2``."""
        if self.choices is not None:
            return "{" + ", ".join(repr(c) for c in self.choices) + "}"
        text = ("integers in " if self.integer else "") + f"[{self.low:g}, {self.high:g}]"
        text += " log" if self.log else ""
        return text + (", every entry" if self.entries is not None else "")
