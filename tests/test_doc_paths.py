"""Every repository path README.md and the docs pages name in backticks exists (prose that
cannot drift, issue 60): a module moved or removed without its page updated is named here.

A path is a backticked token rooted at one of the repository's folders (``evaluation/...``,
``docs/...``). Left out: placeholders (a segment in capitals, ``data/NAME/run.tar.xz``), what a
run writes (:data:`OUTPUTS`), and a path named as history (:data:`HISTORY`, each with the sentence's
reason).
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("koopman_envs", "controllers", "baselines", "evaluation", "tests", "docs", "bench", ".ci", "data")
PATH = re.compile(r"`((?:" + "|".join(re.escape(f) for f in FOLDERS) + r")/[A-Za-z0-9_./-]*)`")
PLACEHOLDER = re.compile(r"(?:^|/)[A-Z][A-Z_]*(?:[./]|$)")

#: written by a run or a build, not committed
OUTPUTS = {
    "docs/_build/html/index.html": "docs/build.sh's output",
    "data/runs/": "the runs' working folder (untracked)",
}
#: outputs that stay local (a working copy may hold them): never committed
LOCAL = ("data/runs/", "docs/_build/")
#: named as what was: the page says the path is gone or moved
HISTORY = {
    ("docs/ci.md", "evaluation/baseline.py"): "the scores were measured at the modules' earlier paths",
    ("docs/layout.md", "koopman_envs/builder/"): "the simulator core's earlier name",
    ("docs/benchmark.md", "controllers/tuned/dwa.json"): "dwa's withdrawn preset, removed",
}


def missing_paths(name: str, text: str) -> list[str]:
    """The backticked repository paths of page ``name`` (its ``text``) that do not exist."""
    missing = []
    for match in PATH.finditer(text):
        path = match[1].split("::")[0]
        if PLACEHOLDER.search(path) or path in OUTPUTS or (name, path) in HISTORY:
            continue
        if not (ROOT / path).exists():
            missing.append(f"{name}: `{path}`")
    return missing


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_every_path_the_pages_name_exists() -> None:
    problems = [
        p for page in _pages() for p in missing_paths(str(page.relative_to(ROOT)), page.read_text("utf-8"))
    ]
    assert problems == []


def test_a_moved_module_is_named() -> None:
    text = "The filter is `controllers/safety.py`; the runner `koopman_envs/episodes/single.py`."
    assert missing_paths("docs/x.md", text) == ["docs/x.md: `controllers/safety.py`"]


def test_placeholders_outputs_and_history_are_not_paths_to_check() -> None:
    text = "`data/NAME/run.tar.xz`, `data/runs/`, `evaluation/baseline.py`"
    assert missing_paths("docs/ci.md", text) == []
    assert missing_paths("docs/other.md", text) == ["docs/other.md: `evaluation/baseline.py`"]


def test_every_listed_exception_is_still_needed() -> None:
    """An output that now exists, or history a page no longer states, leaves its list."""
    texts = {str(p.relative_to(ROOT)): p.read_text("utf-8") for p in _pages()}
    # a local build or run folder may exist in a working copy; a publication once committed may not
    stale = [path for path in OUTPUTS if (ROOT / path).exists() and not path.startswith(LOCAL)]
    stale += [f"{name}: {path}" for name, path in HISTORY if f"`{path}`" not in texts.get(name, "")]
    assert stale == []
