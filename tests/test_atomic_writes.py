"""Every file the library writes is written whole or not at all (issue 59).

A report, a manifest, a figure, a model, a cache entry or an animation that KoopNav (or its user)
reads back must not be left half-written by a kill or a full disk: it goes through
:func:`koopman_envs.files.write_atomic` (a temporary file beside it, flushed, renamed over it;
``controllers.disk_cache.write_atomic`` is the cache's best-effort face of the same writer).

This test walks the library's code (:data:`SCANNED`) with :mod:`ast` and fails on a call that
writes a file any other way: ``open``/``os.fdopen``/``Path.open``/``ZipFile``/``tarfile.open`` in a
writing mode, ``os.open`` with a writing flag, ``write_text``/``write_bytes``, ``savefig``,
``imsave``, ``np.save``/``savez``/``savetxt``, ``torch.save``, ``.save(...)`` (SB3 models, Pillow
images, matplotlib animations), ``json.dump``/``pickle.dump`` to a handle and ``shutil.copy*``.
Not counted: a call inside the content written by ``write_atomic`` (a lambda or
``functools.partial`` given to it, or a function of the module passed to it by name), a call with
``fileobj=`` (the handle's own open is what is scanned), and a call of a function of the project's
own modules (``resume_state.save(...)``: its body is scanned where it is defined). Every other
write must be in :data:`ALLOWED`, each with the reason it is safe.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the library's code: the packages, the evaluator's entry point and the page generators
SCANNED = ("koopman_envs", "controllers", "baselines", "evaluation", "evaluate.py", "docs/make_*.py")
#: the project's packages: a call of a function of one of their modules is scanned where defined
PROJECT_PACKAGES = ("koopman_envs", "controllers", "baselines", "evaluation", "evaluate")
#: the atomic writers: what their content argument does is written whole
ATOMIC_WRITERS = frozenset({"write_atomic"})

#: (file, function) -> why its non-atomic write is safe. Keep it small: fix a write instead of
#: adding it here unless nothing ever reads a torn file.
ALLOWED: dict[tuple[str, str], str] = {
    ("koopman_envs/files.py", "_make_temporary"): (
        "the atomic writer's own temporary file (O_EXCL, beside the target): write_atomic fills it, "
        "fsyncs it and renames it over the target, or removes it"
    ),
    ("controllers/solvers/cached_cc.py", "_store"): (
        "the compiler cache's own temporary file + os.replace (the script runs standalone, "
        "without the package, so it cannot import write_atomic); a reader checks the entry's SHA-256"
    ),
    ("controllers/solvers/cached_cc.py", "main"): (
        "the lock file, opened for appending only to hold flock on it: nothing is written to it or read from it"
    ),
    ("controllers/solvers/cached_cc.py", "_copy_if_valid"): (
        "the compiler's own output (-o OUT.o), which CasADi reads only after the compiler exits "
        "successfully, as after any compiler"
    ),
    ("controllers/koopman/__main__.py", "cmd_fit"): (
        "KoopmanModel.save writes through write_atomic (controllers.koopman.model_file.write_model_file)"
    ),
    ("evaluation/episodes/runlog.py", "_open_append"): (
        "the append-only episode log, one whole line per record under a lock; its reader validates "
        "every line and drops a torn last one (--resume reruns that episode)"
    ),
    ("evaluation/episodes/runlog.py", "cut_torn"): (
        "cuts a kill's torn last line off an append-only log (an episode log, a study log) with one "
        "truncate and writes no byte: a kill leaves the log before the cut or after it, both read back whole"
    ),
    ("evaluation/cli/command.py", "print_summary"): (
        "GitHub's job summary ($GITHUB_STEP_SUMMARY), appended to as GitHub asks; KoopNav never reads it"
    ),
}

#: an open mode string (``"w"``, ``"rb"``, ``"a+"``, ``"w:xz"``, ``"r|"``)
_MODE = re.compile(r"[rwaxbtU+]{1,4}(?:[:|][a-z0-9]*)?")
#: calls that open a file in their mode argument
_OPENERS = frozenset({"open", "fdopen", "ZipFile", "TarFile"})
#: os.open flags that write
_WRITE_FLAGS = frozenset({"O_WRONLY", "O_RDWR", "O_CREAT", "O_APPEND", "O_TRUNC"})
#: methods that write their argument's file whatever their receiver
_WRITERS = frozenset(
    {
        "write_text",
        "write_bytes",
        "savefig",
        "imsave",
        "mimsave",
        "imwrite",
        "savez",
        "savez_compressed",
        "savetxt",
    }
)
#: receivers whose ``dump``/``save`` writes a file handle or a path
_DUMPERS = frozenset({"json", "pickle", "yaml", "tomli_w", "toml", "marshal", "joblib"})
#: ``shutil`` functions that write their destination in place
_COPIERS = frozenset({"copy", "copy2", "copyfile", "copytree", "copyfileobj"})


@dataclass(frozen=True)
class Write:
    """A non-atomic write found: where (file, enclosing function, line) and what (the call)."""

    path: str
    function: str
    line: int
    call: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line} in {self.function}: {self.call}"


def _mode_writes(mode: str) -> bool:
    return any(c in mode.split(":")[0].split("|")[0] for c in "wax+")


def _names(node: ast.AST) -> set[str]:
    """Every name and attribute name in an expression."""
    found = set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            found.add(sub.id)
        elif isinstance(sub, ast.Attribute):
            found.add(sub.attr)
    return found


class _Scanner(ast.NodeVisitor):
    def __init__(self, path: str, tree: ast.Module) -> None:
        self.path = path
        self.found: list[Write] = []
        self.scope: list[str] = []
        self.atomic_depth = 0  # > 0 inside the content of an atomic writer
        # names bound to the project's modules (``from baselines.sb3 import resume_state``)
        self.project_names: set[str] = set()
        # every assignment of a name, for os.open's flags (``flags = os.O_WRONLY | ...``)
        self.assigned: dict[str, list[ast.expr]] = {}
        # functions passed by name (or through functools.partial) to an atomic writer
        self.atomic_functions: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split(".")[0] in PROJECT_PACKAGES:
                        self.project_names.add(alias.asname or alias.name.split(".")[0])
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                if node.module.split(".")[0] in PROJECT_PACKAGES:
                    self.project_names.update(alias.asname or alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level > 0:  # relative: the project's own
                self.project_names.update(alias.asname or alias.name for alias in node.names)
            elif isinstance(node, ast.Assign):
                for target in node.targets:
                    if isinstance(target, ast.Name):
                        self.assigned.setdefault(target.id, []).append(node.value)
            elif isinstance(node, ast.Call) and self._is_atomic(node):
                for arg in [*node.args[1:], *(k.value for k in node.keywords if k.arg != "path")]:
                    if isinstance(arg, ast.Call) and _call_name(arg) == "partial" and arg.args:
                        arg = arg.args[0]
                    if isinstance(arg, ast.Name):
                        self.atomic_functions.add(arg.id)
                    elif isinstance(arg, ast.Attribute) and ast.unparse(arg.value) == "self":
                        self.atomic_functions.add(arg.attr)  # a method of the class

    @staticmethod
    def _is_atomic(call: ast.Call) -> bool:
        return _call_name(call) in ATOMIC_WRITERS

    def _function_visit(self, node: ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) -> None:
        inside = not isinstance(node, ast.ClassDef) and node.name in self.atomic_functions
        self.scope.append(node.name)
        self.atomic_depth += inside
        self.generic_visit(node)
        self.atomic_depth -= inside
        self.scope.pop()

    visit_FunctionDef = visit_AsyncFunctionDef = visit_ClassDef = _function_visit

    def visit_Call(self, node: ast.Call) -> None:
        if self._is_atomic(node):
            self.visit(node.func)
            if node.args:
                self.visit(node.args[0])  # the path: not the content
            self.atomic_depth += 1
            for arg in [*node.args[1:], *node.keywords]:
                self.visit(arg)
            self.atomic_depth -= 1
            return
        if not self.atomic_depth and self._writes(node):
            self.found.append(
                Write(self.path, ".".join(self.scope) or "<module>", node.lineno, ast.unparse(node.func))
            )
        self.generic_visit(node)

    def _flags_write(self, expr: ast.expr, depth: int = 0) -> bool:
        names = _names(expr)
        if names & _WRITE_FLAGS:
            return True
        if depth > 3:
            return False
        return any(
            self._flags_write(value, depth + 1) for name in names for value in self.assigned.get(name, ())
        )

    def _writes(self, call: ast.Call) -> bool:
        name = _call_name(call)
        receiver = call.func.value if isinstance(call.func, ast.Attribute) else None
        receiver_name = receiver.id if isinstance(receiver, ast.Name) else None
        if receiver_name in self.project_names:
            return False  # the project's own function: scanned where it is defined
        if any(k.arg == "fileobj" for k in call.keywords):
            return False  # a handle given: its own open is what writes
        if name == "open" and receiver_name == "os":
            flags = (
                call.args[1]
                if len(call.args) > 1
                else next((k.value for k in call.keywords if k.arg == "flags"), None)
            )
            return flags is not None and self._flags_write(flags)
        if name in _OPENERS:
            modes = [k.value for k in call.keywords if k.arg == "mode"] or [
                a for a in call.args if isinstance(a, ast.Constant) and isinstance(a.value, str)
            ]
            for mode in modes:
                if not isinstance(mode, ast.Constant):
                    return True  # a mode decided at run time: it may write
                if isinstance(mode.value, str) and _MODE.fullmatch(mode.value) and _mode_writes(mode.value):
                    return True
            # builtin open(path, mode) with a mode that is not a literal
            return (
                name == "open"
                and receiver is None
                and len(call.args) > 1
                and not isinstance(call.args[1], ast.Constant)
            )
        if name in _WRITERS:
            return True
        if name in ("dump", "save"):
            if receiver_name in _DUMPERS or receiver_name in ("np", "numpy", "torch"):
                return not (
                    name == "dump"
                    and len(call.args) > 1
                    and ast.unparse(call.args[1]) in ("sys.stdout", "sys.stderr")
                )
            return name == "save" and bool(call.args or call.keywords)  # a model's, an image's
        if name == "saving":  # matplotlib's animation writer
            return True
        return name in _COPIERS and (receiver_name == "shutil" or receiver is None)


def _call_name(call: ast.Call) -> str | None:
    if isinstance(call.func, ast.Name):
        return call.func.id
    if isinstance(call.func, ast.Attribute):
        return call.func.attr
    return None


def scan_source(source: str, path: str = "<source>") -> list[Write]:
    """The non-atomic file writes of one module's source (none allowed: see :data:`ALLOWED`)."""
    tree = ast.parse(source)
    scanner = _Scanner(path, tree)
    scanner.visit(tree)
    return scanner.found


