"""The audit of the hand-written docs pages' numbers (issue 60, "prose that cannot drift"): one
machinery for every page; each page's test file (tests/test_hand_pages*.py) holds only that
page's claims and lists, in an :class:`Audit`.

Every result-like token of a page (:func:`result_tokens`: a rate, a count "N of M" or "N/M", a
p-value, a family size, a quantity with its unit, a ratio written with its "x" such as ``0.47x``,
and every number of a table cell that holds numbers only) is one of:

- **checked against its source** by a :class:`Claim` (a pattern and the check that holds it to
  the committed data, the code or the rows another test rebuilds from the data). A number
  checked against the code equals the code's value exactly (:func:`code_value`); a claim that
  means a rounded figure says so with ``places``;
- **a repeat** of a number of a table of its own section (:attr:`Audit.repeats`), so an edit of
  the prose alone fails: of a row its sentence names (the row's label, :func:`named_rows`: a
  figure of any row of the tables would let about half of all edits through);
- **a measurement with no committed record** (:attr:`Audit.measured`: the phrase as the page
  states it, and the command that measured it), pinned word for word, so an edit fails too;
- **no result** (:attr:`Audit.not_results`: a definition, a setting or an input that reads like
  one).

:func:`page_problems` names every token none of these covers (page, line and token), every claim
or pinned phrase the page no longer states, and every check that fails.
"""

from __future__ import annotations

import functools
import json
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from koopman_envs.params import SLIP_SURFACES

ROOT = Path(__file__).resolve().parents[2]

# --------------------------------------------------------------------------- result-like tokens
NUM = r"\d+(?:,\d{3})*(?:\.\d+)?(?:e-?\d+)?"
RANGE = rf"{NUM}(?:\s?-\s?{NUM})?"
UNITS = (
    r"%|points|CPU-seconds|CPU-s|CPU-hours|CPU-minutes|seconds|s|ms|us|min|minutes|h|hours"
    r"|robot-steps/s|frames/s|env-steps/s|m/s|KB|MB|MiB|bytes|lines|rows|episodes|controllers"
    r"|cm|mm|times|-fold"
)
#: a result-like number in running text
RESULT = re.compile(
    r"(?<![\w.])(?:"
    rf"{NUM}/{NUM}(?![\w/])"  # N/M
    rf"|{NUM} of (?:the )?{NUM}"  # N of M
    rf"|p\s?[=<>]\s?{NUM}"  # a p-value
    rf"|\bm = {NUM}"  # a family's size
    rf"|{RANGE}\s?(?:{UNITS})(?![\w/])"  # a quantity with its unit
    r")"
)
#: a ratio written with its "x" (``0.47x``, ``12.72x``, ``7x faster``)
RATIO = re.compile(r"(?<![\w.])\d+(?:\.\d+)?x(?![\w])")
#: a table cell that holds numbers only (every number in it is a result)
CELL_CHARS = re.compile(r"(?:[\d.,/()+\-=\s*]|\bx\b|\bus\b|\bpoints\b|%|\babout\b|\bmore than\b)+")


