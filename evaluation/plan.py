"""The plan of a run: which episodes, with which settings, checked before any episode starts.

A run is a grid of cells (env, controller configuration, map, slip) times trials. Trial ``i``
of every cell uses seed ``seed + i``, so all controllers face the same slip draws, start
perturbations and (on ``map="random"``) the same layouts: comparisons are paired.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

from controllers.calibration import data_spec_for
from evaluation.configs import ControllerConfig
from koopman_envs.engine import ENV_KEYWORDS, EngineConfig
from koopman_envs.params import PARAMS, SLIP_SETTINGS, slip_lambdas
from koopman_envs.sim.maps import BUILTIN_MAPS
from koopman_envs.sim.slip import RANDOM_SLIP
from koopman_envs.sim.slip_schedule import DRIFT_SLIP
from koopman_envs.tasks.base import ENV_IDS, task_for_env

__all__ = [
    "CELL_AXES",
    "EpisodeSpec",
    "EnvSettings",
    "RANDOM_MAP",
    "env_settings",
    "map_fingerprints",
    "plan_episodes",
    "safe_file_name",
    "slip_value",
    "validate_plan",
]

RANDOM_MAP = "random"
#: env keywords that are axes of the grid (set through ``maps`` and ``slips``, never env kwargs)
CELL_AXES = ("map", "slip")
#: env keywords the evaluator owns: rendering is its business (``--gifs``)
_NOT_ENV_KWARGS = (*CELL_AXES, "render_mode")


def slip_value(slip: str) -> str | list[float]:
    """A slip cell name as the env takes it: a setting name, ``"random"``, ``"drift"`` or per-robot
    lambdas (a listed schedule of levels over time is an env keyword only, not a cell)."""
    if slip in SLIP_SETTINGS or slip in (RANDOM_SLIP, DRIFT_SLIP):
        return slip
    try:
        return [float(v) for v in slip.split(",")]
    except ValueError:
        raise ValueError(
            f"slip={slip!r} is not one of {[*SLIP_SETTINGS, RANDOM_SLIP, DRIFT_SLIP]} "
            "nor comma-separated per-robot lambdas"
        ) from None


@dataclass(frozen=True)
class EnvSettings:
    """The env keywords every episode of a run shares (beyond its map and slip).

    Attributes
    ----------
    kwargs : tuple of (str, value)
        Keyword arguments of ``gym.make`` (sorted), e.g. ``n_robots``, ``goal_tolerance``,
        ``max_episode_steps``, ``start_noise``, ``random_map``.
    """

    kwargs: tuple[tuple[str, Any], ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """The keywords as a fresh dict."""
        return json.loads(json.dumps(dict(self.kwargs)))

    @property
    def n_robots(self) -> int:
        """Team size of the run's envs."""
        return int(dict(self.kwargs).get("n_robots", PARAMS.n_robots))


def env_settings(
    env_kwargs: Mapping[str, Any] | None,
    tolerance: float = PARAMS.goal_tolerance,
    max_episode_steps: int = PARAMS.max_episode_steps,
    start_noise: float = 0.0,
) -> EnvSettings:
    """Merge the dedicated arguments with user env kwargs (which win) into one settings object.

    Raises
    ------
    ValueError
        A keyword that is a cell axis (``map``, ``slip``: use ``maps``/``slips``), one the env
        does not take, or a value that is not plain JSON (settings are recorded in the results).
    """
    merged: dict[str, Any] = {"goal_tolerance": tolerance, "max_episode_steps": max_episode_steps,
                              "start_noise": start_noise}  # fmt: skip
    env_kwargs = dict(env_kwargs or {})
    allowed = sorted(k.name for k in ENV_KEYWORDS if k.name not in _NOT_ENV_KWARGS)
    for key, value in env_kwargs.items():
        if key in CELL_AXES:
            raise ValueError(f"env kwarg {key!r} is a cell axis: give it with --{key}s / {key}s=, not as an env kwarg")
        if key not in allowed:
            raise ValueError(f"env kwarg {key!r} is not one the environments take; allowed: {allowed}")
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError):
            raise ValueError(f"env kwarg {key}={value!r} must be plain JSON (a number, text, list or dict)") from None
        merged[key] = value
    return EnvSettings(tuple(sorted(merged.items())))


