"""CI thresholds: cells of a run checked against floors committed in a TOML file.

The file is read and checked whole (:func:`load_thresholds`: types, ranges, known keys) before any
episode runs. A floor is read statistically by default: ``reading = "interval"`` (the file's top level) fails a
cell only when the 95% Wilson interval of its success rate lies entirely below
``min_success_rate``, so that one unlucky seed of a small cell does not fail a run that a
real regression would (``reading = "point"``: the observed rate itself must reach the floor).
A rule that matches no cell because its controller cannot be built here (an optional extra not
installed, e.g. ``rl-ppo`` without ``[rl]``) is skipped with the reason, and fails only with
``strict=True`` (``--strict``); any other rule that matches nothing fails.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from evaluation.reports.results import Results
from koopman_envs.checks import check_choice, check_number, did_you_mean
from koopman_envs.files import MAX_TEXT_BYTES, read_text

__all__ = ["READINGS", "ThresholdCheck", "Thresholds", "check_thresholds", "load_thresholds"]

#: what a [[cell]] matches on (text; omitted = any) and its limits (numbers)
_MATCH_KEYS = ("env", "controller", "map", "slip")
_LIMIT_KEYS = ("min_success_rate", "max_final_distance_cm")
_KEYS = (*_MATCH_KEYS, *_LIMIT_KEYS)
_TOP_KEYS = ("cell", "reading")

#: how ``min_success_rate`` is read, by the TOML's top-level ``reading``
READINGS = ("interval", "point")


@dataclass(frozen=True)
class Thresholds:
    """A thresholds file, read and checked (:func:`load_thresholds`).

    Attributes
    ----------
    path : str
        Where it was read from (named in every message).
    rules : tuple of dict
        The ``[[cell]]`` tables: text values under ``env``, ``controller``, ``map``, ``slip``,
        floats under ``min_success_rate`` (in [0, 1]) and ``max_final_distance_cm`` (>= 0).
    reading : str
        One of :data:`READINGS`.
    """

    path: str
    rules: tuple[dict[str, Any], ...]
    reading: str = "interval"


@dataclass
class ThresholdCheck:
    """Outcome of :func:`check_thresholds`.

    Attributes
    ----------
    problems : list of str
        Cells below their floors, and rules that match nothing (a failed check).
    skipped : list of str
        Rules skipped because their controller cannot be built here, with the reason.
    reading : str
        How the success floors were read (one of :data:`READINGS`).
    """

    problems: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    reading: str = "interval"


def _unknown(where: str, given: Mapping[str, Any], allowed: tuple[str, ...]) -> None:
    unknown = [key for key in given if key not in allowed]
    if unknown:
        raise ValueError(
            f"{where}: unknown key {unknown[0]!r}{did_you_mean(unknown[0], allowed)}; allowed: {list(allowed)}"
        )


def _checked_rule(where: str, rule: Any) -> dict[str, Any]:
    """One ``[[cell]]`` table with its types and ranges checked (``ValueError`` naming the key)."""
    if not isinstance(rule, dict):
        raise ValueError(f"{where} is {rule!r}, not a table of {list(_KEYS)}")
    _unknown(where, rule, _KEYS)
    out: dict[str, Any] = {}
    for key in _MATCH_KEYS:
        if key in rule:
            if not isinstance(rule[key], str) or not rule[key].strip():
                raise ValueError(
                    f"{where}: {key}={rule[key]!r} must be non-empty text (omit it to match any)"
                )
            out[key] = rule[key]
    if "min_success_rate" in rule:
        out["min_success_rate"] = check_number(
            f"{where}: min_success_rate", rule["min_success_rate"], at_least=0, at_most=1, note="a fraction"
        )
    if "max_final_distance_cm" in rule:
        out["max_final_distance_cm"] = check_number(
            f"{where}: max_final_distance_cm", rule["max_final_distance_cm"], at_least=0, note="centimetres"
        )
    return out


def load_thresholds(path: str | os.PathLike[str]) -> Thresholds:
    """Read a thresholds TOML file and check it whole, before any episode runs.

    Raises
    ------
    ValueError
        A file that cannot be read or is not TOML; an unknown key (with did-you-mean); no
        ``[[cell]]`` table; a ``reading`` outside :data:`READINGS`; a match key that is not
        text; a limit that is not a finite number in its range (``min_success_rate`` in [0, 1],
        ``max_final_distance_cm`` >= 0; ``true`` is not a number). Each names the file, the table
        and the key.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: the same parser as the tomli backport
        import tomli as tomllib  # type: ignore[no-redef]  # the same module, another name

    name = f"thresholds file {os.fspath(path)!r}"
    # a regular file of bounded size, refused unread otherwise (a FIFO as --check hung forever)
    text = read_text(path, MAX_TEXT_BYTES, what="thresholds file", expected="a TOML thresholds file")
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{name} is not valid TOML: {exc}") from None
    _unknown(name, spec, _TOP_KEYS)
    rules = spec.get("cell")
    if not isinstance(rules, list) or not rules:
        raise ValueError(f"{name} has no [[cell]] tables")
    reading = spec.get("reading", "interval")
    check_choice(f"{name}: reading", reading, READINGS)
    checked = tuple(_checked_rule(f"{name}: [[cell]] {i + 1}", rule) for i, rule in enumerate(rules))
    return Thresholds(os.fspath(path), checked, reading)


