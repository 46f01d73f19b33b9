#!/usr/bin/env bash
# The benchmark's tuning studies (issue 60, docs/benchmark.md#tuning): every tunable controller with
# the same budget on koopnav-bench-v1's validation split, both tasks, Optuna TPE seeded 0.
#
#   bash data/tuning/run.sh [CONTROLLER ...]     # default: every controller below, in turn
#
# Budget per controller: TRIALS configurations x LAYOUTS validation layouts per task x EPISODES
# episodes per layout, both tasks (24 x 25 x 1 x 2 = 1,200 episodes). Each study is logged in
# data/tuning/CONTROLLER/study.jsonl and resumed where it stopped (--resume), so the script can be
# interrupted and run again.
set -euo pipefail
cd "$(dirname "$0")/../.."
# the OpenBLAS kernels pinned where the CPU allows, so that a study resumed on another machine
# goes on with the same arithmetic (.ci/blas_pin.sh; studies before koopman-nmpc's ran unpinned)
# shellcheck source=.ci/blas_pin.sh
source .ci/blas_pin.sh
TRIALS="${TRIALS:-24}"
LAYOUTS="${LAYOUTS:-25}"
EPISODES="${EPISODES:-1}"
WORKERS="${WORKERS:-1}" # worker processes per evaluation: results do not depend on it
controllers=("$@")
[ ${#controllers[@]} -gt 0 ] || controllers=(orca dwa consensus mpc-cbf nominal-nmpc koopman-nmpc)
for name in "${controllers[@]}"; do
    out="data/tuning/$name"
    resume=()
    [ -f "$out/study.jsonl" ] && resume=(--resume)
    python -m evaluation.tune "$name" --task both --trials "$TRIALS" --layouts "$LAYOUTS" \
        --episodes "$EPISODES" --seed 0 --workers "$WORKERS" --out "$out" "${resume[@]}"
done
