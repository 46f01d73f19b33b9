"""One episode of a run (``EpisodeSpec``, what a worker gets) and the helpers that name cells.

:class:`evaluation.run.spec.RunSpec` plans a run into these; a worker builds its env and controller
from one and returns the episode's record.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from evaluation.run.configs import ControllerConfig
from evaluation.run.slip_text import is_lambda, slip_value
from evaluation.run.suite_runs import LAYOUT_FIELDS
from koopman_envs import BUILTIN_MAPS, SUITE_PREFIX, ComputeCharge, MapSpec
from koopman_envs.files import read_text
from koopman_envs.params import LIMITS, PARAMS

__all__ = [
    "EpisodeSpec",
    "MapFile",
    "RANDOM_MAP",
    "is_lambda",
    "is_map_file",
    "map_fingerprints",
    "read_map_files",
    "safe_file_name",
    "slip_value",
]

RANDOM_MAP = "random"


@dataclass(frozen=True)
class EpisodeSpec:
    """One episode to run: a cell plus the trial index (which fixes the seed)."""

    env_id: str
    controller: str  # the configuration's label (its row in the reports)
    map: str
    slip: str  # a setting name, or comma-separated lambdas
    trial: int
    seed: int
    controller_name: str = ""  # registered name (default: the label)
    controller_options: str = "{}"  # JSON object of factory options
    calibration_budget: int = PARAMS.calibration_budget
    calibration_seed: int = 0
    env_kwargs: str = "{}"  # JSON object of the run's env settings (goal_tolerance, n_robots, ...)
    animation: str = ""  # relative path of the GIF to record for this episode ("" = none)
    run_dir: str = ""  # the run's output directory (where ``animation`` goes)
    # compute-aware: the charge for the controller's decision time (RunSpec.compute), handed as it
    # is to the episode runner; None: free compute. Recorded as ``compute_scale`` (record_fields)
    compute: ComputeCharge | None = None
    # a suite run's episode: the layout's index in the split (the env's reset option), its family
    # and tier, and the split's label (evaluation.run.suite_runs); None elsewhere, and then not recorded
    layout: int | None = None
    layout_family: str | None = None
    layout_tier: str | None = None
    suite: str | None = None
    # a factory given as a callable (API only); sent to workers by reference, not recorded
    controller_factory: Callable[..., Any] | None = field(default=None, compare=False, repr=False)
    # a user map file's text as the run read it once (read_map_files) and fingerprinted it: the
    # episode's map is built from it, never from the file again; not recorded (the fingerprint is,
    # in the run's config). None: the map is a name (a shipped map, random, a suite split)
    map_text: str | None = field(default=None, compare=False, repr=False)

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
        return ControllerConfig(
            self.controller,
            self.controller_name or self.controller,
            tuple(sorted(options.items())),
            self.controller_factory,
        )

    def make_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``gym.make`` for this episode (without ``render_mode``)."""
        # a user map from the text the run fingerprinted, not from the file (edited meanwhile?)
        map_arg = self.map if self.map_text is None else MapSpec.from_file_text(self.map_text, self.map)
        return {**json.loads(self.env_kwargs), "map": map_arg, "slip": slip_value(self.slip)}

    def reset_options(self) -> dict[str, Any] | None:
        """The env's reset options of this episode: its suite layout (None off a suite)."""
        return None if self.layout is None else {"layout": self.layout}

    def record_fields(self) -> dict[str, Any]:
        """The plain-JSON fields of the spec, as every episode record starts (the layout fields
        only in a suite run's records, so that every other record is as before)."""
        fields: dict[str, Any] = {}
        for k in self.__dataclass_fields__:
            if k in ("controller_factory", "run_dir", "map_text") or (
                k in LAYOUT_FIELDS and self.layout is None
            ):
                continue
            if k == "compute":  # as its scale, the field records have always had (0.0: free compute)
                fields["compute_scale"] = 0.0 if self.compute is None else self.compute.scale
            else:
                fields[k] = getattr(self, k)
        # the recorded env settings also as fields of their own (results schema v2 readers)
        env = json.loads(self.env_kwargs)
        recorded = {
            "tolerance": env.get("goal_tolerance", PARAMS.goal_tolerance),
            "max_episode_steps": env.get("max_episode_steps", PARAMS.max_episode_steps),
            "start_noise": env.get("start_noise", 0.0),
        }
        return {"key": self.key, **fields, **recorded}


def safe_file_name(*parts: str) -> str:
    """Cell coordinates joined into a file-name stem (``,:=/`` and the path separator become ``-``)."""
    return "_".join(
        str(p).replace(",", "-").replace(":", "-").replace("=", "-").replace("/", "-").replace(os.sep, "-")
        for p in parts
    )


def is_map_file(name: str) -> bool:
    """Whether a map of a run is a user map file (not a shipped map, ``random`` or a suite split):
    a path, as :func:`koopman_envs.load_map` tells one (a ``.json`` name or one with a directory);
    any other name is an unknown map, which the run's checks refuse naming the shipped ones."""
    if name == RANDOM_MAP or name in BUILTIN_MAPS or name.startswith(SUITE_PREFIX):
        return False
    return name.endswith(".json") or os.path.sep in name


@dataclass(frozen=True)
class MapFile:
    """A user map file of a run, read once: its text and the SHA-256 of its bytes (its UTF-8)."""

    path: str
    text: str
    sha256: str


def read_map_files(maps: Mapping[str, Sequence[str]]) -> dict[str, MapFile]:
    """Every user map file of the run, each read once (bounded, as :func:`koopman_envs.load_map`
    reads it): the run records these fingerprints and builds its episodes' maps from these texts,
    so that a file edited during the run changes neither.

    Raises
    ------
    koopman_envs.files.FileRefused
        A map file is missing, not a regular file, too large or not UTF-8 text; the message names it.
    """
    files = {}
    for names in maps.values():
        for name in names:
            if is_map_file(name) and name not in files:
                text = read_text(name, LIMITS.map_file_bytes, what="map file", expected="a JSON map file")
                # strict UTF-8 decodes and encodes back to the very bytes read: the file's hash
                files[name] = MapFile(name, text, hashlib.sha256(text.encode("utf-8")).hexdigest())
    return files


def map_fingerprints(
    maps: Mapping[str, Sequence[str]], files: Mapping[str, MapFile] | None = None
) -> dict[str, str]:
    """SHA-256 of every user map file of the run (so a resume notices an edited file; a suite
    split's hash is the run's ``suite`` record): of ``files`` when given (what the run read, see
    :func:`read_map_files`), else of the files read now."""
    files = read_map_files(maps) if files is None else files
    return {name: files[name].sha256 for names in maps.values() for name in names if is_map_file(name)}
