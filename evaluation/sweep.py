"""``--sweep KEY=v1,v2,...``: the same run at every level of an env setting, for robustness profiles.

A sweep axis names an env keyword of :data:`~koopman_envs.keywords.ENV_KEYWORDS` (``actuation_delay``,
``uncertainty``, ``sensing``, ``slip``) or a field of a dict-valued one (``comm.drop``,
``pose_noise.xy``, ``lidar.noise``). Each level is one ordinary run (every controller, cell and
trial of the spec) with the level set on top of the spec's env settings, logged in its own
directory ``OUT/sweep/<KEY>=<level>/`` and resumable like any run. Trial i uses seed
``seed + i`` at every level, and the uncertainty draws come from their own stream
(:mod:`koopman_envs.sim.perception`), so the maps, starts and slip draws are the same at every
level: the curves are paired. :mod:`evaluation.robustness` turns the levels into profiles.
"""

from __future__ import annotations

import copy
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evaluation.plan import safe_file_name
from evaluation.results import Results
from evaluation.spec import RunSpec
from koopman_envs.config import EngineConfig
from koopman_envs.keywords import ENV_KEYWORDS
from koopman_envs.suggest import did_you_mean
from koopman_envs.tasks.base import task_for_env

__all__ = ["SweepAxis", "parse_sweep", "run_sweep"]

#: keywords a sweep cannot vary: the map is a cell axis, rendering is the evaluator's business,
#: and the team size changes what a controller is (sweep it as separate runs)
_NOT_SWEPT = ("map", "render_mode", "max_cycles")


@dataclass(frozen=True)
class SweepAxis:
    """One swept env setting and its levels.

    Attributes
    ----------
    key : str
        An env keyword, or ``keyword.field`` for a field of a dict-valued keyword.
    levels : tuple
        Its values, in order (numbers or text, as JSON reads them).
    """

    key: str
    levels: tuple[Any, ...]

    @property
    def label(self) -> str:
        """``KEY=v1,v2,...`` as given."""
        return f"{self.key}=" + ",".join(_text(v) for v in self.levels)

    def level_dir(self, out: str | os.PathLike, level: Any) -> Path:
        """The run directory of one level."""
        return Path(out) / "sweep" / safe_file_name(f"{self.key}={_text(level)}")

    def apply(self, spec: RunSpec, level: Any) -> RunSpec:
        """``spec`` with this axis at ``level`` (over the spec's own env settings)."""
        if self.key == "slip":
            return spec.replace(slips=(level,))
        env_kwargs = copy.deepcopy(dict(spec.env_kwargs))
        root, _, field = self.key.partition(".")
        if field:
            inner = env_kwargs.get(root) or {}
            if not isinstance(inner, dict):
                raise ValueError(f"--sweep {self.key}: env_kwargs {root}={inner!r} is not a dict of fields")
            env_kwargs[root] = {**inner, field: level}
        else:
            env_kwargs[root] = level
        return spec.replace(env_kwargs=env_kwargs)


def _text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def parse_sweep(text: str) -> SweepAxis:
    """``"comm.drop=0,0.1,0.3"`` -> :class:`SweepAxis` (values parsed as JSON, else text).

    Raises
    ------
    ValueError
        Not ``KEY=v1,v2,...``, an unknown or unsweepable keyword (with did-you-mean), fewer than
        two levels, or a level given twice.
    """
    key, eq, values = text.partition("=")
    key = key.strip()
    if not eq or not key:
        raise ValueError(f"--sweep {text!r} is not KEY=v1,v2,... (e.g. comm.drop=0,0.1,0.3)")
    root = key.partition(".")[0]
    allowed = [k.name for k in ENV_KEYWORDS if k.name not in _NOT_SWEPT]
    if root not in allowed:
        raise ValueError(
            f"--sweep {key!r}: {root!r} is not an env keyword{did_you_mean(root, allowed)}; allowed: {allowed}"
        )
    levels: list[Any] = []
    for word in values.split(","):
        word = word.strip()
        try:
            level = json.loads(word)
        except json.JSONDecodeError:
            level = word
        if level in levels:
            raise ValueError(f"--sweep {key}: level {word!r} is given twice")
        levels.append(level)
    if len(levels) < 2 or any(level == "" for level in levels):
        raise ValueError(f"--sweep {text!r}: give at least two levels, separated by commas")
    return SweepAxis(key, tuple(levels))


def check_levels(spec: RunSpec, axes: list[SweepAxis]) -> None:
    """Build every level's env config of every env of ``spec`` (fast, no episode): a bad level
    is a ``ValueError`` naming the axis and the level before anything runs."""
    for axis in axes:
        for level in axis.levels:
            sub = axis.apply(spec, level)
            for env_id in sub.envs:
                settings = dict(sub.env_settings())
                try:
                    for slip in sub.slips:
                        EngineConfig.create(
                            task_for_env(env_id).name, slip=_slip(slip), map="random", **settings
                        )
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"--sweep {axis.key}={_text(level)}: {exc}") from None


def _slip(slip: str) -> Any:
    from evaluation.plan import slip_value

    return slip_value(slip)


def run_sweep(
    spec: RunSpec,
    axes: list[SweepAxis],
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    backend: str = "process",
    resume: bool = False,
    progress: bool = True,
) -> dict[str, list[tuple[Any, Results]]]:
    """Run ``spec`` at every level of every axis; each level's run lands in its own directory.

    Returns
    -------
    dict
        Axis key -> [(level, that level's Results), ...] in the given order.

    Raises
    ------
    ValueError
        A bad axis or level, before any episode.
    RunInterrupted
        Ctrl-C: every finished episode is logged; ``resume=True`` continues where it stopped.
    """
    from evaluation.runner import evaluate

    check_levels(spec, axes)
    done: dict[str, list[tuple[Any, Results]]] = {}
    for axis in axes:
        done[axis.key] = []
        for level in axis.levels:
            level_dir = axis.level_dir(out, level)
            again = resume and (level_dir / "episodes.jsonl").exists()
            if progress:
                print(f"sweep {axis.key}={_text(level)} -> {level_dir}", flush=True)
            results = evaluate(
                axis.apply(spec, level),
                workers=workers,
                backend=backend,
                out=level_dir,
                resume=again,
                progress=progress,
            )
            results.write(level_dir)
            done[axis.key].append((level, results))
    return done
