"""An SVG badge of one controller's success rate with its interval, for a README (``--badge``)."""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

from evaluation.reports.results import Results
from koopman_envs.files import write_atomic

__all__ = ["badge_svg", "write_badge"]

#: approximate advance of a character of the badge's 11 px Verdana/DejaVu text [px]
_CHAR_WIDTH = 6.6


def _colour(rate: float) -> str:
    """Shields-style colour by success rate."""
    for floor, colour in ((0.9, "#4c1"), (0.75, "#97ca00"), (0.5, "#dfb317"), (0.25, "#fe7d37")):
        if rate >= floor:
            return colour
    return "#e05d44"


def badge_svg(label: str, value: str, colour: str) -> str:
    """A flat two-part badge (label on grey, value on ``colour``) as SVG text."""
    left = round(len(label) * _CHAR_WIDTH) + 10
    right = round(len(value) * _CHAR_WIDTH) + 10
    width = left + right
    label, value = escape(label), escape(value)
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="20" role="img" '
        f'aria-label="{label}: {value}">'
        f"<title>{label}: {value}</title>"
        f'<rect width="{left}" height="20" fill="#555"/>'
        f'<rect x="{left}" width="{right}" height="20" fill="{colour}"/>'
        f'<g fill="#fff" text-anchor="middle" font-family="Verdana,DejaVu Sans,sans-serif" font-size="11">'
        f'<text x="{left / 2:.1f}" y="14">{label}</text>'
        f'<text x="{left + right / 2:.1f}" y="14">{value}</text></g></svg>'
    )


def write_badge(results: Results, controller: str, path: str | Path) -> Path:
    """Write the badge of ``controller``'s pooled success rate (all tasks and cells of the run)
    with its 95% Wilson interval, e.g. ``koopman-nmpc success | 88% [80-93]``.

    Raises ``ValueError`` naming the controller and the run's controllers when it did not run.
    """
    from evaluation.stats.statistics import wilson_interval

    cells = [c for c in results.cells if c.controller == controller]
    if not cells:
        names = sorted({c.controller for c in results.cells})
        raise ValueError(f"--badge {controller!r} is not a controller of this run; it ran {names}")
    successes, valid = sum(c.successes for c in cells), sum(c.valid for c in cells)
    low, high = wilson_interval(successes, valid)
    rate = successes / valid if valid else 0.0
    value = f"{100 * rate:.0f}% [{100 * low:.0f}-{100 * high:.0f}], n={valid}"
    return write_atomic(path, badge_svg(f"{controller} success", value, _colour(rate)) + "\n")
