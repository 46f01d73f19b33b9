"""Sphinx configuration of the KoopNav documentation (MyST Markdown pages, furo theme).

Build: ``bash docs/build.sh [OUT]`` (warnings are errors, internal links checked), or
``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the API pages import the package from this checkout, not from wherever an install points
sys.path.insert(0, str(ROOT))
# NMPC modules are imported, never solved, during a build; keep solvers uncompiled all the same
os.environ.setdefault("KOOPNAV_NMPC_JIT", "0")

project = "KoopNav"
author = "KoopNav developers"
copyright = "KoopNav developers"
release = version = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = [
    "_build",
    "_intros",  # text the page scripts insert into pages, not a page itself
    "Thumbs.db",
    ".DS_Store",
    "**/__pycache__",
]

# MyST: anchors for headings down to ###, so that [text](page.md#a-heading) links resolve
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "deflist"]

# numpy-style docstrings (see /STYLE: Parameters / Returns with shapes and units)
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}
autosummary_generate = False

html_theme = "furo"
html_title = "KoopNav"
html_static_path = ["_static"]
autodoc_inherit_docstrings = False  # Gymnasium's and PettingZoo's own docstrings are not numpy style


# ------------------------------------------------------------------------------------------------
# The env classes and the PettingZoo modules keep Gymnasium's docstring layout, which is Markdown
# (## sections, | tables |, ```python fences). autodoc reads reStructuredText, so those few
# docstrings are translated here, line by line, before napoleon sees them.
def _md_table(rows: list[str]) -> list[str]:
    cells = [[c.strip() for c in row.strip().strip("|").split("|")] for row in rows]
    body = [r for r in cells if not all(set(c) <= set("-: ") for c in r)]
    out = ["", ".. list-table::", "   :header-rows: 1", ""]
    for row in body:
        for i, cell in enumerate(row):
            out.append(("   * - " if i == 0 else "     - ") + (cell or " "))
    return out + [""]


def _markdown_to_rst(lines: list[str]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("## "):
            out += ["", f".. rubric:: {line[3:].strip()}", ""]
        elif line.lstrip().startswith("|"):
            rows = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append(lines[i])
                i += 1
            out += _md_table(rows)
            continue
        elif line.lstrip().startswith("```"):
            lang = line.strip().strip("`") or "text"
            out += ["", f".. code-block:: {lang}", ""]
            i += 1
            while i < len(lines) and not lines[i].lstrip().startswith("```"):
                out.append("   " + lines[i])
                i += 1
            out.append("")
        else:
            out.append(line)
        i += 1
    return out


def _is_markdown(lines: list[str]) -> bool:
    return any(
        line.startswith("## ")
        or line.lstrip().startswith("|---")
        or line.lstrip().startswith("| ---")
        or line.lstrip().startswith("|--")
        for line in lines
    )


def _docstring_markdown(app, what, name, obj, options, lines):  # Sphinx calls it with these
    if _is_markdown(lines):
        lines[:] = _markdown_to_rst(lines)


def setup(app):
    app.connect("autodoc-process-docstring", _docstring_markdown, priority=400)  # napoleon runs at 500
