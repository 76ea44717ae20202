#!/usr/bin/env bash
# A firmware-sim Monte Carlo sweep as a Slurm job array: array task K runs
# shard K/N of the sweep (K = SLURM_ARRAY_TASK_ID, counted from 0, like
# firmware-sim's K), into a shard directory on a file system every node
# sees. A second job, started once every task has succeeded, merges the
# shards into the files the unsharded sweep writes (docs/monte-carlo.md,
# "Sweeps beyond one machine"). Slurm does the scheduling; firmware-sim
# only runs its share and merges.
#
# Run it with bash, from the repository root, on that shared file system:
#   cargo build --release -p firmware-sim
#   bash docs/examples/sweep-slurm.sh                  # submits the array and the merge
#   SHARDS=4 CPUS=2 RUNS=200 bash docs/examples/sweep-slurm.sh
# It submits itself twice with sbatch: as the array (`… shard`, one task a
# shard) and as the merge (`… merge`, --dependency=afterok on the array),
# passing the array's size and the CPUs on sbatch's command line, since
# #SBATCH lines cannot read variables. The jobs read the knobs below from
# the environment sbatch exports to them.
#
# Knobs (environment variables; the defaults in brackets):
#   SCENARIOS   scenario names or files, space-separated
#               [figure_eight_rfid figure_eight_rfid_pose_observer
#                figure_eight_rfid_fusion_ekf figure_eight_rfid_full_stack]
#   RUNS        runs of the whole sweep, not of a shard [1000]
#   SEED        the sweep's seed [1]
#   SHARDS      N, the number of shards: array tasks 0 … N−1 [10]
#   CPUS        CPUs per array task (sbatch --cpus-per-task): the task runs
#               that many runs at a time [4]. More than any node has and the
#               task pends forever, so the script refuses it (`sinfo -N -o %c`
#               lists each node's CPUs)
#   TIME_LIMIT  time limit of each job (sbatch --time) [00:30:00]
#   SIM         the firmware-sim binary [target/release/firmware-sim]
#   SHARDS_DIR  where shard K goes, as SHARDS_DIR/shard-K [out/sweep-shards]
#   OUT         the merged sweep [out/sweep]
#   LOGS        the jobs' logs [out/slurm]
#   TASKS       the array tasks to submit [0-(SHARDS−1)]; a failed shard's
#               K (e.g. TASKS=7 or TASKS=3,7) reruns just those
#
# out/sweep then holds runs.csv, summary.json, table.md and the plots (with
# several scenarios, as here: out/sweep/<name>/ and out/sweep/table.md),
# byte for byte what `firmware-sim sweep … --out out/sweep` on one machine
# writes. Use an empty SHARDS_DIR for each sweep: the merge refuses a shard
# of another sweep left there.
#
# When a task fails, its shard has no shard.json, and the merge job, whose
# afterok can no longer be met, stays pending forever (squeue reason
# DependencyNeverSatisfied); a rerun task does not release it. So cancel it,
# then rerun the failed shards with the same knobs, which submits a new
# merge after them:
#   sacct -j ARRAY_JOB_ID --format=JobID,State,ExitCode   # which K failed
#   scancel MERGE_JOB_ID
#   TASKS=7 bash docs/examples/sweep-slurm.sh
# or, once every shard has its shard.json, merge by hand:
#   target/release/firmware-sim sweep-merge out/sweep-shards/shard-* --out out/sweep
#
# Without the wrapper (SHARDS, CPUS and any other knob exported, and
# mkdir -p out/slurm), the same two jobs are
#   sbatch --parsable --array=0-$((SHARDS-1)) --cpus-per-task=$CPUS docs/examples/sweep-slurm.sh shard
#   sbatch --dependency=afterok:ARRAY_JOB_ID --job-name=wmr-sweep-merge \
#       --output=out/slurm/%x-%j.log docs/examples/sweep-slurm.sh merge

#SBATCH --job-name=wmr-sweep
#SBATCH --ntasks=1
#SBATCH --time=00:30:00
#SBATCH --output=out/slurm/%x-%A_%a.log

set -euo pipefail

