#!/usr/bin/env bash
# A firmware-sim Monte Carlo sweep as a Slurm job array: array task K runs
# shard K/N of the sweep (K = SLURM_ARRAY_TASK_ID, counted from 0, like
# firmware-sim's K), into a shard directory on a file system every node
# sees. A second job, started once every task has succeeded, merges the
# shards into the files the unsharded sweep writes (docs/monte-carlo.md,
# "Sweeps beyond one machine"). Slurm does the scheduling; firmware-sim
# only runs its share and merges.
#
# From the repository root, on a shared file system:
#   cargo build --release -p firmware-sim
#   mkdir -p out/slurm
#   array=$(sbatch --parsable docs/examples/sweep-slurm.sh)
#   sbatch --dependency=afterok:"$array" --job-name=wmr-sweep-merge \
#       --output=out/slurm/%x-%j.log \
#       --wrap "target/release/firmware-sim sweep-merge out/sweep-shards/shard-* --out out/sweep"
#
# out/sweep then holds runs.csv, summary.json, table.md and the plots (with
# several scenarios, as here: out/sweep/<name>/ and out/sweep/table.md),
# byte for byte what `firmware-sim sweep … --out out/sweep` on one machine
# writes. A task that failed leaves its shard without shard.json; the merge
# names the missing shard, and `sbatch --array=K docs/examples/sweep-slurm.sh`
# runs that one again (N stays SHARDS below), after which merge again.
#
# SHARDS (N) must equal the number of array tasks, and --array must be
# 0-(N-1): 0-9 for the 10 shards here. A task with K ≥ N is refused by
# firmware-sim; a missing K by the merge. Each task runs one run per CPU it
# is given (--cpus-per-task) at a time.

#SBATCH --job-name=wmr-sweep
#SBATCH --array=0-9
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=4
#SBATCH --time=00:30:00
#SBATCH --output=out/slurm/%x-%A_%a.log

set -euo pipefail

# What is swept: the same in every task (a shard records it, and the merge
# refuses shards that differ).
SCENARIOS=(figure_eight_rfid figure_eight_rfid_pose_observer
           figure_eight_rfid_fusion_ekf figure_eight_rfid_full_stack)
RUNS=1000
SEED=1
SHARDS=10 # N: the number of array tasks, 0-(N-1)
SIM=${SIM:-target/release/firmware-sim}
SHARDS_DIR=${SHARDS_DIR:-out/sweep-shards}

K=${SLURM_ARRAY_TASK_ID:?submit this script with sbatch, as a job array}
exec "$SIM" sweep "${SCENARIOS[@]}" --runs "$RUNS" --seed "$SEED" \
    --threads "${SLURM_CPUS_PER_TASK:-0}" \
    --shard "$K/$SHARDS" --out "$SHARDS_DIR/shard-$K"
