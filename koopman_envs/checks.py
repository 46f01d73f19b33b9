"""Checks with one wording everywhere: ``name=value must be an integer >= 1``, and the commands.

Every public function and keyword of KoopNav checks its numbers before any work starts; these
helpers make the messages the same across the package, so that a user (and a test) reads the
bad value and what is allowed in one form. The did-you-mean hint for a name that is not among the
allowed ones (as Gymnasium's registry gives), :func:`did_you_mean`, is here too: every error
message of the package that names an allowed set uses it.
"""

from __future__ import annotations

import difflib
import functools
import importlib
import itertools
import json
import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from numbers import Integral, Real
from types import ModuleType
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "CLI_JSON_CHARS",
    "MAX_NUMBER",
    "MAX_JSON_CHARS",
    "MAX_JSON_DEPTH",
    "Range",
    "check_choice",
    "check_commands",
    "check_flag",
    "check_int",
    "check_number",
    "checked_options",
    "choice_message",
    "closest",
    "did_you_mean",
    "differing_settings",
    "import_optional",
    "parse_json",
]

#: the largest number :func:`check_number` accepts where its caller sets no upper bound: far
#: beyond any physical setting of KoopNav (metres, seconds, gains), and small enough that its
#: square and products stay finite (``movers.detection_noise=1e200`` overflowed when squared)
MAX_NUMBER = 1e9
#: the deepest nesting of lists and objects :func:`parse_json` reads: the deepest of KoopNav's own
#: documents (a sweep manifest, a results file, an env setting) is under 10 levels
MAX_JSON_DEPTH = 64
#: the longest JSON text :func:`parse_json` reads by default [characters]: a results file of
#: 10,000 episodes per cell of a large run is tens of MiB
MAX_JSON_CHARS = 256 * 2**20
#: the longest JSON value of one command-line word [characters] (the largest real one, a map
#: given inline or a curriculum of stages, is a few KiB)
CLI_JSON_CHARS = 2**20
#: a JSON string literal (escapes included), removed before the brackets are counted
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")


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


def choice_message(
    name: str,
    value: Any,
    allowed: Iterable[Any],
    also: str = "",
    *,
    sep: str = "=",
    among: str = "",
    suggest: Iterable[str] | None = None,
) -> str:
    """The one wording of a value outside its allowed set: ``name=value is not one of [...]``,
    then ``also`` and, for a near miss, a did-you-mean. :func:`check_choice` raises it; a caller
    that raises another exception (a policy file's ``PolicyLoadError``, argparse's
    ``ArgumentTypeError``) or has already found the value unknown takes the text from here.

    Parameters
    ----------
    name : str
        What was given, as the user wrote it (``"movers.behaviour"``, ``"--reference"``).
    value : object
        The value given (shown by its ``repr``).
    allowed : iterable
        The allowed values, in the order the message lists them.
    also : str
        Appended after the list (what else is allowed, or a hint), e.g. ``" or None"``.
    sep : str
        Between ``name`` and the value: ``"="`` for a keyword (``slip='icy'``), ``" "`` for a
        command-line flag or a noun (``--reference 'x'``, ``protocol 'papr'``).
    among : str
        What the allowed values are, said before the list (``"the run's controllers"``).
    suggest : iterable of str, optional
        The names a did-you-mean may propose (default: the allowed values that are text), for a
        message whose ``also`` allows more names than the list shows.
    """
    options = list(allowed)
    words = [option for option in options if isinstance(option, str)] if suggest is None else list(suggest)
    listed = f"{among} {options}" if among else f"{options}"
    return f"{name}{sep}{value!r} is not one of {listed}{also}{did_you_mean(value, words)}"


def differing_settings(logged: Mapping[str, Any], now: Mapping[str, Any]) -> str:
    """The one wording of the settings a logged run (an episode log, a study, a resume
    checkpoint) and this one do not share: ``key: logged X, now Y`` for each differing key, in
    key order, joined by ``"; "`` (a key one side lacks shows ``None`` there)."""
    differ = sorted(k for k in set(logged) | set(now) if logged.get(k) != now.get(k))
    return "; ".join(f"{k}: logged {logged.get(k)!r}, now {now.get(k)!r}" for k in differ)


