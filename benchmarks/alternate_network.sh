#!/bin/bash
# The network alone, another tree against this one, alternated in one sitting (lighter than alternate.sh, which
# also times training):
#   benchmarks/alternate_network.sh BEFORE_DIR [ROUNDS]   # BEFORE_DIR: git worktree add /tmp/before COMMIT
# Each round runs benchmarks/network.py's worker (1 and 64 networks, 3 timed runs, one thread) in fresh processes,
# BEFORE_DIR first; prints "ROUND SIDE NETWORKS NETWORK-S/S" lines (the median of the 3 runs each).
set -euo pipefail
before=$(cd "$1" && pwd); rounds=${2:-4}
now=$(cd "$(dirname "$0")/.." && pwd); py=${PYTHON:-$now/.venv/bin/python}
for r in $(seq 1 "$rounds"); do
  for side in before now; do
    if [ $side = before ]; then dir=$before; else dir=$now; fi
    for n in 1 64; do
      v=$(cd "$dir" && PYTHONPATH=$dir "$py" benchmarks/network.py --worker $n --repeats 3 --threads 1 | tail -1 |
          "$py" -c "import json, sys; print(json.loads(sys.stdin.read())['network_s_per_s'])")
      echo "$r $side $n $v"
    done
  done
done
