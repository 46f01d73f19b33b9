"""docs/getting_started.md's install section names every dependency pyproject.toml declares: each
core dependency in its "Core dependencies" paragraph, and each extra in a row of its table with
every package the extra installs (the list had left out five extras, pyyaml and hypothesis of
``[test]``, scikit-learn of ``[bench]`` and four core dependencies)."""

from __future__ import annotations

import re
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the core install's tomli backport
    import tomli as tomllib  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parents[1]
PAGE = (ROOT / "docs" / "getting_started.md").read_text(encoding="utf-8")
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def _name(requirement: str) -> str:
    """A requirement's distribution name, lower case (``"ruff==0.17.6"`` -> ``"ruff"``)."""
    match = re.match(r"[A-Za-z0-9][A-Za-z0-9._-]*", requirement.strip())
    assert match, requirement
    return match[0].lower()


def _core_paragraph() -> str:
    start = PAGE.index("Core dependencies:")
    return PAGE[start : PAGE.index("\n\n", start)].lower()


def _extra_rows() -> dict[str, str]:
    return {m[1]: m[2].lower() for m in re.finditer(r"^\| `\[([\w-]+)\]` \| ([^|]+) \|", PAGE, re.M)}


def test_every_core_dependency_is_named() -> None:
    paragraph = _core_paragraph()
    missing = [_name(r) for r in PROJECT["dependencies"] if _name(r) not in paragraph]
    assert missing == [], f"docs/getting_started.md's core dependencies leave out {missing}"


def test_every_extra_has_a_row_naming_its_packages() -> None:
    rows = _extra_rows()
    extras = PROJECT["optional-dependencies"]
    assert sorted(rows) == sorted(extras), "the table's extras are not pyproject.toml's"
    missing = {
        extra: [_name(r) for r in packages if _name(r) not in rows[extra]]
        for extra, packages in extras.items()
        if any(_name(r) not in rows[extra] for r in packages)
    }
    assert missing == {}, f"rows that leave out packages of their extra: {missing}"


def test_the_check_reads_the_page_it_claims() -> None:
    # the parsers find what they check: a row per extra and a paragraph that names numpy
    assert len(_extra_rows()) >= 10 and "numpy" in _core_paragraph()
    assert _name("tomli>=1.1; python_version < '3.11'") == "tomli"
