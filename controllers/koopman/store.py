"""Where models come from: fitted on a calibration plant, cached on disk, shipped for the paper.

:func:`calibrated_model` is what Koopman-NMPC's ``calibrate`` calls: it draws the identification
set from the plant (the paper's protocol, :func:`controllers.calibration.collect_data`), fits
the bilinear model and caches it keyed by the plant's signature, the budget, the seed and the
dictionary, so a rerun loads instead of refitting. The shipped files
``controllers/koopman/models/{nominal,low,high}.npz`` are the cache entries of the paper's three
slip settings (3 robots, default budget, seed 0, minimal dictionary) and are regenerated bit for
bit by ``python -m controllers.koopman fit --slip SETTING --out controllers/koopman/models/SETTING.npz``.

:func:`fit_for_env` fits a model for any env id and keyword arguments::

    from controllers.koopman import fit_for_env
    model = fit_for_env("KoopNav-Formation-v0", slip="high")
    ctrl = KoopmanNMPC(model=model)
"""

from __future__ import annotations

import time
import warnings
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from controllers.calibration import (
    CacheWarning,
    DataSpec,
    cache_key,
    cache_path,
    collect_data,
    data_spec_for,
    write_atomic,
)
from controllers.disk_cache import entry_exists
from controllers.koopman.dictionary import check_memory, check_velocity, get_dictionary
from controllers.koopman.fit import STRUCTURES, BilinearFit, fit_bilinear, fit_per_robot
from controllers.koopman.model import KoopmanModel, ModelFileError
from controllers.koopman.refit import check_rollout_refits, refit_on_rollouts
from koopman_envs import CalibrationPlant, make_plant
from koopman_envs import __version__ as envs_version
from koopman_envs.checks import check_choice
from koopman_envs.params import PARAMS

__all__ = ["SHIPPED", "calibrated_model", "default_structure", "fit_for_env", "fit_on_plant", "shipped_path"]

#: Slip settings whose models ship with the package (3 robots, default budget, seed 0, minimal).
SHIPPED = ("nominal", "low", "high")
_SHIPPED_ENV = "KoopNav-TargetReaching-v0"  # the plant does not depend on the task


def check_structure(structure: str) -> str:
    """``structure`` if it is one of :data:`controllers.koopman.fit.STRUCTURES`, else ValueError."""
    return str(check_choice("structure", structure, STRUCTURES))


def default_structure(n_robots: int) -> str:
    """The structure ``structure="auto"`` picks: the paper's stacked model up to its 3 robots,
    per-robot beyond (the fit and the NMPC problem then grow linearly with N)."""
    return "stacked" if n_robots <= PARAMS.n_robots else "per-robot"


def fit_on_plant(
    plant: CalibrationPlant,
    spec: DataSpec,
    dictionary: str = "minimal",
    ridge: float = 0.0,
    structure: str = "stacked",
    memory: int = 0,
    velocity: bool = False,
    rollout_refits: int = 0,
) -> KoopmanModel:
    """Collect the data set ``spec`` on ``plant`` and fit a model; metadata records the provenance.

    ``structure``: ``"stacked"`` (the paper's) or ``"per-robot"``
    (:func:`controllers.koopman.fit.fit_per_robot`). ``memory``: previous commands in the lift
    (0: the paper's pose-only lift; stacked models only); ``velocity``: the last period's move
    in the lift (stacked models only); ``rollout_refits``: refits on the model's own open-loop
    rollouts (:func:`controllers.koopman.refit.refit_on_rollouts`; 0: the least-squares fit
    alone; stacked models only).
    """
    dic = get_dictionary(dictionary)
    check_structure(structure)
    memory, velocity = check_lift(memory, velocity, structure)
    rollout_refits = check_refits(rollout_refits, structure)
    data = collect_data(plant, spec)

    def model_of(fit: BilinearFit, meta: dict[str, Any] | None = None) -> KoopmanModel:
        return KoopmanModel(
            fit.A,
            fit.N,
            fit.B,
            fit.C,
            dic,
            plant.n_robots,
            plant.dt,
            meta or {},
            memory=memory,
            velocity=velocity,
        )

    if rollout_refits:
        fit = refit_on_rollouts(
            data.states, data.commands, dic, model_of, rollout_refits, memory, velocity, ridge
        )
    elif structure == "stacked":
        fit = fit_bilinear(data.states, data.commands, dic, ridge=ridge, memory=memory, velocity=velocity)
    else:
        fit = fit_per_robot(data.states, data.commands, dic, ridge=ridge)
    rows = dic.state_rows(plant.n_robots)  # (N, 4): x, y, cos, sin
    position_residual = np.hypot(fit.coordinate_residual[rows[:, 0]], fit.coordinate_residual[rows[:, 1]])
    meta = {
        "plant": plant.signature,
        "budget": plant.budget,
        "data": spec.to_dict(),
        "ridge": ridge,
        "fit_residual": fit.residual,
        # RMS one-step position error of each robot on the calibration data [m]: the model's
        # own measure of how far the robots stray from its prediction (uncertainty_margin)
        "position_residual": [float(v) for v in position_residual],
        "rank": fit.rank,
        "transitions": spec.transitions,
        "cache_key": _model_key(plant, spec, dictionary, ridge, structure, memory, velocity, rollout_refits),
        # only beyond the paper's stacked fit, as in the cache key: the documented command then
        # regenerates the shipped files bit for bit (tests/test_koopman.py)
        **({} if structure == "stacked" else {"structure": structure}),
        **({"rollout_refits": rollout_refits} if rollout_refits else {}),
        "package_version": envs_version,
    }
    return model_of(fit, meta)


