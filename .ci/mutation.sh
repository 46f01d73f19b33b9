#!/usr/bin/env bash
# Mutation testing (issue 41) of the modules whose bugs would silently change results, with mutmut 3.
#
#   bash .ci/mutation.sh MODULE [MODULE ...]     # MODULE from the list below, or "all"
#
# For each module: clones the committed HEAD of this repository into a temporary directory (the
# mutants/ folder never lands in the checkout), appends a [tool.mutmut] section to the clone's
# pyproject.toml that mutates only that module and runs only the test files that exercise it,
# runs `mutmut run`, and prints the score: killed / total, then every mutant not killed with its
# status (survived, timeout, "no tests": no selected test reaches it). Exit 1 when a module scores
# below MIN_SCORE.
#
# mutmut does not mutate decorated functions (its trampolines replace the function object): the
# numba kernels (@njit) and properties (@property) are out of its reach. The module
# "perception-kernels" measures perception.py with its @njit decorators removed in the clone, so
# that the kernels _perceive and _delay run as Python and are mutated too (slower; the tests hold
# in both modes, see tests/test_perception_faults.py).
#
# Environment:
#   JOBS=N          mutmut's --max-children (default 1: the machine is shared)
#   KEEP=1          keep the clone and print its path (then `cd CLONE && mutmut results --all true`,
#                   `mutmut show NAME` show the mutants)
#   SOURCE=DIR      the repository to clone (default: this one)
#   COPY_TESTS=1    copy the module's test files from SOURCE's working tree into the clone (measures
#                   tests not yet committed)
#   WITHOUT="tests/a.py ..."   leave those test files out (a score before they were added)
#   MIN_SCORE=P     percent of mutants to kill (default 85)
#   DRY=1           print each module's [tool.mutmut] section and run nothing
# Needs mutmut 3 (pip install 'mutmut>=3'; measured with 3.8.1).
set -euo pipefail

# module -> "file to mutate|test files, globs or test ids (files missing from the clone are skipped)|tests
# left out (pytest --deselect prefixes)". A selection holds every test file that imports the module
# (`grep -l 'koopman_envs.observed' tests/*.py`, ...; tests/test_classic_controllers.py, which only
# reads the uncertainty presets through 4 whole episodes per controller, excepted): a test file left
# out lets its mutants survive (Holm without its step-down maximum survived the statistics selection
# without tests/test_distinct_statistics.py). Left out: tests of timing, signals and worker processes
# (a SIGINT or SIGKILL sent at a chosen moment to `evaluate.py --workers 2`), which time out under
# mutmut's load instead of failing on a mutant.
SIGNALS="tests/test_runlog.py::test_sigkill_at_any_point tests/test_runlog.py::test_ctrl_c_exits_130 tests/test_runlog.py::test_sigterm_stops_the_workers"
# Left out of the archive reader's selection: the test of data/publish.sh itself, whose Python runs in
# the script's own working directory, where mutmut's trampolines cannot find their configuration
# (tests/test_bounded_reads.py calls the same unpack_run in-process, so its mutants are still reached).
SHELL_SCRIPT="tests/test_bounded_reads.py::test_unpack_keeps_a_local_log_with_more_records_unless_forced"
SPLIT_SCRIPT="tests/test_publications.py::test_publish_sh_pack_keeps_an_unchanged_whole_archive_and_splits_a_republished_run"
declare -A MODULES=(
    [perception]="koopman_envs/sim/perception.py|tests/test_uncertainty.py tests/test_comm_delivery.py tests/test_lidar_statistics.py tests/test_observation_uncertainty.py tests/test_truth_isolation.py tests/test_perception_faults.py tests/test_pcg64.py"
    [uncertainty]="koopman_envs/uncertainty.py|tests/test_uncertainty.py tests/test_comm_delivery.py tests/test_lidar_statistics.py tests/test_bad_input.py tests/test_env_limits.py tests/test_keyword_spec.py tests/test_perception_faults.py tests/test_uncertainty_settings.py tests/test_pcg64.py tests/test_keyword_properties.py tests/test_estimator_levers.py"
    [observed]="koopman_envs/observed.py|tests/test_observed_view.py tests/test_observation_uncertainty.py tests/test_truth_isolation.py tests/test_movers.py tests/test_mover_controllers.py tests/test_observed_view_exact.py tests/test_estimator_levers.py tests/test_perceived_policy.py tests/test_perception.py"
    [baseline]="evaluation/reports/baseline.py|tests/test_baseline.py tests/test_gate_decisions.py tests/test_duplicate_records.py tests/test_bounded_reads.py"
    [statistics]="evaluation/stats/statistics.py|tests/test_statistics.py tests/test_sweep.py tests/test_fair_comparison.py::test_reports_carry_intervals_and_paired_comparisons tests/test_statistics_exact.py tests/test_clustered_statistics.py tests/test_distinct_statistics.py tests/test_gate_decisions.py"
    [clustered]="evaluation/stats/clustered.py|tests/test_clustered_statistics.py"
    [layout_tests]="evaluation/stats/layout_tests.py|tests/test_clustered_statistics.py"
    [families]="evaluation/stats/families.py|tests/test_clustered_statistics.py"
    [runlog]="evaluation/episodes/runlog.py|tests/test_runlog.py tests/test_output_dir.py tests/test_runlog_records.py tests/test_duplicate_records.py tests/test_bounded_reads.py tests/test_tune.py tests/test_cli.py tests/test_evaluate.py|$SIGNALS"
    [records]="evaluation/episodes/records.py|tests/test_records*.py tests/test_runlog.py tests/test_runlog_records.py tests/test_duplicate_records.py tests/test_collision_fault.py tests/test_suite_runs.py tests/test_cache_entries.py tests/test_pictures.py::test_the_worker_records_the_movers_paths_and_the_figure_draws_them|$SIGNALS"
    [published]="evaluation/reports/published.py|tests/test_published_pages.py tests/test_bounded_reads.py tests/test_published_archive.py tests/test_publications.py|$SHELL_SCRIPT $SPLIT_SCRIPT"
    [publications]="evaluation/reports/publications.py|tests/test_publications.py tests/test_published_archive.py tests/test_bounded_reads.py|$SHELL_SCRIPT $SPLIT_SCRIPT"
)
MODULES[perception-kernels]=${MODULES[perception]}
ORDER=(perception uncertainty observed baseline statistics clustered layout_tests families runlog records published publications)

