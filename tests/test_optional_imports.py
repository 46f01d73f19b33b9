"""Every optional dependency is imported through :func:`koopman_envs.checks.import_optional`:
a missing module gives its loader's install hint, in the exception type the loader documents; a
module that is installed but broken (a library it needs is missing) surfaces its own error."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from controllers.classic.orca import _import_pyrvo as orca_pyrvo
from evaluation.execution.backends import _run_ray
from evaluation.tune.study import _optuna
from koopman_envs.checks import import_optional
from koopman_envs.sim.movers.crowd import _import_pyrvo as crowd_pyrvo

BROKEN = "libsomething.so: cannot open shared object file"


def _ray() -> Any:
    return next(iter(_run_ray([], 1)))


#: (loader, the module it imports, its refusal's type, a phrase of its hint)
LOADERS: list[tuple[Callable[[], Any], str, type[Exception], str]] = [
    (orca_pyrvo, "pyrvo", ImportError, "orca needs pyrvo"),
    (crowd_pyrvo, "pyrvo", ValueError, "behaviour='crowd' need pyrvo"),
    (_optuna, "optuna", ImportError, "the tuner needs Optuna: pip install -e '.[tune]'"),
    (_ray, "ray", ValueError, "--backend ray needs Ray: pip install -e '.[ray]'"),
]
IDS = ["orca", "crowd", "tuner", "ray-backend"]


@pytest.mark.parametrize(("load", "module", "refusal", "hint"), LOADERS, ids=IDS)
def test_a_missing_module_gives_the_install_hint(
    monkeypatch: pytest.MonkeyPatch, load: Callable[[], Any], module: str, refusal: type[Exception], hint: str
) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # import: ModuleNotFoundError naming the module
    with pytest.raises(refusal) as raised:
        load()
    assert type(raised.value) is refusal
    assert hint in str(raised.value)


@pytest.mark.parametrize(("load", "module", "refusal", "hint"), LOADERS, ids=IDS)
def test_a_broken_install_surfaces_its_own_error(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    load: Callable[[], Any],
    module: str,
    refusal: type[Exception],
    hint: str,
) -> None:
    (tmp_path / f"{module}.py").write_text(f"raise ImportError({BROKEN!r})\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, module, raising=False)
    with pytest.raises(ImportError, match=BROKEN):
        load()


def test_a_missing_dependency_of_an_installed_module_is_not_the_hint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "koopnav_probe_module.py").write_text("import koopnav_probe_missing_dependency\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="koopnav_probe_missing_dependency"):
        import_optional("koopnav_probe_module", "the hint")
    with pytest.raises(ValueError, match="^the hint$"):
        import_optional("koopnav_probe_absent_module", "the hint", ValueError)
