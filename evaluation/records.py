"""Episode records: what a record's ``status`` means (the statuses, which of them ran, and when a
finished episode counts as degraded) and the plain-JSON form records are written in. Every
reader of records asks here, so that the rule is one.

- ``"ok"``: the episode ran to its end and its controller decided normally.
- ``"degraded"``: it ran to its end, but the controller's optimizer failed in more than
  :data:`DEGRADED_FAILURE_SHARE` of its decisions (each failure fell back to the previous plan or a
  safe command). Its outcome counts like any other, and the report counts such episodes per
  controller, so that a broken calibration or solver cannot pass as a normal run.
- ``"error"``: the episode raised; its record holds the error and no outcome.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["DEGRADED_FAILURE_SHARE", "RAN", "STATUSES", "finished_status", "is_degraded", "json_safe", "ran"]

STATUSES = ("ok", "degraded", "error")
#: statuses of episodes that ran to their end (their outcome counts)
RAN = ("ok", "degraded")
#: share of a controller's decisions in an episode whose solver failure makes the episode degraded
#: (ours: the committed CI baseline's highest share is 2%, so a quarter means something broke)
DEGRADED_FAILURE_SHARE = 0.25


def ran(record: Mapping[str, Any]) -> bool:
    """Whether an episode ran to its end (``ok`` or ``degraded``; not ``error``)."""
    return record.get("status") in RAN


def is_degraded(record: Mapping[str, Any]) -> bool:
    """Whether an episode ran with its solver failing in too many decisions."""
    return record.get("status") == "degraded"


def finished_status(failures: int, decisions: int) -> str:
    """``"degraded"`` when more than :data:`DEGRADED_FAILURE_SHARE` of ``decisions`` failed, else ``"ok"``."""
    return "degraded" if decisions > 0 and failures > DEGRADED_FAILURE_SHARE * decisions else "ok"


def json_safe(value: Any) -> Any:
    """A record (or any value) as plain JSON: NaN and inf become null (JSON has no such numbers),
    tuples become lists."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value
