"""Controllers named by import path are checked before anything is called (issue 41, item 6): a
class with the controller's methods, or a function annotated to return one; any other importable
callable (``os:mkdir``, ``os:system``) is refused with nothing run."""

from __future__ import annotations

import pytest

import controllers
import evaluate as ev


def test_an_importable_callable_that_is_no_controller_is_refused_before_it_is_called(
    tmp_path, capsys
) -> None:
    target = tmp_path / "made-by-os-mkdir"
    code = ev.main(
        [
            "--env",
            "KoopNav-TargetReaching-v0",
            "--maps",
            "map1",
            "--episodes",
            "1",
            "--workers",
            "1",
            "--quiet",
            "--controllers",
            f"os:mkdir:path={target}",
            "--out",
            str(tmp_path / "run"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert (
        "controller 'os:mkdir' names builtin_function_or_method 'mkdir', which declares no controller" in err
    )
    assert "it does not declare the controller contract, and nothing was called" in err
    assert not target.exists()  # refused, not run


@pytest.mark.parametrize(
    "name",
    [
        "os:system",
        "os:mkdir",
        "subprocess:Popen",
        "plugin_controllers:NotAController",
        "plugin_controllers:make_anything",
    ],
)
def test_undeclared_targets_are_refused_by_make(name) -> None:
    with pytest.raises(
        ValueError, match="it does not declare the controller contract, and nothing was called"
    ):
        controllers.make(name, command="touch /nonexistent/never")


def test_declared_classes_and_annotated_factories_are_built() -> None:
    assert controllers.make("plugin_controllers:PlainTimed").name == "plain-timed"
    assert controllers.make("plugin_controllers:make_plain_timed").name == "plain-timed"
    assert controllers.make("consensus").name  # registered names are unaffected
