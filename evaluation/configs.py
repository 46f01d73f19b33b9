"""Controller configurations: a registered controller plus options, as one leaderboard row.

On the command line a configuration is ``name`` or ``name:key=value,key=value`` (values parsed
as JSON scalars, else kept as text; ``label=...`` names the row, by default the text itself)::

    nominal-nmpc   nominal-nmpc:solver=fatrop   koopman-nmpc:uncertainty_margin=0,horizon=30
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import controllers

__all__ = ["ControllerConfig", "parse_controller"]


@dataclass(frozen=True)
class ControllerConfig:
    """A controller as the evaluator runs it.

    Attributes
    ----------
    label : str
        Row name in every report (unique within a run).
    name : str
        Registered controller name.
    options : tuple of (str, value)
        Keyword options of the factory, sorted by key (plain JSON scalars).
    """

    label: str
    name: str
    options: tuple[tuple[str, Any], ...] = ()

    def build(self) -> Any:
        """A fresh controller instance."""
        ctrl = controllers.make(self.name, **dict(self.options))
        return ctrl

    def validate(self) -> None:
        """Build once to reject unknown names and options before any episode starts."""
        available = controllers.available()
        if self.name not in available:
            raise ValueError(f"controller {self.name!r} is not one of {available}")
        try:
            self.build()
        except TypeError as exc:
            raise ValueError(f"controller {self.label!r}: bad option in {dict(self.options)} ({exc})") from None
        except ValueError as exc:
            raise ValueError(f"controller {self.label!r}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (recorded in results)."""
        return {"label": self.label, "name": self.name, "options": dict(self.options)}


def _scalar(text: str) -> Any:
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        return text
    if isinstance(value, (list, dict)):
        raise ValueError(f"option value {text!r} must be a scalar (number, true/false, null or text)")
    return value


def parse_controller(text: str | ControllerConfig) -> ControllerConfig:
    """``name`` or ``name:key=value,...`` -> :class:`ControllerConfig` (``ValueError`` when malformed)."""
    if isinstance(text, ControllerConfig):
        return text
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"controller {text!r} must be a non-empty 'name' or 'name:key=value,...'")
    name, sep, rest = text.strip().partition(":")
    options: dict[str, Any] = {}
    label = text.strip()
    if sep:
        if not rest:
            raise ValueError(f"controller {text!r}: nothing after ':'; expected 'name:key=value,...'")
        for item in rest.split(","):
            key, eq, value = item.partition("=")
            key = key.strip()
            if not eq or not key.isidentifier():
                raise ValueError(f"controller {text!r}: {item!r} is not key=value (a Python identifier as key)")
            if key == "label":
                label = value.strip()
            else:
                options[key] = _scalar(value.strip())
    return ControllerConfig(label, name.strip(), tuple(sorted(options.items())))
