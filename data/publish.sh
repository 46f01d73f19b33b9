#!/usr/bin/env bash
# The published runs behind docs/*_results.md, each resumable: run this script again after an
# interruption (or in a new session, after `unpack`) and every run continues where its log ends.
# Each run writes data/runs/NAME/ (work files, not committed); `bash data/publish.sh pack` packs
# its episode logs (JSON lines) into data/NAME/ (committed: the published data), split per
# controller (data/NAME/run.tar.xz, the run's headers and sweep manifest, and
# data/NAME/controllers/LABEL.tar.xz, each controller's records), so that republishing one
# controller's rows rewrites its file only (docs/layout.md, "What a clone weighs"). The runs published
# before that are one archive each, data/NAME.tar.xz: read alike, left as they are while their logs
# are unchanged (repacking them would add their whole size to the history again); the first
# republication of such a run replaces it with data/NAME/ (then point data/pages.json at data/NAME).
#
#   bash data/publish.sh [NAME ...]    run (or continue) the named runs, default all, in order
#   bash data/publish.sh pack          pack every changed run's episode logs into data/NAME/
#   bash data/publish.sh unpack        restore data/runs/ from data/NAME/ and data/NAME.tar.xz (a new machine);
#                                      a local log holding more records than its publication stops it
#                                      (unpack --force replaces it)
# After a change to some controllers that changes what they do, republish only their rows: drop
# their records (`python -m evaluation.forget LABEL... -- data/runs/NAME`), then run NAME
# again (it resumes and runs just those episodes), then `pack` (it rewrites their files only). A controller added to a run's
# --controllers (or newly registered, for the runs of every registered controller) joins it the
# same way: the resume keeps the logged records and runs only its episodes.
# KOOPNAV_PUBLISH_WORKERS: worker processes (default 1: a core stays free for other work).
set -euo pipefail
cd "$(dirname "$0")/.."
workers="${KOOPNAV_PUBLISH_WORKERS:-1}"
# the OpenBLAS kernels pinned where the CPU allows, so that a run resumed on another machine
# continues with the same arithmetic (.ci/blas_pin.sh)
# shellcheck source=.ci/blas_pin.sh
source .ci/blas_pin.sh

