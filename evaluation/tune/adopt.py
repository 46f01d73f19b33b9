"""``python -m evaluation.tune adopt NAME``: install what the adoption rule admits of a finished study.

The rule (:data:`controllers.tuning.studies.ADOPTION_RULE`, decided by :func:`controllers.tuning.studies.adoption`):
a study's best configuration becomes ``NAME``'s shipped default only with strictly more validation
successes than the defaults had in the same study. Adopted, the preset the study wrote
(``data/tuning/NAME/NAME.json``) is copied unchanged to ``controllers/tuned/NAME.json``; kept, no
preset of ``NAME`` is installed (one installed before is removed), so ``NAME`` keeps its defaults.
With ``--confirm N`` (:func:`adopt_confirmed`), an adopted study's best configuration is first
rerun with the defaults on N validation layouts per task the study did not use
(:mod:`evaluation.tune.confirm`) and installed only if that confirms it.
"""

from __future__ import annotations

import os
from pathlib import Path

from controllers.tuning import STUDIES_DIR, TUNED_DIR, Adoption, check_study, study_adoption
from evaluation.tune.configuration import Evaluator, evaluate_configuration
from evaluation.tune.confirm import Confirmation, confirm
from koopman_envs.files import write_atomic

__all__ = ["adopt", "adopt_confirmed"]


def adopt(
    name: str,
    studies: str | os.PathLike[str] = STUDIES_DIR,
    tuned: str | os.PathLike[str] = TUNED_DIR,
) -> Adoption:
    """Apply the adoption rule to the finished study of ``name`` and install what it admits.

    Parameters
    ----------
    name : str
        The controller or preset the study tuned: its study is ``studies/NAME/``.
    studies : path
        The folder of the studies (default ``data/tuning``).
    tuned : path
        The folder of the installed presets (default ``controllers/tuned``).

    Returns
    -------
    Adoption
        The rule's decision: adopted, ``tuned/NAME.json`` is the study's preset byte for byte;
        kept, ``tuned/NAME.json`` does not exist.

    Raises
    ------
    ValueError
        Before anything is installed or removed: the study has no preset (``NAME.json``, written
        when a study ends), or :func:`controllers.tuning.presets.check_study` refuses it (missing, torn,
        unfinished, another controller's or task's, tuned on the test split, or a preset that is
        not the study's best), each named.
    """
    decision, written = _checked(name, studies)
    target = Path(tuned) / written.name
    if decision.adopted:
        write_atomic(target, written.read_bytes())
    else:
        target.unlink(missing_ok=True)
    return decision


def _checked(name: str, studies: str | os.PathLike[str]) -> tuple[Adoption, Path]:
    """The rule's decision on ``name``'s study and the preset it wrote, refused (:func:`adopt`
    says how) before anything is installed, removed or run."""
    study_adoption(name, studies)  # a missing, torn or unfinished study is refused as such first
    written = Path(studies) / name / f"{name}.json"
    if not written.is_file():
        raise ValueError(
            f"{name}: {written} is missing; a study writes its preset when it ends "
            f"(`python -m evaluation.tune {name} --task both ... --out {written.parent}`)"
        )
    return check_study(written, studies), written


def adopt_confirmed(
    name: str,
    layouts: int,
    studies: str | os.PathLike[str] = STUDIES_DIR,
    tuned: str | os.PathLike[str] = TUNED_DIR,
    *,
    workers: int = 1,
    evaluator: Evaluator = evaluate_configuration,
) -> tuple[Adoption, Confirmation | None]:
    """:func:`adopt`, with an adopted study's best configuration confirmed first on ``layouts``
    fresh validation layouts per task (:func:`evaluation.tune.confirm.confirm`).

    Returns
    -------
    (Adoption, Confirmation or None)
        The rule's decision on the study, and the confirmation (None when the rule keeps the
        defaults: nothing to confirm). Not confirmed, ``tuned/NAME.json`` does not exist.
    """
    decision, _ = _checked(name, studies)
    if not decision.adopted:
        return adopt(name, studies, tuned), None
    confirmation = confirm(name, layouts, studies, workers=workers, evaluator=evaluator)
    if confirmation.confirmed:
        return adopt(name, studies, tuned), confirmation
    (Path(tuned) / f"{name}.json").unlink(missing_ok=True)
    return decision, confirmation
