"""koopman_envs.deprecation: the import hook that keeps moved module paths for one release (the
registered paths themselves are tested over the registry in tests/test_architecture.py)."""

from __future__ import annotations

import importlib
import importlib.machinery
import runpy
import sys
import warnings

import pytest

import evaluation
from koopman_envs.deprecation import MovedPathFinder, moved_paths, register_moved_paths


def test_the_warning_names_the_importing_line() -> None:
    """An import statement's warning is reported at that statement (the default filters show
    it when that code is ``__main__``), not inside the import system."""
    sys.modules.pop("evaluation.spec", None)
    code = compile("x = 1\nfrom evaluation.spec import RunSpec\n", "<user script>", "exec")
    with pytest.warns(DeprecationWarning, match="evaluation.spec is deprecated") as caught:
        exec(code, {"__name__": "__main__"})
    assert [(w.filename, w.lineno) for w in caught] == [("<user script>", 2)]


def test_a_moved_package_carries_its_submodules_without_a_second_copy(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``evaluation.report`` (a package, now ``evaluation.reports.sections``): its submodule read
    under the old name is the new module, not a second one loaded from the shared folder."""
    new = importlib.import_module("evaluation.reports.sections.blocks")
    for name in ("evaluation.report", "evaluation.report.blocks"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    with pytest.warns(DeprecationWarning) as caught:
        assert importlib.import_module("evaluation.report.blocks") is new
    assert [str(w.message).split(";")[1] for w in caught] == [
        " import from evaluation.reports.sections",
        " import from evaluation.reports.sections.blocks",
    ]


def test_a_moved_command_runs_nothing_under_another_name(monkeypatch: pytest.MonkeyPatch) -> None:
    """multiprocessing's spawned workers run the main module again as ``__mp_main__``: the old
    path's command code must not run the command (or warn) there."""
    monkeypatch.delitem(sys.modules, "evaluation.seeds", raising=False)  # else runpy reads the new module's
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        namespace = runpy.run_module("evaluation.seeds", run_name="__mp_main__")
    assert namespace["__name__"] == "__mp_main__"
    assert [w for w in caught if issubclass(w.category, DeprecationWarning)] == []


def test_registering_again_changes_nothing() -> None:
    before = moved_paths()
    register_moved_paths(evaluation.MOVED_PATHS, commands=("evaluation.seeds",))
    assert moved_paths() == before
    finders = [i for i, f in enumerate(sys.meta_path) if isinstance(f, MovedPathFinder)]
    assert len(finders) == 1
    assert finders[0] < sys.meta_path.index(importlib.machinery.PathFinder)  # before the files


@pytest.mark.parametrize(
    ("moved", "commands", "message"),
    [
        ({"x.old": "not a path"}, (), r"new='not a path' is not a dotted module path"),
        ({1: "x.new"}, (), r"old=1 is not a dotted module path"),
        ({"x.old": "x.old.inner"}, (), r"'x.old' cannot move to 'x.old.inner'"),
        ({"x.old": "evaluation.spec"}, (), r"makes a chain of moved paths"),
        ({"evaluation.run.spec": "x.new"}, (), r"makes a chain of moved paths"),
        (
            {"evaluation.spec": "evaluation.run.plan"},
            (),
            r"already registered as moved to 'evaluation.run.spec'",
        ),
        (
            {"x.old": "x.new"},
            ("x.other",),
            r"commands \['x.other'\] are not among the moved paths \['x.old'\]",
        ),
    ],
)
def test_a_bad_registration_is_refused_by_name(moved: dict, commands: tuple, message: str) -> None:
    before = moved_paths()
    with pytest.raises(ValueError, match=message):
        register_moved_paths(moved, commands=commands)
    assert moved_paths() == before
