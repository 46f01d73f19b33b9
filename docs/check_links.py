"""Check that every relative link of a built HTML site resolves to a file and, if it names one, an anchor.

``python docs/check_links.py OUT`` (OUT: the output folder of ``sphinx -b html``). Prints every
broken link as ``page: href (why)`` and exits 1 if there is one. External links (``http:``,
``mailto:``, ...) are not fetched: ``-b linkcheck`` would need the network.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from evaluation.exit_codes import BAD_INPUT_EXIT, FAILED_CHECK_EXIT, SUCCESS_EXIT  # noqa: E402


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        for key in ("id", "name"):
            if values.get(key):
                self.ids.add(values[key])
        for key in ("href", "src"):
            if values.get(key) and tag in ("a", "img", "link", "script"):
                self.links.append(values[key])


def _parse(path: Path, cache: dict[Path, _Page]) -> _Page:
    if path not in cache:
        page = _Page()
        page.feed(path.read_text(encoding="utf-8", errors="replace"))
        cache[path] = page
    return cache[path]


def broken_links(out: Path) -> list[str]:
    """``"page: href (why)"`` for every relative link of the site under ``out`` that does not resolve."""
    cache: dict[Path, _Page] = {}
    bad = []
    for html in sorted(out.rglob("*.html")):
        if "_sources" in html.parts or "_modules" in html.parts:
            continue
        for href in _parse(html, cache).links:
            parts = urlsplit(href)
            if parts.scheme or parts.netloc or href.startswith("//"):
                continue
            target = (html.parent / unquote(parts.path)).resolve() if parts.path else html
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                bad.append(
                    f"{html.relative_to(out)}: {href} (no file {target.relative_to(out.resolve()) if target.is_relative_to(out.resolve()) else target})"
                )
            elif "_modules" in target.parts:
                # viewcode's highlighted sources: generated, and their anchors follow the import
                # state of the build (an anchor of a function once went missing in one build of
                # three); the file's existence is what a reader needs
                continue
            elif (
                parts.fragment
                and target.suffix == ".html"
                and unquote(parts.fragment) not in _parse(target, cache).ids
            ):
                bad.append(f"{html.relative_to(out)}: {href} (no anchor #{parts.fragment})")
    return bad


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or not Path(args[0]).is_dir():
        print(__doc__.strip().split("\n\n")[1], file=sys.stderr)
        return BAD_INPUT_EXIT
    bad = broken_links(Path(args[0]))
    for line in bad:
        print(line)
    print(f"{len(bad)} broken relative links" if bad else "every relative link resolves")
    return FAILED_CHECK_EXIT if bad else SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
