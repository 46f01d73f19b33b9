"""Every ```python block of README.md and docs/*.md runs alone and prints what the page says it
prints, and every relative link resolves.

Each block runs by itself in a process of its own, as a reader who pastes that one block would run
it: no earlier block's imports or variables, no module of this project imported (``import
koopman_envs`` registers the env ids, so a block that forgets it fails here as it would for the
reader). That process is forked from a server that has imported only third-party libraries
(:data:`PRELOADED`: numpy, numba, ...), which a fresh interpreter would import the same way: it
saves each block the interpreter's start and those imports (about 1.5 of a block's 2.4 CPU-s);
``run_alone``, a fresh interpreter (``python -c DRIVER`` with the block on stdin), stays the
reference, and a test checks that the forked runner sees what it sees. The working directory is
a fresh temporary folder. What
a block prints is its ``print`` output plus, as in an interactive session, the repr of a final bare
expression (the docs end blocks with ``info["poses"], ...`` to show a value). The line right after
a block's closing fence, ``<!-- prints: REGEX -->``, says what that output must contain
(``re.search``, one line of regex; invisible in the rendered page); every block that runs has one.
A block preceded by the line ``<!-- no-test: why -->`` is skipped; the reason is required and such
blocks stay rare (training for minutes, a fragment that is only a signature). A block preceded by
``<!-- requires: module -->`` is skipped when that module is not installed (an optional extra).
A block preceded by ``<!-- slow: tests/test_x.py why -->`` runs with ``-m slow`` only (CI runs both):
a block of many seconds whose behaviour the named test file checks in the default run. These
markers may stand together, one per line, right above the block. ```bash blocks are not run.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import select
import signal
import subprocess
import sys
from collections.abc import Iterator
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
SLOW = re.compile(r"<!--\s*slow:\s*(?P<covered>tests/\S+\.py)\s+(?P<why>\S[^>]*?)\s*-->[ \t]*$", re.MULTILINE)
#: the HTML comment lines right above a block, where its markers stand
MARKERS = re.compile(r"(?:^[ \t]*<!--[^\n]*-->[ \t]*\n)*\Z", re.MULTILINE)
PRINTS = re.compile(r"\A\n[ \t]*<!-- prints: (?P<regex>.+?) -->[ \t]*$", re.MULTILINE)
#: at most this many skipped blocks over all pages: a skip needs a reason, and the docs should run
MAX_SKIPS = 4


def python_blocks(text: str) -> list[tuple[int, str, str | None]]:
    """``(line, code, skip_reason)`` for every ```python fenced block of a Markdown text."""
    return [(line, code, why) for line, code, why, *_ in _blocks(text)]


def _blocks(text: str) -> list[tuple[int, str, str | None, str | None, str | None]]:
    """``(line, code, skip_reason, prints, slow)`` for every ```python fenced block; ``prints`` is
    the regex of the ``<!-- prints: ... -->`` line right after it, or None; ``slow`` the test file
    its ``<!-- slow: ... -->`` marker names, or None."""
    blocks = []
    for m in FENCE.finditer(text):
        if m["info"].strip().split(" ")[0] not in ("python", "py", "{code-block} python"):
            continue
        line = text.count("\n", 0, m.start()) + 1
        above = text[: m.start()]
        before = above[MARKERS.search(above).start() :]  # type: ignore[union-attr]  # matches "" at least
        skip, needs, slow = SKIP.search(before), REQUIRES.search(before), SLOW.search(before)
        why = skip["why"] if skip else None
        if needs and importlib.util.find_spec(needs["module"]) is None:
            why = f"needs {needs['module']}, not installed"
        indent = len(m["indent"])
        code = "\n".join(row[indent:] for row in m["body"].split("\n"))
        prints = PRINTS.search(text[m.end() :])
        blocks.append(
            (line, code, why, prints["regex"] if prints else None, slow["covered"] if slow else None)
        )
    return blocks


#: what the fresh interpreter runs: the block (stdin) compiled under its page and line, then the
#: repr of a final bare expression printed, as an interactive session shows it
DRIVER = """
import ast, sys
code, where = sys.stdin.read(), sys.argv[1]
tree = ast.parse(code, where)
shown = tree.body.pop() if tree.body and isinstance(tree.body[-1], ast.Expr) else None
namespace = {"__name__": "__main__"}
exec(compile(tree, where, "exec"), namespace)
if shown is not None:
    value = eval(compile(ast.Expression(shown.value), where, "eval"), namespace)
    if value is not None:
        print(repr(value))