# the model-based controllers as deployed (estimator="auto", stall resolution, the real-time
# iteration) beside the paper's (no estimator, no stall resolution), paired on the same episodes
PAPER_VARIANTS=(
    "koopman-nmpc:estimator=none,unstall=false,label=koopman-nmpc-paper"
    "nominal-nmpc:estimator=none,unstall=false,label=nominal-nmpc-paper"
)
declare -A RUNS
# issue 42, the target table: the paper protocol's cells under `realistic`
# (the set policies on the same episodes: one episode set for every comparison of the page)
RUNS[paper_realistic]="--paper --solver rti --controllers koopman-nmpc nominal-nmpc consensus ${PAPER_VARIANTS[*]} consensus:estimator=none,label=consensus-paper rl-ppo-set rl-ppo-set-realistic --sweep uncertainty=nominal,realistic --reference koopman-nmpc"
# issue 42: pose noise and actuation delay swept alone (the paper's maps, nominal slip, 20 per cell)
RUNS[lab_day_sweep]="--slips nominal --episodes 20 --controllers koopman-nmpc nominal-nmpc dmpc-koopman dmpc-nominal ${PAPER_VARIANTS[*]} dmpc-koopman:estimator=none,label=dmpc-koopman-paper dmpc-nominal:estimator=none,label=dmpc-nominal-paper --sweep pose_noise.xy=0,0.05,0.1 --sweep actuation_delay=0,1,2,4 --reference koopman-nmpc"
# issue 42: the mis-specified datasheet (the realistic preset's values, whatever the team has)
RUNS[lab_day_misspecified]="--slips nominal --episodes 20 --controllers koopman-nmpc koopman-nmpc:estimator=realistic,label=koopman-nmpc-datasheet nominal-nmpc:estimator=realistic,label=nominal-nmpc-datasheet dmpc-koopman:estimator=realistic,label=dmpc-koopman-datasheet consensus:estimator=realistic,label=consensus-datasheet --sweep pose_noise.xy=0,0.05,0.1 --sweep actuation_delay=0,1,2,4 --reference koopman-nmpc"
# issue 42: the ablation, each lever off alone (Koopman-NMPC), under realistic, on the delay
# sweep and on the noise sweep
ABLATION="--slips nominal --episodes 20 --controllers koopman-nmpc koopman-nmpc:ablate=estimation,label=no-estimation koopman-nmpc:ablate=delay_compensation,label=no-delay-compensation koopman-nmpc:ablate=tightening,label=no-tightening koopman-nmpc:ablate=settling,label=no-settling koopman-nmpc:unstall=false,label=no-unstall"
RUNS[lab_day_ablation]="$ABLATION --sweep uncertainty=nominal,realistic --sweep actuation_delay=2,4 --sweep pose_noise.xy=0.05,0.1 --reference koopman-nmpc"
# issue 43: the paper protocol republished (IPOPT, perturbed starts: distinct episodes), the
# controllers as deployed beside the paper's, the PPO policies and the classic baselines (issue 45)
RUNS[paper]="--paper --solver ipopt --controllers koopman-nmpc nominal-nmpc consensus ${PAPER_VARIANTS[*]} rl-ppo rl-ppo-set orca dwa mpc-cbf ippo --reference koopman-nmpc"
# issue 43: docs/results.md's changing-uncertainty runs (slip zones, drifting and random slip),
# republished from perturbed starts (distinct episodes) on the controllers' current defaults
ADAPTIVE="adaptive-koopman-nmpc koopman-nmpc koopman-nmpc-robust nominal-nmpc rl-ppo adaptive-koopman-nmpc:adapt=false,label=adaptive-frozen"
INPUT="adaptive-koopman-nmpc:adapted=input,label=adaptive-input"
RUNS[zones_tr]="--env KoopNav-TargetReaching-v0 --maps map5 --slips nominal drift --episodes 30 --controllers $ADAPTIVE $INPUT"
RUNS[zones_tr_random]="--env KoopNav-TargetReaching-v0 --maps map5 --slips random --episodes 30 --controllers $ADAPTIVE"
RUNS[zones_fm]="--env KoopNav-Formation-v0 --maps map6 --slips nominal --episodes 30 --controllers $ADAPTIVE $INPUT"
RUNS[zones_fm_changing]="--env KoopNav-Formation-v0 --maps map6 --slips drift random --episodes 30 --controllers $ADAPTIVE"
RUNS[zones_paper_maps]="--env KoopNav-TargetReaching-v0 KoopNav-Formation-v0 --maps map1 map2 map3 map4 --slips random --episodes 10 --controllers koopman-nmpc koopman-nmpc-robust adaptive-koopman-nmpc"
# issue 43: docs/results.md's team-size table (seeded random maps, nominal slip)
TEAM="koopman-nmpc nominal-nmpc consensus consensus-free rl-ppo orca dwa mpc-cbf"
# (ippo, an MLP over a 3-robot block, in the 3-robot run only)
RUNS[scale_n3]="--env KoopNav-TargetReaching-v0 --maps random --slips nominal --episodes 20 --env-kwargs n_robots=3 --controllers $TEAM ippo"
RUNS[scale_n6]="--env KoopNav-TargetReaching-v0 --maps random --slips nominal --episodes 10 --env-kwargs n_robots=6 --controllers $TEAM"
RUNS[scale_n10]="--env KoopNav-TargetReaching-v0 --maps random --slips nominal --episodes 5 --env-kwargs n_robots=10 --controllers $TEAM"
RUNS[scale_n16]="--env KoopNav-TargetReaching-v0 --maps random --slips nominal --episodes 3 --env-kwargs n_robots=16 --max-episode-steps 300 --controllers $TEAM"
# issue 45: the classic baselines and MPC-CBF on the realistic page's episodes (Koopman-NMPC again
# as the reference: its rows repeat paper_realistic's bit for bit)
RUNS[realistic_classic]="--paper --solver rti --controllers koopman-nmpc orca dwa mpc-cbf ippo --sweep uncertainty=nominal,realistic --reference koopman-nmpc"
# issue 43: the realistic protocol with compute charged (--realtime; decision times measured on
# this machine, one worker, and at --compute-scale 5 for a board five times slower)
REALTIME_CONTROLLERS="koopman-nmpc nominal-nmpc consensus mpc-cbf orca dwa rl-ppo-set rl-ppo-set-realistic"
RUNS[realistic_realtime]="--paper --solver rti --controllers $REALTIME_CONTROLLERS --sweep uncertainty=nominal,realistic --reference koopman-nmpc --realtime"
RUNS[realistic_realtime5]="--paper --solver rti --controllers $REALTIME_CONTROLLERS --sweep uncertainty=nominal,realistic --reference koopman-nmpc --realtime --compute-scale 5"
# issue 45: MPC-CBF's decay rate gamma ablated on the paper protocol (the real-time iteration)
GAMMAS=""
for g in 0.05 0.1 0.2 0.5 1.0; do GAMMAS="$GAMMAS mpc-cbf:cbf_gamma=$g,label=mpc-cbf-gamma$g"; done
RUNS[cbf_gamma]="--paper --solver rti --controllers nominal-nmpc$GAMMAS --reference nominal-nmpc"
# issue 43: the robustness profiles republished (every registered controller, each axis alone)
RUNS[robustness]="--slips nominal --episodes 20 --sweep pose_noise.xy=0,0.05,0.1,0.2 --sweep comm.latency=0,1,3,6 --sweep comm.drop=0,0.2,0.5,0.8 --sweep actuation_delay=0,1,2,4 --reference koopman-nmpc"
# issue 43, 45: the crowd protocol republished (every registered controller among 0-16 movers of
# each behaviour; --crowd adds the movers.count sweep)
for behaviour in constant waypoints crowd; do RUNS[crowd_$behaviour]="--crowd $behaviour --reference koopman-nmpc"; done
# issue 43, 46: what the people tracker costs among 16 constant movers (the movers observed
# through it, the protocol's default, against their exact states); its tracked level repeats
# crowd_constant's 16-mover episodes bit for bit
TRACKING_CONTROLLERS="koopman-nmpc nominal-nmpc dmpc-koopman dmpc-nominal adaptive-koopman-nmpc mpc-cbf orca dwa consensus rl-ppo-set-movers"
RUNS[crowd_tracking]="--crowd constant --env-kwargs movers={\"count\":16,\"behaviour\":\"constant\",\"speed\":0.3} --sweep movers.tracking=true,false --solver rti --controllers $TRACKING_CONTROLLERS --reference koopman-nmpc"
# issue 43: the crowd protocol's oblivious ORCA crowd with compute charged (--realtime, as the
# realistic page's twin): the realistic page's controllers and the movers policy
RUNS[crowd_realtime]="--crowd crowd --solver rti --controllers $REALTIME_CONTROLLERS rl-ppo-set-movers --reference koopman-nmpc --realtime"
# issue 60: crowd collisions split by fault (docs/crowd_results.md, "Collisions by fault"): the
# oblivious ORCA crowd of crowd_crowd on the same episodes (seeds, maps, starts, settings: its
# records pair with crowd_crowd's by key) for the primary controllers, whose records now carry
# collision_at_fault and success_excusing_unavoidable (crowd_crowd's predate the fault rule).
# 3,360 episodes (7 controllers x 120 x 4 mover counts), about 25 CPU-minutes with 1 worker
# (projected from 2 episodes per controller and level). On those 56 episodes orca, dwa and
# rl-ppo-set-movers repeated crowd_crowd's records in every field both hold but the times; the
# NMPCs, mpc-cbf and consensus have changed since crowd_crowd ran and did not (4 of their 32
# outcomes differ): their rows here are today's code's
RUNS[crowd_faults]="--crowd crowd --solver rti --controllers koopman-nmpc nominal-nmpc consensus orca dwa mpc-cbf rl-ppo-set-movers --reference koopman-nmpc"
# issue 46: navigating on what the robots see (every controller that perceives; exact state, the
# lidar with the map known, the lidar only; 4 constant movers; docs/perception.md)
RUNS[lidar]="--lidar --reference koopman-nmpc"
# issue 46: the learned set policies on the sensing protocol's episodes, reading the perceived
# obstacle and mover sets (baselines/features/perceived.py); Koopman-NMPC again as the reference (its rows
# repeat the lidar run's bit for bit)
RUNS[lidar_policies]="--lidar --solver rti --controllers koopman-nmpc rl-ppo-set rl-ppo-set-realistic rl-ppo-set-movers --reference koopman-nmpc"
# issue 60: the ablation of the NMPC's design factors (docs/ablation.md; 640 episodes on IPOPT)
RUNS[ablation]="--ablation"
# issue 60, KoopNav-Bench v1: the held-out test suite (200 layouts per task, one episode each,
# high slip, the NMPCs on the real-time iteration), on the same (layout, seed) units in both modes:
# docs/bench_results.md and README's headline (docs/make_bench_md.py). Each mode's list is sized to
# the compute we have (docs/benchmark.md, "Compute per mode": about 18 CPU-hours for 22 controllers
# per mode); the variants (the robust and distributed NMPCs, adaptive-koopman-nmpc and the
# fine-tuned set policies) have their own pages and are not in it.
BENCH="--suite koopnav-bench-v1 --split test --reference koopman-nmpc"
# compute charged (the headline: decision time delays the command, docs/evaluator.md): the primary
# controllers on their shipped defaults
BENCH_CHARGED="koopman-nmpc nominal-nmpc consensus consensus-free orca dwa mpc-cbf rl-ppo rl-ppo-set ippo"
RUNS[bench_test_realtime]="$BENCH --controllers $BENCH_CHARGED --realtime"
# free compute (the idealised case): the same controllers and the hand-set defaults the tuned
# presets replaced (-v0), so that what tuning gained is paired on the held-out split. A resume may
# only add controllers (evaluation/episodes/runlog.py): once the run has started, a change goes at
# the end of the list. dwa has no -v0: its study's best was not confirmed on fresh validation
# layouts (data/tuning/dwa/confirmation.json), so dwa ships its hand-set defaults.
BENCH_FREE="koopman-nmpc nominal-nmpc consensus consensus-free orca dwa mpc-cbf rl-ppo rl-ppo-set ippo consensus-v0 mpc-cbf-v0 nominal-nmpc-v0 koopman-nmpc-v0"
RUNS[bench_test]="$BENCH --controllers $BENCH_FREE"
# issue 60: why charging decision time raises Koopman-NMPC at nominal (docs/compute.md): the
# realistic_realtime gain sits in the high-slip cells, so each mechanism is run there on the
# paper protocol's episodes (its seeds, maps and starts) and paired with the published ones.
# compute_free: free compute, no delay; the NMPC as shipped (repeats paper_realistic's rows bit for
# bit) and with its margins widened by what the chance constraints add at one period of delay
# (z(0.95) x 1 cm, the estimator's process noise: 0.0164 m toward obstacles, 0.0233 m per pair)
WIDE="koopman-nmpc:obstacle_offset=0.03145,robot_offset=0.03826,label=koopman-nmpc-wide-margins"
MECHANISM="--paper --slips high --reference koopman-nmpc"
RUNS[compute_free]="$MECHANISM --solver rti --controllers koopman-nmpc $WIDE --env-kwargs uncertainty=nominal"
# compute_delay: one period of actuation delay in the env, free compute: the estimator identifies
# and compensates it as under --realtime; each of its levers off alone
RUNS[compute_delay]="$MECHANISM --solver rti --controllers koopman-nmpc koopman-nmpc:ablate=tightening,label=koopman-nmpc-no-tightening koopman-nmpc:ablate=delay_compensation,label=koopman-nmpc-no-compensation --env-kwargs uncertainty=nominal actuation_delay=1"
# compute_ipopt_delay: one period of delay with IPOPT solved to convergence instead of the
# real-time iteration (paired with the paper run's koopman-nmpc rows: IPOPT, free compute, no delay)
RUNS[compute_ipopt_delay]="$MECHANISM --solver ipopt --controllers koopman-nmpc --env-kwargs actuation_delay=1"
COMPUTE_RUNS=(compute_free compute_delay compute_ipopt_delay)
# issue 62: the sim-to-sim protocol (docs/sim2sim_results.md): every registered controller, as
# tuned or trained on the kinematic plant, on the suite's first 10 test layouts of both tasks on
# carpet and on ice (slip=nominal and high: the physics plant's extremes of friction), on the
# kinematic plant and on the physics plant; the two runs differ by --plant only, so every episode
# pairs with its twin (same layout, starts and seed). Estimated 2.2 CPU-hours with 1 worker (24
# controllers), 56 CPU-minutes of it the physics run's calibrations: the Koopman models (stacked and per-robot) and the robust
# NMPCs' residual calibrate on the plant they run on, 1,000,000 team-transitions each per friction
# level, about 28 CPU-minutes per level on the physics plant (docs/physics.md, "The sim-to-sim
# protocol"); gravel (slip=low) would add about 1.1 CPU-hours. rl-ppo-set-physics, fine-tuned on
# the physics plant (docs/rl.md), runs in both as a row of its own (docs/make_sim2sim_md.py FINE_TUNED).
SIM2SIM="--suite koopnav-bench-v1 --split test --layouts 0:10 --sweep slip=nominal,high --reference koopman-nmpc"
RUNS[sim2sim_kinematic]="$SIM2SIM"
RUNS[sim2sim_physics]="$SIM2SIM --plant mujoco"
# issue 60: the learned policies over training seeds (docs/seeds_results.md): every finished seed
# under data/training (data/training/run.sh; a controller <policy>@seed<k> each) on the suite's test
# split, 200 layouts per task, one episode each, one run per task (data/runs/seeds/<task>/). Not
# evaluate.py: `python -m evaluation.experiments.seeds` with these options (run() below). It
# resumes each task's log by itself; a seed finished since joins it as a controller added (the
# resume rule of evaluation/episodes/runlog.py), the logged seeds' records kept.
RUNS[seeds]="--split test"
RESULTS_RUNS=(paper zones_tr zones_tr_random zones_fm zones_fm_changing zones_paper_maps scale_n3 scale_n6 scale_n10 scale_n16)
ORDER=(paper_realistic lab_day_ablation lab_day_sweep lab_day_misspecified "${RESULTS_RUNS[@]}" realistic_classic cbf_gamma realistic_realtime realistic_realtime5 "${COMPUTE_RUNS[@]}" robustness lidar lidar_policies crowd_constant crowd_waypoints crowd_crowd crowd_tracking crowd_realtime crowd_faults ablation bench_test_realtime bench_test sim2sim_kinematic sim2sim_physics seeds)