def check_lift(memory: object, velocity: object, structure: str) -> tuple[int, bool]:
    """``memory`` and ``velocity`` checked (:func:`~controllers.koopman.dictionary.check_memory`,
    :func:`~controllers.koopman.dictionary.check_velocity`), and refused with a ``ValueError``
    beside the per-robot structure, whose blocks hold poses only."""
    memory, velocity = check_memory(memory), check_velocity(velocity)
    for name, value in (("memory", memory), ("velocity", velocity)):
        if value and structure == "per-robot":
            raise ValueError(
                f"{name}={value} needs structure='stacked'; the per-robot fit lifts the poses only"
            )
    return memory, velocity


def check_refits(rollout_refits: object, structure: str) -> int:
    """``rollout_refits`` checked (:func:`~controllers.koopman.refit.check_rollout_refits`), and
    refused with a ``ValueError`` beside the per-robot structure, which is fitted robot by robot."""
    rollout_refits = check_rollout_refits(rollout_refits)
    if rollout_refits and structure == "per-robot":
        raise ValueError(
            f"rollout_refits={rollout_refits} needs structure='stacked'; the per-robot fit refits nothing"
        )
    return rollout_refits


def _model_key(
    plant: CalibrationPlant,
    spec: DataSpec,
    dictionary: str,
    ridge: float,
    structure: str = "stacked",
    memory: int = 0,
    velocity: bool = False,
    rollout_refits: int = 0,
) -> str:
    # the stacked structure and the pose-only lift keep the key they had before structures,
    # memory, velocity and refits existed (shipped files, caches)
    extra: dict[str, Any] = {} if structure == "stacked" else {"structure": structure}
    if memory:
        extra["memory"] = memory
    if velocity:
        extra["velocity"] = True
    if rollout_refits:
        extra["rollout_refits"] = rollout_refits
    return cache_key("koopman", plant, spec, dictionary=dictionary, ridge=ridge, **extra)


def shipped_path(setting: str) -> Path:
    """Path of the shipped model of a named slip setting (3 robots, minimal dictionary)."""
    check_choice("setting", setting, SHIPPED, among="the shipped")
    return Path(str(resources.files("controllers.koopman").joinpath("models", f"{setting}.npz")))


def _shipped_for(key: str) -> Path | None:
    """The shipped file whose calibration has cache key ``key``, if any."""
    spec = data_spec_for(PARAMS.calibration_budget, 0)
    for setting in SHIPPED:
        plant = make_plant(_SHIPPED_ENV, slip=setting, budget=PARAMS.calibration_budget, seed=0)
        if _model_key(plant, spec, "minimal", 0.0) == key:
            return shipped_path(setting)
    return None


