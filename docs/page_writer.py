"""``write_publication_page``, the end of every page script whose publication may not exist yet
(docs/make_ablation_md.py, docs/make_seeds_md.py): the pending page while it is missing, the
built page once it is, and a publication that is not as KoopNav packs it refused by name.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

__all__ = ["write_publication_page"]


def write_publication_page(
    out: str, publication: Path, build: Callable[[], str], pending: Callable[[], str], run: str
) -> int:
    """Write a publication's page to ``out``; the script's exit code.

    Parameters
    ----------
    out
        The page to write.
    publication
        The published run the page reads (``data/NAME`` or ``NAME.tar.xz``).
    build
        The page from the publication; raises ``ValueError`` naming what is wrong with it.
    pending
        The page while the publication does not exist: it says so and states no number.
    run
        The publication's name in ``bash data/publish.sh NAME``, printed with the pending page.

    Returns
    -------
    int
        ``SUCCESS_EXIT``, or ``BAD_INPUT_EXIT`` with the reason on stderr (nothing written).
    """
    try:
        if not publication.exists():  # not published yet: a page that says so, not a failure
            write_atomic(out, pending())
            print(f"wrote {out} (pending: {publication} is not published yet; bash data/publish.sh {run})")
            return SUCCESS_EXIT
        text = build()
    except ValueError as exc:  # a publication that is not as KoopNav packs it (the message names it)
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    write_atomic(out, text)
    print(f"wrote {out}")
    return SUCCESS_EXIT
