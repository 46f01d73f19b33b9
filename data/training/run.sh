#!/usr/bin/env bash
# The learned policies over seeds (issue 60, docs/benchmark.md#learned-policies): every policy
# trained on koopnav-bench-v1's train layouts with seeds 0..SEEDS-1, each seed's checkpoint chosen
# on the validation layouts by the trainer itself (--suite), never on test.
#
#   bash data/training/run.sh [POLICY ...]     # default: rl-ppo-set ippo; also rl-ppo
#
# Each seed trains in data/training/POLICY/TASK/seedK/ (a policy root: TASK/ holds the kept
# policy, selection.json the validation table, train.log the trainer's output, every session's).
# finished.json is written last, atomically (a rename); a seed that has it is skipped. A seed
# folder without it is an interrupted run: one whose folder holds a sound resume checkpoint of its
# trainer (resume.ckpt, written every RESUME_EVERY rollouts of an SB3 seed, rl-ppo-set and rl-ppo,
# or iterations of an ippo seed; checked with python -m baselines.resume FILE sb3-ppo or
# benchmarl-ppo) continues from it (--resume), bit for bit as if it had never stopped; one without
# is removed and trained again from the start. So the script can be stopped (Ctrl-C, kill) and run
# again, in this session or another.
#
# Settings (environment variables):
#   SEEDS               seeds per policy and task (default 3: seeds 0, 1, 2)
#   TASKS               the tasks (default "target_reaching formation")
#   TIMESTEPS           rl-ppo-set / rl-ppo budget in robot-steps (default: the task's
#                       baselines.sb3.train_options.TIMESTEPS, 14 M target reaching, 12 M formation)
#   FRAMES              ippo budget in frames (default 6_000_000, the shipped ippo's)
#   VALIDATION_LAYOUTS  validation layouts per checkpoint (default 50)
#   THREADS             torch threads of a training run (default 1; a seed's weights are the
#                       same bit for bit at the same thread count)
#   RESUME_EVERY        rollouts (rl-ppo-set, rl-ppo) or iterations (ippo) between resume checkpoints
#                       (default 10: 491,520 robot-steps at SB3's default 128 envs, 120,000 frames of
#                       ippo; 0: none, an interrupted seed starts again)
#   SB3_ARGS, IPPO_ARGS further options of baselines.sb3.train / baselines.marl.benchmarl_train (after
#                       the defaults here, so they win), e.g. a tiny network for a smoke run
#   TRAINING_ROOT       where the seed folders go (default data/training)
set -euo pipefail
cd "$(dirname "$0")/../.."
SUITE=koopnav-bench-v1
ROOT="${TRAINING_ROOT:-data/training}"
SEEDS="${SEEDS:-3}"
FRAMES="${FRAMES:-6_000_000}"
VALIDATION_LAYOUTS="${VALIDATION_LAYOUTS:-50}"
THREADS="${THREADS:-1}"
RESUME_EVERY="${RESUME_EVERY:-10}"
read -r -a tasks <<< "${TASKS:-target_reaching formation}"
read -r -a sb3_args <<< "${SB3_ARGS:-}"
read -r -a ippo_args <<< "${IPPO_ARGS:-}"
policies=("$@")
[ ${#policies[@]} -gt 0 ] || policies=(rl-ppo-set ippo)
for policy in "${policies[@]}"; do  # checked before any folder is touched
    case "$policy" in
        rl-ppo-set | rl-ppo | ippo) ;;
        *) echo "unknown policy '$policy'; allowed: rl-ppo-set rl-ppo ippo" >&2; exit 2 ;;
    esac
done
[[ "$SEEDS" =~ ^[0-9]+$ ]] || { echo "SEEDS='$SEEDS'; allowed: a whole number" >&2; exit 2; }
[[ "$RESUME_EVERY" =~ ^[0-9]+$ ]] || { echo "RESUME_EVERY='$RESUME_EVERY'; allowed: a whole number" >&2; exit 2; }

env_id() {
    case "$1" in
        target_reaching) echo KoopNav-TargetReaching-v0 ;;
        formation) echo KoopNav-Formation-v0 ;;
        *) echo "unknown task '$1'; allowed: target_reaching formation" >&2; return 2 ;;
    esac
}

