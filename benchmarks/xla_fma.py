"""What XLA:CPU without fused multiply-add costs (jaxarm.cpu_arithmetic): closed-loop training with and without it.

    python benchmarks/xla_fma.py --json [--rounds 3] [--networks 8] [--seconds 5]

Each round runs one fresh process per side (``JAXARM_XLA_FMA=1``: XLA keeps FMA; unset: jaxarm's default, no FMA),
alternating, so both sides see the same machine load. A process compiles one training epoch of ``--seconds`` per
arm for one group of ``--networks`` networks (original metaparameters; XLA single-threaded) and times three runs
by the process's CPU time (less sensitive than wall time to other work on a shared machine); the figure is
network-seconds per CPU-second, median of the three. Prints the medians over rounds per side and the ratio.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys

CHILD = """
import json, statistics, sys, time
import jaxarm, jax
from jaxarm.learning.metaparams import MetaParams
from jaxarm.loop import LoopConfig
from jaxarm.task.config import TaskConfig
from jaxarm.train import make_train
n, seconds = int(sys.argv[1]), float(sys.argv[2])
out = {}
for arm in ("simple", "musculoskeletal"):
    fns = make_train(LoopConfig(arm=arm, task=TaskConfig(epochs=1, epoch_duration_s=seconds)))
    mp = MetaParams.original()
    carry = jax.jit(jax.vmap(fns.init))(jax.random.split(jax.random.PRNGKey(0), n))
    epoch = jax.jit(jax.vmap(fns.epoch, in_axes=(0, None))).lower(carry, mp).compile()
    jax.block_until_ready(epoch(carry, mp))
    times = []
    for _ in range(3):
        t = time.process_time()
        jax.block_until_ready(epoch(carry, mp))
        times.append(time.process_time() - t)
    out[arm] = n * seconds / statistics.median(times)
print(json.dumps(out))
"""


def run(keep_fma: bool, networks: int, seconds: float) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "JAXARM_XLA_FMA"}
    env["XLA_FLAGS"] = "--xla_cpu_multi_thread_eigen=false"
    if keep_fma:
        env["JAXARM_XLA_FMA"] = "1"
    proc = subprocess.run([sys.executable, "-c", CHILD, str(networks), str(seconds)], capture_output=True, text=True,
                          env=env, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--networks", type=int, default=8, help="one group (jaxarm.parallel.CPU_NETWORKS_AT_ONCE)")
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per epoch, s")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    sides = {"fma": [], "no_fma": []}
    for _ in range(args.rounds):
        sides["fma"].append(run(True, args.networks, args.seconds))
        sides["no_fma"].append(run(False, args.networks, args.seconds))
    result = {"command": "python benchmarks/xla_fma.py --json " + " ".join(sys.argv[1:]).replace("--json", "").strip(),
              "date": datetime.date.today().isoformat(),
              "machine": f"{platform.machine()}, {os.cpu_count()} cores",
              "network_s_per_cpu_s": {}, "no_fma_over_fma": {}}
    for arm in ("simple", "musculoskeletal"):
        med = {side: statistics.median(r[arm] for r in runs) for side, runs in sides.items()}
        result["network_s_per_cpu_s"][arm] = {side: round(v, 2) for side, v in med.items()}
        result["no_fma_over_fma"][arm] = round(med["no_fma"] / med["fma"], 3)
    result["rounds"] = sides
    print(json.dumps(result, indent=1) if args.json else
          "\n".join(f"{arm}: no FMA / FMA = {r}" for arm, r in result["no_fma_over_fma"].items()))


if __name__ == "__main__":
    main()
