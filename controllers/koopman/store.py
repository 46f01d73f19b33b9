"""Where models come from: shipped files for the paper's settings, a user cache for the rest.

``get_model(slip, n_robots)`` returns the shipped model for ``"nominal"``, ``"low"`` and ``"high"``
with 3 robots (files in ``controllers/koopman/models``, regenerated bit for bit by
``python -m controllers.koopman fit --slip SETTING --out controllers/koopman/models/SETTING.npz``)
and fits any other setting on demand, caching it under ``$KOOPNAV_CACHE`` (default
``~/.cache/koopnav/models``) keyed by everything that determines the data and the fit.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from importlib import resources
from pathlib import Path
from typing import Sequence

import numpy as np

from controllers.koopman.data import DataSpec, collect_data
from controllers.koopman.dictionary import get_dictionary
from controllers.koopman.fit import fit_bilinear
from controllers.koopman.model import KoopmanModel
from koopman_envs import __version__ as envs_version
from koopman_envs.params import PARAMS, slip_lambdas

__all__ = ["SHIPPED", "cache_dir", "fit_model", "get_model", "shipped_path"]

SHIPPED = ("nominal", "low", "high")


def fit_model(spec: DataSpec, dictionary: str = "minimal", ridge: float = 0.0) -> KoopmanModel:
    """Collect data for ``spec`` and fit a model; metadata records the provenance."""
    dic = get_dictionary(dictionary)
    data = collect_data(spec)
    fit = fit_bilinear(data.states, data.commands, dic, ridge=ridge)
    rows = dic.state_rows(spec.n_robots)  # (N, 4): x, y, cos, sin
    position_residual = np.hypot(fit.coordinate_residual[rows[:, 0]], fit.coordinate_residual[rows[:, 1]])
    meta = {
        "data": spec.to_dict(),
        "ridge": ridge,
        "fit_residual": fit.residual,
        # RMS one-step position error of each robot on the training data [m]: the model's own
        # estimate of how far reality strays from a prediction (used for safety margins)
        "position_residual": [float(v) for v in position_residual],
        "rank": fit.rank,
        "transitions": spec.transitions,
        "package_version": envs_version,
    }
    return KoopmanModel(fit.A, fit.N, fit.B, fit.C, dic, spec.n_robots, spec.dt, meta)


def shipped_path(setting: str) -> Path:
    """Path of the shipped model of a named slip setting (3 robots, minimal dictionary)."""
    if setting not in SHIPPED:
        raise ValueError(f"setting={setting!r} is not one of the shipped {list(SHIPPED)}")
    return Path(str(resources.files("controllers.koopman").joinpath("models", f"{setting}.npz")))


def cache_dir() -> Path:
    """User cache directory for fitted models (``$KOOPNAV_CACHE`` overrides)."""
    root = os.environ.get("KOOPNAV_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "koopnav")
    return Path(root) / "models"


def _cache_key(spec: DataSpec, dictionary: str, ridge: float) -> str:
    blob = json.dumps({"data": spec.to_dict(), "dictionary": dictionary, "ridge": ridge, "v": envs_version},
                      sort_keys=True)  # fmt: skip
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def get_model(
    slip: str | Sequence[float] = "nominal",
    n_robots: int = PARAMS.n_robots,
    dictionary: str = "minimal",
    seed: int = 0,
    trajectories: int = PARAMS.koopman_trajectories,
    steps: int = PARAMS.koopman_steps,
) -> KoopmanModel:
    """The Koopman model of a slip setting, learned from simulator data of that setting only.

    The slip setting selects which simulator produces the training data (as a real deployment
    would collect data on its own robots); the fitted model never contains lambda.
    """
    lambdas = slip_lambdas(slip, n_robots)
    spec = DataSpec(tuple(float(v) for v in lambdas), trajectories, steps, seed=seed)
    default_protocol = (
        dictionary == "minimal" and seed == 0 and n_robots == PARAMS.n_robots
        and trajectories == PARAMS.koopman_trajectories and steps == PARAMS.koopman_steps
    )  # fmt: skip
    if isinstance(slip, str) and slip in SHIPPED and default_protocol:
        return KoopmanModel.load(shipped_path(slip), n_robots=n_robots)
    path = cache_dir() / f"{_cache_key(spec, dictionary, 0.0)}.npz"
    if path.exists():
        return KoopmanModel.load(path, n_robots=n_robots)
    model = fit_model(spec, dictionary)
    path.parent.mkdir(parents=True, exist_ok=True)
    # write then rename, so a concurrent reader never sees half a file
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
    os.close(fd)
    model.save(tmp)
    os.replace(tmp, path)
    return model

