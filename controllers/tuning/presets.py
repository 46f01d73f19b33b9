"""The built-in controllers and their named presets, as one table.

A *controller* is a class registered under a name. A *preset* is a registered controller with
some options set by default (``koopman-nmpc-robust`` is ``koopman-nmpc`` with
``uncertainty_margin=3``); it is built by :func:`build_preset`, which gives the controller the
preset's name, so reports and statistics name what was asked for. Options given to
``controllers.make`` override a preset's defaults.

*Tuned presets* (issue 60): a file ``controllers/tuned/<name>.json``, written by the tuner
(``python -m evaluation.tune NAME --task both ...``, :mod:`evaluation.tune`) from a study on the
validation layouts, gives the controller or preset ``<name>`` the tuned options as its defaults,
and ``<name>-v0`` keeps the defaults it had before, for comparison (:func:`with_tuned`). A file is
applied only beside its finished study (``data/tuning/<name>/``: :func:`check_study`).
"""

from __future__ import annotations

import functools
import importlib
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from controllers.tuning.search_space import Search
from controllers.tuning.studies import (
    ADOPTION_RULE,
    BEST_FILE,
    SHIPPED_TASK,
    STUDIES_DIR,
    Adoption,
    adoption,
    finished_study,
    study_record,
)
from koopman_envs import check_split_allowed
from koopman_envs.checks import check_choice, parse_json
from koopman_envs.files import MAX_TEXT_BYTES, read_text

__all__ = [
    "CONTROLLERS",
    "PRESETS",
    "TUNED_DIR",
    "TUNED_KIND",
    "V0_SUFFIX",
    "WEIGHT_VARIANTS",
    "Preset",
    "build_preset",
    "builtin_names",
    "check_study",
    "is_comparison_variant",
    "read_tuned",
    "register_builtins",
    "tuned_file",
    "with_tuned",
]

#: the robust presets' ``uncertainty_margin`` (kept equal to controllers.mpc.config's, tested):
#: written here so that listing the presets imports no solver
_ROBUST = 3.0
#: the ``mpc-cbf`` preset's barrier decay rate gamma (controllers.mpc.config.NMPCConfig.cbf_gamma):
#: chosen on a slalom map of our own that no protocol uses (tests/test_mpc_cbf.py), and ablated on the protocols in
#: docs/controllers.md
_CBF_GAMMA = 0.1

#: the built-in controllers: name -> "module:Class"
CONTROLLERS = {
    "koopman-nmpc": "controllers.mpc.variants:KoopmanNMPC",
    "adaptive-koopman-nmpc": "controllers.mpc.variants:AdaptiveKoopmanNMPC",
    "nominal-nmpc": "controllers.mpc.variants:NominalNMPC",
    # distributed: every robot its own small NMPC, neighbours' plans as moving obstacles (16-32 robots)
    "dmpc-nominal": "controllers.mpc.distributed:DistributedNMPC",
    "consensus": "controllers.consensus:ConsensusController",
    # the classic baselines (issue 45): ORCA through pyrvo (the [crowd] extra) and DWA (numpy)
    "orca": "controllers.classic.orca:ORCAController",
    "dwa": "controllers.classic.dwa:DWAController",
}


@dataclass(frozen=True)
class Preset:
    """A registered controller with some options set by default.

    Attributes
    ----------
    name : str
        The preset's registered name (and the built controller's ``name``).
    base : str
        The controller it builds (a name of :data:`CONTROLLERS`).
    defaults : dict
        Options set unless the caller sets them.
    doc : str
        One line for listings and docs.
    tunable : dict
        Options the tuner searches beyond the base's ``TUNABLE`` (name ->
        :class:`~controllers.option_spec.Search`), e.g. the barrier rate of ``mpc-cbf``.
    untuned : str
        Non-empty: the preset declares no tunable options (its base's searches dropped), and
        this says why; the tuner refuses it with this reason. A mechanism ablation keeps its
        base's hand-set gains so that it differs from them in the mechanism alone.
    """

    name: str
    base: str
    defaults: dict[str, Any] = field(default_factory=dict)
    doc: str = ""
    tunable: dict[str, Search] = field(default_factory=dict)
    untuned: str = ""

    def __post_init__(self) -> None:
        if self.untuned and self.tunable:
            raise ValueError(
                f"preset {self.name!r}: tunable={sorted(self.tunable)} with untuned={self.untuned!r}; "
                "a preset either declares searches or says why it has none"
            )