run() {
    local name="$1" out="data/runs/$1"
    if [ "$name" = seeds ]; then  # the seeds' own command; it resumes each task's log itself
        # shellcheck disable=SC2086  # the option string is split on purpose
        python -m evaluation.experiments.seeds ${RUNS[$name]} --out "$out" --workers "$workers"
        return
    fi
    local resume=()
    [ -e "$out" ] && resume=(--resume)
    # shellcheck disable=SC2086  # the option strings are split on purpose
    python evaluate.py ${RUNS[$name]} --out "$out" --workers "$workers" --quiet "${resume[@]}"
}

case "${1:-}" in
pack)  # the episode logs and sweep manifests only: everything else is rebuilt from them
    scratch="$(mktemp -d)"
    trap 'rm -rf "$scratch"' EXIT
    for dir in data/runs/*/; do
        name="$(basename "$dir")"
        if [ -e "data/$name.tar.xz" ]; then  # published whole: kept while its logs are unchanged
            python -m evaluation.archive "data/runs/$name" "$scratch/$name.tar.xz" > /dev/null
            cmp -s "$scratch/$name.tar.xz" "data/$name.tar.xz" && continue
            rm "data/$name.tar.xz"
            echo "data/$name.tar.xz is now data/$name/ (split per controller): point data/pages.json at data/$name" >&2
        fi
        python -m evaluation.archive "data/runs/$name" "data/$name" > /dev/null
    done
    git status --short -- data/ 2> /dev/null || true
    ;;
unpack)  # a new machine: the committed logs back into data/runs/, to resume or to report from
    # (a local log with more records than its archive is kept and the script stops, naming it;
    # `unpack --force` replaces it)
    force=()
    [ "${2:-}" = "--force" ] && force=(--force)
    mkdir -p data/runs
    for frame in data/*.tar.xz data/*/run.tar.xz; do
        [ -e "$frame" ] || continue
        publication="${frame%/run.tar.xz}"  # data/NAME/ when split, else data/NAME.tar.xz itself
        python -m evaluation.archive unpack "$publication" data/runs "${force[@]}" > /dev/null
    done
    ;;
*)
    names=("$@")
    [ ${#names[@]} -eq 0 ] && names=("${ORDER[@]}")
    for name in "${names[@]}"; do
        [ -n "${RUNS[$name]+x}" ] || { echo "unknown run $name; known: ${ORDER[*]}" >&2; exit 2; }
        echo "== $name"
        run "$name"
    done
    ;;
esac
