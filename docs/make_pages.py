"""Rebuild every published page listed in data/pages.json from the committed episode logs (the
same commands tests/test_published_pages.py checks byte for byte).

    python docs/make_pages.py            # every page
    python docs/make_pages.py docs/lidar_results.md   # the named ones
    python docs/make_pages.py --check [PAGE ...]       # rebuild elsewhere, say which differ (exit 101)

Each rebuilt page's SHA-256 goes into data/pages.sha256 (``sha256sum -c data/pages.sha256``
reads it): tests/test_prose_checks.py compares every published page with it in a second, so a
page edited by hand fails the fast tests; the slow ones rebuild the pages from the data.

A page whose entry names a ``"readme"`` block (docs/bench_results.md: ``bench-headline``) holds
that block between ``<!-- begin NAME ...-->`` and ``<!-- end NAME -->`` lines; rebuilding the
page copies it into README.md in place of README's block of that name (:func:`with_block`), and
tests/test_prose_checks.py checks README's copy against the page's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from evaluation.exit_codes import BAD_INPUT_EXIT, FAILED_CHECK_EXIT, SUCCESS_EXIT  # noqa: E402
from koopman_envs.checks import check_choice  # noqa: E402
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic  # noqa: E402

#: the published pages: page, generator and the generator's arguments
PAGES: list[dict] = json.loads(read_text(ROOT / "data" / "pages.json", MAX_TEXT_BYTES, what="page list"))


#: the SHA-256 of every published page as its generator last wrote it: ``HASH  PAGE`` per line
DIGESTS = ROOT / "data" / "pages.sha256"


def page_digest(data: bytes) -> str:
    """A page's SHA-256, as ``sha256sum`` prints it."""
    return hashlib.sha256(data).hexdigest()


def read_digests(path: Path = DIGESTS) -> dict[str, str]:
    """Page -> the SHA-256 its generator's output had (empty without the file)."""
    if not path.exists():
        return {}
    text = read_text(path, MAX_TEXT_BYTES, what="page digests")
    return {page: digest for digest, page in (line.split("  ", 1) for line in text.splitlines() if line)}


def write_digests(digests: dict[str, str], path: Path = DIGESTS) -> None:
    """Write ``digests`` in page order, as ``sha256sum`` writes them."""
    write_atomic(path, "".join(f"{digests[page]}  {page}\n" for page in sorted(digests)))


def edited_pages(pages: dict[str, bytes] | None = None) -> list[str]:
    """The published pages whose bytes (default: the checkout's) are not what their generator
    last wrote (:data:`DIGESTS`): edited by hand, or written otherwise than by this script."""
    recorded = read_digests()
    if pages is None:
        pages = {entry["page"]: (ROOT / entry["page"]).read_bytes() for entry in PAGES}
    return [page for page, data in pages.items() if recorded.get(page) != page_digest(data)]


#: the file a page's ``"readme"`` block is copied into
README = ROOT / "README.md"


def _block_pattern(name: str) -> re.Pattern[str]:
    return re.compile(
        rf"^<!-- begin {re.escape(name)}\b[^\n]*-->\n.*?^<!-- end {re.escape(name)} -->\n", re.M | re.S
    )


def block_of(text: str, name: str) -> str | None:
    """The block ``name`` of ``text``, its ``<!-- begin NAME`` and ``<!-- end NAME -->`` lines
    included (None when ``text`` has none)."""
    found = _block_pattern(name).search(text)
    return None if found is None else found[0]


def with_block(text: str, name: str, block: str) -> str:
    """``text`` with its block ``name`` replaced by ``block``; ``ValueError`` when it has none
    (README.md must hold the block's two lines where the block goes)."""
    pattern = _block_pattern(name)
    if not pattern.search(text):
        raise ValueError(
            f"no block {name!r} (a '<!-- begin {name} -->' line, then '<!-- end {name} -->') to replace"
        )
    return pattern.sub(lambda _: block, text, count=1)


def stale_readme_blocks(readme: str | None = None) -> list[str]:
    """The ``"readme"`` blocks of the published pages that README.md (or ``readme``) does not
    hold as the page holds them: edited by hand, or not copied since the page was rebuilt."""
    text = README.read_text(encoding="utf-8") if readme is None else readme
    stale = []
    for entry in PAGES:
        if "readme" in entry:
            page = (ROOT / entry["page"]).read_text(encoding="utf-8")
            block = block_of(page, entry["readme"])
            if block is None or block_of(text, entry["readme"]) != block:
                stale.append(entry["readme"])
    return stale


def page_command(entry: dict, out: Path, figures: Path | None = None) -> list[str]:
    """The command that rebuilds ``entry``'s page (one item of :data:`PAGES`) into ``out``, its
    figures into ``figures`` (default: the generator's, ``_static`` beside the page: docs/_static);
    run it from the root."""
    command = [sys.executable, str(ROOT / entry["generator"]), *entry["args"], "--out", str(out)]
    return command if figures is None else [*command, "--figures", str(figures)]


def parser(known: list[str]) -> argparse.ArgumentParser:
    """The command line: the pages to rebuild (default: every page of ``known``) and ``--check``;
    ``--help`` shows the module's examples and lists ``known``."""
    cli = argparse.ArgumentParser(
        prog="python docs/make_pages.py",
        description=__doc__,  # what it does, with examples
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="published pages (data/pages.json):\n" + "".join(f"  {page}\n" for page in known),
    )
    cli.add_argument(
        "pages", nargs="*", metavar="PAGE", help="a published page to rebuild (default: every one)"
    )
    cli.add_argument(
        "--check",
        action="store_true",
        help="rebuild in a scratch folder and name the pages that differ (exit 101); the checkout is left alone",
    )
    return cli


def main(argv: list[str]) -> int:
    pages = PAGES
    known = [entry["page"] for entry in pages]
    cli = parser(known)
    args = cli.parse_args(argv)  # --help exits 0; an unknown option exits 2 (BAD_INPUT_EXIT)
    check, names = args.check, args.pages
    for name in names:
        try:
            check_choice("page", name, known, among="the pages of data/pages.json")
        except ValueError as exc:
            print(f"{cli.prog}: error: {exc}", file=sys.stderr)
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
            if not check:  # what the generator wrote, for the fast check of hand edits
                write_digests({**read_digests(), entry["page"]: page_digest(out.read_bytes())})
            if "readme" in entry:  # README.md's copy of the page's block
                block = block_of(out.read_text(encoding="utf-8"), entry["readme"])
                if block is None:
                    raise ValueError(
                        f"{entry['page']} holds no block {entry['readme']!r} to copy into README.md"
                    )
                readme = README.read_text(encoding="utf-8")
                if check and block_of(readme, entry["readme"]) != block:
                    stale.append(f"{README.name} ({entry['readme']})")
                if not check:
                    write_atomic(README, with_block(readme, entry["readme"], block))
    if check:
        print(f"differ from the committed data: {stale}" if stale else "every page checked is up to date")
    return FAILED_CHECK_EXIT if stale else SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
