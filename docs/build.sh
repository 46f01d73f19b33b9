#!/usr/bin/env bash
# Build the documentation site with warnings as errors, then check its internal links.
#   bash docs/build.sh [OUT]      (default OUT: docs/_build/html; needs the [docs] extra)
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-docs/_build/html}"
# -W: every warning fails the build (a link to a missing page or heading is one: myst_heading_anchors);
# -E: read every page again, so that a warning of an unchanged page is not hidden by the cache
python -m sphinx -W --keep-going -E -q -b html docs "$out"
python docs/check_links.py "$out"
