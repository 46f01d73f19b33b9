"""Every ```python block of README.md and docs/*.md runs and prints what the page says it
prints, and every relative link resolves.

The blocks of one page run in order in one namespace (a later block may use an earlier one's
``env``), with the working directory a fresh temporary folder. What a block prints is its
``print`` output plus, as in an interactive session, the repr of a final bare expression (the
docs end blocks with ``info["poses"], ...`` to show a value). The line right after a block's
closing fence, ``<!-- prints: REGEX -->``, says what that output must contain (``re.search``,
one line of regex; invisible in the rendered page); every block that runs has one. A block
preceded by the line ``<!-- no-test: why -->`` is skipped; the reason is required and such
blocks stay rare (training for minutes, a fragment that is only a signature). ```bash blocks are
not run.
"""

from __future__ import annotations

import ast
import contextlib
import importlib.util
import io
import re
import traceback
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
PAGES = [p for p in PAGES if "_build" not in p.parts]

FENCE = re.compile(
    r"^(?P<indent> *)(?P<fence>```+)(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=indent)(?P=fence)[ \t]*$",
    re.DOTALL | re.MULTILINE,
)
SKIP = re.compile(r"<!--\s*no-test:\s*(?P<why>\S[^>]*?)\s*-->[ \t]*$", re.MULTILINE)
REQUIRES = re.compile(r"<!--\s*requires:\s*(?P<module>[\w.]+)\s*-->[ \t]*$", re.MULTILINE)
PRINTS = re.compile(r"\A\n[ \t]*<!-- prints: (?P<regex>.+?) -->[ \t]*$", re.MULTILINE)
#: at most this many skipped blocks over all pages: a skip needs a reason, and the docs should run
MAX_SKIPS = 4


def python_blocks(text: str) -> list[tuple[int, str, str | None]]:
    """``(line, code, skip_reason)`` for every ```python fenced block of a Markdown text."""
    return [(line, code, why) for line, code, why, _ in _blocks(text)]


def _blocks(text: str) -> list[tuple[int, str, str | None, str | None]]:
    """``(line, code, skip_reason, prints)`` for every ```python fenced block; ``prints`` is the
    regex of the ``<!-- prints: ... -->`` line right after it, or None."""
    blocks = []
    for m in FENCE.finditer(text):
        if m["info"].strip().split(" ")[0] not in ("python", "py", "{code-block} python"):
            continue
        line = text.count("\n", 0, m.start()) + 1
        before = text[: m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        skip, needs = SKIP.search(before), REQUIRES.search(before)
        why = skip["why"] if skip else None
        if needs and importlib.util.find_spec(needs["module"]) is None:
            why = f"needs {needs['module']}, not installed"
        indent = len(m["indent"])
        code = "\n".join(row[indent:] for row in m["body"].split("\n"))
        prints = PRINTS.search(text[m.end() :])
        blocks.append((line, code, why, prints["regex"] if prints else None))
    return blocks


def run_block(code: str, filename: str, namespace: dict) -> str:
    """Run ``code`` in ``namespace`` and return what it printed, a final bare expression's repr
    included (as an interactive session shows it)."""
    tree = ast.parse(code, filename)
    shown = tree.body[-1] if tree.body else None
    if isinstance(shown, ast.Expr):
        tree.body.pop()
    else:
        shown = None
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(tree, filename, "exec"), namespace)  # noqa: S102 - running the docs is the test
        if shown is not None:
            value = eval(compile(ast.Expression(shown.value), filename, "eval"), namespace)  # noqa: S307
            if value is not None:
                print(repr(value))
    return out.getvalue()


def _rel(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


@pytest.mark.parametrize("page", [p for p in PAGES if python_blocks(p.read_text())], ids=_rel)
def test_the_python_blocks_of_a_page_run(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": f"docs_snippets_{page.stem}"}
    for line, code, skip, prints in _blocks(page.read_text()):
        if skip:
            continue
        where = f"{_rel(page)}:{line}"
        assert prints is not None, f"{where}: no '<!-- prints: REGEX -->' line right after the block"
        try:
            out = run_block(code, where, namespace)
        except Exception:  # noqa: BLE001 - name the block, then fail
            pytest.fail(f"{_rel(page)}, the python block at line {line} raised:\n{traceback.format_exc()}")
        assert re.search(prints, out, re.MULTILINE), (
            f"{where} printed:\n{out[-2000:]}\nnot matching {prints!r}"
        )
    for value in namespace.values():  # close what the page opened (envs with figures)
        close = getattr(value, "close", None)
        if callable(close) and hasattr(value, "unwrapped"):
            close()


def test_skipped_blocks_are_rare_and_say_why() -> None:
    skipped = [
        (p, line, why)
        for p in PAGES
        for line, _, why in python_blocks(p.read_text())
        if why and not why.startswith("needs ")
    ]
    assert len(skipped) <= MAX_SKIPS, skipped
    assert all(len(why) >= 10 for _, _, why in skipped), skipped
    for page in PAGES:  # a marker that does not sit right before a python block is a mistake
        text = page.read_text()
        assert text.count("no-test") == len(SKIP.findall(text)), _rel(page)
        assert text.count("requires:") == len(REQUIRES.findall(text)), _rel(page)
        # a prints line that follows no python block would check nothing
        assert text.count("<!-- prints:") == sum(p is not None for *_, p in _blocks(text)), _rel(page)


def test_the_readme_and_the_docs_have_snippets() -> None:
    counts = {_rel(p): len(python_blocks(p.read_text())) for p in PAGES}
    assert counts["README.md"] >= 2 and counts["docs/getting_started.md"] >= 3, counts


# --- links ----------------------------------------------------------------------------------------

LINK = re.compile(r"(?<!!)\[[^\]]*\]\((?P<target>[^)\s]+)\)|!\[[^\]]*\]\((?P<image>[^)\s]+)\)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$", re.MULTILINE)


def slug(title: str) -> str:
    """The anchor of a heading, as GitHub and MyST (``myst_heading_anchors``) make it."""
    title = re.sub(r"`([^`]*)`", r"\1", title)
    title = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", title)
    return re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text())
    return {slug(m[2]) for m in HEADING.finditer(text)} | set(
        re.findall(r"\(([\w-]+)\)=\s*$", text, re.MULTILINE)
    )


def broken_links(page: Path) -> list[str]:
    text = FENCE.sub("", page.read_text())
    text = re.sub(r"`[^`\n]*`", "", text)  # inline code is not a link
    bad = []
    # docs/_intros/ holds text a page script inserts into a page of docs/: its links are docs/'s
    base = page.parent.parent if page.parent.name == "_intros" else page.parent
    for m in LINK.finditer(text):
        target = m["target"] or m["image"]
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, mailto:, ...: not checked here
            continue
        path, _, anchor = target.partition("#")
        dest = (base / path).resolve() if path else page
        if not dest.exists():
            bad.append(f"{target}: no file {dest}")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no heading with anchor #{anchor} in {_rel(dest)}")
    return bad


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_relative_links_resolve(page: Path) -> None:
    assert broken_links(page) == []


def test_the_controller_options_page_is_what_the_specs_generate() -> None:
    """docs/controller_options.md is generated from controllers.options; regenerate it with
    `python docs/make_options_md.py` after changing a controller's options."""
    pytest.importorskip("stable_baselines3")  # the page lists the RL controllers' options too
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("make_options_md", root / "docs" / "make_options_md.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert (root / "docs" / "controller_options.md").read_text(encoding="utf-8") == module.page()
