"""Rebuild every published page listed in data/pages.json from the committed episode logs (the
same commands tests/test_published_pages.py checks byte for byte).

    python docs/make_pages.py            # every page
    python docs/make_pages.py docs/lidar_results.md   # the named ones
    python docs/make_pages.py --check [PAGE ...]       # rebuild elsewhere, say which differ (exit 1)
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from evaluation.exit_codes import BAD_INPUT_EXIT, FAILED_CHECK_EXIT, SUCCESS_EXIT  # noqa: E402
from koopman_envs.files import MAX_TEXT_BYTES, read_text  # noqa: E402

#: the published pages: page, generator and the generator's arguments
PAGES: list[dict] = json.loads(read_text(ROOT / "data" / "pages.json", MAX_TEXT_BYTES, what="page list"))


def page_command(entry: dict, out: Path, figures: Path | None = None) -> list[str]:
    """The command that rebuilds ``entry``'s page (one item of :data:`PAGES`) into ``out``, its
    figures into ``figures`` (default: the generator's, ``_static`` beside the page: docs/_static);
    run it from the root."""
    command = [sys.executable, str(ROOT / entry["generator"]), *entry["args"], "--out", str(out)]
    return command if figures is None else [*command, "--figures", str(figures)]


def main(argv: list[str]) -> int:
    check = "--check" in argv
    names = [name for name in argv if name != "--check"]
    pages = PAGES
    known = [entry["page"] for entry in pages]
    unknown = [name for name in names if name not in known]
    if unknown:
        print(f"not a published page: {unknown}; data/pages.json lists {known}", file=sys.stderr)
        return BAD_INPUT_EXIT
    stale = []
    with tempfile.TemporaryDirectory() as scratch:
        for entry in pages:
            if names and entry["page"] not in names:
                continue
            out = Path(scratch) / Path(entry["page"]).name if check else ROOT / entry["page"]
            # with --check the figures too go to the scratch folder: the checkout is left alone
            command = page_command(entry, out, Path(scratch) / "_static" if check else None)
            print(f"== {entry['page']}", flush=True)
            subprocess.run(command, cwd=ROOT, check=True, capture_output=check)
            if check and out.read_bytes() != (ROOT / entry["page"]).read_bytes():
                stale.append(entry["page"])
    if check:
        print(f"differ from the committed data: {stale}" if stale else "every page checked is up to date")
    return FAILED_CHECK_EXIT if stale else SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