@dataclass(frozen=True)
class EpisodeSpec:
    """One episode to run: a cell plus the trial index (which fixes the seed)."""

    env_id: str
    controller: str  # the configuration's label (its row in the reports)
    map: str
    slip: str  # a setting name, or comma-separated lambdas
    trial: int
    seed: int
    tolerance: float
    max_episode_steps: int
    controller_name: str = ""  # registered name (default: the label)
    controller_options: str = "{}"  # JSON object of factory options
    calibration_budget: int = PARAMS.calibration_budget
    calibration_seed: int = 0
    start_noise: float = 0.0
    env_kwargs: str = "{}"  # JSON object of the other env keywords (n_robots, random_map, ...)
    animation: str = ""  # relative path of the GIF to record for this episode ("" = none)
    run_dir: str = ""  # the run's output directory (where ``animation`` goes)
    # a factory given as a callable (API only); sent to workers by reference, not recorded
    controller_factory: Callable[..., Any] | None = field(default=None, compare=False, repr=False)

    @property
    def key(self) -> str:
        """Unique id of the episode within a run."""
        return f"{self.env_id}|{self.controller}|{self.map}|{self.slip}|{self.trial}"

    @property
    def cell(self) -> tuple[str, str, str, str]:
        """(env, controller, map, slip)."""
        return (self.env_id, self.controller, self.map, self.slip)

    @property
    def config(self) -> ControllerConfig:
        """The controller configuration of this episode."""
        options = json.loads(self.controller_options)
        return ControllerConfig(self.controller, self.controller_name or self.controller,
                                tuple(sorted(options.items())), self.controller_factory)  # fmt: skip

    def make_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``gym.make`` for this episode (without ``render_mode``)."""
        kwargs = json.loads(self.env_kwargs)
        kwargs.update(map=self.map, slip=slip_value(self.slip), goal_tolerance=self.tolerance,
                      max_episode_steps=self.max_episode_steps, start_noise=self.start_noise)  # fmt: skip
        return kwargs

    def record_fields(self) -> dict[str, Any]:
        """The plain-JSON fields of the spec, as every episode record starts."""
        fields = {k: getattr(self, k) for k in self.__dataclass_fields__ if k not in ("controller_factory", "run_dir")}
        return {"key": self.key, **fields}


def safe_file_name(*parts: str) -> str:
    """Cell coordinates joined into a file-name stem (``,:=/`` and the path separator become ``-``)."""
    return "_".join(str(p).replace(",", "-").replace(":", "-").replace("=", "-").replace("/", "-")
                    .replace(os.sep, "-") for p in parts)  # fmt: skip


def plan_episodes(
    env_ids: Sequence[str],
    configs: Sequence[ControllerConfig],
    maps: Mapping[str, Sequence[str]],
    slips: Sequence[str],
    episodes: int,
    seed: int,
    settings: EnvSettings,
    calibration_budget: int = PARAMS.calibration_budget,
    calibration_seed: int = 0,
    random_maps: int | None = None,
    gifs: bool = False,
    run_dir: str = "",
) -> list[EpisodeSpec]:
    """Every episode of a run, in a fixed order.

    Trial i of every cell uses seed ``seed + i``. The ``random`` map row runs ``random_maps``
    trials when given (one seeded layout each), the other maps ``episodes``. With ``gifs``, trial
    0 of every cell records an animation under ``animations/``.
    """
    env = settings.as_dict()
    tolerance, steps, noise = env.pop("goal_tolerance"), env.pop("max_episode_steps"), env.pop("start_noise")
    env_json = json.dumps(env, sort_keys=True)
    plan = []
    for env_id in env_ids:
        for cfg in configs:
            options = json.dumps(dict(cfg.options), sort_keys=True)
            for map_name in maps[env_id]:
                trials = random_maps if (map_name == RANDOM_MAP and random_maps) else episodes
                for slip in slips:
                    for trial in range(trials):
                        animation = f"animations/{safe_file_name(env_id, cfg.label, map_name, slip)}.gif" \
                            if gifs and trial == 0 else ""  # fmt: skip
                        plan.append(EpisodeSpec(env_id, cfg.label, map_name, slip, trial, seed + trial, tolerance,
                                                steps, cfg.name, options, calibration_budget, calibration_seed,
                                                noise, env_json, animation, run_dir, cfg.factory))  # fmt: skip
    return plan


def map_fingerprints(maps: Mapping[str, Sequence[str]]) -> dict[str, str]:
    """SHA-256 of every user map file of the run (so a resume notices an edited file)."""
    prints = {}
    for names in maps.values():
        for name in names:
            if name != RANDOM_MAP and name not in BUILTIN_MAPS:
                with open(name, "rb") as fh:
                    prints[name] = hashlib.sha256(fh.read()).hexdigest()
    return prints


def validate_plan(
    env_ids: Sequence[str],
    configs: Sequence[ControllerConfig],
    maps: Mapping[str, Sequence[str]],
    slips: Sequence[str],
    episodes: int,
    workers: int,
    settings: EnvSettings,
    calibration_budget: int = PARAMS.calibration_budget,
    random_maps: int | None = None,
) -> None:
    """Raise ``ValueError`` naming the bad value and what is allowed, before any episode starts."""
    for env_id in env_ids:
        if env_id not in ENV_IDS:
            raise ValueError(f"env {env_id!r} is not one of {list(ENV_IDS)}")
    labels = [cfg.label for cfg in configs]
    duplicated = sorted({label for label in labels if labels.count(label) > 1})
    if duplicated:
        raise ValueError(f"controller labels {duplicated} appear twice; give each configuration its own label=")
    if not configs:
        raise ValueError("no controller to evaluate")
    if not slips:
        raise ValueError(
            "no slip setting to evaluate; allowed: nominal, low, high, random, drift or per-robot lambdas"
        )
    for cfg in configs:
        cfg.validate(across_processes=workers > 1)
    data_spec_for(calibration_budget)  # raises for a budget that is not an integer >= 1
    if not isinstance(episodes, int) or isinstance(episodes, bool) or episodes < 1:
        raise ValueError(f"episodes={episodes!r} must be an integer >= 1")
    if random_maps is not None and (not isinstance(random_maps, int) or isinstance(random_maps, bool)
                                    or random_maps < 1):  # fmt: skip
        raise ValueError(f"random_maps={random_maps!r} must be an integer >= 1 (layouts per cell)")
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r} must be an integer >= 1")
    for slip in slips:
        try:
            value = slip_value(slip)
            if value not in (RANDOM_SLIP, DRIFT_SLIP):
                slip_lambdas(value, settings.n_robots)
        except ValueError as exc:
            raise ValueError(f"slip {slip!r}: {exc}") from None
    # every (env, map) with the run's env settings, built as the episodes will build it, so that an
    # env kwarg the env rejects (or a map with too few starts for n_robots) fails here
    for env_id in env_ids:
        for map_name in maps[env_id]:
            try:
                EngineConfig.create(task_for_env(env_id).name, map=map_name, slip=slip_value(slips[0]),
                                    **settings.as_dict())  # fmt: skip
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{env_id} on map {map_name!r} with env settings {settings.as_dict()}: {exc}") from None
