"""ORCA's and the crowd's pyrvo import: a missing pyrvo gives the install hint; a pyrvo that is
installed but fails to import (a library it needs is missing) surfaces its own error instead of
the hint, which would send the user to install what is already there."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from controllers.classic.orca import INSTALL_HINT
from controllers.classic.orca import _import_pyrvo as orca_import
from koopman_envs.sim.movers.crowd import _import_pyrvo as crowd_import

BROKEN = "librvo2.so: cannot open shared object file"


@pytest.fixture
def broken_pyrvo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A ``pyrvo`` on the path whose import fails as a broken install's does."""
    (tmp_path / "pyrvo.py").write_text(f"raise ImportError({BROKEN!r})\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "pyrvo", raising=False)


@pytest.mark.parametrize("load", [orca_import, crowd_import], ids=["orca", "crowd"])
def test_a_broken_pyrvo_surfaces_its_own_error(broken_pyrvo: None, load) -> None:
    with pytest.raises(ImportError, match=BROKEN):
        load()


def test_a_missing_pyrvo_gives_the_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pyrvo", None)  # import pyrvo: ModuleNotFoundError, name 'pyrvo'
    with pytest.raises(ImportError, match=r"orca needs pyrvo") as raised:
        orca_import()
    assert str(raised.value) == INSTALL_HINT
    with pytest.raises(ValueError, match=r"behaviour='crowd' need pyrvo"):
        crowd_import()
