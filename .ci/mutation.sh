#!/usr/bin/env bash
# Mutation testing (issue 41) of the modules whose bugs would silently change results, with mutmut 3.
#
#   bash .ci/mutation.sh MODULE [MODULE ...]     # MODULE from the list below, or "all"
#
# For each module: clones the committed HEAD of this repository into a temporary directory, or
# WORKDIR/MODULE (the mutants/ folder never lands in the checkout), appends a [tool.mutmut]
# section to the clone's pyproject.toml that mutates only that module and runs only the test files
# that exercise it, runs `mutmut run`, and prints the score: killed / total, then every mutant not
# killed with its status (survived, timeout, "no tests": no selected test reaches it), and at the
# end every module's score line. Exit 1 when a module scores below MIN_SCORE, 2 on bad input or a WORKDIR that does not
# match, 130 when stopped by a signal.
#
# mutmut does not mutate decorated functions (its trampolines replace the function object): the
# numba kernels (@njit) and properties (@property) are out of its reach. The module
# "perception-kernels" measures perception.py with its @njit decorators removed in the clone, so
# that the kernels _perceive and _delay run as Python and are mutated too (slower; the tests hold
# in both modes, see tests/test_perception_faults.py).
#
# Environment:
#   JOBS=N          mutmut's --max-children (default 1: the machine is shared)
#   WORKDIR=DIR     a work directory that outlives the session: the clone of each module lives in
#                   DIR/MODULE/koopnav and a rerun of the same command continues where the last one
#                   stopped (mutmut keeps every verdict in the clone's mutants/*.meta and tests only
#                   the mutants without one). A module whose run finished writes DIR/MODULE/score
#                   (killed / total and the survivors) and is not rerun; its score is printed again.
#                   A clone made from another commit or with another test selection is refused by
#                   name (remove DIR/MODULE to start it afresh). Ctrl-C, SIGTERM or SIGHUP stop the
#                   run at the mutant under test (exit 130); a torn meta or score file is found and
#                   its module rerun, never trusted.
#   KEEP=1          keep the clone and print its path (then `cd CLONE && mutmut results --all true`,
#                   `mutmut show NAME` show the mutants; with WORKDIR the clone is always kept)
#   SOURCE=DIR      the repository to clone (default: this one)
#   COPY_TESTS=1    copy the module's test files from SOURCE's working tree into the clone (measures
#                   tests not yet committed)
#   WITHOUT="tests/a.py ..."   leave those test files out (a score before they were added)
#   MIN_SCORE=P     percent of mutants to kill (default 85)
#   DRY=1           print each module's [tool.mutmut] section and mutant count, how many of them
#                   the store would restore, and run nothing (with WORKDIR, also how many of them
#                   have a verdict there)
#   STORE=DIR       the committed store of verdicts (default SOURCE/data/mutation): DIR/MODULE.json
#                   holds every final verdict with the digests it was decided against (the module's
#                   source, each test file of its selection, mutmut's version, the [tool.mutmut]
#                   section). Before `mutmut run` the verdicts that still match are restored into
#                   the clone (a module whose every mutant has one is not run at all); the clone's
#                   verdicts are written back every SAVE_EVERY seconds (default 120), at the end and
#                   when stopped. Commit DIR to carry a run to the next machine. A stale verdict is
#                   tested again; a torn or foreign store is refused by name (exit 2).
#                   `python -m evaluation.mutation report` prints each stored module's score.
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
# The audits of the hand-written docs pages (issue 60) hold stated numbers to these modules
# (detectable_difference and power_statement's power in docs/benchmark.md, the gamma table's
# paired statistics in docs/controllers.md, the uncertainty presets in docs/uncertainty.md): each
# selection takes the page-wide test only (their edited-copy tests run the same checks again).
HAND_FAMILIES="tests/test_hand_pages.py::test_every_result_of_the_hand_written_page_is_checked_or_pinned"
HAND_STATISTICS="tests/test_hand_pages_controllers.py::test_every_result_of_controllers_md_is_checked_or_pinned"
HAND_UNCERTAINTY="tests/test_hand_pages_ops.py::test_every_result_of_the_hand_written_page_is_checked_or_pinned"
declare -A MODULES=(
    [perception]="koopman_envs/sim/perception.py|tests/test_uncertainty.py tests/test_comm_delivery.py tests/test_lidar_statistics.py tests/test_observation_uncertainty.py tests/test_truth_isolation.py tests/test_perception_faults.py tests/test_pcg64.py"
    [uncertainty]="koopman_envs/settings/uncertainty.py|tests/test_uncertainty.py tests/test_comm_delivery.py tests/test_lidar_statistics.py tests/test_bad_input.py tests/test_env_limits.py tests/test_keyword_spec.py tests/test_perception_faults.py tests/test_uncertainty_settings.py tests/test_pcg64.py tests/test_keyword_properties.py tests/test_estimator_levers.py $HAND_UNCERTAINTY"
    [observed]="koopman_envs/observed.py|tests/test_observed_view.py tests/test_observation_uncertainty.py tests/test_truth_isolation.py tests/test_movers.py tests/test_mover_controllers.py tests/test_observed_view_exact.py tests/test_estimator_levers.py tests/test_perceived_policy.py tests/test_perception.py tests/test_observation_layout.py"
    [baseline]="evaluation/reports/baseline.py|tests/test_baseline.py tests/test_gate_decisions.py tests/test_duplicate_records.py tests/test_bounded_reads.py tests/test_publications.py|$SHELL_SCRIPT $SPLIT_SCRIPT"
    [statistics]="evaluation/stats/statistics.py|tests/test_statistics.py tests/test_sweep.py tests/test_fair_comparison.py::test_reports_carry_intervals_and_paired_comparisons tests/test_statistics_exact.py tests/test_clustered_statistics.py tests/test_distinct_statistics.py tests/test_gate_decisions.py tests/test_suite_statistics.py tests/test_sim2sim.py tests/test_sim2sim_family.py tests/test_prose_checks.py tests/test_fault_split_unhit.py tests/test_within_scheme.py $HAND_STATISTICS"
    [clustered]="evaluation/stats/clustered.py|tests/test_clustered_statistics.py tests/test_distinct_statistics.py tests/test_suite_statistics.py tests/test_within_scheme.py"
    [layout_tests]="evaluation/stats/layout_tests.py|tests/test_clustered_statistics.py tests/test_suite_statistics.py tests/test_ablation_units.py tests/test_table_power.py tests/test_ablation_power.py"
    [families]="evaluation/stats/families.py|tests/test_clustered_statistics.py tests/test_suite_statistics.py tests/test_ablation_units.py tests/test_bench_page.py tests/test_table_power.py tests/test_ablation_power.py $HAND_FAMILIES"
    [runlog]="evaluation/episodes/runlog.py|tests/test_runlog.py tests/test_output_dir.py tests/test_runlog_records.py tests/test_duplicate_records.py tests/test_bounded_reads.py tests/test_tune.py tests/test_cli.py tests/test_evaluate.py tests/test_seeds_page.py tests/test_policy_weights.py tests/test_weights_added.py tests/test_weights_refusal_names_log.py tests/test_preset_digests.py|$SIGNALS"
    [records]="evaluation/episodes/records.py|tests/test_records*.py tests/test_runlog.py tests/test_runlog_records.py tests/test_duplicate_records.py tests/test_collision_fault.py tests/test_suite_runs.py tests/test_cache_entries.py tests/test_episode_metrics.py tests/test_suite_statistics.py tests/test_tune.py tests/test_learned_seeds.py tests/test_pictures.py::test_the_worker_records_the_movers_paths_and_the_figure_draws_them|$SIGNALS"
    [published]="evaluation/reports/published.py|tests/test_published_pages.py tests/test_bounded_reads.py tests/test_published_archive.py tests/test_publications.py tests/test_duplicate_records.py tests/test_cli.py tests/test_bench_page.py tests/test_prose_pages.py tests/test_prose_intros.py tests/test_ablation_partial.py tests/test_run_progress.py tests/test_policy_weights.py tests/test_ablation_power.py|$SHELL_SCRIPT $SPLIT_SCRIPT"
    [publications]="evaluation/reports/publications.py|tests/test_publications.py tests/test_published_archive.py tests/test_bounded_reads.py tests/test_published_pages.py tests/test_bench_page.py tests/test_prose_pages.py tests/test_sim2sim.py tests/test_publication_labels.py tests/test_ablation_partial.py tests/test_run_progress.py tests/test_ablation_power.py tests/test_unpack_run_bound.py|$SHELL_SCRIPT $SPLIT_SCRIPT"
)
# not selected: records tests/test_mutation_script.py: it runs this script itself (mutmut in mutmut)
# not selected: uncertainty tests/test_classic_controllers.py: reads the presets through 4 whole episodes per controller
# not selected: publications tests/test_hand_pages.py: it reads data/bench_test's wall times through extracted_archive for one claim; the reader's own tests are selected
# not selected: layout_tests tests/test_tune.py tests/test_hand_pages.py: they read sign_flip_p_text through whole pages (the confirmation table); tests/test_clustered_statistics.py tests it directly
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
# the verdicts are read with python3's mutmut (its version keys the store): the same install as the command's
python3 -c "import mutmut" 2>/dev/null || {
    echo "mutmut is on PATH ($(command -v mutmut)) but python3 ($(command -v python3)) cannot import it: pip install 'mutmut>=3' into the environment of python3" >&2
    exit 2
}

