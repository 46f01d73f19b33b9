"""When a test may skip for a missing extra: only when the ImportError it caught is a module of
one of pyproject's optional extras that is not installed here. Any other ImportError (a name
that moved, a KoopNav module gone, an installed extra failing to import) is a fault the test must
report, not skip."""

from __future__ import annotations

import importlib.util

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
