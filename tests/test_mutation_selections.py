""".ci/mutation.sh's test selections hold every test file that imports the mutated module (issue 59).

A test file left out of a module's selection lets the mutants it would kill survive (Holm without
its step-down maximum survived the statistics selection without tests/test_distinct_statistics.py),
so the script's claim that a selection is every importing test file is checked here, by reading
the script's MODULES table and the tests' imports.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = (ROOT / ".ci" / "mutation.sh").read_text(encoding="utf-8")


def _selections() -> dict[str, tuple[str, set[str]]]:
    """Module name -> (the file it mutates, the test files of its selection, globs expanded)."""
    shell = dict(re.findall(r'^([A-Z_]+)="([^"]*)"$', SCRIPT, flags=re.M))
    table: dict[str, tuple[str, set[str]]] = {}
    for name, entry in re.findall(r'^\s+\[([\w-]+)\]="([^"]+)"$', SCRIPT, flags=re.M):
        target, selection = entry.split("|")[:2]
        files: set[str] = set()
        for item in selection.split():
            item = re.sub(r"\$(\w+)", lambda m: shell.get(m[1], ""), item).split("::")[0]
            files |= {str(p.relative_to(ROOT)) for p in ROOT.glob(item)}
        table[name] = (target, files)
    return table


def _importers(target: str) -> set[str]:
    dotted = target.removesuffix(".py").replace("/", ".")
    package, name = dotted.rsplit(".", 1)
    pattern = re.compile(
        rf"^\s*(?:import {re.escape(dotted)}\b|from {re.escape(dotted)} import"
        rf"|from {re.escape(package)} import [^\n]*\b{name}\b)",
        flags=re.M,
    )
    return {
        str(path.relative_to(ROOT))
        for path in sorted((ROOT / "tests").glob("test_*.py"))
        if pattern.search(path.read_text(encoding="utf-8"))
    }


def _left_out() -> dict[str, set[str]]:
    """The script's declared exceptions: `# not selected: MODULE FILE ...` lines, each with its reason."""
    declared: dict[str, set[str]] = {}
    for module, files in re.findall(r"^# not selected: ([\w-]+) ([^:]+):", SCRIPT, flags=re.M):
        declared.setdefault(module, set()).update(files.split())
    return declared


def test_the_table_is_read() -> None:
    table = _selections()
    assert {"baseline", "statistics", "runlog", "records", "published", "publications"} <= table.keys()
    assert "tests/test_distinct_statistics.py" in table["statistics"][1]


@pytest.mark.parametrize("module", sorted(_selections()))
def test_every_importing_test_file_is_selected(module: str) -> None:
    target, selected = _selections()[module]
    assert (ROOT / target).is_file(), target
    missing = _importers(target) - selected - _left_out().get(module, set())
    assert not missing, f"{module}: {sorted(missing)} import {target} but are not in its selection"
