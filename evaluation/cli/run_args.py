"""The run the command line asks for: the parsed options (:mod:`evaluation.cli.options`) read into
a :class:`~evaluation.run.spec.RunSpec` (a protocol preset with the given options replacing its
fields), the sweep axes and the reference, without changing the options."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from typing import Any

from evaluation.experiments.ablation import check_factors
from evaluation.experiments.protocols import (
    CROWD_COUNTS,
    CROWD_REFERENCE,
    LIDAR_AXES,
    ablation_protocol,
    crowd_protocol,
    lidar_protocol,
    paper_protocol,
    quick_protocol,
    suite_protocol,
)
from evaluation.experiments.sweep import refuse_sweep_clash
from evaluation.run.configs import split_controller_list
from evaluation.run.slip_text import split_slips
from evaluation.run.spec import RunSpec, with_env_setting
from evaluation.run.suite_runs import refuse_suite_clash
from koopman_envs.checks import CLI_JSON_CHARS, parse_json

__all__ = ["CommandLineRun", "parse_env_kwargs", "run_from_args", "spec_from_args", "split_words"]


def split_words(words: list[str] | None) -> list[str] | None:
    """``["a,b", "c"]`` -> ``["a", "b", "c"]``: comma-separated lists work like spaced ones."""
    if words is None:
        return None
    return [piece.strip() for word in words for piece in word.split(",") if piece.strip()]


def parse_env_kwargs(words: list[str] | None, into: dict[str, Any] | None = None) -> dict[str, Any]:
    """``["n_robots=5", "pose_noise.xy=0.1"]`` -> dict (values parsed as JSON, else text).

    A dotted key sets one field of a dict keyword, over that keyword's fields in ``into`` (the
    settings given before, which the result copies and overrides). A key given twice is refused
    (``ValueError`` naming it), as are JSON values nested or sized beyond
    :func:`koopman_envs.checks.parse_json`'s bounds.
    """
    kwargs: dict[str, Any] = dict(into or {})
    seen: set[str] = set()
    for word in words or []:
        key, eq, value = word.partition("=")
        if key.strip() in seen:
            raise ValueError(f"--env-kwargs {key.strip()!r} is given twice; give each key once")
        seen.add(key.strip())
        root, dot, field = key.strip().partition(".")
        if not eq or not root.isidentifier() or (dot and not field.isidentifier()):
            raise ValueError(
                f"--env-kwargs {word!r} is not key=value (a Python identifier as key, or "
                "keyword.field for one field of a dict keyword, e.g. pose_noise.xy=0.1)"
            )
        try:
            parsed = parse_json(value, f"--env-kwargs {key.strip()}", max_chars=CLI_JSON_CHARS)
        except json.JSONDecodeError:
            parsed = value
        kwargs = with_env_setting(kwargs, key.strip(), parsed, f"--env-kwargs {word!r}")
    return kwargs


#: the env keywords with an option of their own: (argparse destination, keyword)
_DEDICATED = (
    ("tolerance", "goal_tolerance"),
    ("max_episode_steps", "max_episode_steps"),
    ("start_noise", "start_noise"),
    ("plant", "plant"),
)


@dataclass(frozen=True)
class CommandLineRun:
    """What the command line asks to run (:func:`run_from_args`).

    Attributes
    ----------
    spec : RunSpec
        The run (a sweep's base run: every level changes one env setting of it).
    sweep : tuple of str
        The ``--sweep`` axes (``key=v1,v2,...``); a protocol with axes of its own (``--crowd``,
        ``--lidar``) gives them when ``--sweep`` is not given. Empty: no sweep.
    reference : str, optional
        The controller every other is paired against in a sweep's profiles (``--reference``; the
        paper's method for ``--crowd`` and ``--lidar`` when neither it nor ``--controllers`` is
        given).
    """

    spec: RunSpec
    sweep: tuple[str, ...] = ()
    reference: str | None = None


def run_from_args(args: argparse.Namespace) -> CommandLineRun:
    """The run the command line asks for: a protocol preset with the given options replacing its
    fields, and the sweep axes and reference, the protocol's own where the options give none.
    ``args`` is read, never changed."""
    refuse_suite_clash(args)
    sweep, reference = tuple(args.sweep or ()), args.reference
    if args.suite is not None:
        spec = suite_protocol(args.suite, args.split or "test")
    elif args.ablation is not None:
        spec = ablation_protocol(check_factors(args.ablation))
    elif args.paper or args.paper_strict:
        spec = paper_protocol(strict=args.paper_strict)
    elif args.crowd is not None or args.lidar:
        spec = crowd_protocol(args.crowd) if args.crowd is not None else lidar_protocol()
        # the protocol's own axes: the mover count (--crowd); state, beams with the map, beams
        # only (--lidar)
        own = (
            ("movers.count=" + ",".join(str(c) for c in CROWD_COUNTS),)
            if args.crowd is not None
            else LIDAR_AXES
        )
        sweep = sweep or tuple(own)
        if reference is None and not args.controllers:  # pair everyone against the paper's method
            reference = CROWD_REFERENCE
    else:
        spec = quick_protocol()
    changes: dict[str, Any] = {}
    if args.env:
        changes["envs"] = split_words(args.env)
    if args.maps:
        changes["maps"] = split_words(args.maps)
    if args.controllers:
        # a protocol's solver goes with its own controller list; controllers named on the command
        # line keep their own defaults unless --solver says otherwise
        changes.update(controllers=split_controller_list(args.controllers), solver=None)
        if spec.solver not in (None, "rti") and not args.solver:  # the NMPCs default to "rti"
            print(
                f"note: the protocol's solver ({spec.solver}) goes with its own controller list; the "
                f"controllers named by --controllers keep their own default solver (--solver {spec.solver} "
                "sets it for them)",
                file=sys.stderr,
            )
    if args.solver:
        changes["solver"] = args.solver
    if args.fallback_solver:
        changes["fallback_solver"] = args.fallback_solver
    if args.slips:
        changes["slips"] = split_slips(args.slips)
    if args.episodes is not None:
        changes["episodes"] = args.episodes
    # the env settings: the preset's, then the dedicated options, then --env-kwargs (which win)
    env_kwargs = dict(spec.env_kwargs)
    dedicated: dict[str, Any] = {}
    for option, keyword in _DEDICATED:
        if getattr(args, option) is not None:
            env_kwargs[keyword] = dedicated[keyword] = getattr(args, option)
    given = parse_env_kwargs(args.env_kwargs)
    for keyword, value in dedicated.items():
        if keyword in given and given[keyword] != value:
            option = "--" + next(o for o, k in _DEDICATED if k == keyword).replace("_", "-")
            raise ValueError(
                f"{option} {value} and --env-kwargs {keyword}={given[keyword]!r} set the same env "
                "keyword to different values; give it once"
            )
    env_kwargs = parse_env_kwargs(args.env_kwargs, into=env_kwargs)
    refuse_sweep_clash(list(sweep), {**dedicated, **given})
    spec = spec.replace(
        **changes,
        env_kwargs=env_kwargs,
        seed=args.seed,
        calibration_budget=args.calibration_budget,
        calibration_seed=args.calibration_seed,
        random_maps=args.random_maps if args.random_maps is not None else spec.random_maps,
        **({"layouts": args.layouts} if args.layouts is not None else {}),
        gifs=args.gifs,
        compute_scale=args.compute_scale
        if args.compute_scale is not None
        else (1.0 if args.realtime else None),
    )
    return CommandLineRun(spec, sweep, reference)


def spec_from_args(args: argparse.Namespace) -> RunSpec:
    """The run the command line asks for (:func:`run_from_args`'s ``spec``); ``args`` is read,
    never changed."""
    return run_from_args(args).spec