HERE=$(cd "$(dirname "$0")/.." && pwd) # this repository: evaluation/mutation.py keeps the store
SOURCE=${SOURCE:-$(git -C "$HERE" rev-parse --show-toplevel)}
STORE=$(realpath -m "${STORE:-$SOURCE/data/mutation}")
SAVE_EVERY=${SAVE_EVERY:-120}
store() { # restore|save MODULE CLONE TARGET SETTINGS TEST...: in the clone (mutmut reads its
    # configuration there), with this repository's evaluation/mutation.py (python -P: not the clone's)
    local command=$1 module=$2 clone=$3
    shift 3
    (cd "$clone" && PYTHONPATH=$HERE exec python3 -P -m evaluation.mutation "$command" \
        "$STORE/$module.json" "$module" . "$@")
}
JOBS=${JOBS:-1}
MIN_SCORE=${MIN_SCORE:-85}
WORKDIR=${WORKDIR:-}
if [ -n "$WORKDIR" ]; then
    mkdir -p "$WORKDIR" && WORKDIR=$(cd "$WORKDIR" && pwd)
fi
export KOOPNAV_NMPC_JIT=0 # no test compiles an NMPC solver (tests/conftest.py sets it too)

# The clone's state, read and written by one program: `count TARGET` (mutants mutmut makes of
# TARGET), `resume TARGET [--dry]` (in a clone: the meta file checked whole, the verdicts an
# interruption can leave reset), `score MODULE RESULTS MIN SECONDS KEY [FILE]` (the score of
# `mutmut results`, kept in FILE when every mutant has a verdict), `show FILE KEY MIN` (a kept
# score, refused when torn or made from another KEY). Exit 0: at least MIN percent killed, 1: below, 3: no whole score.
read -r -d '' STATE <<'EOF' || true
import hashlib
import json
import os
import re
import shutil
import sys
from pathlib import Path

