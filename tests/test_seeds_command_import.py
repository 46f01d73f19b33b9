"""``python -m evaluation.experiments.seeds`` runs a module its package has not imported already:
the package reads :mod:`evaluation.experiments.seeds_published` (which imports the command's
module) on first use, so runpy neither warns nor keeps two copies of the command's globals."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_seeds_command_runs_without_runpys_warning() -> None:
    done = subprocess.run(
        [sys.executable, "-W", "error::RuntimeWarning", "-m", "evaluation.experiments.seeds", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: python -m evaluation.experiments.seeds")
    assert "RuntimeWarning" not in done.stderr


def test_the_package_still_exports_the_publications_names_lazily() -> None:
    import evaluation.experiments as experiments
    from evaluation.experiments import seeds_published

    assert experiments.read_publication is seeds_published.read_publication
    assert experiments.DRIVER == seeds_published.DRIVER
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        experiments.no_such_name  # noqa: B018
