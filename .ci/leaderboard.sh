#!/usr/bin/env bash
# The repository's leaderboard gate (run by .ci/run and by .github/workflows/leaderboard.yml).
#
# Every registered controller on the quick board's cells (both tasks, their paper maps under high
# slip, perturbed starts, the NMPCs on the real-time iteration), KOOPNAV_GATE_EPISODES episodes
# per cell (default 10: 40 paired episodes per controller over both tasks, the count at which the
# gate catches a 20-point drop from 90% with 80% power; docs/ci.md), paired on shared seeds with
# the committed baseline .ci/baseline/results.json. Exit 102 when a controller is significantly
# worse than the baseline, 101 when a floor of .ci/thresholds.toml fails, 3 when episodes raised, 2
# for bad input (evaluation/exit_codes.py: the highest-priority code when several apply).
#
#   bash .ci/leaderboard.sh [OUT]       run and gate (OUT: report directory, default a temp dir)
#   bash .ci/leaderboard.sh --exact [OUT]
#                                       run and gate, then check that every episode equals the
#                                       baseline's field for field, timings aside (python -m
#                                       evaluation.exact: exit 101 naming every episode missing, extra
#                                       or different); for a change meant to keep outcomes
#   bash .ci/leaderboard.sh --update    re-run without the gate and replace the committed baseline
#                                       (after a change that is meant to change outcomes)
# KOOPNAV_GATE_ARGS: further evaluator options for a subset run (e.g. "--controllers consensus
# --solver rti"); a subset run is not held to the floors.
set -euo pipefail
cd "$(dirname "$0")/.."
# the OpenBLAS kernels pinned where the CPU allows: the gate's episodes equal the baseline's bit for
# bit across machines (.ci/blas_pin.sh)
# shellcheck source=.ci/blas_pin.sh
source .ci/blas_pin.sh
episodes="${KOOPNAV_GATE_EPISODES:-10}"
baseline=".ci/baseline/results.json"
# shellcheck disable=SC2206  # word splitting of the extra options is intended
extra=(${KOOPNAV_GATE_ARGS:-})
if [ "${1:-}" = "--update" ]; then
    out="$(mktemp -d)"
    python evaluate.py --episodes "$episodes" --out "$out" --quiet "${extra[@]}"
    mkdir -p "$(dirname "$baseline")"
    cp "$out/results.json" "$baseline"
    echo "baseline updated: $baseline ($(python -c "import json,sys; print(len(json.load(open(sys.argv[1]))['episodes']))" "$baseline") episodes)"
    exit 0
fi
exact=false
if [ "${1:-}" = "--exact" ]; then
    exact=true
    shift
fi
out="${1:-$(mktemp -d)}"
floors=(--check .ci/thresholds.toml)
# a subset run (KOOPNAV_GATE_ARGS) is gated against the baseline but not held to the floors, whose
# rules name controllers and cells it may not run
[ ${#extra[@]} -eq 0 ] || floors=()
python evaluate.py --episodes "$episodes" --out "$out" --quiet "${extra[@]}" \
    --baseline "$baseline" --fail-if-worse "${floors[@]}"
if [ "$exact" = true ]; then
    # a subset run (KOOPNAV_GATE_ARGS, KOOPNAV_GATE_EPISODES) is held to the baseline's episodes it
    # planned; the whole gate to every episode of the baseline
    subset=()
    if [ ${#extra[@]} -gt 0 ] || [ -n "${KOOPNAV_GATE_EPISODES:-}" ]; then
        subset=(--subset)
    fi
    python -m evaluation.exact "$out" "$baseline" "${subset[@]}"
fi