def calibrated_model(
    plant: CalibrationPlant,
    seed: int = 0,
    dictionary: str = "minimal",
    spec: DataSpec | None = None,
    structure: str = "stacked",
    memory: int = 0,
    velocity: bool = False,
    hold: int = 1,
    random_hold: bool = False,
    rollout_refits: int = 0,
) -> tuple[KoopmanModel, dict[str, Any]]:
    """The model of ``plant``'s robots: shipped, cached, or fitted now (and cached if the cache can be
    written: a failed write warns once and the fitted model is returned all the same).

    Parameters
    ----------
    plant : CalibrationPlant
        The deployment env's robots; its budget bounds the data set.
    seed : int
        Seed of the identification inputs.
    dictionary : str
        Observables (``"minimal"``: the paper's).
    spec : DataSpec, optional
        The data set (default: what the plant's budget buys, :func:`data_spec_for`, with ``hold``).
    structure : str
        ``"stacked"`` (the paper's team regression) or ``"per-robot"``.
    memory : int
        Previous commands in the lift (0: the paper's pose-only lift; stacked only).
    velocity : bool
        The last period's move in the lift (stacked only).
    hold : int
        Periods each identification input is held (:class:`~controllers.calibration.DataSpec`;
        1: the paper's inputs, drawn anew every period). Ignored when ``spec`` is given (its own
        ``hold`` counts). Part of the cache key through the data set.
    random_hold : bool
        Each input held for a number of periods drawn from 1..``hold`` (``hold`` >= 2) instead of
        ``hold`` periods; ignored, as ``hold``, when ``spec`` is given.
    rollout_refits : int
        Refits of the model on its own open-loop rollouts of the data
        (:func:`~controllers.koopman.refit.refit_on_rollouts`; 0: the least-squares fit alone;
        stacked only). Part of the cache key.

    Returns
    -------
    model : KoopmanModel
    summary : dict
        ``transitions`` (data behind the model), ``source`` (``"shipped"``, ``"cache"`` or
        ``"fitted"``), ``seconds`` and the cache ``key``.
    """
    start = time.perf_counter()
    spec = data_spec_for(plant.budget, seed, hold, random_hold) if spec is None else spec
    memory, velocity = check_lift(memory, velocity, check_structure(structure))
    rollout_refits = check_refits(rollout_refits, structure)
    key = _model_key(plant, spec, dictionary, 0.0, structure, memory, velocity, rollout_refits)
    summary = {"transitions": spec.transitions, "key": key}
    shipped = _shipped_for(key)
    path = shipped if shipped is not None else cache_path("koopman", key, ".npz")
    if entry_exists(path):
        try:
            model = KoopmanModel.load(path, n_robots=plant.n_robots)
            if model.metadata.get("cache_key") == key:
                return model, {
                    **summary,
                    "source": "shipped" if shipped else "cache",
                    "seconds": time.perf_counter() - start,
                }
        except ModelFileError as exc:
            if shipped is not None:
                raise
            warnings.warn(f"{exc}; fitting it again", CacheWarning, stacklevel=2)
        # a corrupt or stale cache entry is refitted and replaced, never used
    model = fit_on_plant(
        plant,
        spec,
        dictionary,
        structure=structure,
        memory=memory,
        velocity=velocity,
        rollout_refits=rollout_refits,
    )
    if shipped is None:
        # best effort: a cache that cannot be written warns once and the fitted model is used
        write_atomic(path, model.save, ".npz")
    return model, {**summary, "source": "fitted", "seconds": time.perf_counter() - start}


def fit_for_env(
    env: Any,
    *,
    budget: int = PARAMS.calibration_budget,
    seed: int = 0,
    dictionary: str = "minimal",
    memory: int = 0,
    velocity: bool = False,
    hold: int = 1,
    random_hold: bool = False,
    rollout_refits: int = 0,
    **env_kwargs: Any,
) -> KoopmanModel:
    """Fit (or load from the cache) the Koopman model of an environment's robots.

    Parameters
    ----------
    env : str or env
        A registered env id with its keyword arguments in ``env_kwargs`` (``slip="high"``,
        ``n_robots=5``, ...), or an env instance.
    budget : int
        Team-transitions of identification data (default: the paper's 1000 x 1000).
    seed : int
        Seed of the plant's slip and of the identification inputs.
    dictionary : str
        ``"minimal"`` (the paper's) or ``"extended"``.
    memory : int
        Previous commands in the lift (0: the paper's pose-only lift).
    velocity : bool
        The last period's move in the lift.
    hold : int
        Periods each identification input is held (1: the paper's inputs).
    random_hold : bool
        Each input held for 1..``hold`` periods, drawn per input (``hold`` >= 2).
    rollout_refits : int
        Refits of the model on its own open-loop rollouts (0: the least-squares fit alone).
    """
    plant = make_plant(env, budget=budget, seed=seed, **env_kwargs)
    return calibrated_model(
        plant,
        seed,
        dictionary,
        memory=memory,
        velocity=velocity,
        hold=hold,
        random_hold=random_hold,
        rollout_refits=rollout_refits,
    )[0]
