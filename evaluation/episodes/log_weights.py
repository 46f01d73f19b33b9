"""The weights a run's learned controllers play, as its log header records them (issue 60).

A learned controller's options (``policy_root``) name a folder, not the weights in it: a policy
shipped or retrained while a run is paused would be played, under the same row, for the rest of
the run. So a run's configuration holds :data:`WEIGHTS_KEY`: per controller label that loads a
policy, the SHA-256 of its policy files per task (:func:`evaluation.run.weights.run_weights`), and
:func:`evaluation.episodes.runlog.read_log` refuses a resume whose controller would load other
weights than its logged episodes did (:func:`changed_weights`, :func:`weights_refusal`). A
controller with no logged episode takes the new digest (its episodes all run on it).

A log written before the digests were recorded has none: its resume is not checked (nothing can
be), says so (:func:`unchecked_notes`), and its header stays without digests, also when a
controller is added to it (:func:`without_weights`): a digest there would claim weights for
episodes nobody checked. A log without digests none of whose logged episodes is a learned
controller's (a run of model-based controllers only, as the current code writes it too) has
nothing unchecked: a learned controller added to it takes its digests, checked from then on.

The tuned presets go the same way under :data:`PRESETS_KEY`: per controller label whose defaults
a tuned preset file sets (``controllers/tuned/NAME.json``), that file's SHA-256
(:func:`evaluation.run.weights.run_presets`). A resume whose controller would run on another
preset file than its logged episodes did (``python -m evaluation.tune adopt``, a pull, while the
run was paused) is refused, naming it, the file and both digests; a log without preset digests
resumes unchecked for them, with its note, and its header stays without them.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "PRESETS_KEY",
    "WEIGHTS_KEY",
    "changed_weights",
    "check_weights",
    "signed_weights",
    "unchecked_notes",
    "weights_refusal",
    "without_weights",
]

#: the run configuration's (and header's) digests of the learned controllers' policy files,
#: ``{label: {task: sha256}}``; absent from a run without one, and from every log written before
#: they were recorded
WEIGHTS_KEY = "weights"
#: the run configuration's (and header's) digests of the tuned preset files that set the
#: controllers' defaults, ``{label: {"tuned/NAME.json": sha256}}``; absent from a run without one
#: (only ``-v0`` variants, learned and classic controllers), and from every log written before
#: they were recorded
PRESETS_KEY = "presets"
#: the digests a resume checks, each key alike (the weights first)
_DIGEST_KEYS = (WEIGHTS_KEY, PRESETS_KEY)


def without_weights(signature: Any) -> Any:
    """``signature`` (a run's configuration or signature) without its digests; anything that is
    not a mapping as it is (a log's line 1 that is no run header, refused by the caller)."""
    if not isinstance(signature, Mapping):
        return signature
    return {k: v for k, v in signature.items() if k not in _DIGEST_KEYS}


def signed_weights(config: Mapping[str, Any]) -> dict[str, Any]:
    """What a run's resume signature holds of ``config``'s digests: ``{WEIGHTS_KEY: ...}`` and
    ``{PRESETS_KEY: ...}``, each left out when no controller has one (as in the logs written
    before the digests were)."""
    return {key: config[key] for key in _DIGEST_KEYS if config.get(key)}


def unchecked_notes(path: Path, ours: Mapping[str, Any], key: str = WEIGHTS_KEY) -> list[str]:
    """The note of a resume of a log without digests under ``key`` (``ours``: the digests the run
    has now of the controllers with logged episodes, which nothing can check)."""
    if not ours:
        return []
    if key == PRESETS_KEY:
        return [
            f"{path} records no tuned preset digests (written before run logs recorded them, or "
            f"none of its controllers ran on a tuned preset then): whether {', '.join(sorted(ours))} "
            "run on the tuned presets of its logged episodes cannot be checked (its header stays "
            "without preset digests)"
        ]
    return [
        f"{path} was written before run logs recorded the learned controllers' weights: whether "
        f"{', '.join(sorted(ours))} play the weights of its logged episodes cannot be checked "
        "(its header stays without digests)"
    ]


def changed_weights(theirs: Any, ours: Mapping[str, Any], played: Collection[Any]) -> list[str]:
    """Each controller with logged episodes (its label in ``played``) whose digests ``ours`` are
    not the logged ones ``theirs``, described with both digests of each task that differs."""
    logged = theirs if isinstance(theirs, Mapping) else {}
    changed = []
    for label in sorted(set(logged) | set(ours)):
        before, now = logged.get(label) or {}, ours.get(label) or {}
        if before == now or label not in played:  # no episode of it logged: it runs on the new ones
            continue
        tasks = [task for task in sorted(set(before) | set(now)) if before.get(task) != now.get(task)]
        described = "; ".join(
            f"{task}: logged sha256 {before.get(task) or 'none'}, now {now.get(task) or 'none'}"
            for task in tasks
        )
        changed.append(f"{label} ({described})")
    return changed


def weights_refusal(path: Path, changed: list[str], key: str = WEIGHTS_KEY) -> str:
    """The refusal of a resume on other weights (``key``: or on other tuned presets): the
    controllers, their digests, what to do."""
    if key == PRESETS_KEY:
        return (
            f"{path} cannot be resumed: {'; '.join(changed)} would run on another tuned preset than "
            "its logged episodes did (its controllers/tuned file changed since the run started: "
            "`python -m evaluation.tune adopt`, a pull). Put the file the run started with back to "
            "resume it; or drop that controller's episodes (python -m evaluation.forget LABEL -- OUT) "
            "and resume to run them all on the new preset; or run into another --out. Nothing was changed"
        )
    return (
        f"{path} cannot be resumed: {'; '.join(changed)} would play other weights than its logged "
        "episodes did (its policy files changed since the run started: a policy shipped or retrained). "
        "Put the files the run started with back to resume it; or drop that controller's episodes "
        "(python -m evaluation.forget LABEL -- OUT) and resume to run them all on the new weights; "
        "or run into another --out. Nothing was changed"
    )


def check_weights(
    path: Path,
    logged: Mapping[str, Any],
    config: Mapping[str, Any],
    records: Sequence[Mapping[str, Any]],
    error: type[Exception] = ValueError,
    notes: list[str] | None = None,
) -> dict[str, Any]:
    """A resume's check of the weights and the tuned presets: the configuration whose header the
    log keeps (``config``, or without the digests of a key that ``logged``, its header's
    signature, has none of: a log written before they were recorded), its notes appended to
    ``notes``; ``error`` (:class:`evaluation.episodes.runlog.LogError` for a resume) with
    :func:`weights_refusal` when a controller with logged episodes would play other weights, or
    run on another tuned preset, than they did."""
    played = {rec.get("controller") for rec in records}
    for key in _DIGEST_KEYS:  # every refusal before any note
        if key in logged:
            changed = changed_weights(logged[key], config.get(key) or {}, played)
            if changed:
                raise error(weights_refusal(path, changed, key))
    kept = dict(config)
    for key in _DIGEST_KEYS:
        if key in logged:
            continue
        # a log without these digests: written before they were recorded, or of a run whose
        # logged controllers had none to record. Only a controller with logged episodes is
        # unchecked; with none, the controllers this run adds have no logged episode and the
        # header takes their digests (as changed_weights does)
        unchecked = {label: digests for label, digests in (config.get(key) or {}).items() if label in played}
        if unchecked:
            (notes if notes is not None else []).extend(unchecked_notes(path, unchecked, key))
            kept.pop(key, None)
    return kept
