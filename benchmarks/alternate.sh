#!/bin/bash
# Alternate the network and training benchmarks between another tree and this one, in one sitting:
#   benchmarks/alternate.sh BEFORE_DIR OUT_DIR [ROUNDS]
# BEFORE_DIR: a checkout of the commit to compare with (git worktree add /tmp/before COMMIT). Each round runs
# benchmarks/network.py (1 and 64 networks, each tree's own script) and this tree's benchmarks/train.py (60
# networks, both arms), one thread, on BEFORE_DIR, then on this tree, each with PYTHONPATH pointing at its own tree
# and this tree's Python; each side runs the networks as its own commands do by default (its
# jaxarm.parallel.networks_at_once: one at a time on a CPU since 2026-12-07, groups of 8 before). (A checkout whose
# network.py has no --networks-at-once times one vmap of all: copy this tree's network.py into it.)
# Writes OUT_DIR/{net,train}-{before,now}-R.json and prints the medians over the rounds and their ratio now /
# before (benchmarks/ab_summary.py, also written as OUT_DIR/summary.json).
set -euo pipefail
before=$(cd "$1" && pwd); out=$2; rounds=${3:-4}
now=$(cd "$(dirname "$0")/.." && pwd); py=${PYTHON:-$now/.venv/bin/python}
mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
  for side in before now; do
    if [ $side = before ]; then dir=$before; else dir=$now; fi
    (cd "$dir" && PYTHONPATH=$dir "$py" benchmarks/network.py --networks 1,64 --seconds 10 --repeats 3 --no-brian2 --threads 1 \
        --json > "$out/net-$side-$r.json")
    (cd "$dir" && PYTHONPATH=$dir "$py" "$now/benchmarks/train.py" --networks 60 --seconds 10 --repeats 3 --threads 1 \
        --json > "$out/train-$side-$r.json")
    echo "$side round $r done $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg)"
  done
done
# the rounds' medians and ratios: printed, and written as a result file
"$py" "$now/benchmarks/ab_summary.py" "$out" "$before" --command "benchmarks/alternate.sh $*" > "$out/summary.json"
