"""``RunSpec``: what a run is (envs, controllers, maps, slips, trials, env settings), checked
before any episode starts, planned into episodes, and signed for ``--resume``.

A run is a grid of cells (env, controller configuration, map, slip) times trials. Trial ``i``
of every cell uses seed ``seed + i``, so all controllers face the same slip draws, start
perturbations and (on ``map="random"``) the same layouts: comparisons are paired.

The env settings of a run are its ``env_kwargs``, the ``gym.make`` keywords every episode and
calibration plant gets (``goal_tolerance``, ``max_episode_steps``, ``start_noise``, ``n_robots``,
...). They live only there; the named protocols (:mod:`evaluation.experiments.protocols`) are presets of
this class.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from controllers.calibration import data_spec_for
from evaluation.episodes.log_weights import PRESETS_KEY, WEIGHTS_KEY
from evaluation.episodes.runlog import run_signature
from evaluation.run.configs import controller_configs, with_solver
from evaluation.run.plan import (
    RANDOM_MAP,
    EpisodeSpec,
    MapFile,
    map_fingerprints,
    read_map_files,
    safe_file_name,
    slip_value,
)
from evaluation.run.suite_runs import check_suite_run, layout_slice, suite_config, suite_map, suite_units
from evaluation.run.weights import run_presets, run_weights
from koopman_envs import (
    BUILTIN_MAPS,
    ENV_IDS,
    ENV_KEYWORDS,
    TASKS,
    ComputeCharge,
    EngineConfig,
    MapSpec,
    task_for_env,
)
from koopman_envs.checks import check_choice, check_int, check_number, did_you_mean
from koopman_envs.params import (
    DRIFT_SLIP,
    MAX_EPISODES_PER_CELL,
    PARAMS,
    RANDOM_SLIP,
    SLIP_NAMES,
    SLIP_SETTINGS,
    slip_lambdas,
)

__all__ = ["CELL_AXES", "MAX_WORKERS", "RECORDED_ENV_SETTINGS", "RunSpec", "with_env_setting"]

#: env keywords that are axes of the grid (set through ``maps`` and ``slips``, never env kwargs)
CELL_AXES = ("map", "slip")
#: env keywords the evaluator owns: rendering is its business (``gifs``)
_NOT_ENV_KWARGS = (*CELL_AXES, "render_mode")
#: env settings every run records, with these values when the run does not set them (the envs'
#: defaults, with the time limit spelled out: the Gymnasium env leaves it to gym.make's TimeLimit)
RECORDED_ENV_SETTINGS = {
    "goal_tolerance": PARAMS.goal_tolerance,
    "max_episode_steps": PARAMS.max_episode_steps,
    "start_noise": 0.0,
}
#: each task's paper maps
TASK_MAPS = {spec.env_id: spec.paper_maps for spec in TASKS.values()}


def with_env_setting(env_kwargs: Mapping[str, Any], key: str, value: Any, where: str) -> dict[str, Any]:
    """A copy of ``env_kwargs`` with ``key`` set to ``value``; a dotted key ``keyword.field`` sets
    one field of a dict keyword over its other fields (``pose_noise.xy``). ``where`` names the
    option in the error raised when the keyword holds something other than a dict."""
    out = copy.deepcopy(dict(env_kwargs))
    root, _, field = key.partition(".")
    if not field:
        out[root] = value
        return out
    inner = out.get(root)
    if inner is None:
        inner = {}
    if not isinstance(inner, dict):
        raise ValueError(f"{where}: {root} is already {inner!r}, not a dict of fields")
    out[root] = {**inner, field: value}
    return out


#: the most worker processes (or Ray tasks at once) a run starts: far above any one machine's
#: cores, and a bound on what a typo such as --workers 10000000 would fork
MAX_WORKERS = 1024


@dataclass(frozen=True)
class RunSpec:
    """One evaluation run, as data: what :func:`evaluation.execution.runner.evaluate` runs.

    Lists are stored as tuples and ``maps`` as a table env id -> maps, so that two specs of the
    same run compare equal whichever form they were written in.

    Attributes
    ----------
    envs : str or sequence of str
        Environment ids (default: both tasks).
    controllers : sequence or mapping, optional
        Controller configurations (default: every usable registered controller): registered
        names, ``"name:key=value,..."`` texts, :class:`~evaluation.run.configs.ControllerConfig`,
        factories / controller classes, or a mapping ``{label: entry}`` where an entry is any
        of those or a ``(name or factory, {options})`` pair. Each configuration is one row; a
        factory must be defined at module level to reach worker processes.
    maps : sequence or mapping, optional
        Maps for every env (shipped names, ``"random"``, or paths of JSON map files), or a
        mapping env id -> maps (default: each task's paper maps).
    slips : sequence of str
        Setting names (``nominal``, ``low``, ``high``, ``random``, ``drift``) or per-robot
        lambdas (``"0,0.1,0.2"`` or a list of numbers).
    episodes : int
        Trials per cell (trial i uses seed ``seed + i``).
    seed : int
        Base seed.
    env_kwargs : mapping
        ``gym.make`` keywords of every episode and calibration plant, e.g. ``{"n_robots": 5,
        "max_episode_steps": 150, "start_noise": 0.05}`` (plain JSON; ``map`` and ``slip`` are
        the grid's axes, not env kwargs). Recorded in the results and checked on resume.
    calibration_budget : int
        Team-transitions every controller may simulate on the cell's calibration plant before
        its episodes (the same for all; default the paper's 1000 x 1000).
    calibration_seed : int
        Seed of the calibration plant and data (never one of the episode seeds' streams).
    random_maps : int, optional
        Add a ``random`` map row to every env with this many seeded layouts (one per trial;
        the same layouts for every controller).
    gifs : bool
        Record trial 0 of every cell as ``OUT/animations/*.gif`` (needs an output directory).
    compute_scale : float, optional
        Compute-aware episodes (``--realtime``, ``--compute-scale``): every controller's decision
        time, times this factor, is charged to its robots
        (:class:`koopman_envs.episodes.single.ComputeCharge`, which every episode receives as it is:
        :attr:`compute`); None (default): the env waits for the controller.
    solver : str, optional
        Optimizer (``rti``, ``ipopt``, ``fatrop``) of every NMPC configuration that names none
        (default: each controller's own).
    fallback_solver : str, optional
        NLP rescue (``ipopt``, ``fatrop``, or ``"none"`` for no rescue) of every NMPC
        configuration that names none (default: each controller's own: none).
    suite : str, optional
        A benchmark suite (``"koopnav-bench-v1"``, :mod:`koopman_envs.suites`): each task's map
        axis becomes its split of the suite, and each selected layout runs ``episodes`` episodes
        (:mod:`evaluation.run.suite_runs`). Not with ``maps`` or ``random_maps``.
    split : str, optional
        The suite's split (``train``, ``validation``, ``test``; default ``test``); only with ``suite``.
    layouts : int, str or (int, int), optional
        The layouts of the split to run: N (the first N), ``"a:b"`` or ``(a, b)`` (layouts a to
        b-1); default every layout. Only with ``suite``.
    """

    envs: str | Sequence[str] = tuple(TASK_MAPS)
    controllers: Any = None
    maps: Any = None
    slips: Sequence[Any] = SLIP_SETTINGS
    episodes: int = 2
    seed: int = 0
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    calibration_budget: int = PARAMS.calibration_budget
    calibration_seed: int = 0
    random_maps: int | None = None
    gifs: bool = False
    compute_scale: float | None = None
    solver: str | None = None
    fallback_solver: str | None = None
    suite: str | None = None
    split: str | None = None
    layouts: int | str | tuple[int, int] | None = None

    def __post_init__(self) -> None:
        # normal forms only (nothing here can fail on a value: validate() names bad ones)
        envs = (self.envs,) if isinstance(self.envs, str) else tuple(self.envs)

        def set_(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)  # a frozen dataclass normalizing its own fields

        set_("envs", envs)
        if self.controllers is not None:
            try:
                set_("controllers", tuple(controller_configs(self.controllers)))
            except ValueError as exc:
                raise ValueError(f"controllers: {exc}") from None
        if self.suite is not None:
            set_("split", self.split if self.split is not None else "test")
            if self.maps is None:  # the map axis is each task's split of the suite
                set_("maps", {e: (suite_map(str(self.suite), str(self.split)),) for e in envs})
        set_("layouts", layout_slice(self.layouts))
        set_("maps", self._map_table(envs, self.maps, self.random_maps))
        set_("slips", tuple(s if isinstance(s, str) else ",".join(str(v) for v in s) for s in self.slips))
        set_("env_kwargs", dict(self.env_kwargs or {}))

    @staticmethod
    def _map_table(envs: tuple[str, ...], maps: Any, random_maps: Any) -> dict[str, tuple[str, ...]]:
        if maps is None:
            table = {e: tuple(TASK_MAPS.get(e, BUILTIN_MAPS)) for e in envs}
        elif isinstance(maps, Mapping):
            missing = [e for e in envs if e not in maps]
            if missing:
                raise ValueError(f"maps has no entry for env {missing[0]!r}; it has {sorted(maps)}")
            table = {
                e: tuple(os.fspath(m) for m in ([maps[e]] if isinstance(maps[e], str) else maps[e]))
                for e in envs
            }
        else:
            if isinstance(maps, (str, os.PathLike)):
                maps = [maps]
            table = {e: tuple(os.fspath(m) for m in maps) for e in envs}
        if random_maps:  # the seeded random layouts are one more map row
            table = {e: m if RANDOM_MAP in m else (*m, RANDOM_MAP) for e, m in table.items()}
        return table

    # ------------------------------------------------------------------ derived views
    def replace(self, **changes: Any) -> RunSpec:
        """A copy with some fields changed (``maps`` recomputed when ``envs`` change and
        ``maps`` is not given)."""
        suite_run = changes.get("suite", self.suite) is not None
        if "maps" not in changes and ({"suite", "split"} & set(changes) or ("envs" in changes and suite_run)):
            changes["maps"] = None  # each task's suite split again, or the paper maps (__post_init__)
        elif "envs" in changes and "maps" not in changes:
            old = self.maps
            envs = (changes["envs"],) if isinstance(changes["envs"], str) else tuple(changes["envs"])
            changes["maps"] = {e: old.get(e, TASK_MAPS.get(e, BUILTIN_MAPS)) for e in envs}
        return dataclasses.replace(self, **changes)

    def env_settings(self) -> dict[str, Any]:
        """The env keywords every episode runs with: ``env_kwargs`` over the defaults of
        :data:`RECORDED_ENV_SETTINGS` (so two runs that differ only in spelling a default out
        record the same settings)."""
        settings = dict(RECORDED_ENV_SETTINGS)
        settings.update(self.env_kwargs)
        plain: dict[str, Any] = json.loads(json.dumps(dict(sorted(settings.items()))))
        return plain

    @property
    def compute(self) -> ComputeCharge | None:
        """What every episode charges for its controller's decision time (``compute_scale``), as
        the episode runner takes it; None: free compute (the env waits for the controller)."""
        return None if self.compute_scale is None else ComputeCharge(scale=self.compute_scale)

    @property
    def n_robots(self) -> int:
        """Team size of the run's envs."""
        return int(self.env_kwargs.get("n_robots", PARAMS.n_robots))

    def resolved(self, controllers: Sequence[Any] | None = None) -> RunSpec:
        """This spec with its controller list explicit and ``solver`` and ``fallback_solver``
        applied to it.

        ``controllers`` fills in a spec without controllers (the evaluator passes every usable
        registered controller).
        """
        configs = self.controllers if self.controllers is not None else controllers
        if configs is None:
            raise ValueError("RunSpec.controllers is empty: name the controllers to evaluate")
        configs = with_solver(controller_configs(configs), self.solver, self.fallback_solver)
        return dataclasses.replace(self, controllers=tuple(configs), solver=None, fallback_solver=None)

    # ------------------------------------------------------------------ checks
    def validate(self, workers: int = 1, map_files: Mapping[str, MapFile] | None = None) -> None:
        """Raise ``ValueError`` naming the bad field, its value and what is allowed.

        Called by :func:`~evaluation.execution.runner.evaluate` before any episode starts; every
        (env, map) is built with the run's env settings as the episodes will build it, so an
        env kwarg the env rejects (or a map with too few starts for ``n_robots``) fails here.
        A user map file is built from ``map_files``, the texts the run read once
        (:func:`~evaluation.run.plan.read_map_files`), when given; else from the file.
        """
        for env_id in self.envs:
            check_choice("envs:", env_id, ENV_IDS, sep=" ")
        configs = self.controllers
        if configs is not None:
            if not configs:
                raise ValueError("controllers: no controller to evaluate")
            labels = [cfg.label for cfg in configs]
            duplicated = sorted({label for label in labels if labels.count(label) > 1})
            if duplicated:
                raise ValueError(
                    f"controllers: labels {duplicated} appear twice; give each configuration its own label="
                )
            for cfg in configs:
                cfg.validate(across_processes=workers > 1)
        if self.solver is not None or self.fallback_solver is not None:
            with_solver([], self.solver, self.fallback_solver)  # names a bad solver and the allowed ones
        data_spec_for(self.calibration_budget)  # raises for a budget that is not an integer >= 1
        check_int("calibration_seed", self.calibration_seed, 0)
        # bounded before planning: a run plans every episode up front (--episodes 10**22 would
        # fill the memory instead of failing)
        check_int("episodes", self.episodes, 1, maximum=MAX_EPISODES_PER_CELL, note="trials per cell")
        check_int("seed", self.seed, 0)
        if self.random_maps is not None:
            check_int(
                "random_maps", self.random_maps, 1, maximum=MAX_EPISODES_PER_CELL, note="layouts per cell"
            )
        if not isinstance(self.gifs, bool):
            raise ValueError(f"gifs={self.gifs!r} must be True or False")
        if self.compute_scale is not None:
            check_number(
                "compute_scale",
                self.compute_scale,
                above=0,
                at_most=1000,
                note="a factor on the decision time",
            )
        check_int("workers", workers, 1, maximum=MAX_WORKERS, note="processes or Ray tasks at once")
        check_suite_run(self, MAX_EPISODES_PER_CELL)
        self._validate_env_kwargs()
        if not self.slips:
            raise ValueError(
                f"slips: no slip setting to evaluate; allowed: {', '.join(SLIP_NAMES)} or per-robot lambdas"
            )
        for slip in self.slips:
            try:
                value = slip_value(slip)
                if value not in (RANDOM_SLIP, DRIFT_SLIP):
                    slip_lambdas(value, self.n_robots)
            except ValueError as exc:
                raise ValueError(f"slips: {slip!r}: {exc}") from None
        settings = self.env_settings()
        files = map_files or {}
        for env_id in self.envs:
            for map_name in self.maps[env_id]:
                read = files.get(map_name)
                map_arg = map_name if read is None else MapSpec.from_file_text(read.text, map_name)
                try:
                    EngineConfig.create(
                        task_for_env(env_id).name, map=map_arg, slip=slip_value(self.slips[0]), **settings
                    )
                except (TypeError, ValueError) as exc:
                    raise ValueError(
                        f"{env_id} on map {map_name!r} with env settings {settings}: {exc}"
                    ) from None

    def _validate_env_kwargs(self) -> None:
        allowed = sorted(k.name for k in ENV_KEYWORDS if k.name not in _NOT_ENV_KWARGS)
        for key, value in self.env_kwargs.items():
            if key in CELL_AXES:
                raise ValueError(
                    f"env_kwargs: {key!r} is a cell axis: give it with --{key}s / {key}s=, not as an "
                    "env kwarg"
                )
            if key not in allowed:
                raise ValueError(
                    f"env_kwargs: {key!r} is not one the environments take"
                    f"{did_you_mean(key, allowed)}; allowed: {allowed}"
                )
            try:
                json.dumps(value, allow_nan=False)
            except (TypeError, ValueError):
                raise ValueError(
                    f"env_kwargs: {key}={value!r} must be plain JSON (a number, text, list or dict)"
                ) from None
            # the keyword's own check first, so that its message names it (n_robots="abc" was
            # reported by the first check that used the team size: the slips')
            row = next(k for k in ENV_KEYWORDS if k.name == key)
            try:
                row.resolve(value)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"env_kwargs: {exc}") from None

    # ------------------------------------------------------------------ the run
    def episodes_plan(
        self, run_dir: str = "", map_files: Mapping[str, MapFile] | None = None
    ) -> list[EpisodeSpec]:
        """Every episode of the run, in a fixed order (needs explicit controllers: see :meth:`resolved`).

        Trial i of every cell uses seed ``seed + i``. The ``random`` map row runs
        ``random_maps`` trials when given (one seeded layout each), the other maps
        ``episodes``. A suite run runs ``episodes`` episodes on each selected layout of the
        split, episode j of layout l as trial ``j * len(split) + l``
        (:func:`evaluation.run.suite_runs.unit_trial`), its layout given to the env's reset. With
        ``gifs``, the first episode of every cell records an animation under ``animations/`` of
        ``run_dir``. A user map file's episodes carry its text as ``map_files`` holds it (what
        :meth:`config` fingerprinted: :func:`evaluation.run.plan.read_map_files`; default: read
        now) and build their map from it, never from the file again.
        """
        if self.controllers is None:
            raise ValueError("RunSpec.episodes_plan() needs explicit controllers; call resolved() first")
        files = read_map_files(self.maps) if map_files is None else map_files
        env_json = json.dumps(self.env_settings(), sort_keys=True)
        compute = self.compute
        plan = []
        for env_id in self.envs:
            for cfg in self.controllers:
                options = json.dumps(dict(cfg.options), sort_keys=True)
                for map_name in self.maps[env_id]:
                    units = self._units(env_id, map_name)
                    for slip in self.slips:
                        for n, (trial, layout) in enumerate(units):
                            animation = ""
                            if self.gifs and n == 0:
                                animation = (
                                    f"animations/{safe_file_name(env_id, cfg.label, map_name, slip)}.gif"
                                )
                            plan.append(
                                EpisodeSpec(
                                    env_id=env_id,
                                    controller=cfg.label,
                                    map=map_name,
                                    slip=slip,
                                    trial=trial,
                                    seed=self.seed + trial,
                                    controller_name=cfg.name,
                                    controller_options=options,
                                    calibration_budget=self.calibration_budget,
                                    calibration_seed=self.calibration_seed,
                                    env_kwargs=env_json,
                                    animation=animation,
                                    run_dir=run_dir,
                                    compute=compute,
                                    controller_factory=cfg.factory,
                                    map_text=files[map_name].text if map_name in files else None,
                                    **layout,
                                )
                            )
        return plan

    def _units(self, env_id: str, map_name: str) -> list[tuple[int, dict[str, Any]]]:
        """The (trial index, layout fields of the episode) of every episode of a cell."""
        if self.suite is not None:
            return suite_units(env_id, self.suite, str(self.split), self.layouts, self.episodes)  # type: ignore[arg-type]
        trials = self.random_maps if (map_name == RANDOM_MAP and self.random_maps) else self.episodes
        return [(trial, {}) for trial in range(trials)]

    def config(
        self, workers: int, backend: str, map_files: Mapping[str, MapFile] | None = None
    ) -> dict[str, Any]:
        """The run's configuration as ``results.json`` records it (plain JSON; explicit controllers).

        ``map_files``: the user map files as the run read them (their fingerprints are recorded;
        default: read now), the same that :meth:`episodes_plan` is given."""
        if self.controllers is None:
            raise ValueError("RunSpec.config() needs explicit controllers; call resolved() first")
        settings = self.env_settings()
        # which weights the learned controllers play, which tuned preset files set the controllers'
        # defaults (each checked on --resume; absent without one: evaluation.run.weights)
        weights, presets = run_weights(self.controllers, self.envs), run_presets(self.controllers)
        return {
            "env_ids": list(self.envs),
            "controllers": [c.label for c in self.controllers],
            "controller_configs": [c.to_dict() for c in self.controllers],
            "calibration": {
                "budget": self.calibration_budget,
                "seed": self.calibration_seed,
                "unit": "team-transitions, offered to every controller alike",
            },
            "maps": {e: list(m) for e, m in self.maps.items()},
            "map_files": map_fingerprints(self.maps, map_files),
            "slips": list(self.slips),
            "episodes": self.episodes,
            "random_maps": self.random_maps,
            # a suite run: the suite's name, version, split, selection and each task's label and hash
            "suite": None
            if self.suite is None
            else suite_config(self.envs, self.suite, str(self.split), self.layouts, self.episodes),  # type: ignore[arg-type]
            "env_settings": settings,
            "gifs": bool(self.gifs),
            # compute-aware runs name the machine their decision times were measured on
            "compute": None
            if self.compute_scale is None
            else {"scale": self.compute_scale, "machine": machine_name()},
            # the recorded settings also at the top level (schema v2 readers)
            "start_noise": settings["start_noise"],
            "tolerance": settings["goal_tolerance"],
            "max_episode_steps": settings["max_episode_steps"],
            "seed": self.seed,
            "workers": workers,
            "backend": backend,
            **{key: value for key, value in ((WEIGHTS_KEY, weights), (PRESETS_KEY, presets)) if value},
        }

    def signature(self) -> dict[str, Any]:
        """What ``--resume`` checks: the settings that change what an episode does."""
        return run_signature(self.config(workers=1, backend="process"))


def machine_name() -> str:
    """The CPU a compute-aware run measured its decision times on (model name and cores)."""
    import platform

    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            for line in handle:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores"
