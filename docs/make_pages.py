"""Rebuild every published page listed in data/pages.json from the committed episode logs (the
same commands tests/test_published_pages.py checks byte for byte).

    python docs/make_pages.py            # every page
    python docs/make_pages.py docs/lidar_results.md   # the named ones
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    pages = json.loads((ROOT / "data" / "pages.json").read_text())
    known = [entry["page"] for entry in pages]
    unknown = [name for name in argv if name not in known]
    if unknown:
        print(f"not a published page: {unknown}; data/pages.json lists {known}", file=sys.stderr)
        return 2
    for entry in pages:
        if argv and entry["page"] not in argv:
            continue
        print(f"== {entry['page']}", flush=True)
        command = [sys.executable, str(ROOT / entry["generator"]), *entry["args"], "--out", entry["page"]]
        subprocess.run(command, cwd=ROOT, check=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