# mutmut's own verdicts that a rerun would repeat; any other (pytest interrupted, a worker killed
# by a signal, "suspicious", none yet) may be an interruption's and is tested again on a resume
FINAL = {"killed", "survived", "no tests", "timeout", "caught by type check", "skipped"}


def write_atomically(path: Path, text: str) -> None:
    part = path.with_name(path.name + ".part")
    part.write_text(text, encoding="utf-8")
    os.replace(part, path)


def whole_meta(path: Path) -> dict | None:
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    keys = {"exit_code_by_key", "hash_by_function_name", "durations_by_key", "estimated_durations_by_key"}
    if not isinstance(meta, dict) or not keys <= meta.keys():
        return None
    codes = meta["exit_code_by_key"]
    if not isinstance(codes, dict) or not all(c is None or isinstance(c, int) for c in codes.values()):
        return None
    return meta


def resume(target: str, dry: bool) -> None:
    from mutmut.stats import status_by_exit_code

    path = Path("mutants") / f"{target}.meta"
    meta = whole_meta(path)
    if meta is None:
        # mutmut writes the meta file once it has copied the packages and made the mutants, so a
        # mutants/ folder without a whole one was stopped before (a copy may be cut short) or torn:
        # nothing in it is trusted, every mutant is made and tested afresh
        print(f"  {path} is {'torn' if path.exists() else 'missing'}: every mutant is made and tested afresh")
        if not dry:
            shutil.rmtree("mutants")
        return
    stats = Path("mutants/mutmut-stats.json")
    if stats.exists():
        try:
            json.loads(stats.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            print(f"  torn {stats}: mutmut collects the tests' coverage again")
            if not dry:
                stats.unlink()
    codes = meta["exit_code_by_key"]
    reset = [name for name, code in codes.items() if code is not None and status_by_exit_code[code] not in FINAL]
    for name in reset:
        codes[name] = None
    if reset and not dry:
        write_atomically(path, json.dumps(meta, indent=4))
    decided = sum(code is not None for code in codes.values())
    again = f", {len(reset)} interrupted or doubtful verdicts to test again" if reset else ""
    print(f"  {decided} of {len(codes)} mutants have a verdict{again}")


def score_line(killed: int, total: int, seconds: int, counts: dict[str, int]) -> str:
    detail = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
    return f"{killed}/{total} killed ({100.0 * killed / total:.1f}%) in {seconds} s; {detail}"


def passed(killed: int, total: int, minimum: float) -> int:
    return 0 if total and 100.0 * killed / total >= minimum else 1


def score(module: str, results: str, minimum: float, seconds: int, key: str, keep: str) -> int:
    counts: dict[str, int] = {}
    others = []
    for line in open(results, encoding="utf-8"):
        name, _, state = line.strip().rpartition(": ")
        if name:
            counts[state] = counts.get(state, 0) + 1
            if state != "killed":
                others.append(f"  {state}: {name}")
    total, killed = sum(counts.values()), counts.get("killed", 0)
    if not total:
        print(f"{module}: no mutants listed (see the run's log)")
        return 1
    if counts.get("not checked"):
        print(f"{module}: {total - counts['not checked']} of {total} mutants have a verdict; rerun to finish")
        return 3
    text = "\n".join([f"{module}: {score_line(killed, total, seconds, counts)}", *others]) + "\n"
    print(text, end="")
    if keep:
        # the key names the clone's commit and test selection; the digest finds a torn file
        body = f"{text}key {key}\n"
        write_atomically(Path(keep), f"{body}sha256 {hashlib.sha256(body.encode()).hexdigest()}\n")
    return passed(killed, total, minimum)


def show(path: str, key: str, minimum: float) -> int:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        text = ""
    body, _, digest = text.rpartition("sha256 ")
    if digest.strip() != hashlib.sha256(body.encode()).hexdigest():
        print(f"  torn score file {path}: the module is run again")
        return 3
    lines = body.splitlines()
    if lines[-1] != f"key {key}":
        print(f"  {path} was made from {lines[-1][4:]!r}, not {key!r}: the module is run again")
        return 3
    found = re.match(r"\S+: (\d+)/(\d+) killed", lines[0])
    if found is None:
        print(f"  {path} holds no score line: the module is run again")
        return 3
    print("\n".join(lines[:-1]))
    return passed(int(found[1]), int(found[2]), minimum)


def count(target: str) -> None:
    from mutmut.mutation.file_mutation import mutate_file_contents

    print(len(mutate_file_contents(target, Path(target).read_text(encoding="utf-8")).mutant_names))


command, args = sys.argv[1], sys.argv[2:]
if command == "count":
    count(args[0])
elif command == "resume":
    resume(args[0], dry=args[1:] == ["--dry"])
elif command == "score":
    sys.exit(score(args[0], args[1], float(args[2]), int(args[3]), args[4], args[5] if len(args) > 5 else ""))
elif command == "show":
    sys.exit(show(args[0], args[1], float(args[2])))
EOF

# `mutmut run` made resumable: every verdict saved whole (mutmut rewrites its meta file in place
# after each mutant, which a kill mid-write tears), and SIGTERM/SIGHUP handled as Ctrl-C, on which
# mutmut stops its workers and keeps the verdicts it saved.
read -r -d '' RUN <<'EOF' || true
import os
import signal

from mutmut.mutation import data

save = data.SourceFileMutationData.save


def save_whole(self) -> None:
    final = self.meta_path
    self.meta_path = final.with_name(final.name + ".part")
    try:
        save(self)
    finally:
        self.meta_path = final
    os.replace(final.with_name(final.name + ".part"), final)


data.SourceFileMutationData.save = save_whole
main = os.getpid()


def stop(signum, frame):
    if os.getpid() != main:  # a forked worker dies as it would have
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    raise KeyboardInterrupt


signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job starts with it ignored
signal.signal(signal.SIGTERM, stop)
signal.signal(signal.SIGHUP, stop)
from mutmut.__main__ import cli

cli(prog_name="mutmut")
EOF

status=0
summary=()
pid=""
scratch=""
stopped=0
# a signal while mutmut runs stops it (its verdicts are kept); any other time it ends the script
trap 'stopped=1
if [ -n "$pid" ]; then
    kill -TERM "$pid" 2>/dev/null || true
else
    [ -z "$scratch" ] || rm -rf "$scratch"
    echo "stopped" >&2
    exit 130
fi' INT TERM HUP
commit=$(git -C "$SOURCE" rev-parse HEAD)
refuse_another_commit() { # MODULE: its kept clone, if any, must come from $commit
    local kept=$WORKDIR/$1/key
    if [ -f "$kept" ] && [ "$(sed -n 's/^commit //p' "$kept")" != "$commit" ]; then
        echo "$WORKDIR/$1 was cloned from commit $(sed -n 's/^commit //p' "$kept"), not from" \
            "$SOURCE's HEAD $commit; remove $WORKDIR/$1 to start $1 afresh at $commit, or use" \
            "another WORKDIR" >&2
        exit 2
    fi
}
if [ -n "$WORKDIR" ] && [ "${DRY:-0}" != 1 ]; then
    for m in "${wanted[@]}"; do # before any module runs for hours
        refuse_another_commit "$m"
    done
fi
for m in "${wanted[@]}"; do
    IFS="|" read -r target selection deselect <<<"${MODULES[$m]}"
    if [ -n "$WORKDIR" ] && [ "${DRY:-0}" != 1 ]; then
        base=$WORKDIR/$m
        mkdir -p "$base"
    else
        base=$(mktemp -d)
        scratch=$base
    fi
    clone=$base/koopnav
    # the key file is written last: a clone without one never finished its setup and is made anew
    fresh=0
    if [ ! -f "$base/key" ]; then
        rm -rf "$clone" "$base/score" "$base/seconds"
        git clone -q "$SOURCE" "$clone"
        fresh=1
    else
        refuse_another_commit "$m"
    fi
    tests=""
    testfiles=()
    copied=""
    where="$clone"
    [ "${COPY_TESTS:-0}" = 1 ] && where=$SOURCE
    for t in $(cd "$where" && shopt -s nullglob && for p in $selection; do
        # a glob names every file that matches (tests other engineers add, e.g. tests/test_records*.py)
        case $p in *"*"*) printf '%s\n' $p ;; *) printf '%s\n' "$p" ;; esac
    done | awk '!seen[$0]++'); do
        file=${t%%::*}
        case " ${WITHOUT:-} " in *" $file "*) continue ;; esac
        if [ "${COPY_TESTS:-0}" = 1 ] && [ -f "$SOURCE/$file" ]; then
            copied+="$(sha256sum <"$SOURCE/$file" | cut -c1-64) $file"$'\n'
            [ $fresh = 0 ] || cp "$SOURCE/$file" "$clone/$file"
        fi
        [ -f "$clone/$file" ] && tests+="\"$t\", " && testfiles+=("$file")
    done
    tests=${tests%, }
    # -n 0: mutmut runs the tests in its own process (pyproject's addopts spread them over xdist
    # workers); -m: the slow tests too (addopts leaves them out, and a selection is every test of
    # the module: without them the archive reader's page rebuilds were never run on a mutant)
    args='"-p", "no:cacheprovider", "-n", "0", "-m", "slow or not slow"'
    for t in ${deselect:-}; do
        args+=", \"--deselect\", \"$t\""
    done
    # mutmut 3.8 ends a mutant's run at a wall-clock timeout of half its CPU budget, (estimate + 1 s)
    # x 15 x 2 / 2 by default: 45 s for a 2-s estimate. The gate's and the archive reader's test
    # files build module fixtures of real episodes (65 s of setup alone for tests/test_baseline.py
    # at a load of 10-20) that the estimate leaves out, so at that budget 99 of the gate's first
    # 506 verdicts were timeouts that a rerun without it killed. (estimate + 5 s) x 60: at least
    # 300 s of wall time, so a timeout is left to a mutant that really runs away.
    section="
