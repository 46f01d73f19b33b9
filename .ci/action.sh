#!/usr/bin/env bash
# The steps of the KoopNav GitHub Action (action.yml at the repository root), as one script so
# that tests/test_workflows.py runs exactly what the action runs. Inputs come as environment
# variables (action.yml sets them from its inputs):
#   KOOPNAV_SOURCE       where KoopNav is (the action's own checkout); installed with pip
#   KOOPNAV_PACKAGE      pip requirement of the package that holds the controller ("" = none)
#   KOOPNAV_CONTROLLERS  controller configurations: registered names (entry points of the package
#                        included) or import paths "package.module:Class[:key=value,...]"
#   KOOPNAV_EPISODES     episodes per cell (default 10)
#   KOOPNAV_ARGS         further evaluator options (e.g. "--env KoopNav-Formation-v0 --maps map4")
#   KOOPNAV_BASELINE     results.json or run directory to compare with ("" = no comparison)
#   KOOPNAV_FAIL_IF_WORSE  "true": exit 102 when a controller is significantly worse than the baseline
#   KOOPNAV_OUT          report directory (default koopnav-results)
set -euo pipefail
: "${KOOPNAV_SOURCE:?the path of KoopNav (the action sets it)}"
: "${KOOPNAV_CONTROLLERS:?at least one controller configuration}"
out="${KOOPNAV_OUT:-koopnav-results}"
python -m pip install --quiet "$KOOPNAV_SOURCE"
if [ -n "${KOOPNAV_PACKAGE:-}" ]; then
    python -m pip install --quiet "$KOOPNAV_PACKAGE"
fi
# shellcheck disable=SC2206  # word splitting of the lists is intended
controllers=(${KOOPNAV_CONTROLLERS})
# shellcheck disable=SC2206
extra=(${KOOPNAV_ARGS:-})
gate=()
if [ -n "${KOOPNAV_BASELINE:-}" ]; then
    if [ -e "$KOOPNAV_BASELINE" ]; then
        gate+=(--baseline "$KOOPNAV_BASELINE")
        [ "${KOOPNAV_FAIL_IF_WORSE:-true}" = "true" ] && gate+=(--fail-if-worse)
    else
        echo "note: baseline $KOOPNAV_BASELINE not found; running without a comparison" >&2
    fi
fi
koopnav-evaluate --controllers "${controllers[@]}" --episodes "${KOOPNAV_EPISODES:-10}" --out "$out" --quiet \
    --badge "${controllers[0]}" "${extra[@]}" "${gate[@]}"