def check_choice(
    name: str,
    value: Any,
    allowed: Iterable[Any],
    also: str = "",
    *,
    sep: str = "=",
    among: str = "",
    suggest: Iterable[str] | None = None,
) -> Any:
    """``value`` if it is one of ``allowed``, else ``ValueError``: ``name=value is not one of
    [...]`` with ``also`` (e.g. ``" or None"``) and, for a near miss, a did-you-mean; the one
    wording of every choice check in KoopNav (:func:`choice_message`, whose parameters these are).

    A bool is never taken for one of the allowed numbers (``True == 1``).
    """
    options = list(allowed)
    try:
        ok = any(value == option and type(value) is not bool for option in options)
    except (TypeError, ValueError):  # an array or another value without a plain ==
        ok = False
    if ok:
        return value
    raise ValueError(choice_message(name, value, options, also, sep=sep, among=among, suggest=suggest))


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
    below: float | None = None,
    note: str = "",
) -> float:
    """``value`` as a finite ``float``, or ``ValueError`` naming it and the allowed range.

    Parameters
    ----------
    name : str
        The argument's name, as the user wrote it.
    value : object
        A real number (``bool``, text, NaN and infinities are refused).
    above, at_least, at_most, below : float, optional
        Bounds: ``value > above``, ``value >= at_least``, ``value <= at_most``, ``value < below``;
        without ``at_most`` and ``below`` the bound is ``value <= MAX_NUMBER`` (every number is
        bounded, so that no float overflows further on).
    note : str
        Appended to the message in parentheses (e.g. the unit).
    """
    if at_most is None and below is None:
        at_most = MAX_NUMBER  # no float setting is unbounded: see MAX_NUMBER
    bounds = [
        f"> {above}" if above is not None else "",
        f">= {at_least}" if at_least is not None else "",
        f"<= {at_most}" if at_most is not None else "",
        f"< {below}" if below is not None else "",
    ]
    allowed = "a finite number" + "".join(f" {b}" for b in bounds if b)
    ok = isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        ok = not (
            (above is not None and value <= above)
            or (at_least is not None and value < at_least)
            or (at_most is not None and value > at_most)
            or (below is not None and value >= below)
        )
    if not ok:
        raise ValueError(f"{name}={value!r} must be {allowed}" + (f" ({note})" if note else ""))
    return float(value)


@dataclass(frozen=True)
class Range:
    """The allowed values of a numeric setting, declared once beside it (a controller's option
    table, an options dataclass) and checked by :meth:`check` with the one wording of
    :func:`check_int` / :func:`check_number`.

    Every range is bounded on both sides: an unbounded size or weight let a typo
    (``horizon=100000000``) allocate until the machine ran out of memory, and a huge float
    overflow further on instead of being refused by name.

    Attributes
    ----------
    low, high : float
        The bounds.
    integer : bool
        Integers only (``bool`` is never a number).
    low_open, high_open : bool
        The bound itself is excluded (``(0, 1]``: ``low_open=True``).
    note : str
        The unit or a hint, shown in the message in parentheses.
    """

    low: float
    high: float
    integer: bool = False
    low_open: bool = False
    high_open: bool = False
    note: str = ""

    def check(self, name: str, value: Any) -> Any:
        """``value`` as an ``int`` or ``float`` in the range, else ``ValueError`` naming ``name``,
        the value and the range."""
        if self.integer:
            low = int(self.low) + (1 if self.low_open else 0)
            high = int(self.high) - (1 if self.high_open else 0)
            return check_int(name, value, low, maximum=high, note=self.note)
        return check_number(
            name,
            value,
            above=self.low if self.low_open else None,
            at_least=None if self.low_open else self.low,
            at_most=None if self.high_open else self.high,
            below=self.high if self.high_open else None,
            note=self.note,
        )

    def __str__(self) -> str:
        """``an integer in [1, 200]``, ``(0, 0.5)``, ``[0, 1] m``: the range in interval notation,
        then the note."""
        text = f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}{')' if self.high_open else ']'}"
        return ("an integer in " if self.integer else "") + text + (f" {self.note}" if self.note else "")


