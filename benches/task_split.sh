#!/usr/bin/env bash
# The CPU of a conversion split into tasks against the single run of the same input, in rounds
# that interleave the two (issue 21's target: within 10 %); prints each round's ratio. Every step is timed on its own with
# /usr/bin/time (user + sys); the split's total is the plan, the tasks (run one after another,
# in shuffled order) and the finish; the datasets are compared with cmp.
#
#   benches/task_split.sh INPUT [TASKS] [ROUNDS]
#
# STRATA names the binary (default target/release/strata), WORK a scratch folder on the same
# disk as INPUT (default: beside it). FILLER, a file about as large as the machine's memory,
# is read before every step, so that the page cache is full and no step pays for a virtual
# machine's first touches of memory it freed long ago (free page reporting makes those cost a
# few microseconds a page).
set -euo pipefail
input=$(realpath "$1")
tasks=${2:-8}
rounds=${3:-3}
strata=$(realpath "${STRATA:-target/release/strata}")
work=${WORK:-$(dirname "$input")/task-split-bench}
mkdir -p "$work"
cd "$work"
times=$work/times.txt
: > "$times"
warm() {
  if [ -n "${FILLER:-}" ]; then cat "$FILLER" "$input" > /dev/null; fi
}
step() {
  local name=$1
  shift
  warm
  /usr/bin/time -f "$name %e %U %S" -a -o "$times" "$@" > /dev/null
}
for round in $(seq "$rounds"); do
  rm -rf single split plan
  # The single run before the split in odd rounds, after it in even ones: the machine's speed
  # drifts over minutes, and a pair's ratio should not lean one way.
  if [ $((round % 2)) = 1 ]; then step single "$strata" convert "$input" -o single --threads 2 -q; fi
  step plan "$strata" convert "$input" --plan-only plan --tasks "$tasks" --threads 2 -q
  for k in $(shuf -e $(seq 0 $((tasks - 1)))); do
    step "task$k" "$strata" convert --plan plan --task "$k" -q
  done
  step finish "$strata" convert --plan plan --finish -o split -q
  if [ $((round % 2)) = 0 ]; then step single "$strata" convert "$input" -o single --threads 2 -q; fi
  for f in octree.bin hierarchy.bin metadata.json; do cmp "single/$f" "split/$f"; done
  echo "round $round" >> "$times"
done
rm -rf single split plan
awk '
  $1 == "single" { single = $3 + $4; su = $3 }
  $1 != "single" && $1 != "round" { split_cpu += $3 + $4; split_user += $3 }
  $1 == "round" {
    printf "round %d: single %.1f s (user %.1f), split %.1f s (user %.1f): %+.1f %% (user %+.1f %%)\n",
      $2, single, su, split_cpu, split_user, 100 * (split_cpu / single - 1), 100 * (split_user / su - 1)
    split_cpu = 0; split_user = 0
  }' "$times"
