"""What a coarser clock buys: the network alone (benchmarks/network.py's worker: training drive, plasticity
bookkeeping, one native thread) at each (dt, same_step_inhibition) setting, the settings alternated round by round
in fresh processes so drifts in the machine's speed fall on all alike; medians over rounds, ratios to the default.

    python benchmarks/clock_step.py --json-out docs/results/clock_step_speed.json   # ~7 min on the 2-core machine

The accuracy of each setting (rates against a 0.05 ms clock) is experiments/dt_ablation.py's.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SETTINGS = (("0.25", "end_of_step"), ("0.25", "random_order"), ("0.5", "end_of_step"), ("0.5", "random_order"))


def label(dt: str, rule: str) -> str:
    """A setting's key in the result file, without dots (the docs' placeholders split paths at dots)."""
    return f"{round(float(dt) * 1000)} us {rule}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", default="1,64", help="comma-separated network counts")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per process (their median)")
    ap.add_argument("--json-out", default=None)
    args = ap.parse_args(argv)
    counts = [int(x) for x in args.networks.split(",")]
    t0 = time.perf_counter()
    runs: dict[str, dict[str, list[float]]] = {label(dt, rule): {str(n): [] for n in counts} for dt, rule in SETTINGS}
    for r in range(args.rounds):
        for dt, rule in SETTINGS:
            for n in counts:
                cmd = [sys.executable, str(HERE / "network.py"), "--worker", str(n), "--repeats", str(args.repeats),
                       "--dt", dt, "--same-step-inhibition", rule, "--threads", "1"]
                out = json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True)
                                 .stdout.strip().splitlines()[-1])
                runs[label(dt, rule)][str(n)].append(out["network_s_per_s"])
                print(f"round {r}: dt {dt} ms, {rule:12s}, {n:3d} networks: {out['network_s_per_s']:7.1f} "
                      "network-s/s", flush=True)
    default = label(*SETTINGS[0])
    median = {k: {n: float(np.median(v)) for n, v in per.items()} for k, per in runs.items()}
    result = {
        "command": "python benchmarks/clock_step.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {len(os.sched_getaffinity(0))} CPUs",
        "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                 cwd=HERE).stdout.strip(),
        "network_s_per_s_median": median,
        "over_default": {k: {n: round(v / median[default][n], 3) for n, v in per.items()} for k, per in median.items()},
        "rounds": runs, "wall_s": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(result["over_default"], indent=1))
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
