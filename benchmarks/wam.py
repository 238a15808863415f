"""Offline WAM simulation speed as a real-time factor (simulated seconds per wall second).

    python benchmarks/wam.py --json [--duration 20] [--repeats 5] [--mode velocity position] [--variant wam4]

Each repeat simulates ``--duration`` s of robot time (500 Hz ticks: receiver + libbarrett-like chain + MuJoCo C,
2 physics substeps) fed by the seeded stand-in trajectory (``synthetic:0``) at the paper's Gamma packet timing
(seed 0), and times only the tick loop (``SimLog.wall_s``; model compilation and packet encoding excluded). The
median over repeats is reported, with the min and max. The issue's bar: >= 10x real time on a 2-core machine.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print only the JSON result")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds per repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mode", nargs="+", default=["velocity", "position"], choices=["velocity", "position"])
    ap.add_argument("--variant", default="wam4", choices=["wam4", "wam7_wrist_locked"])
    args = ap.parse_args(argv)

    import mujoco
    import numpy as np

    from jaxarm.robot.config import ControllerConfig, PhysicsConfig, WamSimConfig
    from jaxarm.robot.exporter import load_trajectory, simulate

    traj = load_trajectory("synthetic:0")
    result = {"real_time_factor": {}, "config": vars(args) | {
        "cpu_count": os.cpu_count(), "machine": platform.machine(), "python": sys.version.split()[0],
        "mujoco": mujoco.__version__, "numpy": np.__version__, "trajectory": "synthetic:0", "seed": 0}}
    for mode in args.mode:
        cfg = WamSimConfig(controller=ControllerConfig(mode=mode), physics=PhysicsConfig(variant=args.variant))
        rtf = []
        for _ in range(args.repeats):
            log = simulate(traj, cfg, timing="jitter", seed=0, duration_s=args.duration)
            rtf.append(args.duration / log.wall_s)
        result["real_time_factor"][mode] = {"median": statistics.median(rtf), "min": min(rtf), "max": max(rtf),
                                            "ticks_per_s_median": statistics.median(rtf) * 500}
    if not args.json:
        for mode, r in result["real_time_factor"].items():
            print(f"{mode:>8}: {r['median']:.1f}x real time (min {r['min']:.1f}, max {r['max']:.1f})")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
