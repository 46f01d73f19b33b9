""".ci/mutation.sh run for real on a repository of one tiny module that stands in for
``evaluation/episodes/records.py`` (tests/test_mutation_script.py, tests/test_mutation_store.py)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
from pathlib import Path

#: the checkout's script, run on the tiny repository
#: why a test of the script cannot run here, or None: the script runs mutmut from PATH and reads its
#: verdicts with python3's mutmut, so both must be installed (a venv without mutmut beside a
#: mutmut on PATH skips, where it failed)
MUTMUT_MISSING = (
    "mutmut is not on PATH"
    if shutil.which("mutmut") is None
    else "mutmut is not installed in this environment"
    if importlib.util.find_spec("mutmut") is None
    else None
)
SCRIPT = Path(__file__).resolve().parents[2] / ".ci" / "mutation.sh"

# x > 2 as x >= 2 survives the test (both agree at 1 and 3); the other mutants are killed
TINY = {
    "pyproject.toml": "[project]\nname = 'tiny'\nversion = '0'\n",
    "evaluation/__init__.py": "",
    "evaluation/episodes/__init__.py": "",
    "evaluation/episodes/records.py": (
        "def grade(x):\n    if x > 2:\n        return x * 3\n    return x - 1\n"
    ),
    "tests/test_records.py": (
        "from evaluation.episodes.records import grade\n\n\n"
        "def test_grade():\n    assert grade(3) == 9\n    assert grade(1) == 0\n"
    ),
}


def git(repo: Path, *args: str) -> str:
    """``git ARGS`` in ``repo`` as a user of its own; what it printed, stripped."""
    command = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(repo), *args]
    return subprocess.run(command, check=True, capture_output=True, text=True).stdout.strip()


def tiny_source(source: Path) -> Path:
    """The repository of :data:`TINY` at ``source``, its files in one commit."""
    for name, text in TINY.items():
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        (source / name).write_text(text)
    git(source, "init", "-q")
    git(source, "add", ".")
    git(source, "commit", "-qm", "tiny")
    return source


def run_script(
    source: Path, store: Path, workdir: Path | None = None, **extra: str
) -> subprocess.CompletedProcess[str]:
    """``.ci/mutation.sh records`` on the repository at ``source``, one job, a score of 50% to
    pass, the committed verdicts in ``store``, and the clone kept in ``workdir`` (None: every run a
    fresh clone, a new machine); ``extra``: more of the script's variables."""
    env = {**os.environ, "SOURCE": str(source), "STORE": str(store), "JOBS": "1", "MIN_SCORE": "50"}
    if workdir is None:
        env.pop("WORKDIR", None)
    else:
        env["WORKDIR"] = str(workdir)
    env.update(extra)
    env.pop("PYTHONPATH", None)  # the tiny repository's package, not this checkout's
    return subprocess.run(
        ["bash", str(SCRIPT), "records"], env=env, capture_output=True, text=True, timeout=900
    )


def score_line(result: subprocess.CompletedProcess[str]) -> str:
    """The line the script printed under ``== scores``."""
    lines = result.stdout.splitlines()
    return lines[lines.index("== scores") + 1]
