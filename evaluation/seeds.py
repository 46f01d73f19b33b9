"""Deprecated path of :mod:`evaluation.experiments.seeds` (moved by issue 61, folders by concept).

``python -m evaluation.seeds`` still runs ``python -m evaluation.experiments.seeds``, and the
seeds' names are still read from here (``from evaluation.seeds import aggregate``), for one
release, with a ``DeprecationWarning``; the path is removed in KoopNav 0.2.0 (CHANGELOG.md,
Deprecated). It was the one module path of the evaluator that docs/ told users to run.
"""

from __future__ import annotations

import warnings
from typing import Any

from evaluation.experiments import seeds as _moved

__all__ = list(_moved.__all__)

# run as a command, this module is __main__ (whose warnings Python shows by default); imported,
# the warning points at the importer
warnings.warn(
    "evaluation.seeds is deprecated and will be removed in KoopNav 0.2.0; run "
    "`python -m evaluation.experiments.seeds`, import from evaluation.experiments.seeds",
    DeprecationWarning,
    stacklevel=1 if __name__ == "__main__" else 2,
)


def __getattr__(name: str) -> Any:
    """The moved module's names (PEP 562)."""
    return getattr(_moved, name)


if __name__ == "__main__":
    raise SystemExit(_moved.main())
