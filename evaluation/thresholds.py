"""CI thresholds: cells of a run checked against limits committed in a TOML file."""

from __future__ import annotations

import math
import os

from evaluation.results import Results

__all__ = ["check_thresholds"]

_KEYS = {"env", "controller", "map", "slip", "min_success_rate", "max_final_distance_cm"}


def check_thresholds(results: Results, path: str | os.PathLike) -> list[str]:
    """Cells below the committed thresholds (empty list = pass).

    The TOML file holds ``[[cell]]`` tables with any of ``env``, ``controller``, ``map``,
    ``slip`` (omitted = any) and limits ``min_success_rate`` (0-1) and/or
    ``max_final_distance_cm`` (mean over robots and successful runs).
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: the same parser as the tomli backport
        import tomli as tomllib

    try:
        with open(path, "rb") as fh:
            spec = tomllib.load(fh)
    except OSError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} cannot be read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"thresholds file {os.fspath(path)!r} is not valid TOML: {exc}") from None
    rules = spec.get("cell")
    if not isinstance(rules, list) or not rules:
        raise ValueError(f"thresholds file {os.fspath(path)!r} has no [[cell]] tables")
    problems = []
    for rule in rules:
        unknown = set(rule) - _KEYS
        if unknown:
            raise ValueError(f"thresholds file {os.fspath(path)!r}: unknown keys {sorted(unknown)}; allowed: {sorted(_KEYS)}")
        matched = [
            c for c in results.cells
            if all(rule.get(k) in (None, v) for k, v in (("env", c.env_id), ("controller", c.controller),
                                                          ("map", c.map), ("slip", c.slip)))
        ]  # fmt: skip
        if not matched:
            problems.append(f"no evaluated cell matches {rule}")
        for c in matched:
            name = f"{c.env_id} / {c.controller} / {c.map} / {c.slip}"
            if "min_success_rate" in rule and not c.success_rate >= rule["min_success_rate"]:
                problems.append(f"{name}: success rate {c.success_rate:.2f} < {rule['min_success_rate']:.2f}")
            if "max_final_distance_cm" in rule:
                mean = c.distance_settled.team_mean
                mean = float("inf") if math.isnan(mean) else mean
                if not mean <= rule["max_final_distance_cm"]:
                    problems.append(f"{name}: final distance {mean:.1f} cm > {rule['max_final_distance_cm']:.1f} cm")
    return problems