def _unusable(controller: str | None) -> str | None:
    """Why ``controller`` cannot be built here, or None when it can (or is not registered)."""
    if controller is None:
        return None
    from controllers import registry

    if controller not in registry.available():
        return None
    try:
        registry.make(controller)
    except (ImportError, ValueError) as exc:
        return str(exc)
    return None


def check_thresholds(
    results: Results, thresholds: Thresholds | str | os.PathLike[str], *, strict: bool = False
) -> ThresholdCheck:
    """Check the run's cells against the floors of a thresholds file (see the module docstring).

    ``thresholds`` is a :class:`Thresholds` (read before the run by :func:`load_thresholds`) or
    the path of a TOML file holding ``[[cell]]`` tables with any of ``env``, ``controller``,
    ``map``, ``slip`` (omitted = any) and limits ``min_success_rate`` (0-1) and/or
    ``max_final_distance_cm`` (mean over robots and successful runs), and optionally a top-level
    ``reading``.
    """
    if not isinstance(thresholds, Thresholds):
        thresholds = load_thresholds(thresholds)
    reading = thresholds.reading
    check = ThresholdCheck(reading=reading)
    for rule in thresholds.rules:
        matched = [
            c
            for c in results.cells
            if all(
                rule.get(k) in (None, v)
                for k, v in (
                    ("env", c.env_id),
                    ("controller", c.controller),
                    ("map", c.map),
                    ("slip", c.slip),
                )
            )
        ]
        if not matched:
            reason = _unusable(rule.get("controller"))
            if reason is None:
                check.problems.append(f"no evaluated cell matches {rule}")
            elif strict:
                check.problems.append(f"no evaluated cell matches {rule} ({reason}; --strict)")
            else:
                check.skipped.append(f"{rule}: skipped ({reason})")
        for c in matched:
            name = f"{c.env_id} / {c.controller} / {c.map} / {c.slip}"
            floor = rule.get("min_success_rate")
            if floor is not None:
                low, high = c.success_ci
                if reading == "interval" and not high >= floor:
                    check.problems.append(
                        f"{name}: success rate {c.success_rate:.2f}, 95% interval "
                        f"[{low:.2f}, {high:.2f}] entirely below {floor:.2f}"
                    )
                elif reading == "point" and not c.success_rate >= floor:
                    check.problems.append(f"{name}: success rate {c.success_rate:.2f} < {floor:.2f}")
            if "max_final_distance_cm" in rule:
                mean = c.distance_settled.team_mean
                mean = float("inf") if math.isnan(mean) else mean
                if not mean <= rule["max_final_distance_cm"]:
                    check.problems.append(
                        f"{name}: final distance {mean:.1f} cm > {rule['max_final_distance_cm']:.1f} cm"
                    )
    return check