def prose(text: str) -> str:
    """``text`` with what is not prose blanked (positions kept): python and bash blocks (run or
    parsed by other tests), HTML comments, inline code and link targets."""

    def blank(match: re.Match[str]) -> str:
        return re.sub(r"[^\n]", " ", match[0])

    text = re.sub(r"```(?:python|bash)\n.*?```", blank, text, flags=re.S)
    text = re.sub(r"<!--.*?-->", blank, text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", blank, text)
    return re.sub(r"\]\([^)]*\)", blank, text)


def result_tokens(text: str) -> list[tuple[int, int]]:
    """The spans of every result-like token of ``text``: :data:`RESULT` and :data:`RATIO` in
    running text (a ratio inside a token of :data:`RESULT` left to it), and every number of a
    table cell that holds numbers only (a table's rule row left out)."""
    text = prose(text)
    spans = [m.span() for m in RESULT.finditer(text)]
    for row in re.finditer(r"^\|.*\|$", text, re.M):
        if re.fullmatch(r"[|\s:-]+", row[0]):
            continue
        start = row.start()
        for cell in re.finditer(r"[^|]+", row[0]):
            if re.search(r"\d", cell[0]) and CELL_CHARS.fullmatch(cell[0]):
                base = start + cell.start()
                spans += [(base + n.start(), base + n.end()) for n in re.finditer(NUM, cell[0])]
    ratios = [m.span() for m in RATIO.finditer(text)]
    spans += [(a, b) for a, b in ratios if not any(s <= a and b <= e for s, e in spans)]
    return sorted(set(spans))


def numbers(token: str) -> list[str]:
    """The numbers of a token, thousands separators dropped (``1,200`` -> ``1200``)."""
    return [n.replace(",", "") for n in re.findall(NUM, token)]


# --------------------------------------------------------------------------- claims
#: a check: the match of a claim's pattern (``match.string`` is the whole page) -> its problems
CheckFn = Callable[[re.Match[str]], list[str]]


@dataclass(frozen=True)
class Claim:
    """A statement of a page: ``pattern`` finds it, ``check`` holds it to its source (``by``
    names what does). It covers the tokens of its groups (a pattern without groups, or a
    ``whole`` one: every token inside its match)."""

    pattern: re.Pattern[str]
    check: CheckFn
    by: str
    #: the check reads the whole match (else only its groups, and the tokens they fall in)
    whole: bool = False


def exact(text: str) -> re.Pattern[str]:
    """``text`` as a pattern, a line break or a run of spaces matching any whitespace."""
    return re.compile(r"\s+".join(re.escape(word) for word in text.split()))


def rows(lines: Iterable[str], by: str) -> list[Claim]:
    """Rows another test (or a check of the page's file) writes from the data, each found whole."""
    return [
        Claim(re.compile("^" + re.escape(row) + "$", re.M), lambda m: [], by, whole=True) for row in lines
    ]


def whole_page(problems: Callable[[str], list[str]]) -> CheckFn:
    """A check of the whole page by an existing function of the page's text."""
    return lambda match: problems(match.string)


def same(stated: object, actual: object, what: str) -> list[str]:
    return [] if stated == actual else [f"{what} is stated as {stated}; the source gives {actual}"]


def code_value(stated: str, actual: float, what: str, places: int | None = None) -> list[str]:
    """A number ``stated`` by the page (thousands separators allowed) against the code's value:
    equal to it (to 6 places, for the float's noise), or, where the claim says the page rounds,
    to ``actual`` rounded to ``places``. A "0.1" for 0.05 fails unless the claim asks for 1 place."""
    value = float(stated.replace(",", ""))
    return same(value, round(actual, 6 if places is None else places), what)


# --------------------------------------------------------------------------- one page's audit
@dataclass(frozen=True)
class Audit:
    """What covers the result-like tokens of one page."""

    #: the page's file name under docs/
    page: str
    #: the test file that holds the page's claims and lists (named in the problems)
    owner: str
    claims: Callable[[], Iterable[Claim]]
    #: a measurement with no committed record: the phrase as stated -> what measured it
    measured: dict[str, str] = field(default_factory=dict)
    #: a setting, a definition or an input that reads like a result -> why it is none
    not_results: dict[str, str] = field(default_factory=dict)
    #: (first heading, the heading that ends the region; "" the page's end): a token of the
    #: region's prose is a repeat when each of its numbers is a number of a row of the region's
    #: tables that its sentence names (the row's label: a controller, a floor, a lift)
    repeats: list[tuple[str, str]] = field(default_factory=list)
    #: (first heading, the heading that ends it, why): regions not audited
    left_out: list[tuple[str, str, str]] = field(default_factory=list)

    @functools.cached_property
    def built(self) -> tuple[Claim, ...]:
        return tuple(self.claims())

    def read(self) -> str:
        return read(self.page)


def read(page: str) -> str:
    return (ROOT / "docs" / page).read_text(encoding="utf-8")


def region(text: str, start: str, end: str) -> tuple[int, int]:
    """The span from the heading line ``start`` to the heading line ``end`` ("": the page's end)."""
    first = text.index("\n" + start + "\n")
    return first, (text.index("\n" + end + "\n", first) if end else len(text))


@dataclass(frozen=True)
class Row:
    """A table row of a repeats region: its labels (its first cell and every other cell that
    names, :data:`NAME_CELL`, lower case, markup dropped: a controller, a floor, a lift, a plant;
    an empty first cell takes the row above's), each as
    the names that name it (:func:`_names`), and its numbers (thousands separators dropped)."""

    labels: tuple[tuple[str, ...], ...]
    numbers: tuple[str, ...]


def _plain(text: str) -> str:
    """``text`` lower case, without markdown's emphasis and code marks, its whitespace single."""
    return " ".join(re.sub(r"[`*_]", "", text).lower().split())


#: a table cell that names (a controller, a lift, a plant): it starts with a letter and holds no
#: comma or colon (a cell such as ``time limit, 600: 1, 202, 1`` describes, it does not name)
NAME_CELL = re.compile(r"[a-z][^,:]*")
#: the plants as a table names them and as prose does
PLANT_NAMES = {"mujoco": "physics"}


def _names(label: str) -> list[str]:
    """What names a row's label: itself, each of its parts around parentheses (``high (ice)``:
    ``high``, ``ice``), a slip level's surface (``nominal``: ``carpet``, as the pages call it)
    and a plant's name in prose (:data:`PLANT_NAMES`)."""
    parts = [part.strip() for part in re.split(r"[()]", label) if part.strip()]
    aliases = {**SLIP_SURFACES, **PLANT_NAMES}
    return [label, *parts, *(aliases[part] for part in parts if part in aliases)]


def table_rows(text: str) -> list[Row]:
    """The rows of the tables of ``text`` (a rule row left out)."""
    found: list[Row] = []
    above = ""
    for row in re.finditer(r"^\|.*\|$", text, re.M):
        if re.fullmatch(r"[|\s:-]+", row[0]):
            above = ""
            continue
        cells = [_plain(cell) for cell in row[0].strip().strip("|").split("|")]
        first = cells[0] or above
        above = first
        words = [first] if first else []
        words += [cell for cell in cells[1:] if NAME_CELL.fullmatch(cell) and not CELL_CHARS.fullmatch(cell)]
        labels = tuple(tuple(dict.fromkeys(_names(word))) for word in dict.fromkeys(words))
        found.append(Row(labels, tuple(n.replace(",", "") for n in re.findall(NUM, prose(row[0])))))
    return found


def table_numbers(text: str) -> list[str]:
    return [n for row in table_rows(text) for n in row.numbers]


#: where a sentence ends: a full stop, "!" or "?" before a capital, a blank line, a list item
SENTENCE_END = re.compile(r"[.!?]\)?\s+(?=[A-Z*(`\[])|\n\s*\n|\n\s*(?:[-*]|\d+\.)\s")


def sentence(text: str, start: int, end: int) -> str:
    """The sentence of ``text`` around the span ``start:end`` (:data:`SENTENCE_END`), plain."""
    ends = [m.span() for m in SENTENCE_END.finditer(text)]
    first = max((b for a, b in ends if b <= start), default=0)
    last = min((a for a, b in ends if a >= end), default=len(text))
    return _plain(text[first:last])


def named_rows(rows: Iterable[Row], words: str) -> list[Row]:
    """The rows ``words`` (a plain sentence) names: every label of the row by one of its names,
    as whole words (a row of ``high (ice)`` and ``memory 3`` needs both: "memory 3 on ice"). A
    name inside a longer one the sentence states does not count ("memory 3 + velocity" names
    no ``velocity`` row)."""
    rows = list(rows)
    every = {name for row in rows for label in row.labels for name in label}

    def spans(name: str) -> list[tuple[int, int]]:
        return [m.span() for m in re.finditer(rf"(?<![\w-]){re.escape(name)}(?![\w-])", words)]

    longer = [span for name in every for span in spans(name)]

    def names(name: str) -> bool:
        return any(
            not any(a <= start and end <= b and (a, b) != (start, end) for a, b in longer)
            for start, end in spans(name)
        )

    return [row for row in rows if row.labels and all(any(names(n) for n in label) for label in row.labels)]


def is_repeat(token: str, table: list[str]) -> bool:
    """Each number of ``token`` is a number of ``table``: the same count, a decimal rounded to
    the places the token gives, or a percentage of a table's fraction (97 % of 0.97) or of its
    percentages (95% of a ``95% [90-98]`` cell). :func:`page_problems` passes the numbers of the
    rows the token's sentence names only (:func:`named_rows`)."""

    def matches(number: str) -> bool:
        if "." not in number:  # a count: the same number
            return number in table
        places, value = len(number.split(".")[1]), float(number)
        return any("." in t and round(float(t), places) == value for t in table)

    def percent(number: str) -> bool:
        return number in table or any(
            t.startswith("0.") and round(100 * float(t), 6) == float(number) for t in table
        )

    if token.rstrip().endswith("%"):
        return all(percent(n) for n in numbers(token))
    return all(matches(n) for n in numbers(token))


def page_problems(text: str, audit: Audit) -> list[str]:
    """Every way ``text`` (the page of ``audit``, or an edited copy) breaks the audit: a claim
    gone or failing, a pinned phrase gone, a result-like token that nothing covers (named with
    its line)."""
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
            found = list(exact(phrase).finditer(text))
            if not found:
                problems.append(f"{page} no longer states the {kind} {phrase!r}: update {audit.owner}")
            for match in found:
                covered.update(range(*match.span()))
    left_out = [region(text, a, b) for a, b, _ in audit.left_out]
    repeats = [region(text, a, b) for a, b in audit.repeats]
    tables = [table_rows(text[a:b]) for a, b in repeats]
    is_row = {m.start() for m in re.finditer(r"^\|", text, re.M)}
    for start, end in tokens:
        if covered.issuperset(range(start, end)) or any(a <= start < b for a, b in left_out):
            continue
        token = text[start:end]
        line_start = text.rfind("\n", 0, start) + 1
        if line_start not in is_row and any(
            a <= start < b
            and is_repeat(
                token, [n for row in named_rows(table, sentence(text, start, end)) for n in row.numbers]
            )
            for (a, b), table in zip(repeats, tables, strict=True)
        ):
            continue
        line = text.count("\n", 0, start) + 1
        problems.append(f"docs/{page} line {line}: {token!r} is checked by nothing")
    return list(dict.fromkeys(problems))


def line_of(text: str, phrase: str) -> int:
    """The line (1-based) of ``text`` on which ``phrase`` first starts."""
    return text[: text.index(phrase)].count("\n") + 1


def typed_into(audit: Audit, after: str, typed: str) -> tuple[str, int]:
    """The page of ``audit`` with the line ``typed`` added after ``after`` (a line the page
    states once), and the line ``typed`` is on."""
    text = audit.read()
    assert text.count(after) == 1, f"docs/{audit.page} states {after!r} {text.count(after)} times"
    edited = text.replace(after, after + "\n" + typed)
    return edited, line_of(edited, typed)


def pinned_problems(audit: Audit) -> list[str]:
    """The pinned phrases of ``audit`` that hold no result-like token or do not say why."""
    problems = []
    for phrases in (audit.measured, audit.not_results):
        problems += [
            f"{phrase!r} holds no result-like token" for phrase in phrases if not result_tokens(phrase)
        ]
        problems += [
            f"{phrase!r}: {why!r} says too little" for phrase, why in phrases.items() if len(why) <= 20
        ]
    return problems


def shipped_seed_problems(
    match: re.Match[str], *, budget: bool = False, policy: str = "rl-ppo-set"
) -> list[str]:
    """A claim "TASK seed K (validation S/E, mean final distance D m, kept checkpoint step C of T
    trained[, budget B])" (groups: task, K, S, E, D, then C, T[, B]) against the shipped policy's
    ``metadata.json`` for the task: docs/benchmark.md's sentence and docs/rl.md's tables.
    ``rl-ppo-set`` counts robot-steps (``budget``: its last column, the run's planned robot-steps);
    ``ippo`` counts BenchMARL's frames (its runs train exactly their budget)."""
    task = match[1].replace(" ", "_")
    folder = {"rl-ppo-set": "set", "ippo": "ippo"}[policy]
    m = json.loads((ROOT / "baselines" / "policies" / folder / task / "metadata.json").read_text())
    chosen = m["selection"]["chosen"]
    stated = [int(match[2]), int(match[3]), int(match[4]), match[5]]
    stated += [int(g.replace(",", "")) for g in match.groups()[5:]]
    trained = m["trained_timesteps"] if policy == "rl-ppo-set" else m["frames"]
    actual = [
        m["seed"],
        chosen["successes"],
        chosen["episodes"],
        f"{chosen['mean_final_distance']:.2f}",
        chosen["step"],
        trained,
        *([m["timesteps"]] if budget else []),
    ]
    return same(stated, actual, f"{policy}'s shipped {task} seed")
