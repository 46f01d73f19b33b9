"""A test skips for a missing extra only when the extra's module is missing
(:func:`helpers.extras.missing_extra`): tests/test_input_bounds.py's option check skipped on any
ImportError, so a controller whose import broke (a name moved, a module gone) was skipped, not
failed."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10 (requires-python >= 3.10): the core install's tomli backport
    import tomli as tomllib  # type: ignore[no-redef]

from evaluation.run.configs import parse_controller

from helpers.extras import EXTRA_MODULES, missing_extra

ROOT = Path(__file__).resolve().parent.parent


def test_every_extra_named_is_one_pyproject_declares() -> None:
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(EXTRA_MODULES.values()) <= set(extras)


def test_orca_without_pyrvo_names_the_crowd_extra(monkeypatch) -> None:
    """orca re-raises pyrvo's ModuleNotFoundError as an install hint ``from None``: the missing
    module is found in its context."""
    monkeypatch.setitem(sys.modules, "pyrvo", None)  # import pyrvo fails, find_spec says missing
    with pytest.raises(ImportError) as caught:
        parse_controller("orca").build()  # as the option check builds it
    assert missing_extra(caught.value) == "pyrvo (the [crowd] extra)"


def test_an_import_error_that_is_not_a_missing_extra_is_a_fault() -> None:
    def raised(error: BaseException) -> BaseException:
        try:
            try:
                raise error
            except ImportError:
                raise ImportError("a hint") from None
        except ImportError as exc:
            return exc

    # a name that moved, a KoopNav module gone, an extra that is installed (here: pyrvo)
    pytest.importorskip("pyrvo", reason="the installed-extra case needs pyrvo: the [crowd] extra")
    for error in (
        ImportError("cannot import name 'gone' from 'controllers'"),
        ModuleNotFoundError("No module named 'controllers.gone'", name="controllers.gone"),
        ModuleNotFoundError("No module named 'pyrvo'", name="pyrvo"),
        ModuleNotFoundError("No module named 'not_an_extra'", name="not_an_extra"),
    ):
        assert missing_extra(error) is None, error
        assert missing_extra(raised(error)) is None, error
