#!/usr/bin/env bash
# Mutation testing (issue 41) of one module whose bugs would silently change results, with mutmut 3.
#
#   bash .ci/mutation.sh MODULE [MODULE ...]      # MODULE: see the table below, or "all"
#
# Clones the committed HEAD of this repository into a temporary directory (the mutants/ folder
# never lands in the checkout), appends a [tool.mutmut] section to the clone's pyproject.toml that
# mutates only the module and runs only the test files that exercise it, runs `mutmut run`, and
# prints the score: killed / total, survivors, timeouts and mutants no selected test reaches.
# numba-compiled functions (@njit) and other decorated functions (@property) are not mutated by
# mutmut; the score covers the rest of the module.
#
# Environment: JOBS (mutmut's --max-children, default 1), KEEP=1 keeps the clone (its path is
# printed; `cd CLONE && mutmut results` / `mutmut show NAME` read the survivors), SOURCE (the
# repository to clone, default this one), COPY_TESTS=1 (copy the module's test files from SOURCE's
# working tree into the clone: measures tests not yet committed), MIN_SCORE (exit 1 when a module scores below it, in
# percent; default 85). Needs mutmut 3 (pip install mutmut).
set -euo pipefail

# module -> "file to mutate|test files (those missing are skipped)"
declare -A MODULES=(
    [perception]="koopman_envs/sim/perception.py|tests/test_uncertainty.py tests/test_comm_delivery.py tests/test_lidar_statistics.py tests/test_observation_uncertainty.py tests/test_perception_faults.py tests/test_truth_isolation.py"
    [uncertainty]="koopman_envs/uncertainty.py|tests/test_uncertainty.py tests/test_comm_delivery.py tests/test_lidar_statistics.py tests/test_bad_input.py tests/test_env_limits.py tests/test_keyword_spec.py tests/test_perception_faults.py tests/test_uncertainty_settings.py"
    [observed]="koopman_envs/observed.py|tests/test_observed_view.py tests/test_observation_uncertainty.py tests/test_truth_isolation.py tests/test_movers.py tests/test_mover_controllers.py tests/test_observed_view_exact.py"
    [baseline]="evaluation/baseline.py|tests/test_baseline.py tests/test_gate_decisions.py"
    [statistics]="evaluation/statistics.py|tests/test_statistics.py tests/test_sweep.py tests/test_fair_comparison.py::test_reports_carry_intervals_and_paired_comparisons tests/test_statistics_exact.py"
    [runlog]="evaluation/runlog.py|tests/test_runlog.py tests/test_output_dir.py tests/test_runlog_records.py"
    [records]="evaluation/records.py|tests/test_records.py tests/test_runlog.py tests/test_baseline.py tests/test_records_schema.py tests/test_runlog_records.py"
)
ORDER=(perception uncertainty observed baseline statistics runlog records)

if [ $# -eq 0 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
    sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
    echo "modules: ${ORDER[*]} (or all)"
    exit 2
fi
wanted=("$@")
[ "$1" = "all" ] && wanted=("${ORDER[@]}")
for m in "${wanted[@]}"; do
    [ -n "${MODULES[$m]:-}" ] || { echo "unknown module '$m'; one of: ${ORDER[*]} all" >&2; exit 2; }
done
command -v mutmut >/dev/null || { echo "mutmut is not installed (pip install 'mutmut>=3')" >&2; exit 2; }

SOURCE=${SOURCE:-$(git -C "$(dirname "$0")/.." rev-parse --show-toplevel)}
JOBS=${JOBS:-1}
MIN_SCORE=${MIN_SCORE:-85}
export KOOPNAV_NMPC_JIT=0  # no test compiles an NMPC solver (tests/conftest.py sets it too)
status=0
for m in "${wanted[@]}"; do
    target=${MODULES[$m]%%|*}
    tests=""
    for t in ${MODULES[$m]#*|}; do
        [ -f "$SOURCE/${t%%::*}" ] && tests+="\"$t\", "
    done
    work=$(mktemp -d)
    git clone -q "$SOURCE" "$work/koopnav"
    if [ "${COPY_TESTS:-0}" = 1 ]; then
        for t in ${MODULES[$m]#*|}; do
            [ -f "$SOURCE/${t%%::*}" ] && cp "$SOURCE/${t%%::*}" "$work/koopnav/${t%%::*}"
        done
    fi
    cd "$work/koopnav"
    # the packages are copied whole into mutants/ (the tests import them from there); only the
    # module is mutated
    cat >>pyproject.toml <<EOF

[tool.mutmut]
source_paths = ["koopman_envs", "evaluation", "controllers", "baselines"]
only_mutate = ["$target"]
also_copy = ["evaluate.py", "docs", ".ci", "bench", "examples", "action.yml", "README.md"]
pytest_add_cli_args_test_selection = [${tests%, }]
pytest_add_cli_args = ["-p", "no:cacheprovider"]
EOF
    echo "== $m: mutating $target with ${tests%, } (in $work/koopnav)"
    mutmut run --max-children "$JOBS" >"$work/run.log" 2>&1 || { tail -c 3000 "$work/run.log"; status=1; }
    # one line per mutant: "name: status"
    mutmut results --all true >"$work/results.txt" 2>/dev/null || true
    python - "$m" "$work/results.txt" "$MIN_SCORE" <<'EOF' || status=1
import collections
import sys

module, path, minimum = sys.argv[1], sys.argv[2], float(sys.argv[3])
counts = collections.Counter()
survivors = []
for line in open(path, encoding="utf-8"):
    name, _, state = line.strip().rpartition(": ")
    if not name:
        continue
    counts[state] += 1
    if state not in ("killed",):
        survivors.append(f"  {state}: {name}")
total = sum(counts.values())
killed = counts["killed"]
score = 100.0 * killed / total if total else 0.0
print(f"{module}: {killed}/{total} killed ({score:.1f}%); " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
print("\n".join(survivors))
sys.exit(0 if total and score >= minimum else 1)
EOF
    cd - >/dev/null
    if [ "${KEEP:-0}" = 1 ]; then
        echo "kept $work/koopnav"
    else
        rm -rf "$work"
    fi
done
exit $status
