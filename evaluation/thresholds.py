"""CI thresholds: cells of a run checked against floors committed in a TOML file.

A floor is read statistically by default: ``reading = "interval"`` (the file's top level) fails a
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
from dataclasses import dataclass, field

from evaluation.results import Results
from koopman_envs.files import MAX_TEXT_BYTES, read_text

__all__ = ["READINGS", "ThresholdCheck", "check_thresholds"]

_KEYS = {"env", "controller", "map", "slip", "min_success_rate", "max_final_distance_cm"}

#: how ``min_success_rate`` is read, by the TOML's top-level ``reading``
READINGS = ("interval", "point")


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


def check_thresholds(results: Results, path: str | os.PathLike, *, strict: bool = False) -> ThresholdCheck:
    """Check the run's cells against the floors of a TOML file (see the module docstring).

    The file holds ``[[cell]]`` tables with any of ``env``, ``controller``, ``map``, ``slip``
    (omitted = any) and limits ``min_success_rate`` (0-1) and/or ``max_final_distance_cm`` (mean
    over robots and successful runs), and optionally a top-level ``reading``.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: the same parser as the tomli backport
        import tomli as tomllib  # type: ignore[no-redef]  # the same module, another name

    # a regular file of bounded size, refused unread otherwise (a FIFO as --check hung forever)
    text = read_text(path, MAX_TEXT_BYTES, what="thresholds file", expected="a TOML thresholds file")
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} is not valid TOML: {exc}") from None
    rules = spec.get("cell")
    if not isinstance(rules, list) or not rules:
        raise ValueError(f"thresholds file {os.fspath(path)!r} has no [[cell]] tables")
    reading = spec.get("reading", "interval")
    if reading not in READINGS:
        raise ValueError(
            f"thresholds file {os.fspath(path)!r}: reading={reading!r} is not one of {list(READINGS)}"
        )
    unknown_top = set(spec) - {"cell", "reading"}
    if unknown_top:
        raise ValueError(
            f"thresholds file {os.fspath(path)!r}: unknown top-level keys {sorted(unknown_top)}; "
            "allowed: ['cell', 'reading']"
        )
    check = ThresholdCheck(reading=reading)
    for rule in rules:
        unknown = set(rule) - _KEYS
        if unknown:
            raise ValueError(
                f"thresholds file {os.fspath(path)!r}: unknown keys {sorted(unknown)}; allowed: {sorted(_KEYS)}"
            )
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
