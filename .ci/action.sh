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
#   KOOPNAV_BASELINE_MAY_BE_ABSENT  "true": a baseline path that does not exist yet (a repository's
#                        first run) runs without a comparison; "false" (default): the step fails
#   KOOPNAV_FAIL_IF_WORSE  "true" (default): exit 102 when a controller is significantly worse
#                        than the baseline; "false": compare and report only
#   KOOPNAV_OUT          report directory (default koopnav-results)
#   KOOPNAV_PRINT_ONLY   "true": check the inputs, print the evaluator's words one per line, stop
#                        (nothing installed or run; what tests/test_workflows.py checks quickly)
# Every input is checked before anything is installed; a bad one exits 2 naming it and its value
# (2: bad input, as in the evaluator's table of exit codes, evaluation/exit_codes.py).
set -euo pipefail
# the list inputs are split into words, and never expanded against the workspace's files
set -f

fail() {
    echo "error: $*" >&2
    exit 2
}

# boolean INPUT-NAME VALUE DEFAULT: "true" or "false" (any case), else exit 2
boolean() {
    local value="${2:-$3}"
    case "${value,,}" in
        true | false) printf '%s' "${value,,}" ;;
        *) fail "input $1='$2' is not a boolean; allowed: true or false (any case)" ;;
    esac
}

[ -n "${KOOPNAV_SOURCE:-}" ] || fail "KOOPNAV_SOURCE is empty: the path of KoopNav (the action sets it)"
[ -n "${KOOPNAV_CONTROLLERS//[[:space:]]/}" ] || fail "input controllers is empty: give at least one controller configuration"
episodes="${KOOPNAV_EPISODES:-10}"
# the evaluator's bound (koopman_envs.params.MAX_EPISODES_PER_CELL; tests/test_workflows.py holds
# the two equal), checked here too because this runs before KoopNav is installed
max_episodes=10000
[[ "$episodes" =~ ^[1-9][0-9]{0,5}$ ]] && ((episodes <= max_episodes)) ||
    fail "input episodes='$episodes' is not a whole number from 1 to $max_episodes"
fail_if_worse=$(boolean fail-if-worse "${KOOPNAV_FAIL_IF_WORSE:-}" true)
may_be_absent=$(boolean baseline-may-be-absent "${KOOPNAV_BASELINE_MAY_BE_ABSENT:-}" false)
print_only=$(boolean KOOPNAV_PRINT_ONLY "${KOOPNAV_PRINT_ONLY:-}" false)
out="${KOOPNAV_OUT:-koopnav-results}"

# shellcheck disable=SC2206  # word splitting of the lists is intended (globbing is off: set -f)
controllers=(${KOOPNAV_CONTROLLERS})
# shellcheck disable=SC2206
extra=(${KOOPNAV_ARGS:-})
gate=()
if [ -n "${KOOPNAV_BASELINE:-}" ]; then
    if [ -e "$KOOPNAV_BASELINE" ]; then
        gate+=(--baseline "$KOOPNAV_BASELINE")
        [ "$fail_if_worse" = "true" ] && gate+=(--fail-if-worse)
    elif [ "$may_be_absent" = "true" ]; then
        echo "note: baseline $KOOPNAV_BASELINE does not exist yet (baseline-may-be-absent: true); running without a comparison" >&2
    else
        fail "input baseline='$KOOPNAV_BASELINE' does not exist (from $(pwd)); commit it, fix the path, or set baseline-may-be-absent: true for a repository's first run"
    fi
fi
command=(koopnav-evaluate --controllers "${controllers[@]}" --episodes "$episodes" --out "$out" --quiet
    --badge "${controllers[0]}" "${extra[@]}" "${gate[@]}")
if [ "$print_only" = "true" ]; then
    printf '%s\n' "${command[@]}"
    exit 0
fi
python -m pip install --quiet "$KOOPNAV_SOURCE"
if [ -n "${KOOPNAV_PACKAGE:-}" ]; then
    python -m pip install --quiet "$KOOPNAV_PACKAGE"
fi
"${command[@]}"
