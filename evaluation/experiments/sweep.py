"""``--sweep KEY=v1,v2,...``: the same run at every level of an env setting, for robustness profiles.

A sweep axis names an env keyword of :data:`~koopman_envs.engine.keywords.ENV_KEYWORDS` (``actuation_delay``,
``uncertainty``, ``sensing``, ``slip``) or a field of a dict-valued one (``comm.drop``,
``pose_noise.xy``, ``lidar.noise``). Each level is one ordinary run (every controller, cell and
trial of the spec) with the level set on top of the spec's env settings, logged in its own
directory ``OUT/sweep/<KEY>=<level>/`` and resumable like any run. Trial i uses seed
``seed + i`` at every level, and the uncertainty draws come from their own stream
(:mod:`koopman_envs.sim.perception`), so the maps, starts and slip draws are the same at every
level: the curves are paired. :mod:`evaluation.stats.robustness` turns the levels into profiles, and
:func:`evaluation.reports.results.write_profiles` writes their report (``python evaluate.py
--sweep-report OUT``: from the levels of :func:`load_sweep` finished so far).
"""

from __future__ import annotations

import argparse
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evaluation.execution import runner
from evaluation.execution.backends import BATCH
from evaluation.reports.baseline import load_baseline
from evaluation.reports.publications import extracted_archive, is_published
from evaluation.reports.published import results_from_log
from evaluation.reports.results import Results
from evaluation.reports.sections.blocks import level_text
from evaluation.run.plan import safe_file_name, slip_value
from evaluation.run.spec import RunSpec, with_env_setting
from koopman_envs import ENV_KEYWORDS, EngineConfig, task_for_env
from koopman_envs.checks import CLI_JSON_CHARS, did_you_mean, parse_json
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic

__all__ = [
    "MANIFEST",
    "MAX_SWEEP_LEVELS",
    "SweepAxis",
    "add_sweep_options",
    "check_levels",
    "level_aliases",
    "load_sweep",
    "parse_sweep",
    "refuse_sweep_clash",
    "run_sweep",
    "write_manifest",
]

#: the sweep's axes and reference, written in OUT before the first level runs
MANIFEST = "sweep.json"
_MANIFEST_KIND = "koopnav-sweep"

#: keywords a sweep cannot vary: the map is a cell axis, rendering is the evaluator's business,
#: and the team size changes what a controller is (sweep it as separate runs)
_NOT_SWEPT = ("map", "render_mode", "max_cycles")
#: the most levels of one sweep axis (ours): each level is a whole run of every controller, and a
#: profile of 64 points already resolves any curve; 15,000 were accepted and planned
MAX_SWEEP_LEVELS = 64


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
        return f"{self.key}=" + ",".join(level_text(v) for v in self.levels)

    def level_dir(self, out: str | os.PathLike, level: Any) -> Path:
        """The run directory of one level."""
        return Path(out) / "sweep" / safe_file_name(f"{self.key}={level_text(level)}")

    def apply(self, spec: RunSpec, level: Any) -> RunSpec:
        """``spec`` with this axis at ``level`` (over the spec's own env settings)."""
        if self.key == "slip":
            return spec.replace(slips=(level,))
        return spec.replace(
            env_kwargs=with_env_setting(spec.env_kwargs, self.key, level, f"--sweep {self.key}")
        )


def parse_sweep(text: str) -> SweepAxis:
    """``"comm.drop=0,0.1,0.3"`` -> :class:`SweepAxis` (values parsed as JSON, else text).

    Raises
    ------
    ValueError
        Not ``KEY=v1,v2,...``, an unknown or unsweepable keyword (with did-you-mean), fewer than
        two levels or more than :data:`MAX_SWEEP_LEVELS`, or a level given twice.
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
    words = values.split(",")
    if len(words) > MAX_SWEEP_LEVELS:
        raise ValueError(f"--sweep {key}: {len(words):,} levels; allowed: at most {MAX_SWEEP_LEVELS}")
    levels: list[Any] = []
    for position, word in enumerate(words, start=1):
        word = word.strip()
        if not word:
            raise ValueError(
                f"--sweep {text!r}: level {position} is empty (two commas in a row, or a comma at an "
                "end); give the levels as KEY=v1,v2,..."
            )
        try:
            level = parse_json(word, f"--sweep {key} level {position}", max_chars=CLI_JSON_CHARS)
        except json.JSONDecodeError:
            level = word
        if level in levels:
            raise ValueError(f"--sweep {key}: level {word!r} is given twice")
        levels.append(level)
    if len(levels) < 2:
        raise ValueError(f"--sweep {text!r}: give at least two levels, separated by commas")
    return SweepAxis(key, tuple(levels))


def add_sweep_options(what: argparse._ArgumentGroup) -> None:
    """The evaluator's ``--sweep``, ``--reference`` and ``--sweep-report`` options."""
    what.add_argument(
        "--sweep",
        action="append",
        metavar="KEY=V1,V2,...",
        help="robustness profile: run everything at each level of an env setting (repeatable; nested "
        "fields as comm.drop, pose_noise.xy), same seeds at every level; writes OUT/sweep/<KEY>-<level>/ "
        "and OUT/robustness.{md,json,html} (docs/robustness.md; default: no sweep)",
    )
    what.add_argument(
        "--reference",
        metavar="CONTROLLER",
        help="with --sweep or --sweep-report: the controller every other is paired against (default: "
        "the first; --crowd: koopman-nmpc; --sweep-report: the sweep's own)",
    )
    what.add_argument(
        "--sweep-report",
        metavar="OUT",
        help="write the robustness report of the levels finished so far of the sweep in OUT (its "
        "sweep.json; levels not finished are named and left out) and exit, running nothing "
        "(default: no such report)",
    )