#: the presets written by hand (before the tuned files are applied: :data:`PRESETS`)
HAND_PRESETS = (
    Preset(
        "koopman-nmpc-robust",
        "koopman-nmpc",
        {"uncertainty_margin": _ROBUST},
        "Koopman-NMPC with margins widened by its calibrated residual",
    ),
    Preset(
        "nominal-nmpc-robust",
        "nominal-nmpc",
        {"uncertainty_margin": _ROBUST},
        "nominal NMPC with margins widened by the unicycle's calibrated residual",
    ),
    Preset(
        "dmpc-nominal-robust",
        "dmpc-nominal",
        {"uncertainty_margin": _ROBUST},
        "distributed nominal NMPC with margins widened by each robot's calibrated residual",
    ),
    Preset(
        "dmpc-koopman",
        "dmpc-nominal",
        {"model": "koopman"},
        "distributed NMPC predicting with each robot's block of the per-robot Koopman model",
    ),
    Preset(
        "dmpc-koopman-robust",
        "dmpc-nominal",
        {"model": "koopman", "uncertainty_margin": _ROBUST},
        "distributed Koopman NMPC with margins widened by each robot's calibrated residual",
    ),
    Preset(
        "mpc-cbf",
        "nominal-nmpc",
        {"cbf_gamma": _CBF_GAMMA},
        "nominal NMPC with discrete-time control barrier constraints (Zeng et al. 2021) in the problem",
        # its one option beyond the NMPC's: how fast a clearance may shrink (log: 0.1 and 0.01
        # differ as much as 1 and 0.1)
        {"cbf_gamma": Search(0.02, 1.0, log=True)},
    ),
    Preset(
        "consensus-free",
        "consensus",
        {"collision_avoidance": False},
        "the consensus law with collision avoidance off (the paper's validation variant)",
        untuned=(
            "a mechanism ablation: consensus with collision avoidance off, on the hand-set gains "
            "that consensus-v0 keeps, so that beside consensus-v0 it differs in that mechanism "
            "alone (tuning it would confound the mechanism with its gains)"
        ),
    ),
)


#: where the tuned presets are read from: ``<name>.json`` per tuned controller or preset
TUNED_DIR = Path(__file__).parents[1] / "tuned"
#: the ``kind`` of a tuned preset file (:func:`evaluation.tune.write_best` writes it)
TUNED_KIND = "koopnav-tuned-preset"
#: ``<name>-v0``: the defaults ``<name>`` had before its tuned preset
V0_SUFFIX = "-v0"