SCENARIOS=${SCENARIOS:-figure_eight_rfid figure_eight_rfid_pose_observer figure_eight_rfid_fusion_ekf figure_eight_rfid_full_stack}
RUNS=${RUNS:-1000}
SEED=${SEED:-1}
SHARDS=${SHARDS:-10}
CPUS=${CPUS:-4}
TIME_LIMIT=${TIME_LIMIT:-00:30:00}
SIM=${SIM:-target/release/firmware-sim}
SHARDS_DIR=${SHARDS_DIR:-out/sweep-shards}
OUT=${OUT:-out/sweep}
LOGS=${LOGS:-out/slurm}
TASKS=${TASKS:-}

die() {
    echo "sweep-slurm.sh: $*" >&2
    exit 1
}

# Array task K: shard K/N.
shard() {
    local k=${SLURM_ARRAY_TASK_ID:?submit the shards as a job array: bash docs/examples/sweep-slurm.sh}
    local scenarios
    read -r -a scenarios <<<"$SCENARIOS"
    exec "$SIM" sweep "${scenarios[@]}" --runs "$RUNS" --seed "$SEED" \
        --threads "${SLURM_CPUS_PER_TASK:-0}" \
        --shard "$k/$SHARDS" --out "$SHARDS_DIR/shard-$k"
}

# The merge job: every shard of SHARDS_DIR into OUT.
merge() {
    exec "$SIM" sweep-merge "$SHARDS_DIR"/shard-* --out "$OUT"
}

# On the submit host: the array, then the merge after it.
submit() {
    command -v sbatch >/dev/null || die "sbatch not found: run this on a Slurm submit host"
    [[ -x $SIM ]] || die "$SIM not found: cargo build --release -p firmware-sim first, or set SIM"
    [[ $SHARDS =~ ^[1-9][0-9]*$ ]] || die "SHARDS=$SHARDS: a number of shards ≥ 1"
    [[ $CPUS =~ ^[1-9][0-9]*$ ]] || die "CPUS=$CPUS: a number of CPUs ≥ 1"
    local most
    most=$(sinfo -N -h -o %c 2>/dev/null | sort -n | tail -n 1) || true
    if [[ $most =~ ^[0-9]+$ ]] && ((CPUS > most)); then
        die "CPUS=$CPUS: no node has more than $most CPUs (sinfo -N -o %c), and such a task pends forever"
    fi
    local tasks=${TASKS:-0-$((SHARDS - 1))}
    mkdir -p "$LOGS"
    export SCENARIOS RUNS SEED SHARDS SIM SHARDS_DIR OUT
    local array merge_job
    array=$(sbatch --parsable --export=ALL --job-name=wmr-sweep \
        --array="$tasks" --ntasks=1 --cpus-per-task="$CPUS" --time="$TIME_LIMIT" \
        --output="$LOGS/%x-%A_%a.log" "$0" shard)
    array=${array%%;*} # --parsable prints "job id[;cluster]"
    merge_job=$(sbatch --parsable --export=ALL --job-name=wmr-sweep-merge \
        --dependency=afterok:"$array" --ntasks=1 --time="$TIME_LIMIT" \
        --output="$LOGS/%x-%j.log" "$0" merge)
    merge_job=${merge_job%%;*}
    echo "array job $array: shards $tasks of $SHARDS into $SHARDS_DIR/shard-K"
    echo "merge job $merge_job: into $OUT once every task has succeeded"
    echo "a failed task leaves the merge pending forever: scancel $merge_job, then TASKS=K bash $0"
}

case ${1:-} in
    shard) shard ;;
    merge) merge ;;
    submit) submit ;;
    "")
        if [[ -n ${SLURM_ARRAY_TASK_ID:-} ]]; then
            shard
        elif [[ -n ${SLURM_JOB_ID:-} ]]; then
            die "a batch job that is not an array task: submit with bash docs/examples/sweep-slurm.sh (inside an allocation: … sweep-slurm.sh submit)"
        else
            submit
        fi
        ;;
    *) die "unknown mode '$1' (shard, merge or submit; none: submit, or shard in an array task)" ;;
esac