if [ $# -eq 0 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
    sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
    echo "modules: ${ORDER[*]} perception-kernels (all: the first ${#ORDER[@]})"
    exit 2
fi
wanted=("$@")
[ "$1" = "all" ] && wanted=("${ORDER[@]}")
for m in "${wanted[@]}"; do
    [ -n "${MODULES[$m]:-}" ] || { echo "unknown module '$m'; one of: ${!MODULES[*]} all" >&2; exit 2; }
done
command -v mutmut >/dev/null || { echo "mutmut is not installed (pip install 'mutmut>=3')" >&2; exit 2; }

SOURCE=${SOURCE:-$(git -C "$(dirname "$0")/.." rev-parse --show-toplevel)}
JOBS=${JOBS:-1}
MIN_SCORE=${MIN_SCORE:-85}
export KOOPNAV_NMPC_JIT=0 # no test compiles an NMPC solver (tests/conftest.py sets it too)
status=0
for m in "${wanted[@]}"; do
    IFS="|" read -r target selection deselect <<<"${MODULES[$m]}"
    work=$(mktemp -d)
    git clone -q "$SOURCE" "$work/koopnav"
    tests=""
    where="$work/koopnav"
    [ "${COPY_TESTS:-0}" = 1 ] && where=$SOURCE
    for t in $(cd "$where" && shopt -s nullglob && for p in $selection; do
        # a glob names every file that matches (tests other engineers add, e.g. tests/test_records*.py)
        case $p in *"*"*) printf '%s\n' $p ;; *) printf '%s\n' "$p" ;; esac
    done | awk '!seen[$0]++'); do
        file=${t%%::*}
        case " ${WITHOUT:-} " in *" $file "*) continue ;; esac
        if [ "${COPY_TESTS:-0}" = 1 ] && [ -f "$SOURCE/$file" ]; then
            cp "$SOURCE/$file" "$work/koopnav/$file"
        fi
        [ -f "$work/koopnav/$file" ] && tests+="\"$t\", "
    done
    tests=${tests%, }
    # -n 0: mutmut runs the tests in its own process (pyproject's addopts spread them over xdist
    # workers); -m: the slow tests too (addopts leaves them out, and a selection is every test of
    # the module: without them the archive reader's page rebuilds were never run on a mutant)
    args='"-p", "no:cacheprovider", "-n", "0", "-m", "slow or not slow"'
    for t in ${deselect:-}; do
        args+=", \"--deselect\", \"$t\""
    done
    if [ "$m" = perception-kernels ]; then
        sed -i '/^@njit(.*)$/d' "$work/koopnav/$target" # the kernels as Python: mutmut can mutate them
    fi
    # the packages are copied whole into mutants/ (the tests import them from there); only the
    # module is mutated
    cat >>"$work/koopnav/pyproject.toml" <<EOF

[tool.mutmut]
source_paths = ["koopman_envs", "evaluation", "controllers", "baselines"]
only_mutate = ["$target"]
also_copy = ["evaluate.py", "data", "docs", ".ci", "bench", "examples", "action.yml", "README.md"]
pytest_add_cli_args_test_selection = [$tests]
pytest_add_cli_args = [$args]
EOF
    echo "== $m: mutating $target, tests: $tests${deselect:+, left out: $deselect}"
    if [ "${DRY:-0}" = 1 ]; then
        sed -n '/^\[tool.mutmut\]/,$p' "$work/koopnav/pyproject.toml"
        rm -rf "$work"
        continue
    fi
    start=$(date +%s)
    if ! (cd "$work/koopnav" && mutmut run --max-children "$JOBS" >"$work/run.log" 2>&1); then
        tail -c 3000 "$work/run.log"
        status=1
    fi
    (cd "$work/koopnav" && mutmut results --all true) >"$work/results.txt" 2>/dev/null || true
    python3 - "$m" "$work/results.txt" "$MIN_SCORE" "$(($(date +%s) - start))" <<'EOF' || status=1
import collections
import sys

module, path, minimum, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
counts = collections.Counter()
others = []
for line in open(path, encoding="utf-8"):
    name, _, state = line.strip().rpartition(": ")
    if name:
        counts[state] += 1
        if state != "killed":
            others.append(f"  {state}: {name}")
total, killed = sum(counts.values()), counts["killed"]
score = 100.0 * killed / total if total else 0.0
detail = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
print(f"{module}: {killed}/{total} killed ({score:.1f}%) in {seconds} s; {detail}")
print("\n".join(others))
sys.exit(0 if total and score >= minimum else 1)
EOF
    if [ "${KEEP:-0}" = 1 ]; then
        echo "kept $work/koopnav"
    else
        rm -rf "$work"
    fi
done
exit $status