def library_files() -> Iterator[Path]:
    for pattern in SCANNED:
        target = ROOT / pattern
        if target.is_dir():
            yield from sorted(target.rglob("*.py"))
        else:
            yield from sorted(ROOT.glob(pattern))


def library_writes() -> list[Write]:
    found = []
    for file in library_files():
        rel = file.relative_to(ROOT).as_posix()
        found += scan_source(file.read_text(encoding="utf-8"), rel)
    return found


def test_the_library_writes_every_file_whole() -> None:
    unsafe = [str(w) for w in library_writes() if (w.path, w.function) not in ALLOWED]
    assert unsafe == [], (
        "non-atomic file writes (write them through koopman_envs.files.write_atomic, or add them to "
        "ALLOWED with why a torn file is never read):\n" + "\n".join(unsafe)
    )


def test_every_allowed_write_is_still_there_and_says_why() -> None:
    """An entry whose write went away (fixed, moved, renamed) leaves the list: it stays small."""
    present = {(w.path, w.function) for w in library_writes()}
    assert sorted(set(ALLOWED) - present) == []
    assert all(len(reason) > 40 for reason in ALLOWED.values())
    assert len(ALLOWED) <= 8


def test_the_scan_covers_the_library() -> None:
    files = {f.relative_to(ROOT).as_posix() for f in library_files()}
    assert {
        "evaluate.py",
        "koopman_envs/files.py",
        "evaluation/tune/report.py",
        "docs/make_pages.py",
    } <= files
    assert len(files) > 150


