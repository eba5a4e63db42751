#!/usr/bin/env bash
# Submits a Strata conversion to Slurm as three dependent jobs: the plan, an array of TASKS
# tasks that starts once the plan succeeded, and the finish once every task succeeded.
#
#   deploy/slurm/submit.sh PLAN DATASET TASKS INPUT...
#
# Environment: STRATA (the strata binary, default `strata` on PATH), STRATA_OPTS (convert
# options such as "--threads 8 --memory-limit 16GiB --normals"), SBATCH_OPTS (given to every
# sbatch, e.g. "--partition=batch --time=2:00:00"), LOG_DIR (job output, default .).
# Prints the three job ids. Give each task as many CPUs as the plan's --threads
# (e.g. SBATCH_OPTS="--cpus-per-task=8" with STRATA_OPTS="--threads 8").
set -euo pipefail
if [ $# -lt 4 ]; then
  echo "usage: $0 PLAN DATASET TASKS INPUT..." >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
abs() { case "$1" in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
export PLAN=$(abs "$1") DATASET=$(abs "$2") TASKS=$3
shift 3
inputs=()
for i in "$@"; do inputs+=("$(abs "$i")"); done
export INPUTS="${inputs[*]}"
export STRATA=${STRATA:-strata} STRATA_OPTS=${STRATA_OPTS:-}
logs=$(abs "${LOG_DIR:-.}")
read -ra extra <<< "${SBATCH_OPTS:-}"
submit() { sbatch --parsable --export=ALL "${extra[@]}" "$@" | cut -d';' -f1; }
plan=$(submit --job-name=strata-plan --output="$logs/strata-plan-%j.out" "$here/convert.sbatch" plan)
tasks=$(submit --job-name=strata-task --dependency="afterok:$plan" --array="0-$((TASKS - 1))" \
  --output="$logs/strata-task-%A_%a.out" "$here/convert.sbatch" task)
finish=$(submit --job-name=strata-finish --dependency="afterok:$tasks" \
  --output="$logs/strata-finish-%j.out" "$here/convert.sbatch" finish)
echo "$plan $tasks $finish"
