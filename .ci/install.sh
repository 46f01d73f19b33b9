#!/usr/bin/env bash
# Install KoopNav from this checkout with the given extras (comma-separated, e.g. "rl" or
# "test,ray,rl,docs,lint"). torch comes first as the CPU build (any other torch request pulls a
# multi-GB CUDA build); run by .ci/run and by .github/workflows/leaderboard.yml.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --upgrade pip >/dev/null
case ",${1:-}," in *,rl,* | *,torchrl,* | *,benchmarl,*) python -m pip install torch==2.13.0 ;; esac
# the constraints keep that torch whatever an extra asks for (BenchMARL's torchvision would not)
python -m pip install -c .ci/constraints.txt -e ".${1:+[$1]}"
