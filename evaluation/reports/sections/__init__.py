"""The reports, built once as sections (title, notes, tables, lists) that Markdown (``results.md``,
``robustness.md``, the terminal) and HTML (``index.html``, ``robustness.html``) render alike:

- :mod:`evaluation.reports.sections.blocks`: what a report is made of (sections, notes, tables, lists),
  its Markdown, and the formats of the cells;
- :mod:`evaluation.reports.sections.runs`: a run's report (leaderboard, paired comparisons,
  per-controller tables, episodes that raised or degraded);
- :mod:`evaluation.reports.sections.profiles`: a sweep's report (the robustness profiles of
  :mod:`evaluation.stats.robustness`).

Every table is a :data:`Table`: a header and rows of cells already formatted as text (rates
with their Wilson intervals, means with their bootstrap intervals), so that every format shows
the same numbers. :class:`evaluation.reports.results.Results` writes the files.
"""

from __future__ import annotations

from evaluation.reports.sections.blocks import (
    Block,
    Items,
    Note,
    Section,
    Table,
    TableBlock,
    markdown,
    markdown_cell,
    markdown_table,
    markdown_text,
)
from evaluation.reports.sections.profiles import (
    level_cost_section,
    overview_section,
    robustness_sections,
    terminal_overview,
)
from evaluation.reports.sections.runs import (
    DEGRADED_NOTE,
    LEADERBOARD_NOTE,
    PAIRED_NOTE,
    TABLES_NOTE,
    controller_tables,
    leaderboard_rows,
    paired_power_note,
    paired_rows,
    paper_rows,
    sections,
    suite_heading,
    suite_note,
    task_label,
    terminal_summary,
)

__all__ = [
    "Block",
    "DEGRADED_NOTE",
    "Items",
    "LEADERBOARD_NOTE",
    "Note",
    "PAIRED_NOTE",
    "Section",
    "TABLES_NOTE",
    "Table",
    "TableBlock",
    "controller_tables",
    "leaderboard_rows",
    "markdown",
    "markdown_cell",
    "markdown_table",
    "markdown_text",
    "level_cost_section",
    "overview_section",
    "paired_power_note",
    "paired_rows",
    "paper_rows",
    "robustness_sections",
    "sections",
    "suite_heading",
    "suite_note",
    "task_label",
    "terminal_overview",
    "terminal_summary",
]