def _unique_keys(what: str, pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """An object of :func:`parse_json`'s text, refused when a key stands twice in it."""
    found = dict(pairs)
    if len(found) < len(pairs):  # the rare case: find the first key that repeats
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise ValueError(
                    f"{what}: key {key!r} given twice in one JSON object; allowed: each key once"
                )
            seen.add(key)
    return found


def parse_json(text: str | bytes, what: str, *, max_chars: int = MAX_JSON_CHARS) -> Any:
    """``json.loads(text)`` with its size and nesting bounded first: the one JSON parser of
    command-line values and of files read back (maps, sweep manifests, run logs, baselines).

    Python's parser recurses once per level, so ``[[[[...`` 100,000 deep raised
    ``RecursionError`` (a traceback) instead of a message; here the depth is counted before
    parsing, outside string literals, in linear time.

    Parameters
    ----------
    text : str or bytes
        The JSON text.
    what : str
        What it is, named in the error (e.g. ``"--env-kwargs movers"`` or a file's path).
    max_chars : int
        The longest text accepted (default :data:`MAX_JSON_CHARS`).

    Raises
    ------
    ValueError
        Longer than ``max_chars`` or nested deeper than :data:`MAX_JSON_DEPTH`, naming ``what``
        (a plain ``ValueError``); a syntax error is ``json.JSONDecodeError`` as from ``json.loads``
        (callers that fall back to text catch that one only). A key given twice in one object is a
        plain ``ValueError`` naming it: ``json.loads`` keeps the last one silently
        (``movers={"count":1,"count":2}`` ran with 2).
    """
    if len(text) > max_chars:
        raise ValueError(f"{what}: {len(text):,} characters of JSON, more than the {max_chars:,} allowed")
    plain = text.decode("utf-8", "replace") if isinstance(text, bytes) else text
    brackets = _NOT_BRACKET.sub("", _JSON_STRING.sub("", plain))
    depth = max(itertools.accumulate(1 if c in "[{" else -1 for c in brackets), default=0)
    if depth > MAX_JSON_DEPTH:
        raise ValueError(f"{what}: JSON nested {depth} levels deep; allowed: at most {MAX_JSON_DEPTH}")
    return json.loads(text, object_pairs_hook=functools.partial(_unique_keys, what))


def import_optional(module: str, hint: str, refusal: type[Exception] = ImportError) -> ModuleType:
    """``module`` imported, or ``refusal(hint)`` when it is not installed.

    Parameters
    ----------
    module
        The optional dependency's top-level module (``"pyrvo"``).
    hint
        The whole message: who needs it and the install command (its extra).
    refusal
        The exception to raise: ``ImportError`` for a controller's option, ``ValueError`` for an
        env keyword (the env's documented refusal of a bad setting).

    A module that is installed but fails to import something it needs (a shared library, a
    dependency of its own) raises its own error: the hint would send the user to install what is
    already there.
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as missing:
        if missing.name != module:
            raise
        raise refusal(hint) from None


def check_flag(name: str, value: Any) -> bool:
    """``value`` as a ``bool`` (``True``/``False``, or numpy's), or ``ValueError`` naming it."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ValueError(f"{name}={value!r} is not a flag; allowed: true or false")


@njit(cache=True)
def _all_finite(commands: NDArray[np.float64]) -> bool:  # pragma: no cover - compiled
    """Whether every entry of ``commands`` (K, N, 2) is finite: ``np.isfinite(commands).all()``
    in one compiled call, a fifth of numpy's two on every step of a single env."""
    for k in range(commands.shape[0]):
        for i in range(commands.shape[1]):
            for c in range(commands.shape[2]):
                if not math.isfinite(commands[k, i, c]):
                    return False
    return True


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
    if not _all_finite(arr):
        bad = np.argwhere(~np.isfinite(arr))[0].tolist()
        raise ValueError(
            f"action contains a non-finite value at index {bad} ({arr[tuple(bad)]}); "
            "allowed: finite (v, omega), saturated to the actuation limits"
        )
    return arr
