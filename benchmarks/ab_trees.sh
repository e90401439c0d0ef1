#!/usr/bin/env bash
# Interleaved A/B timing of two commits with benchmarks/peers.py, each run on its own worktree:
#     bash benchmarks/ab_trees.sh BEFORE_REV AFTER_REV [PAIRS]      (default 6 pairs)
# Prints each run's helpers/GTSAM lines and ratios; alternating the trees spreads machine load over both.
set -euo pipefail
before=${1:?before revision}; after=${2:?after revision}; pairs=${3:-6}
repo=$(git rev-parse --show-toplevel)
py="$repo/.venv/bin/python"
work=$(mktemp -d)
trap 'git -C "$repo" worktree remove --force "$work/before"; git -C "$repo" worktree remove --force "$work/after"; rm -rf "$work"' EXIT
git -C "$repo" worktree add -q --detach "$work/before" "$before"
git -C "$repo" worktree add -q --detach "$work/after" "$after"
for i in $(seq "$pairs"); do
  for t in before after; do
    echo "### $t $i $(date +%T) load $(cut -d' ' -f1 /proc/loadavg 2>/dev/null || echo ?)"
    (cd "$work/$t" && PYTHONPATH="$work/$t" OPENBLAS_NUM_THREADS=1 "$py" benchmarks/peers.py 2>&1 |
       grep -E "^==|^helpers|^GTSAM|^ratios")
  done
done