def refuse_sweep_clash(sweeps: list[str] | None, given: dict[str, Any]) -> None:
    """Refuse an env setting given on the command line (``given``: the settings as parsed, dotted
    keys merged into their dicts) that a ``--sweep`` axis (``sweeps``: the ``KEY=v1,...`` texts)
    also sets: the sweep would override it at every level without a word (as
    ``--max-episode-steps`` against ``--env-kwargs`` is refused). ``ValueError`` naming both."""
    for text in sweeps or []:
        key = text.partition("=")[0].strip()
        root, _, field = key.partition(".")
        if root not in given:
            continue
        value = given[root]
        if not field or not isinstance(value, dict) or field in value:
            shown = (
                f"{root}.{field}={value[field]!r}"
                if field and isinstance(value, dict)
                else f"{root}={value!r}"
            )
            raise ValueError(
                f"--sweep {key} and the setting {shown} given on the command line both set {key}; the "
                "sweep sets it at every level: give it once"
            )


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
                            task_for_env(env_id).name, slip=slip_value(slip), map="random", **settings
                        )
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"--sweep {axis.key}={level_text(level)}: {exc}") from None


def _signature(spec: RunSpec) -> str:
    """What makes two levels the same run: the slips and every env setting as the envs resolve
    them (``comm.latency=0`` and ``pose_noise.xy=0`` both resolve to the perfect radio and
    localization, so the sweep runs that configuration once)."""
    settings = dict(spec.env_settings())
    resolved = []
    for env_id in spec.envs:
        config = EngineConfig.create(task_for_env(env_id).name, map="random", **settings)
        resolved.append(
            [repr(config.pose_noise), repr(config.comm), repr(config.lidar), config.actuation_delay]
        )
    rest = {k: v for k, v in settings.items() if k not in _UNCERTAINTY_KEYWORDS}
    return json.dumps([list(spec.slips), resolved, rest], sort_keys=True, default=str)


#: the keywords whose resolved values _signature compares instead of their spelling
_UNCERTAINTY_KEYWORDS = ("uncertainty", "pose_noise", "sensing", "lidar", "comm", "actuation_delay")


def level_aliases(spec: RunSpec, axes: list[SweepAxis]) -> dict[str, str]:
    """``{"KEY=level": "OTHER=level"}`` for every level that is the same run as an earlier one."""
    first: dict[str, str] = {}
    aliases = {}
    for axis in axes:
        for level in axis.levels:
            name = f"{axis.key}={level_text(level)}"
            signature = _signature(axis.apply(spec, level))
            if signature in first:
                aliases[name] = first[signature]
            else:
                first[signature] = name
    return aliases