def _preset_document(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A tuned preset file's JSON object, its kind, controller, task and options checked
    (:func:`read_tuned` says how)."""
    what = os.fspath(path)
    document = parse_json(read_text(path, MAX_TEXT_BYTES, what="tuned preset", expected="JSON"), what)
    if not isinstance(document, dict) or document.get("kind") != TUNED_KIND:
        raise ValueError(f"{what}: not a tuned preset (its 'kind' must be {TUNED_KIND!r})")
    name, task, options = document.get("controller"), document.get("task"), document.get("options")
    known = [*CONTROLLERS, *(p.name for p in HAND_PRESETS)]
    check_choice(f"{what}: controller", name, sorted(known), among="the built-in names")
    if task != SHIPPED_TASK:
        raise ValueError(
            f"{what}: task={task!r}; a shipped preset must come from a task={SHIPPED_TASK!r} study, "
            "because a controller's defaults serve every task"
        )
    if not isinstance(options, dict) or not all(isinstance(k, str) for k in options):
        raise ValueError(f"{what}: options={options!r} is not an object of option values")
    return document


def read_tuned(path: str | os.PathLike[str]) -> tuple[str, dict[str, Any]]:
    """The controller (or preset) name and the tuned options of a tuned preset file.

    Parameters
    ----------
    path : path
        A JSON file as :func:`evaluation.tune.write_best` writes it: ``kind``
        (:data:`TUNED_KIND`), ``controller``, ``task``, ``options`` (and the study's record,
        not read here). Weight lists are returned as tuples.

    Raises
    ------
    ValueError
        The file cannot be read, is not a tuned preset, names a controller that is not a
        built-in controller or preset, or a study of another task than :data:`SHIPPED_TASK`;
        each naming the file and the value.
    """
    document = _preset_document(path)
    name, options = document["controller"], document["options"]
    return name, {k: tuple(v) if isinstance(v, list) else v for k, v in options.items()}


def check_study(path: str | os.PathLike[str], studies: str | os.PathLike[str] = STUDIES_DIR) -> Adoption:
    """Refuse a tuned preset file whose study did not choose it on held-out layouts; the
    adoption rule's decision on that study otherwise.

    The study of ``<name>.json`` is the folder ``studies/<name>/``, as the tuner wrote it.

    Parameters
    ----------
    path : path
        A tuned preset file (:func:`read_tuned`).
    studies : path
        The folder of the studies (default :data:`STUDIES_DIR`).

    Returns
    -------
    Adoption
        :func:`adoption` on the study's trials (:func:`with_tuned` applies only an adopted one).

    Raises
    ------
    ValueError
        Naming the preset, the file and the value, when the study's log or ``best.json`` is
        missing; the log is torn (an interrupted run) or unfinished (fewer trials than its
        budget's configurations); the study is of another controller or task, or tuned on a split
        :func:`koopman_envs.check_split_allowed` refuses for tuning (``test``); or the preset's
        options, score or study record are not the study's best configuration and its record.
    """
    document = _preset_document(path)
    name = document["controller"]
    folder = Path(studies) / name
    header, trials = finished_study(name, studies)
    top = max(t["score"] for t in trials)
    record = study_record(header, len(trials))
    problems = []
    if document.get("score") != top:
        problems.append(f"score={document.get('score')!r} is not the study's best, {top!r}")
    if not any(t["score"] == top and t.get("options") == document["options"] for t in trials):
        problems.append("its options are not those of the study's best trial")
    if document.get("study") != record:
        problems.append(f"study={document.get('study')!r} is not the log's {record!r}")
    best = folder / BEST_FILE
    if not best.is_file():
        problems.append(f"{best} is missing")
    else:
        summary = parse_json(
            read_text(best, MAX_TEXT_BYTES, what="study summary", expected="JSON"), str(best)
        )
        chosen = summary.get("best", {}) if isinstance(summary, dict) else {}
        if chosen.get("options") != document["options"] or chosen.get("score") != top:
            problems.append(f"{best} names another best configuration")
    if problems:
        raise ValueError(f"{name}: {path} does not come from its study {folder}: " + "; ".join(problems))
    return adoption(name, trials)


def with_tuned(
    presets: Sequence[Preset],
    directory: str | os.PathLike[str] = TUNED_DIR,
    studies: str | os.PathLike[str] = STUDIES_DIR,
) -> tuple[Preset, ...]:
    """``presets`` with every tuned preset file of ``directory`` applied (:func:`read_tuned`).

    A file ``<name>.json`` makes ``<name>`` (a controller of :data:`CONTROLLERS` or a preset of
    ``presets``) a preset whose defaults are the tuned options over its own, and adds
    ``<name>-v0`` with the defaults it had before. Files are read in name order; a missing
    directory is no tuned preset. Each file is applied only beside its finished study in
    ``studies`` (:func:`check_study`), so no preset ships without the record that chose it, and
    only when :data:`ADOPTION_RULE` adopts it (a file the rule refuses is an error, named).

    An installed package has no ``studies`` folder (the studies stay in the repository, where
    the tests check every shipped preset against its study): there a preset is applied on its
    own record, whose split must still be one tuning may use.
    """
    out = list(presets)
    folder = Path(directory)
    files = sorted(folder.glob("*.json")) if folder.is_dir() else []
    in_repository = Path(studies).is_dir()
    for path in files:
        name, options = read_tuned(path)
        if path.stem != name:
            raise ValueError(f"{path}: names controller {name!r}; the file must be called {name}.json")
        if not in_repository:
            _check_recorded_split(path)
            out = _apply_tuned(out, name, options, path)
            continue
        decision = check_study(path, studies)
        if not decision.adopted:
            raise ValueError(
                f"{path}: {decision}; the adoption rule keeps the defaults ({ADOPTION_RULE}): "
                f"delete it (`python -m evaluation.tune adopt {name}` installs only what the rule admits)"
            )
        out = _apply_tuned(out, name, options, path)
    return tuple(out)


def _check_recorded_split(path: Path) -> None:
    """Refuse a preset whose own study record names a split tuning may not use (``test``)."""
    study = _preset_document(path).get("study")
    split = study.get("split") if isinstance(study, dict) else None
    if not isinstance(split, str):
        raise ValueError(
            f"{path}: its study record names no split (study={study!r}); a tuned preset records its study"
        )
    check_split_allowed(split, "tuning", label=str(path))


def _apply_tuned(presets: list[Preset], name: str, options: dict[str, Any], path: Path) -> list[Preset]:
    """``presets`` with ``name``'s defaults tuned to ``options`` and ``<name>-v0`` keeping the old."""
    before = next((p for p in presets if p.name == name), None) or Preset(name, name)
    doc = before.doc or f"{name} with the defaults its class declares"
    v0 = replace(before, name=name + V0_SUFFIX, doc=f"{doc} (the defaults before tuning)")
    tuned = replace(
        before,
        defaults={**before.defaults, **options},
        doc=f"{doc}, tuned ({path.parent.name}/{path.name})",
    )
    return [p for p in presets if p.name != name] + [tuned, v0]


#: every preset: the hand-made ones and the tuned ones of :data:`TUNED_DIR`
PRESETS = with_tuned(HAND_PRESETS)


def is_comparison_variant(name: str) -> bool:
    """Whether ``name`` is a ``<name>-v0`` variant: one :func:`with_tuned` registered (the defaults a
    tuned controller had before) or one of :data:`WEIGHT_VARIANTS` (the policies a learned
    controller shipped before), kept for comparison, run only when asked for by name (default
    runs leave them out: :func:`controllers.registry.available`)."""
    return name.endswith(V0_SUFFIX) and (name in _VARIANTS or name in WEIGHT_VARIANTS)


_VARIANTS = frozenset(p.name for p in PRESETS if p.name.endswith(V0_SUFFIX))
#: the ``-v0`` variants of learned controllers: the policies ``<name>`` shipped before its training
#: seed chosen on validation (``baselines/policies/<folder>_v0``; ``rl-ppo-set-v0``,
#: baselines/sb3/policy.py, and ``ippo-v0``, baselines/marl/marl_policy.py;
#: evaluation.experiments.seeds.ship copies them there)
WEIGHT_VARIANTS = frozenset({"rl-ppo-set-v0", "ippo-v0"})


def tuned_file(name: str) -> Path | None:
    """The tuned preset file that sets the defaults of the registered controller ``name``
    (``<name>.json`` of :data:`TUNED_DIR`, read when this module was imported), None for a name
    whose defaults no tuned preset sets (its ``-v0`` variant, a hand-set preset, a controller
    never tuned, a name that is not built in). A run records its digest, so that a resume after
    the file changed (``python -m evaluation.tune adopt``, a pull) is refused
    (:func:`evaluation.run.weights.run_presets`)."""
    return Path(TUNED_DIR) / f"{name}.json" if name + V0_SUFFIX in _VARIANTS else None


def _resolve(path: str) -> Any:
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module), attribute)


def build_preset(preset: Preset, **options: Any) -> Any:
    """The preset's controller: its base built with the preset's defaults under ``options``,
    named after the preset."""
    controller = _resolve(CONTROLLERS[preset.base])(**{**preset.defaults, **options})
    controller.name = preset.name
    return controller


def register_builtins(register: Any) -> None:
    """Register every built-in controller and preset with ``register(name, factory)``; a preset
    with ``builds=`` its base's class, which its partial does not name."""
    presets = {preset.name for preset in PRESETS}
    for name, path in CONTROLLERS.items():
        if name not in presets:  # a tuned controller is registered as its preset below
            register(name, path)
    for preset in PRESETS:
        register(preset.name, functools.partial(build_preset, preset), builds=CONTROLLERS[preset.base])


def builtin_names() -> list[str]:
    """The names of the built-in controllers and presets (not those registered at run time)."""
    return sorted({*CONTROLLERS, *(preset.name for preset in PRESETS)})
