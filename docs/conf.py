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
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "**/__pycache__"]

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
