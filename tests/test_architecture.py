"""The layout rules of docs/layout.md, checked on the source: no import circle (type-only imports
included), no module over 500 lines, no function over 80 lines outside numba kernels (in the
packages and in the scripts of docs/ and bench/ alike), and the environments never import
controllers. Violations still being worked off are listed by name below; the test fails for any
other, and for a listed one that is gone (so the list only shrinks)."""

from __future__ import annotations

import ast
import sys
from pathlib import Path
from types import ModuleType

import pytest

import baselines  # noqa: F401 - importing a package registers its moved paths (MOVED below)
import controllers  # noqa: F401
import evaluation  # noqa: F401
from koopman_envs.deprecation import moved_paths

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("koopman_envs", "controllers", "evaluation", "baselines")
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80  # the body after the docstring

#: still to be split (issue 32): module or "module:function" -> its size when listed
PENDING: set[str] = set()


def _modules() -> dict[str, Path]:
    found = {"evaluate": ROOT / "evaluate.py"}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


def _imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """Every package module ``path`` imports anywhere (functions and TYPE_CHECKING blocks included)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for name in (node.module, *(f"{node.module}.{a.name}" for a in node.names)):
                if name in modules:
                    out.add(name)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name in modules)
    return out


def _circles(graph: dict[str, set[str]]) -> set[tuple[str, ...]]:
    """The strongly connected components of more than one module (Tarjan)."""
    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found = set()

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.add(tuple(sorted(component)))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_import_circle() -> None:
    modules = _modules()
    graph = {name: _imports(path, modules) - {name} for name, path in modules.items()}
    assert _circles(graph) == set(), f"import circles: {sorted(_circles(graph))}"


def test_environments_import_no_controller() -> None:
    modules = _modules()
    for name, path in modules.items():
        if name.startswith("koopman_envs"):
            bad = {m for m in _imports(path, modules) if not m.startswith("koopman_envs")}
            assert not bad, f"{name} imports {sorted(bad)}"


#: the folders of scripts held to the packages' limits (issue 32): the docs' page generators and
#: their modules, the benchmarks; they may import anything (no layer rule applies to them)
SCRIPT_FOLDERS = ("docs", "bench")


def _source_sizes(text: str, where: str) -> dict[str, int]:
    """``where`` -> the lines of ``text``, and ``where:function`` -> the lines of each function's
    body after its docstring, numba kernels left out."""
    sizes = {where: text.count("\n")}
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        if any("jit" in ast.unparse(d) for d in node.decorator_list):
            continue  # numba kernels are long by design: one loop, no calls
        body = node.body
        if (
            body
            and isinstance(body[0], ast.Expr)
            and isinstance(getattr(body[0], "value", None), ast.Constant)
        ):
            body = body[1:]
        if body:
            sizes[f"{where}:{node.name}"] = (node.end_lineno or node.lineno) - body[0].lineno + 1
    return sizes


def _sizes(paths: list[Path]) -> dict[str, int]:
    sizes = {}
    for path in paths:
        sizes.update(_source_sizes(path.read_text(), str(path.relative_to(ROOT))))
    return sizes


def _too_long(sizes: dict[str, int]) -> set[str]:
    return {
        key for key, size in sizes.items() if size > (MAX_FUNCTION_LINES if ":" in key else MAX_MODULE_LINES)
    }


#: what each case of the size limits reads: the packages and evaluate.py; the scripts of SCRIPT_FOLDERS
SIZE_CASES = {
    "packages": lambda: [
        ROOT / "evaluate.py",
        *(p for package in PACKAGES for p in (ROOT / package).rglob("*.py")),
    ],
    "scripts": lambda: [p for folder in SCRIPT_FOLDERS for p in sorted((ROOT / folder).glob("*.py"))],
}


@pytest.mark.parametrize("case", sorted(SIZE_CASES))
def test_module_and_function_sizes(case: str) -> None:
    too_long = _too_long(_sizes(SIZE_CASES[case]()))
    pending = (
        {key for key in PENDING if key.split("/")[0] in SCRIPT_FOLDERS}
        if case == "scripts"
        else {key for key in PENDING if key.split("/")[0] not in SCRIPT_FOLDERS}
    )
    assert too_long - pending == set(), f"over the limits: {sorted(too_long - pending)}"
    assert pending - too_long == set(), (
        f"now within the limits: remove from PENDING: {sorted(pending - too_long)}"
    )


def test_the_scripts_case_reads_every_script_and_lists_a_long_one() -> None:
    """The scripts' case reads docs/*.py and bench/*.py (the page generators among them), and a
    module over 500 lines or a function body over 80 is listed by name."""
    read = {str(p.relative_to(ROOT)) for p in SIZE_CASES["scripts"]()}
    assert {"docs/make_bench_md.py", "docs/make_results_md.py", "bench/nmpc_solve.py"} <= read
    assert not any(name.startswith(("koopman_envs/", "evaluation/")) for name in read)
    body = "".join(f"    x = {i}\n" for i in range(81))
    text = f'def long():\n    """Docstring."""\n{body}\ndef short():\n    return 1\n' + "# filler\n" * 420
    sizes = _source_sizes(text, "bench/x.py")
    assert sizes["bench/x.py:long"] == 81 and sizes["bench/x.py:short"] == 1
    assert _too_long(sizes) == {"bench/x.py", "bench/x.py:long"}
    assert _too_long(_source_sizes(text.replace("    x = 80\n", ""), "b.py")) == {"b.py"}


#: the previous releases' module paths, removed with their stubs once the other packages used the
#: environments through their face (issue 61): nothing in docs/ or README.md named them, so none
#: kept a release of deprecation (CHANGELOG.md, Unreleased); and koopman_envs.builder, the
#: simulator core's folder, renamed engine/ (internal, so without a stub); koopman_envs.rendering
#: names the renderer's folder since the renderer left fronts/ (issue 61)
REMOVED_PATHS = (
    *(f"koopman_envs.{name}" for name in (
        "animation", "builder", "config", "demo", "deprecated", "engine_memory", "episode",
        "episode_layout", "keywords", "plant", "rendering_layers", "tasks.layout",
    )),
    # the engine's and the movers' satellites, cut off to fit the module size, merged back by
    # concept (issue 61): engine.episode, engine.config, engine.plant; the sim.movers folder
    *(f"koopman_envs.engine.{name}" for name in (
        "engine_memory", "engine_plant", "engine_scenario", "episode_layout", "episode_reset",
    )),
    *(f"koopman_envs.sim.{name}" for name in ("crowd", "mover_motion", "mover_placement", "mover_tracking")),
    *(f"controllers.{name}" for name in (
        "adaptive_koopman_nmpc", "cache", "deprecated_paths", "distributed", "koopman_nmpc", "nmpc",
        "nominal_nmpc", "qp2", "rti", "solver_cache", "unicycle",
    )),
    # the controllers' root modules grouped by concept (issue 61): controllers.tuning (presets,
    # search_space and studies) and controllers.estimation (front_end, options, identification);
    # the two its API page named keep a release (MOVED below), controllers.estimation is the folder
    *(f"controllers.{name}" for name in ("estimator_options", "identification", "studies")),
    # the evaluator's root modules before its folders (issue 61, part 2) that docs/ never named;
    # the ones its API page named, and the command evaluation.seeds, keep a release (MOVED below)
    *(f"evaluation.{name}" for name in (
        "ablation", "aggregate", "backends", "badge", "distinct", "html", "plan", "published",
        "records", "robustness", "run_data", "runlog", "slip_text", "sweep", "worker",
    )),
)  # fmt: skip


@pytest.mark.parametrize("old", REMOVED_PATHS)
def test_the_removed_module_paths_are_gone(old: str) -> None:
    """No stub is left behind: the path names no module (its names live in their new modules,
    reached through the package's face)."""
    import importlib.util

    assert importlib.util.find_spec(old) is None, f"{old} is back; import from its new module"


#: the moved module paths kept one release (koopman_envs.deprecation's one registry, which
#: evaluation/__init__.py, baselines/__init__.py, controllers/__init__.py and
#: koopman_envs/__init__.py fill with their MOVED_PATHS): old -> MovedPath
MOVED = moved_paths()
#: the moved paths users ran (docs/benchmark.md, docs/rl.md, docs/getting_started.md of the
#: previous release)
MOVED_COMMANDS = sorted(old for old, moved in MOVED.items() if moved.command)


def test_the_documented_commands_are_kept_and_no_moved_path_is_removed() -> None:
    """Each package registers its own paths, the commands the previous release's docs ran among
    them, and no path is both kept and removed."""
    assert {old.split(".")[0] for old in MOVED} == {"evaluation", "baselines", "controllers", "koopman_envs"}
    assert MOVED_COMMANDS == [
        "baselines.benchmarl_train", "baselines.select", "baselines.train", "evaluation.seeds",
        "koopman_envs.fronts.demo",
    ]  # fmt: skip
    assert set(MOVED).isdisjoint(REMOVED_PATHS)


def _import_new(new: str) -> ModuleType:
    """The new module, or a skip when it needs an extra that is not installed (torch, BenchMARL)."""
    import importlib

    try:
        return importlib.import_module(new)
    except ModuleNotFoundError as missing:
        if (missing.name or "").split(".")[0] in PACKAGES:
            raise
        pytest.skip(f"{new} needs {missing.name}, not installed")


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_moved_path_warns_and_is_its_new_module(old: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Importing the old path warns, naming the new module and the removal release, at the
    importing line, and gives the new module itself (every name, class and patch is the new
    module's); no file is left at the old path."""
    import importlib
    import importlib.machinery

    new = MOVED[old].new
    module = _import_new(new)
    monkeypatch.delitem(sys.modules, old, raising=False)
    with pytest.warns(
        DeprecationWarning,
        match=rf"^{old} is deprecated and will be removed in KoopNav 0\.2\.0; import from {new}$",
    ) as caught:
        assert importlib.import_module(old) is module
    assert [w.filename for w in caught] == [__file__]
    assert sys.modules[old] is module and module.__name__ == new
    assert getattr(module.__spec__, "name", None) == new  # the new module's own spec, untouched
    parent = old.rpartition(".")[0]
    assert importlib.machinery.PathFinder.find_spec(old, sys.modules[parent].__path__) is None, (
        f"a file at {old}: the moved path is the import hook's, not a stub's"
    )


@pytest.mark.parametrize("old", MOVED_COMMANDS)
def test_a_moved_command_warns_and_runs_the_new_one(
    old: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``python -m OLD --help`` (runpy, in this process) warns and prints the help of
    ``python -m NEW``, exit code 0."""
    import runpy

    new = MOVED[old].new
    _import_new(new)
    monkeypatch.delitem(sys.modules, old, raising=False)
    monkeypatch.setattr(sys, "argv", [old, "--help"])
    with pytest.warns(
        DeprecationWarning, match=rf"^python -m {old} is deprecated .* 0\.2\.0; run python -m {new}$"
    ):
        with pytest.raises(SystemExit) as exited:
            runpy.run_module(old, run_name="__main__")
    assert exited.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: python -m {new}")


def test_a_moved_module_that_is_no_command_is_refused_by_python_m(monkeypatch: pytest.MonkeyPatch) -> None:
    import runpy

    monkeypatch.delitem(sys.modules, "evaluation.statistics", raising=False)
    with pytest.raises(
        ImportError, match=r"evaluation\.statistics moved to evaluation\.stats\.statistics .* not a command"
    ):
        runpy.run_module("evaluation.statistics", run_name="__main__")


def _import_statements(body: list[ast.stmt]) -> list[ast.Import | ast.ImportFrom]:
    """The import statements of ``body`` and of every block nested in it (functions, classes,
    branches, handlers), without walking the expressions."""
    found: list[ast.Import | ast.ImportFrom] = []
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append(node)
        for block in ("body", "orelse", "finalbody", "handlers", "cases"):
            nested = getattr(node, block, None)
            if isinstance(nested, list):
                found += _import_statements(nested)
    return found


def test_nothing_of_ours_imports_a_moved_path() -> None:
    """The packages, the scripts, the docs' generators and the tests import the new paths (an old
    one is read only as a string, by the tests of the hook)."""
    sources = [ROOT / "evaluate.py"]
    for folder in (*PACKAGES, "bench", "docs", "tests", "examples"):
        sources += sorted((ROOT / folder).rglob("*.py"))
    packages = {old.split(".")[0] for old in MOVED}
    found = []
    for path in sources:
        text = path.read_text()
        if not any(package in text for package in packages):
            continue  # names none of the packages with moved paths
        for node in _import_statements(ast.parse(text).body):
            if isinstance(node, ast.ImportFrom):
                if node.level or not node.module:
                    continue
                names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            else:
                names = [a.name for a in node.names]
            found += [
                f"{path.relative_to(ROOT)}:{node.lineno} {name}"
                for name in names
                if any(name == old or name.startswith(f"{old}.") for old in MOVED)
            ]
    assert found == [], "imports of moved paths:\n" + "\n".join(found)


@pytest.mark.parametrize(
    ("path", "old_name"),
    [("koopman_envs.engine", "NavigationEngine"), ("koopman_envs.rendering", "Renderer")],
)
def test_a_removed_module_path_that_names_a_folder_now_is_no_stub(path: str, old_name: str) -> None:
    """``koopman_envs.engine`` and ``koopman_envs.rendering``, module paths until their stubs went,
    name folders now (the simulator core, builder/ renamed; the renderer, out of fronts/): packages
    that forward none of the old modules' names."""
    import importlib
    import importlib.util

    spec = importlib.util.find_spec(path)
    assert spec is not None and spec.submodule_search_locations, f"{path} is not a folder"
    folder = importlib.import_module(path)
    assert not hasattr(folder, "__getattr__") and not hasattr(folder, old_name)


#: the environment package's layers, lowest first (docs/layout.md): a module imports its own
#: layer or a lower one, never a higher one (type-only and function-level imports included). The
#: renderer draws the engine's state for the fronts' render(); the episode runners drive the fronts
ENV_LAYERS = ("base", "sim", "tasks", "suites", "engine", "rendering", "fronts", "episodes")
#: the modules and folders of the base layer, at the package root (settings/: what an env keyword or
#: a reset option holds; maps/: the built-in maps' files)
ENV_BASE = {
    "params", "checks", "scenario", "observed", "layout", "files", "deprecation", "settings", "maps",
}  # fmt: skip
#: the PettingZoo modules at the package root (PettingZoo's naming), fronts themselves
ENV_ROOT_FRONTS = {"formation_v0", "target_reaching_v0"}
#: commands that live beside the data they make but run episodes on the fronts: placed on top
#: (the episodes' layer)
ENV_COMMANDS = {"koopman_envs.suites.build"}


def _env_layer(module: str) -> int | None:
    """The layer of a ``koopman_envs`` module (None for the package itself)."""
    parts = module.split(".")
    if parts[0] != "koopman_envs" or len(parts) == 1:
        return None
    if parts[1] in ENV_BASE:
        return 0
    if module in ENV_COMMANDS:
        return len(ENV_LAYERS) - 1
    if len(parts) == 2 and parts[1] in ENV_ROOT_FRONTS:
        return ENV_LAYERS.index("fronts")
    if parts[1] in ENV_LAYERS:
        return ENV_LAYERS.index(parts[1])
    raise AssertionError(f"{module} belongs to no layer of ENV_LAYERS: place it in a layer's folder")


def test_the_environment_package_imports_only_downwards() -> None:
    modules = _modules()
    upward = []
    for name, path in modules.items():
        source = _env_layer(name)
        if source is None:
            continue
        for target in _imports(path, modules):
            if target == "koopman_envs":
                upward.append(f"{name} -> the package root")
                continue
            layer = _env_layer(target)
            if layer is not None and layer > source:
                upward.append(f"{name} ({ENV_LAYERS[source]}) -> {target} ({ENV_LAYERS[layer]})")
    assert upward == [], "upward imports:\n" + "\n".join(upward)


#: the environment package's public face (docs/layout.md): the modules controllers/, baselines/,
#: evaluation/ and evaluate.py may import. Every other koopman_envs module (sim/, tasks/,
#: suites/, engine/, rendering/, fronts/, episodes/) is internal: what the other packages need of it is exported by
#: the package itself (``from koopman_envs import run_episode``), lazily where it is heavy.
PUBLIC_MODULES: dict[str, str] = {
    "koopman_envs": "the face: ids, env classes, episode runner, task table, maps, suites, plant, shared kernels",
    "koopman_envs.params": "the paper's defaults and the slip settings, defined once",
    "koopman_envs.checks": "the number and choice checks and did-you-mean, one wording for every package's errors",
    "koopman_envs.files": "the one bounded reader and the one atomic writer of every file KoopNav keeps",
    "koopman_envs.deprecation": "the removal release and the moved module paths' import hook, for every package",
    "koopman_envs.scenario": "what a model-based controller may know of an episode",
    "koopman_envs.observed": "what a controller may read of an info (the robots' beliefs)",
    "koopman_envs.layout": "one robot's observation block by name, the policies' seam",
    "koopman_envs.settings": "the settings' face: uncertainty, moving obstacles, reset options (dataclasses, presets)",
    "koopman_envs.formation_v0": "a PettingZoo versioned module (PettingZoo's naming)",
    "koopman_envs.target_reaching_v0": "a PettingZoo versioned module (PettingZoo's naming)",
}
#: the packages that use the environments through their face only
FACE_CLIENTS = ("controllers", "baselines", "evaluation", "evaluate.py")


def _face_violations(path: Path, modules: dict[str, Path]) -> list[str]:
    """Imports of ``koopman_envs`` internals in ``path`` (functions and TYPE_CHECKING blocks
    included), and reads of an env's ``engine`` (its accessors are the face: ``config``,
    ``scenario``, ``observation_layout``, ``robot_spaces``)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        named: list[str] = []
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            named = [node.module]
            if node.module == "koopman_envs":  # a module read as an attribute of the package
                named += [f"koopman_envs.{a.name}" for a in node.names if f"koopman_envs.{a.name}" in modules]
        elif isinstance(node, ast.Import):
            named = [a.name for a in node.names]
        elif isinstance(node, ast.Attribute) and node.attr == "engine":
            found.append(f"line {node.lineno}: {ast.unparse(node)} (the env's engine)")
        found += [
            f"line {getattr(node, 'lineno', '?')}: imports {name}"
            for name in named
            if name.split(".")[0] == "koopman_envs" and name not in PUBLIC_MODULES
        ]
    return found


def test_the_other_packages_use_the_environments_through_their_face() -> None:
    modules = _modules()
    found = []
    for client in FACE_CLIENTS:
        paths = [ROOT / client] if client.endswith(".py") else sorted((ROOT / client).rglob("*.py"))
        for path in paths:
            found += [f"{path.relative_to(ROOT)} {v}" for v in _face_violations(path, modules)]
    assert found == [], "koopman_envs internals used outside the package:\n" + "\n".join(found)


def test_every_public_module_exists() -> None:
    modules = _modules()
    assert sorted(set(PUBLIC_MODULES) - set(modules)) == []


#: the evaluator's folders, lowest first (docs/layout.md): a module imports its own folder or a
#: lower one, never a higher one (type-only and function-level imports included)
EVAL_LAYERS = ("base", "episodes", "run", "stats", "reports", "execution", "experiments", "commands")
#: the root modules of the base layer: the exit codes, which every command line reads (baselines'
#: and docs' too), whatever its floor
EVAL_BASE = {"exit_codes"}
#: the command lines, on top: evaluate.py's options, the commands at the root (the mutation store's
#: included) and the tuner
EVAL_COMMANDS = {"cli", "forget", "archive", "exact", "tune", "mutation"}


def _eval_layer(module: str) -> int | None:
    """The layer of an ``evaluation`` module; the package itself (its face, which imports the
    runner) is a command's."""
    parts = module.split(".")
    if parts[0] != "evaluation":
        return None
    if len(parts) == 1 or parts[1] in EVAL_COMMANDS:
        return EVAL_LAYERS.index("commands")
    if len(parts) == 2 and parts[1] in EVAL_BASE:
        return 0
    if parts[1] in EVAL_LAYERS:
        return EVAL_LAYERS.index(parts[1])
    raise AssertionError(f"{module} belongs to no layer of EVAL_LAYERS: place it in a folder")


def test_the_evaluator_imports_only_downwards() -> None:
    """No upward import between the evaluator's folders, and none of a module's own folder's face
    (a module imports its neighbours by their module: the face imports them all)."""
    modules = _modules()
    upward = []
    for name, path in modules.items():
        source = _eval_layer(name)
        if source is None:
            continue
        folder = ".".join(name.split(".")[:2])
        for target in _imports(path, modules):
            layer = _eval_layer(target)
            if layer is not None and layer > source:
                upward.append(f"{name} ({EVAL_LAYERS[source]}) -> {target} ({EVAL_LAYERS[layer]})")
            if target == folder and name != folder and EVAL_LAYERS[source] != "commands":
                upward.append(f"{name} -> its own folder's face {folder}")
    assert upward == [], "upward imports:\n" + "\n".join(upward)


#: the folders whose package is a face, and the modules a face leaves out: a command (its main and
#: aggregate would be ambiguous beside the others')
EVAL_FACES = {
    "episodes": (),
    "run": (),
    "stats": (),
    "reports": (),
    "execution": (),
    "experiments": ("seeds",),
}


@pytest.mark.parametrize("folder", sorted(EVAL_FACES))
def test_every_evaluator_folder_is_the_face_of_its_modules(folder: str) -> None:
    """A folder's package exports the public names (``__all__``) of its modules and subfolders,
    except a name that is also a submodule's, which stays the module (``evaluation.stats.aggregate``
    is the module, its function ``aggregate`` is read from there)."""
    import importlib
    import inspect
    import pkgutil

    package = importlib.import_module(f"evaluation.{folder}")
    found = [m.name for m in pkgutil.iter_modules(package.__path__) if m.name not in EVAL_FACES[folder]]
    expected: dict[str, object] = {}
    for name in found:
        module = importlib.import_module(f"evaluation.{folder}.{name}")
        expected.update({n: getattr(module, n) for n in module.__all__ if n not in found})
    assert sorted(package.__all__) == sorted(expected)
    assert [n for n in package.__all__ if getattr(package, n) is not expected[n]] == []
    assert [n for n in found if not inspect.ismodule(getattr(package, n))] == []


#: baselines' layers (docs/layout.md), lowest first: the root's modules both families share <
#: features/ (what a policy reads) < the two families, sb3/ and marl/, beside each other (neither
#: imports the other). The package itself is the face on top (nothing inside imports it), so every
#: module is importable without the others' libraries.
BASELINES_LAYERS = {"": 0, "features": 1, "sb3": 2, "marl": 2}


def _baselines_layer(module: str) -> tuple[int, str]:
    """The layer and folder of a ``baselines`` module below the face."""
    parts = module.split(".")
    folder = parts[1] if len(parts) > 2 else ""
    if folder not in BASELINES_LAYERS:
        raise AssertionError(f"{module} is in no folder of BASELINES_LAYERS: place it in one")
    return BASELINES_LAYERS[folder], folder


def test_baselines_import_only_downwards() -> None:
    modules = _modules()
    wrong = []
    for name, path in modules.items():
        if not name.startswith("baselines."):
            continue
        layer, folder = _baselines_layer(name)
        for target in _imports(path, modules):
            if target == "baselines":
                wrong.append(f"{name} -> {target} (the face)")
            elif target.startswith("baselines."):
                other_layer, other_folder = _baselines_layer(target)
                if other_layer > layer or (other_layer == layer and other_folder != folder):
                    wrong.append(f"{name} ({folder or 'root'}) -> {target} ({other_folder or 'root'})")
    assert wrong == [], "baselines imports against its layers:\n" + "\n".join(wrong)


def test_the_baselines_root_holds_the_shared_modules_only() -> None:
    """The root's modules are the five both families use; the rest live in the folders of
    BASELINES_LAYERS, and the previous paths are the import hook's (MOVED), not files."""
    root = {p.stem for p in (ROOT / "baselines").glob("*.py")} - {"__init__"}
    assert root == {"shaping", "curriculum", "suite_training", "safe_load", "resume"}


#: the most modules a package root holds before its modules go into folders by concept (issue 61)
ROOT_MODULES_AT_MOST = 12


#: the most modules koopman_envs' root holds (issue 61): the face, the base layer's shared modules
#: and the PettingZoo modules; what belongs to one concept goes into its folder (settings/)
ENV_ROOT_MODULES_AT_MOST = 10


def test_the_environments_root_holds_at_most_ten_modules() -> None:
    """koopman_envs/ keeps its roots few: an eleventh root module (``__init__.py`` counted) belongs in
    a folder of its concept (settings/, sim/, ...), not beside the face."""
    root = sorted(p.stem for p in (ROOT / "koopman_envs").glob("*.py"))
    assert len(root) <= ENV_ROOT_MODULES_AT_MOST, f"koopman_envs/ has {len(root)} root modules: {root}"


def test_the_settings_folder_is_the_face_of_its_modules() -> None:
    """``koopman_envs.settings`` exports the public names (``__all__``) of its modules, the same
    objects, so that the other packages import the settings from the folder."""
    import importlib
    import pkgutil

    package = importlib.import_module("koopman_envs.settings")
    expected: dict[str, object] = {}
    for found in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"koopman_envs.settings.{found.name}")
        expected.update({name: getattr(module, name) for name in module.__all__})
    assert sorted(package.__all__) == sorted(expected)
    assert [name for name in package.__all__ if getattr(package, name) is not expected[name]] == []


def test_the_controllers_root_holds_at_most_twelve_modules() -> None:
    """controllers/ keeps its roots few (tuning/, estimation/ and the rest are folders by concept):
    a thirteenth root module belongs in a folder."""
    root = sorted(p.stem for p in (ROOT / "controllers").glob("*.py"))
    assert len(root) <= ROOT_MODULES_AT_MOST, f"controllers/ has {len(root)} root modules: {root}"


#: the most modules a folder of the packages holds (``__init__.py`` counted, as for the roots above)
#: before its modules go into sub-folders by concept (issue 61: "roots of at most 10-12 modules")
FOLDER_MODULES_AT_MOST = ROOT_MODULES_AT_MOST
#: the folders allowed more, each with its reason and its count when listed (the list only shrinks)
FOLDER_MODULES_EXCEPTIONS: dict[str, tuple[int, str]] = {
    "controllers/mpc": (
        15,
        "the OCP's parts, one job per module as do-mpc and acados split them (config, layout, models, "
        "problem, solve, rti, slots, margins, controller, hooks, variants) and the distributed NMPC "
        "(distributed, detour, plan_exchange), which reuses the problem and the hooks",
    ),
}


def _folder_module_counts() -> dict[str, int]:
    """Every package folder (a folder with ``__init__.py``, the package roots included) -> its
    modules, ``__init__.py`` counted, sub-folders not."""
    counts = {}
    for package in PACKAGES:
        for init in (ROOT / package).rglob("__init__.py"):
            counts[init.parent.relative_to(ROOT).as_posix()] = len(list(init.parent.glob("*.py")))
    return counts


def _crowded_folders(counts: dict[str, int], exceptions: dict[str, tuple[int, str]]) -> list[str]:
    """The folders over the cap and not excepted, the excepted ones that grew past their listed
    count, and the excepted ones now within the cap or gone (to be removed from the list)."""
    crowded = [
        f"{f}: {n}" for f, n in sorted(counts.items()) if n > FOLDER_MODULES_AT_MOST and f not in exceptions
    ]
    crowded += [
        f"{f}: {counts[f]} > its listed {n}" for f, (n, _) in exceptions.items() if counts.get(f, 0) > n
    ]
    crowded += [
        f"{f}: {counts.get(f, 0)}, within the cap: remove its exception"
        for f in exceptions
        if counts.get(f, 0) <= FOLDER_MODULES_AT_MOST
    ]
    return crowded


def test_every_folder_holds_at_most_twelve_modules() -> None:
    """A folder of thirteen modules or more is split into sub-folders by concept (koopman_envs/sim/:
    maps/, slip/, movers/, physics/), unless FOLDER_MODULES_EXCEPTIONS names it with its reason."""
    assert _crowded_folders(_folder_module_counts(), FOLDER_MODULES_EXCEPTIONS) == []


def test_a_crowded_folder_fails_the_module_cap() -> None:
    counts = {"koopman_envs/sim": 18, "controllers/mpc": 16, "baselines/sb3": 12, "evaluation/run": 3}
    assert _crowded_folders(counts, {"controllers/mpc": (15, "why")}) == [
        "koopman_envs/sim: 18",
        "controllers/mpc: 16 > its listed 15",
    ]
    assert _crowded_folders({"controllers/mpc": 12}, {"controllers/mpc": (15, "why")}) == [
        "controllers/mpc: 12, within the cap: remove its exception"
    ]


#: the most parameters a compiled kernel takes (issue 61: the obstacle set, the team state and a
#: kernel's settings travel as one value each, named tuples or arrays, not as long positional lists)
KERNEL_PARAMETERS_AT_MOST = 10


def _kernel_parameters(source: str) -> dict[str, int]:
    """Every numba-compiled function of ``source`` (a decorator naming ``jit``: ``njit``,
    ``numba.njit(...)``, ``jit``) -> its number of parameters (positional, keyword-only, ``*args``,
    ``**kwargs``)."""
    found = {}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and any(
            "jit" in ast.unparse(d) for d in node.decorator_list
        ):
            a = node.args
            starred = (a.vararg is not None) + (a.kwarg is not None)
            found[node.name] = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + starred
    return found


def test_every_compiled_kernel_takes_at_most_ten_parameters() -> None:
    """The longest argument lists (``reward._score`` 23, ``perception._perceive`` 22) were grouped
    (issue 61); a kernel of eleven parameters or more groups its arguments the same way."""
    long = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            long += [
                f"{path.relative_to(ROOT)}:{name} {n}"
                for name, n in _kernel_parameters(path.read_text()).items()
                if n > KERNEL_PARAMETERS_AT_MOST
            ]
    assert long == [], f"kernels over {KERNEL_PARAMETERS_AT_MOST} parameters:\n" + "\n".join(long)


def test_a_kernels_parameters_are_all_counted() -> None:
    source = (
        "import numba\nfrom numba import njit\n"
        "@njit(cache=True)\ndef a(x, y, /, z, *rest, k=1, **more): pass\n"
        "@numba.njit\ndef b(x): pass\n"
        "def plain(a, b, c, d, e, f, g, h, i, j, k, l): pass\n"
    )
    assert _kernel_parameters(source) == {"a": 6, "b": 1}


def _tree_modules_missing(tree: str) -> list[str]:
    """The ``NAME.py`` that a line of docs/layout.md's tree names under a folder holding no such
    file (at any depth: a line may name a subfolder's modules inline, ``maps/: map_spec.py``) nor
    at the repository's root (``evaluate.py``)."""
    import re

    folders: list[tuple[int, str]] = []  # (indent, name) of the folder lines above
    missing = []
    for line in tree.splitlines():
        head = re.match(r"^( *)(\S+)", line[:32])
        if head:
            while folders and folders[-1][0] >= len(head[1]):
                folders.pop()
            if head[2].endswith("/"):
                folders.append((len(head[1]), head[2].rstrip("/")))
        folder = ROOT.joinpath(*(name for _, name in folders))
        for module in re.findall(r"(?<![\w./])(\w+\.py)\b", line):
            if not (ROOT / module).exists() and not any(folder.rglob(module)):
                missing.append(f"{folder.relative_to(ROOT)}/: {module} ({line.strip()[:60]})")
    return missing


def test_the_layout_pages_tree_names_modules_that_exist() -> None:
    tree = (ROOT / "docs" / "layout.md").read_text(encoding="utf-8").split("```")[1]
    assert _tree_modules_missing(tree) == []
    assert _tree_modules_missing("koopman_envs/\n  episodes/  runner.py, the one runner\n") == [
        "koopman_envs/episodes/: runner.py (episodes/  runner.py, the one runner)"
    ]
