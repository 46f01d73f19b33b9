"""``span``, the placeholder function over other number functions (docs/make_prose_md.py): one
of ``docs/prose_numbers.py``'s functions at every combination of alternatives (``A|B``,
``SWEEP@*``), printed as the range of its number (``94-100%``), or with ``max``/``min`` the one
with the largest or smallest number (``Holm p = 0.004``), for prose that says ``52-58%`` or
``Holm p <= ...`` of several controllers or levels.
"""

from __future__ import annotations

import itertools
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one

from prose_numbers import FILTERED, Options, Runs  # noqa: E402
from prose_numbers import NUMBERS as RUN_NUMBERS
from prose_sweeps import SWEEP_NUMBERS  # noqa: E402

from evaluation.reports.sections.blocks import level_text  # noqa: E402

__all__ = ["SPAN", "span"]

#: the functions span ranges over
NUMBERS = {**RUN_NUMBERS, **SWEEP_NUMBERS}


#: a number function's output: its number (sign and thousands' commas kept), then the rest
_NUMBER = re.compile(r"^([+-]?\d[\d,]*(?:\.\d+)?)(.*)$", re.DOTALL)


def _alternatives(runs: Runs, word: str) -> list[str]:
    """A word of ``span``: ``A|B|C`` as its alternatives, ``SWEEP@*`` as every level of the sweep
    (in its order), ``SWEEP@KEY=*`` as every level of that axis."""
    name, at, level = word.partition("@")
    if at and level.endswith("*") and level in ("*", f"{level[:-2]}=*"):
        key = level[:-2]
        levels = runs.sweep(name).levels
        if key and key not in levels:
            raise ValueError(f"{word!r}: sweep {name!r} has the axes {sorted(levels)}")
        return list(
            dict.fromkeys(
                f"{name}@{k}={level_text(value)}"
                for k, pairs in levels.items()
                if k == key or not key
                for value, _ in pairs
            )
        )
    return word.split("|")


def _every(runs: Runs, function: Callable[..., str], args: Sequence[str], options: Options) -> list[str]:
    """What ``function`` prints at every combination of its arguments' and filters' alternatives."""
    choices = [_alternatives(runs, word) for word in args]
    keys = list(options)
    option_choices = [options[key].split("|") for key in keys]
    return [
        function(runs, list(combo[: len(choices)]), dict(zip(keys, combo[len(choices) :], strict=True)))
        for combo in itertools.product(*choices, *option_choices)
    ]


def _extreme(runs: Runs, args: Sequence[str], options: Options) -> str:
    # ``span max FUNCTION ...``: the text whose first number is the largest (a p-value's bound)
    if len(args) < 2 or args[1] not in NUMBERS:
        raise ValueError(f"span {args[0]} takes a number function, got {list(args)}")
    texts = _every(runs, NUMBERS[args[1]], args[2:], options)
    found = [(re.search(r"[+-]?\d[\d,]*(?:\.\d+)?", text), text) for text in texts]
    if not all(m for m, _ in found):
        raise ValueError(f"span {list(args)}: {texts} are not all numbers")
    pick = max if args[0] == "max" else min
    return pick(found, key=lambda item: float(item[0][0].replace(",", "")) if item[0] else 0.0)[1]


def span(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``span FUNCTION ARGUMENT...``: FUNCTION (a number function) at every combination of its
    arguments' and filters' alternatives (``A|B``, ``SWEEP@*``, ``SWEEP@KEY=*``), as the range
    of its number, ``94-100%``; one value when every combination prints the same (``0/80``),
    ``ValueError`` when their units differ. ``span max FUNCTION ...`` (or ``min``) prints the one
    whose first number is the largest (the smallest): ``Holm p = 0.004`` of several p-values."""
    if args and args[0] in ("max", "min"):
        return _extreme(runs, args, options)
    if not args or args[0] not in NUMBERS:
        raise ValueError(f"span takes a number function of {sorted(NUMBERS)}, got {list(args)}")
    function = NUMBERS[args[0]]
    if options and args[0] not in FILTERED:
        raise ValueError(f"{args[0]} takes no filter, got {sorted(options)}")
    texts = _every(runs, function, args[1:], options)
    if len(set(texts)) == 1:
        return texts[0]
    parts = [_NUMBER.match(text) for text in texts]
    if not all(parts) or len({m[2] for m in parts if m}) != 1:
        raise ValueError(f"span {list(args)}: its values {texts} are not one number with one unit")
    values = sorted((float(m[1].replace(",", "")), m[1]) for m in parts if m)
    return f"{values[0][1]}-{values[-1][1]}{parts[0][2] if parts[0] else ''}"


#: the function by name, beside NUMBERS and TABLES
SPAN = {"span": span}
