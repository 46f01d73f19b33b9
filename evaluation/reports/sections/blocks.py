"""What every report is made of: sections of notes, tables and lists (:class:`Section`), their
Markdown, and the formats of the cells, so that a run's report (:mod:`evaluation.reports.sections.runs`)
and a sweep's (:mod:`evaluation.reports.sections.profiles`) read alike in every format.

Every table is a :data:`Table`: a header and rows of cells already formatted as text (rates
with their Wilson intervals, means with their bootstrap intervals), so that Markdown and HTML
(:mod:`evaluation.reports.html`) show the same numbers.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

__all__ = [
    "Block",
    "Items",
    "Note",
    "Section",
    "Table",
    "TableBlock",
    "count_cell",
    "interval_cell",
    "level_text",
    "markdown",
    "markdown_cell",
    "markdown_table",
    "markdown_text",
    "mean_cell",
    "mean_sd_cell",
    "number_cell",
    "p_cell",
    "rate_cell",
]

#: A report table: its header and its rows, every cell already formatted as text.
Table = tuple[list[str], list[list[str]]]


# --------------------------------------------------------------------------- sections
@dataclass(frozen=True)
class Note:
    """A paragraph of explanation."""

    text: str


@dataclass(frozen=True)
class TableBlock:
    """A table with an optional caption."""

    table: Table
    caption: str = ""


@dataclass(frozen=True)
class Items:
    """A list of (code, text) entries, e.g. the episodes that raised and their errors."""

    entries: tuple[tuple[str, str], ...]


Block = Note | TableBlock | Items


@dataclass(frozen=True)
class Section:
    """One part of the report: an anchor (the HTML id), a title and its blocks in order."""

    anchor: str
    title: str
    blocks: tuple[Block, ...]


# --------------------------------------------------------------------------- cell formats
def rate_cell(rate: float, ci: tuple[float, float] | list[float]) -> str:
    """``80% [49-94]``: a rate with its interval, in percent (``-`` for none)."""
    if rate is None or math.isnan(rate):
        return "-"
    return f"{100 * rate:.0f}% [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}]"


def count_cell(k: int, n: int, ci: tuple[float, float]) -> str:
    """``8/10 [49-94%]``: ``k`` of ``n`` with the rate's interval (``-`` for no episode)."""
    if n == 0:
        return "-"
    return f"{k}/{n} [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}%]"


def mean_cell(mean: float, low: float, high: float) -> str:
    """``12.3 [10.1-14.0]``: a mean with its interval (``-`` for none)."""
    if mean is None or math.isnan(mean):
        return "-"
    return f"{mean:.1f} [{low:.1f}-{high:.1f}]"


def mean_sd_cell(mean: float, sd: float, runs: int) -> str:
    """``12.3+-1.2``: a mean and its standard deviation over ``runs`` (the mean alone for one)."""
    if runs == 0 or math.isnan(mean):
        return "-"
    return f"{mean:.1f}" if runs == 1 else f"{mean:.1f}+-{sd:.1f}"


def number_cell(value: float | None, form: str) -> str:
    """``value`` in ``form``, or ``-`` when there is none (None or NaN)."""
    return "-" if value is None or math.isnan(value) else form.format(value)


def p_cell(p: float) -> str:
    """A p-value with three decimals, ``<0.001`` below."""
    return "<0.001" if p < 1e-3 else f"{p:.3f}"


def interval_cell(value: float, low: float, high: float, scale: float = 1.0, digits: int = 0) -> str:
    """``50 [20, 80]``: ``value`` and its interval times ``scale`` with ``digits`` decimals
    (``-`` for NaN)."""
    if math.isnan(value):
        return "-"
    return f"{value * scale:.{digits}f} [{low * scale:.{digits}f}, {high * scale:.{digits}f}]"


def level_text(level: Any) -> str:
    """A sweep level as text: text as it is, anything else as JSON (``0.5``, ``[0, 1]``). The
    sweep's labels and level directories and the robustness report spell a level alike."""
    return level if isinstance(level, str) else json.dumps(level)


# --------------------------------------------------------------------------- Markdown
#: what opens raw HTML in Markdown (CommonMark: "<" before a tag name, "/", "!" or "?"); "<0.001" does not
_HTML_OPENING = re.compile(r"<(?=[A-Za-z/!?])")


def markdown_text(text: str) -> str:
    """``text`` safe in a Markdown document: every ``<`` that could open an HTML tag becomes
    ``&lt;``, as the HTML report escapes it (controller labels and errors are user text: a label
    ``<img onerror=...>`` must show as text, not run in a Markdown viewer)."""
    return _HTML_OPENING.sub("&lt;", text)


def markdown_cell(text: str) -> str:
    """A table cell's text: escaped, and its ``|`` kept from splitting the row."""
    return markdown_text(text).replace("|", "\\|")


def _code(text: str) -> str:
    """``text`` as a Markdown code span, fenced by more backticks than any run inside it."""
    longest = max((len(run) for run in re.findall("`+", text)), default=0)
    fence = "`" * (longest + 1)
    return f"{fence} {text} {fence}" if longest else f"`{text}`"


def markdown_table(table: Table) -> str:
    """A :data:`Table` as a Markdown table (every cell escaped: :func:`markdown_text`)."""
    header, rows = table
    lines = ["| " + " | ".join(map(markdown_cell, header)) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(map(markdown_cell, row)) + " |" for row in rows]
    return "\n".join(lines)


def _markdown_block(block: Block) -> str:
    if isinstance(block, Note):
        return markdown_text(block.text)
    if isinstance(block, TableBlock):
        caption = f"**{markdown_text(block.caption)}**\n\n" if block.caption else ""
        return caption + markdown_table(block.table)
    return "\n".join(f"- {_code(code)}: {markdown_text(text)}" for code, text in block.entries)


def markdown(report: Sequence[Section]) -> str:
    """The sections as one Markdown document (``## title`` per section)."""
    return "\n\n".join(
        f"## {markdown_text(s.title)}\n\n" + "\n\n".join(_markdown_block(b) for b in s.blocks) for s in report
    )