# ---------------------------------------------------------------------------- the scanner itself


@pytest.mark.parametrize(
    "source",
    [
        "def f(path):\n    with open(path, 'w') as fh:\n        fh.write('x')\n",
        "def f(path):\n    open(path, mode='ab').write(b'x')\n",
        "def f(path, mode):\n    open(path, mode)\n",
        "def f(path):\n    path.open('w')\n",
        "def f(path):\n    Path(path).write_text('x')\n",
        "def f(path):\n    path.write_bytes(b'x')\n",
        "def f(fig, path):\n    fig.savefig(path)\n",
        "def f(path, a):\n    np.save(path, a)\n",
        "def f(path, a):\n    np.savez(path, a=a)\n",
        "def f(obj, fh):\n    json.dump(obj, fh)\n",
        "def f(obj, path):\n    torch.save(obj, path)\n",
        "def f(model, path):\n    model.save(path)\n",
        "def f(a, b):\n    shutil.copyfile(a, b)\n",
        "def f(path):\n    zipfile.ZipFile(path, 'w')\n",
        "def f(path):\n    tarfile.open(path, 'w:xz')\n",
        "def f(path):\n    os.open(path, os.O_WRONLY | os.O_CREAT)\n",
        "FLAGS = os.O_RDWR | os.O_CREAT\ndef f(path):\n    os.open(path, FLAGS, 0o644)\n",
        "def f(path):\n    write_atomic(open(path, 'w'), 'x')\n",  # the path argument is not the content
    ],
)
def test_the_scanner_finds_a_plain_write(source) -> None:
    (found,) = scan_source(source, "lib.py")
    assert (found.path, found.function) == ("lib.py", "f")