[tool.mutmut]
source_paths = [\"koopman_envs\", \"evaluation\", \"controllers\", \"baselines\"]
only_mutate = [\"$target\"]
also_copy = [\"evaluate.py\", \"data\", \"docs\", \".ci\", \"bench\", \"examples\", \"action.yml\", \"README.md\"]
pytest_add_cli_args_test_selection = [$tests]
pytest_add_cli_args = [$args]
timeout_constant = 5.0
timeout_multiplier = 60.0"
    # what the verdicts depend on besides the commit: the selection and any tests copied in
    selected=$(printf '%s\n%s' "$section" "$copied" | sha256sum | cut -c1-16)
    key="commit $commit selection $selected"
    if [ $fresh = 1 ]; then
        if [ "$m" = perception-kernels ]; then
            sed -i '/^@njit(.*)$/d' "$clone/$target" # the kernels as Python: mutmut can mutate them
        fi
        # the packages are copied whole into mutants/ (the tests import them from there); only the
        # module is mutated
        printf '%s\n' "$section" >>"$clone/pyproject.toml"
        printf 'commit %s\nselection %s\n' "$commit" "$selected" >"$base/key.part"
        mv "$base/key.part" "$base/key"
    elif [ "$(sed -n 's/^selection //p' "$base/key")" != "$selected" ]; then
        echo "$clone was set up with another test selection than this run's (WITHOUT, COPY_TESTS or" \
            "the tests changed); remove $base to start $m afresh, or use another WORKDIR" >&2
        exit 2
    fi
    echo "== $m: mutating $target, tests: $tests${deselect:+, left out: $deselect}"
    # what the store's verdicts are checked against: the settings, the module and the test files
    printf '%s\nmodule %s\n' "$section" "$m" >"$base/settings"
    stored=("$m" "$clone" "$target" "$base/settings" "${testfiles[@]}")
    if [ "${DRY:-0}" = 1 ]; then
        sed -n '/^\[tool.mutmut\]/,$p' "$clone/pyproject.toml"
        echo "$m: $(cd "$clone" && python3 -c "$STATE" count "$target") mutants"
        echo "$STORE/$m.json (in this fresh clone):"
        store restore "${stored[@]}" || true # its lines say how many verdicts are trusted
        kept=${WORKDIR:+$WORKDIR/$m}
        if [ -n "$kept" ] && [ -f "$kept/key" ] && [ "$(tr '\n' ' ' <"$kept/key")" != "$key " ]; then
            echo "$kept was set up from another commit or test selection: a run would refuse it"
        elif [ -n "$kept" ] && [ -f "$kept/score" ]; then
            python3 -c "$STATE" show "$kept/score" "$key" "$MIN_SCORE" | head -1 || true
        elif [ -n "$kept" ] && [ -d "$kept/koopnav/mutants" ]; then
            echo "$kept:"
            (cd "$kept/koopnav" && python3 -c "$STATE" resume "$target" --dry)
        fi
        rm -rf "$base"
        scratch=""
        continue
    fi
    if [ -f "$base/score" ]; then
        rc=0
        python3 -c "$STATE" show "$base/score" "$key" "$MIN_SCORE" >"$base/shown" || rc=$?
        if [ $rc != 3 ]; then
            cat "$base/shown"
            summary+=("$(head -1 "$base/shown") (finished in an earlier session)")
            [ $rc = 0 ] || status=1
            continue
        fi
        cat "$base/shown"
        rm -f "$base/score"
    fi
    if [ -d "$clone/mutants" ]; then
        echo "resuming $clone"
        (cd "$clone" && python3 -c "$STATE" resume "$target")
    fi
    rc=0
    store restore "${stored[@]}" || rc=$?
    if [ $rc != 0 ] && [ $rc != 10 ]; then # a torn or foreign store, named
        [ -z "$scratch" ] || rm -rf "$scratch"
        exit 2
    fi
    start=$(date +%s)
    if [ $rc = 10 ]; then # every mutant has a trusted verdict: mutmut is not started
        cp "$clone/mutants/results.txt" "$base/results.txt"
        rc=0
    else
        (cd "$clone" && exec python3 -c "$RUN" run --max-children "$JOBS") >>"$base/run.log" 2>&1 &
        pid=$!
        # the verdicts go to the store as they come: a kill of the machine loses SAVE_EVERY seconds
        (
            n=0
            while kill -0 "$pid" 2>/dev/null; do # ends within a second of mutmut
                sleep 1
                n=$((n + 1))
                if [ $n -ge "$SAVE_EVERY" ]; then
                    store save "${stored[@]}" || true
                    n=0
                fi
            done
        ) </dev/null >/dev/null 2>&1 &
        saver=$!
        rc=0
        wait "$pid" || rc=$?
        while kill -0 "$pid" 2>/dev/null; do # a signal ended the first wait: mutmut is still stopping
            rc=0
            wait "$pid" || rc=$?
        done
        pid=""
        wait "$saver" 2>/dev/null || true
        store save "${stored[@]}" || status=2
        (cd "$clone" && mutmut results --all true) >"$base/results.txt" 2>/dev/null || true
    fi
    # seconds over every session of this clone
    seconds=$(($(cat "$base/seconds" 2>/dev/null || echo 0) + $(date +%s) - start))
    echo "$seconds" >"$base/seconds"
    if [ $stopped = 1 ]; then
        if [ -n "$WORKDIR" ]; then
            echo "stopped; every verdict saved is kept in $clone: rerun the same command to continue" >&2
        elif [ "${KEEP:-0}" = 1 ]; then
            echo "stopped; kept $clone; the verdicts so far are in $STORE/$m.json: rerun to continue" >&2
        else
            rm -rf "$base"
            echo "stopped; the verdicts so far are in $STORE/$m.json: rerun to continue (WORKDIR=DIR keeps the clone too)" >&2
        fi
        exit 130
    fi
    if [ $rc != 0 ]; then
        tail -c 3000 "$base/run.log"
        status=1
    fi
    rc=0
    python3 -c "$STATE" score "$m" "$base/results.txt" "$MIN_SCORE" "$seconds" "$key" \
        "${WORKDIR:+$base/score}" >"$base/shown" || rc=$?
    cat "$base/shown"
    summary+=("$(head -1 "$base/shown")")
    [ $rc = 0 ] || status=1
    if [ -n "$WORKDIR" ] || [ "${KEEP:-0}" = 1 ]; then
        echo "kept $clone"
    else
        rm -rf "$base"
    fi
    scratch=""
done
if [ ${#summary[@]} -gt 0 ]; then
    echo "== scores"
    printf '%s\n' "${summary[@]}"
fi
exit $status
