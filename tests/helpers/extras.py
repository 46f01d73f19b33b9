"""When a test may skip for a missing extra: only when the ImportError it caught is a module of
one of pyproject's optional extras that is not installed here. Any other ImportError (a name
that moved, a KoopNav module gone, an installed extra failing to import) is a fault the test must
report, not skip."""

from __future__ import annotations

import importlib.util

import pytest

#: the optional extras' top-level import names -> the extra that installs each
#: (pyproject.toml's [project.optional-dependencies])
EXTRA_MODULES = {
    "pyrvo": "crowd",
    "mujoco": "physics",
    "stable_baselines3": "rl",
    "torch": "rl",
    "optuna": "tune",
    "ray": "ray",
    "torchrl": "torchrl",
    "tensordict": "torchrl",
    "benchmarl": "benchmarl",
    "do_mpc": "bench",
    "mpe2": "bench",
    "sklearn": "bench",
}


def missing_extra(exc: BaseException) -> str | None:
    """``"MODULE (the [EXTRA] extra)"`` when ``exc`` is, or was raised while handling (an install
    hint re-raised ``from None`` keeps it as its context), a ModuleNotFoundError of an extra's
    module that is not installed; None for any other error (the caller re-raises it)."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, ModuleNotFoundError) and seen.name:
            top = seen.name.partition(".")[0]
            if top in EXTRA_MODULES and importlib.util.find_spec(top) is None:
                return f"{top} (the [{EXTRA_MODULES[top]}] extra)"
            return None
        seen = seen.__cause__ or seen.__context__
    return None


def _without(module: str) -> str | None:
    """Why a test cannot run here without ``module`` (a key of :data:`EXTRA_MODULES`), or None."""
    if importlib.util.find_spec(module) is None:
        return f"needs {module}: the [{EXTRA_MODULES[module]}] extra"
    return None


def needs_extra(module: str) -> pytest.MarkDecorator:
    """A skip mark for a test that cannot run without an extra's ``module`` (a key of
    :data:`EXTRA_MODULES`), naming the extra: for a test that needs the module to set up at all
    (it runs the controller), where :func:`missing_extra` judges an error raised."""
    reason = _without(module)
    return pytest.mark.skipif(reason is not None, reason=str(reason))


def skip_without_extra(module: str) -> None:
    """:func:`needs_extra` inside a fixture: skips the tests that use it, not the whole module."""
    reason = _without(module)
    if reason is not None:
        pytest.skip(reason)