@pytest.mark.parametrize(
    "source",
    [
        "def f(path):\n    with open(path) as fh:\n        return fh.read()\n",
        "def f(path):\n    open(path, 'rb')\n",
        "def f(path):\n    os.open(path, os.O_RDONLY | getattr(os, 'O_NONBLOCK', 0))\n",
        "def f(path, fig):\n    write_atomic(path, lambda tmp: fig.savefig(tmp))\n",
        "def f(path, a):\n    write_atomic(path, functools.partial(np.save, a=a))\n",
        "def f(path, a, b):\n    write_atomic(b, functools.partial(shutil.copyfile, a))\n",
        "def f(path):\n    def write(tmp):\n        with open(tmp, 'w') as fh:\n            fh.write('x')\n"
        "    write_atomic(path, write)\n",
        "def f(path):\n    disk_cache.write_atomic(path, lambda t: Path(t).write_text('x'), '.json')\n",
        "def f(blob):\n    tarfile.open(fileobj=blob, mode='w')\n",
        "from baselines.sb3 import resume_state\ndef f(run):\n    resume_state.save(run)\n",
        "def f(obj):\n    json.dump(obj, sys.stdout)\n",
        "def f(d):\n    return d.copy()\n",
    ],
)
def test_the_scanner_passes_a_read_or_an_atomic_write(source) -> None:
    assert scan_source(source, "lib.py") == []


def test_a_new_plain_write_in_library_code_fails_the_scan() -> None:
    """What the library test sees when someone adds ``open(path, "w")`` to report.py: found, and
    not allowed."""
    rel = "evaluation/reports/results.py"
    source = (ROOT / rel).read_text(encoding="utf-8")
    added = (
        source + "\n\ndef dump_raw(path, text):\n    with open(path, 'w') as fh:\n        fh.write(text)\n"
    )
    new = [w for w in scan_source(added, rel) if (w.path, w.function) not in ALLOWED]
    assert [(w.function, w.call) for w in new] == [("dump_raw", "open")]
    assert [w for w in scan_source(source, rel) if (w.path, w.function) not in ALLOWED] == []
