"""The audit of tests/test_hand_pages.py (issue 60) for any hand-written page: its
``page_problems`` reads the module's fixed ``claims``, ``MEASURED``, ``NOT_RESULTS``, ``REPEATS``
and ``LEFT_OUT`` (keyed by the two pages it covers), so the pages audited elsewhere
(tests/test_hand_pages_rl.py, tests/test_hand_pages_controllers.py) pass theirs in through
:class:`Audit`. The same token rules, claims, repeats and pinning; only the tables differ.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable
from dataclasses import dataclass, field

from test_hand_pages import (
    NUM,
    Claim,
    _exact,
    _is_repeat,
    _region,
    _table_numbers,
    result_tokens,
)


@dataclass(frozen=True)
class Audit:
    """What covers the result-like tokens of one page (see tests/test_hand_pages.py)."""

    page: str
    #: the test file that holds the tables (named in the problems)
    owner: str
    claims: Callable[[], list[Claim]]
    measured: dict[str, str]
    not_results: dict[str, str]
    #: (first heading, the heading that ends the region): a token of its prose repeating a
    #: number of one of its tables (""  as the end: the page's end)
    repeats: list[tuple[str, str]] = field(default_factory=list)

    @functools.cached_property
    def built(self) -> tuple[Claim, ...]:
        return tuple(self.claims())


def _span(text: str, start: str, end: str) -> tuple[int, int]:
    if end:
        return _region(text, start, end)
    return text.index("\n" + start + "\n"), len(text)


def page_problems(audit: Audit, text: str) -> list[str]:
    """Every way ``text`` (the page of ``audit``) breaks the audit: a claim gone or failing, a
    pinned phrase gone, a result-like token that nothing covers (named with its line)."""
    page = audit.page
    covered: set[int] = set()
    problems: list[str] = []
    groups: list[tuple[int, int]] = []
    for claim in audit.built:
        found = list(claim.pattern.finditer(text))
        if not found:
            problems.append(
                f"{page} no longer states {claim.pattern.pattern[:120]!r} (checked by {claim.by})"
            )
        for match in found:
            problems += claim.check(match)
            if claim.whole or not claim.pattern.groups:
                covered.update(range(*match.span()))
            else:
                groups += [match.span(i) for i in range(1, claim.pattern.groups + 1) if match[i] is not None]
    tokens = result_tokens(text)
    for start, end in tokens:
        if any(a < end and start < b for a, b in groups):
            covered.update(range(start, end))
    for phrases, kind in ((audit.measured, "measurement"), (audit.not_results, "non-result")):
        for phrase in phrases:
            found = list(_exact(phrase).finditer(text))
            if not found:
                problems.append(f"{page} no longer states the {kind} {phrase!r}: update {audit.owner}")
            for match in found:
                covered.update(range(*match.span()))
    repeats = [_span(text, a, b) for a, b in audit.repeats]
    tables = [_table_numbers(text[a:b]) for a, b in repeats]
    is_row = {m.start() for m in re.finditer(r"^\|", text, re.M)}
    for start, end in tokens:
        if covered.issuperset(range(start, end)):
            continue
        token = text[start:end]
        line_start = text.rfind("\n", 0, start) + 1
        if line_start not in is_row and any(
            a <= start < b and _is_repeat(token, table) for (a, b), table in zip(repeats, tables, strict=True)
        ):
            continue
        line = text.count("\n", 0, start) + 1
        problems.append(f"docs/{page} line {line}: {token!r} is checked by nothing")
    return list(dict.fromkeys(problems))


__all__ = ["NUM", "Audit", "page_problems"]