"""


#: what a block's process has imported before the block runs: third-party libraries only, never
#: this project's packages (a block that forgets ``import koopman_envs`` must still fail), each of
#: which a fresh interpreter imports the same way on the block's first import of it
PRELOADED = ("numpy", "numba", "gymnasium", "casadi", "scipy.stats")

#: the fork server: imports :data:`PRELOADED`, then for each request line (JSON: code, where, cwd,
#: out, err) forks a child that runs DRIVER on the block with its stdout and stderr in the files
#: ``out`` and ``err``, and answers the child's pid, then its exit code, one line each
SERVER = """
import atexit, json, os, sys, traceback
for name in sys.argv[1].split(","):
    __import__(name)
driver = sys.argv[2]
for line in sys.stdin:
    request = json.loads(line)
    pid = os.fork()
    if pid == 0:
        os.chdir(request["cwd"])
        for fd, path, mode in ((0, os.devnull, os.O_RDONLY), (1, request["out"], os.O_WRONLY), (2, request["err"], os.O_WRONLY)):
            os.dup2(os.open(path, mode), fd)
        sys.stdin = open(0, closefd=False)
        sys.argv = ["-c", request["where"]]
        status = 0
        try:
            exec(compile(driver, "<driver>", "exec"), {"__name__": "__main__", "CODE": request["code"]})
        except SystemExit as stop:
            status = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
            if not isinstance(stop.code, (int, type(None))):
                print(stop.code, file=sys.stderr)
        except BaseException:
            traceback.print_exc()
            status = 1
        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    print(pid, flush=True)
    print(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]), flush=True)
"""


class ForkedRunner:
    """Runs blocks as :func:`run_alone` does, each in a child forked from one server process that
    has imported :data:`PRELOADED` (and nothing of this project). Close it to end the server."""

    def __init__(self) -> None:
        preloaded = [name for name in PRELOADED if importlib.util.find_spec(name.split(".")[0])]
        self._server = subprocess.Popen(
            [sys.executable, "-c", SERVER, ",".join(preloaded), DRIVER.replace("sys.stdin.read()", "CODE")],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=_block_env(),
            text=True,
        )

    def run(self, code: str, where: str, cwd: Path, timeout: float = 900) -> subprocess.CompletedProcess[str]:
        """Run one block in a fresh child in ``cwd``; the same result as ``run_alone(code, where, cwd)``."""
        out, err = cwd / ".block-stdout", cwd / ".block-stderr"
        out.touch()
        err.touch()
        request = {"code": code, "where": where, "cwd": str(cwd), "out": str(out), "err": str(err)}
        assert self._server.stdin is not None and self._server.stdout is not None
        self._server.stdin.write(json.dumps(request) + "\n")
        self._server.stdin.flush()
        pid = int(self._server.stdout.readline())
        if not select.select([self._server.stdout], [], [], timeout)[0]:
            os.kill(pid, signal.SIGKILL)
            raise subprocess.TimeoutExpired(where, timeout)
        returncode = int(self._server.stdout.readline())
        stdout, stderr = out.read_text(), err.read_text()
        out.unlink()
        err.unlink()
        return subprocess.CompletedProcess([where], returncode, stdout, stderr)

    def close(self) -> None:
        """End the server (its stdin closed, it leaves its loop)."""
        assert self._server.stdin is not None
        self._server.stdin.close()
        self._server.wait(timeout=60)


@pytest.fixture(scope="module")
def forked() -> Iterator[ForkedRunner]:
    """One fork server for this module's blocks."""
    runner = ForkedRunner()
    yield runner
    runner.close()


def _block_env() -> dict[str, str]:
    """The environment of a block's process: matplotlib without a display, this checkout first on
    the path, as in the tests."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def run_alone(code: str, where: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run one block in a fresh interpreter in ``cwd``; its stdout is what it printed, a final
    bare expression's repr included. This checkout comes first on the path, as in the tests."""
    return subprocess.run(
        [sys.executable, "-c", DRIVER, where],
        input=code,
        cwd=cwd,
        env=_block_env(),
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )


def _rel(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def _every_block() -> list:
    """One pytest parameter per python block of every page, named ``page:line``."""
    return [
        pytest.param(
            f"{_rel(page)}:{line}",
            code,
            skip,
            prints,
            id=f"{_rel(page)}:{line}",
            marks=[pytest.mark.slow] if slow else [],
        )
        for page in PAGES
        for line, code, skip, prints, slow in _blocks(page.read_text())
    ]


@pytest.mark.parametrize(("where", "code", "skip", "prints"), _every_block())
def test_a_python_block_runs_alone_and_prints_what_its_page_says(
    where: str, code: str, skip: str | None, prints: str | None, tmp_path: Path, forked: ForkedRunner
) -> None:
    if skip:
        pytest.skip(skip)
    assert prints is not None, f"{where}: no '<!-- prints: REGEX -->' line right after the block"
    run = forked.run(code, where, tmp_path)
    assert run.returncode == 0, f"{where}, run alone in a process of its own, raised:\n{run.stderr[-4000:]}"
    assert re.search(prints, run.stdout, re.MULTILINE), (
        f"{where} printed:\n{run.stdout[-2000:]}\nnot matching {prints!r}"
    )


@pytest.mark.parametrize("runner", ["fresh", "forked"])
def test_a_block_that_leans_on_an_earlier_one_fails(
    runner: str, tmp_path: Path, forked: ForkedRunner
) -> None:
    """Both runners, the fresh interpreter and the fork server's child: a name or an env id an
    earlier block would have made is not there (the in-process runner the fresh interpreter
    replaced let both through), nor a module of this project, and the exit code, what was printed
    and the exit handlers are a fresh interpreter's."""
    run = run_alone if runner == "fresh" else forked.run
    assert run("import koopman_envs\nprint(1)", "first", tmp_path).returncode == 0
    assert "NameError" in run("gym.make('KoopNav-Formation-v0')", "second", tmp_path).stderr
    unregistered = run("import gymnasium as gym\ngym.make('KoopNav-Formation-v0')", "third", tmp_path)
    assert "NameNotFound" in unregistered.stderr or "not found" in unregistered.stderr, unregistered.stderr
    assert run("x = 1\nx + 1", "fourth", tmp_path).stdout == "2\n"
    ours = "import sys\nsorted(m for m in sys.modules if m.split('.')[0] in {'koopman_envs', 'controllers', 'baselines', 'evaluation'})"
    assert run(ours, "fifth", tmp_path).stdout == "[]\n"
    failed = run("print('before')\n1 / 0", "sixth", tmp_path)
    assert (failed.returncode, failed.stdout) == (1, "before\n") and "ZeroDivisionError" in failed.stderr
    assert run("raise SystemExit(3)", "seventh", tmp_path).returncode == 3
    assert (
        run("import atexit\natexit.register(print, 'bye')\nprint('hi')", "eighth", tmp_path).stdout
        == "hi\nbye\n"
    )
    assert run("import os\nprint(os.getcwd())", "ninth", tmp_path).stdout == f"{tmp_path}\n"


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
        assert text.count("<!-- prints:") == sum(b[3] is not None for b in _blocks(text)), _rel(page)
        # a slow marker stands right above a python block and names the test file that checks the
        # block's behaviour in the default run
        covered = [b[4] for b in _blocks(text) if b[4] is not None]
        assert text.count("<!-- slow:") == len(covered), _rel(page)
        assert all((ROOT / name).is_file() for name in covered), (_rel(page), covered)


def test_the_readme_and_the_docs_have_snippets() -> None:
    counts = {_rel(p): len(python_blocks(p.read_text())) for p in PAGES}
    # README: one short first episode; getting started: env, controller, PettingZoo, vector env
    assert counts["README.md"] >= 1 and counts["docs/getting_started.md"] >= 3, counts


#: README's first command and the time it states: ``... python evaluate.py  # install, run the
#: quick leaderboard (TIME)``
QUICK_TIME = re.compile(r"python evaluate\.py +# install, run the quick leaderboard \((?P<time>[^)]+)\)")


def test_the_quick_leaderboard_has_one_stated_time() -> None:
    """README states how long the quick leaderboard takes; getting started repeats README's two
    commands with the same words, and the evaluator guide states the same time, so that the three
    never give three different times again."""
    stated = QUICK_TIME.search((ROOT / "README.md").read_text())
    assert stated, "README's first command no longer states its time"
    repeated = QUICK_TIME.search((ROOT / "docs" / "getting_started.md").read_text())
    assert repeated and repeated["time"] == stated["time"], repeated
    evaluator = " ".join((ROOT / "docs" / "evaluator.md").read_text().split())
    assert stated["time"] in evaluator, stated["time"]


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
    `python docs/make_options_md.py --out docs/controller_options.md` after changing a controller's options."""
    pytest.importorskip("stable_baselines3")  # the page lists the RL controllers' options too
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("make_options_md", root / "docs" / "make_options_md.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert (root / "docs" / "controller_options.md").read_text(encoding="utf-8") == module.page()