def run_sweep(
    spec: RunSpec,
    axes: list[SweepAxis],
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    backend: str = "process",
    resume: bool = False,
    progress: bool = True,
    batch: int = BATCH,
) -> dict[str, list[tuple[Any, Results]]]:
    """Run ``spec`` at every level of every axis; each level's run lands in its own directory
    (``workers``, ``backend``, ``resume``, ``progress`` and ``batch`` as
    :func:`evaluation.execution.runner.evaluate`'s).

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
    check_levels(spec, axes)
    aliases = level_aliases(spec, axes)
    finished: dict[str, Results] = {}
    done: dict[str, list[tuple[Any, Results]]] = {}
    for axis in axes:
        done[axis.key] = []
        for level in axis.levels:
            name = f"{axis.key}={level_text(level)}"
            if name in aliases:  # the same run as an earlier level: its episodes serve both
                done[axis.key].append((level, finished[aliases[name]]))
                continue
            level_dir = axis.level_dir(out, level)
            again = resume and (level_dir / "episodes.jsonl").exists()
            if progress:
                print(f"sweep {name} -> {level_dir}", flush=True)
            # through the module: a test (or a user) that wraps runner.evaluate wraps every level
            results = runner.evaluate(
                axis.apply(spec, level),
                workers=workers,
                backend=backend,
                out=level_dir,
                resume=again,
                progress=progress,
                batch=batch,
            )
            results.write(level_dir)
            finished[name] = results
            done[axis.key].append((level, results))
    return done


def write_manifest(
    out: str | os.PathLike,
    axes: list[SweepAxis],
    reference: str | None,
    command: str,
    aliases: dict[str, str] | None = None,
) -> Path:
    """Record the sweep in ``OUT/sweep.json`` (what :func:`load_sweep` reads back); ``aliases``
    are the levels run once for several axes (:func:`level_aliases`)."""
    path = Path(out) / MANIFEST
    doc = {
        "kind": _MANIFEST_KIND,
        "axes": [{"key": a.key, "levels": list(a.levels)} for a in axes],
        "reference": reference,
        "command": command,
        "aliases": aliases or {},
    }
    return write_atomic(path, json.dumps(doc, indent=1) + "\n")


def _read_manifest(out: Path) -> dict[str, Any]:
    path = out / MANIFEST
    # a regular file of bounded size, refused unread otherwise (a FIFO here hung --sweep-report)
    text = read_text(
        path, MAX_TEXT_BYTES, what="sweep manifest", expected="a KoopNav sweep.json (UTF-8 JSON)"
    )
    try:
        doc = parse_json(text, f"sweep manifest {str(path)!r}")
    except json.JSONDecodeError as exc:
        raise ValueError(f"sweep manifest {str(path)!r} is not JSON ({exc.msg}, line {exc.lineno})") from None
    axes = doc.get("axes") if isinstance(doc, dict) else None
    if (
        not isinstance(doc, dict)
        or doc.get("kind") != _MANIFEST_KIND
        or not isinstance(axes, list)
        or not all(
            isinstance(a, dict) and isinstance(a.get("key"), str) and isinstance(a.get("levels"), list)
            for a in axes
        )
    ):
        raise ValueError(
            f"sweep manifest {str(path)!r} is not a KoopNav sweep manifest (kind, axes of key and levels)"
        )
    return doc


def _level_setting(config: dict[str, Any], key: str) -> Any:
    """The value of axis ``key`` that a level's results record."""
    if key == "slip":
        return (config.get("slips") or [None])[0]
    root, _, field = key.partition(".")
    value = (config.get("env_settings") or {}).get(root)
    return value.get(field) if field and isinstance(value, dict) else value


def load_sweep(
    out: str | os.PathLike,
    from_logs: bool = False,
) -> tuple[dict[str, list[tuple[Any, Results]]], list[str], dict[str, Any]]:
    """The finished levels of the sweep in ``out``, read back and checked.

    ``from_logs``: read each level from its episode log instead of its results.json (published
    data, :mod:`evaluation.reports.published`: the logs are what the repository keeps). ``out`` may then
    also be a publication: an archive (``.tar.xz``) or a split one (``data/NAME/``,
    :mod:`evaluation.reports.publications`).

    Returns
    -------
    levels : dict
        Axis key -> [(level, Results), ...] of the levels whose run wrote its results.json.
    missing : list of str
        ``KEY=level`` of the levels not (yet) finished, in order: reported, never dropped silently.
    manifest : dict
        The sweep's ``sweep.json``.

    Raises
    ------
    ValueError
        A manifest or a level's results.json that is torn, foreign, of an unreadable schema, or
        recording another value of its axis than its directory's (each named).
    """
    out = Path(out)
    if out.is_file() or is_published(out):  # a publication (an archive refused by name if it is not one)
        with extracted_archive(out) as run_dir:
            return _read_levels(run_dir, from_logs=True)
    return _read_levels(out, from_logs)


def _read_levels(
    out: Path, from_logs: bool
) -> tuple[dict[str, list[tuple[Any, Results]]], list[str], dict[str, Any]]:
    """:func:`load_sweep` of a sweep's directory."""
    manifest = _read_manifest(out)
    done: dict[str, list[tuple[Any, Results]]] = {}
    missing: list[str] = []
    aliases = manifest.get("aliases") or {}
    by_name: dict[str, tuple[SweepAxis, Any]] = {}
    for entry in manifest["axes"]:
        axis = SweepAxis(entry["key"], tuple(entry["levels"]))
        for level in axis.levels:
            by_name[f"{axis.key}={level_text(level)}"] = (axis, level)
    for entry in manifest["axes"]:
        axis = SweepAxis(entry["key"], tuple(entry["levels"]))
        done[axis.key] = []
        for level in axis.levels:
            name = f"{axis.key}={level_text(level)}"
            run_axis, run_level = by_name.get(aliases.get(name, name), (axis, level))
            file = run_axis.level_dir(out, run_level) / ("episodes.jsonl" if from_logs else "results.json")
            if not file.exists():
                missing.append(name)
                continue
            doc: dict[str, Any]
            if from_logs:
                results = results_from_log(file)
                doc = {"config": results.config, "episodes": results.records}
            else:
                doc = load_baseline(file, what="sweep level")
            recorded = _level_setting(doc["config"], run_axis.key)
            if recorded != run_level:
                raise ValueError(
                    f"sweep level {str(file)!r} records {run_axis.key}={recorded!r}, not {run_level!r}: "
                    "it belongs to another run"
                )
            done[axis.key].append((level, Results(doc["episodes"], doc["config"])))
        if not done[axis.key]:
            del done[axis.key]
    return done, missing, manifest