train() {  # train POLICY TASK SEED DIR [--resume]: one seed's run, its output in DIR/train.log
    local policy=$1 task=$2 seed=$3 dir=$4
    local common=(--suite "$SUITE" --seed "$seed" --validation-layouts "$VALIDATION_LAYOUTS" --threads "$THREADS")
    local budget=() resume=(--resume-every "$RESUME_EVERY" "${@:5}")
    [ -n "${TIMESTEPS:-}" ] && budget=(--timesteps "$TIMESTEPS")
    case "$policy" in
        rl-ppo-set)
            python -m baselines.sb3.train --env "$(env_id "$task")" --policy set "${common[@]}" "${budget[@]}" \
                "${sb3_args[@]}" "${resume[@]}" --out "$dir" ;;
        rl-ppo)
            python -m baselines.sb3.train --env "$(env_id "$task")" "${common[@]}" "${budget[@]}" \
                "${sb3_args[@]}" "${resume[@]}" --out "$dir" ;;
        ippo)
            # the shipped ippo's settings (baselines/policies/ippo/*/metadata.json), on the suite's layouts
            python -m baselines.marl.benchmarl_train --task "$task" --algorithm ippo "${common[@]}" \
                --frames "$FRAMES" --frames-per-batch 12000 --minibatch-size 1000 --epochs 5 \
                --normalize-advantage --envs 200 --features bearing+headings --entropy-coef 0.01 \
                "${ippo_args[@]}" "${resume[@]}" --out "$dir" ;;
    esac
}

for task in "${tasks[@]}"; do env_id "$task" > /dev/null || exit 2; done
for policy in "${policies[@]}"; do
    for task in "${tasks[@]}"; do
        for ((seed = 0; seed < SEEDS; seed++)); do
            dir="$ROOT/$policy/$task/seed$seed"
            if [ -f "$dir/finished.json" ]; then
                echo "$policy $task seed $seed: finished, skipped ($dir/finished.json)"
                continue
            fi
            resume=()
            kind=sb3-ppo
            [ "$policy" = ippo ] && kind=benchmarl-ppo
            if [ -f "$dir/resume.ckpt" ]; then
                if check=$(python -m baselines.resume "$dir/resume.ckpt" "$kind" 2>&1); then
                    resume=(--resume)
                    echo "$policy $task seed $seed: unfinished run in $dir; resuming from its checkpoint"
                else
                    echo "$policy $task seed $seed: $check" >&2
                fi
            fi
            if [ ${#resume[@]} -eq 0 ]; then
                [ -e "$dir" ] && echo "$policy $task seed $seed: unfinished run in $dir, removed; training again"
                rm -rf "$dir"
                mkdir -p "$dir"
                echo "$policy $task seed $seed: training into $dir"
            fi
            echo "$(date -u +%Y-%m-%dT%H:%M:%SZ) ${resume[*]:-start}" >> "$dir/sessions.txt"
            start=$(date +%s)
            train "$policy" "$task" "$seed" "$dir" "${resume[@]}" >> "$dir/train.log" 2>&1 || {
                echo "$policy $task seed $seed: the trainer failed (exit $?); see $dir/train.log" >&2
                exit 1
            }
            for file in "$dir/selection.json" "$dir/$task/metadata.json"; do
                [ -f "$file" ] || { echo "$policy $task seed $seed: $file missing" >&2; exit 1; }
            done
            wall=$(( $(date +%s) - start ))
            # sessions: 1 + the resumes (each resumed bit for bit: the policy's metadata.json lists where
            # in resumed_from_timesteps, or resumed_from_frames for ippo); wall_seconds: this last session's
            sessions=$(wc -l < "$dir/sessions.txt")
            printf '{"policy": "%s", "task": "%s", "seed": %d, "wall_seconds": %d, "sessions": %d, "finished": "%s"}\n' \
                "$policy" "$task" "$seed" "$wall" "$sessions" "$(date -u +%Y-%m-%dT%H:%M:%SZ)" > "$dir/finished.json.tmp"
            mv "$dir/finished.json.tmp" "$dir/finished.json"
            echo "$policy $task seed $seed: finished in ${wall} s"
        done
    done
done
