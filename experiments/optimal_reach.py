"""The best reaches the musculoskeletal arm can make: optimal-control references for the paper's two targets.

    python experiments/optimal_reach.py [--targets left bottom] [--iterations 300] [--out runs/optimal-reach]

For each target and each cost of :mod:`jaxarm.control.optimal_reach` (min-effort, min-time): optimise the four
muscle-group excitations over 1 s through the smooth arm, then report the reach metrics of the paper's definitions
(``jaxarm.analysis.reach_metrics`` at the closed loop's 10 ms sampling, 4 cm success circle), the peak speed, the
dimensionless jerk (``jaxarm.analysis.dimensionless_jerk`` at 10 ms) and the peak muscle force, and save
``optimal_reach.png`` (paths, speed profiles, excitations) and ``optimal_reach.json`` (the table and the paths).
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from jaxarm.analysis import dimensionless_jerk, reach_metrics
from jaxarm.control.optimal_reach import COSTS, OptimalReachConfig, make_optimal_reach
from jaxarm.task.config import Target

SAMPLE_S = 0.01  # the closed loop's reach metrics sample the hand every 10 ms


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--targets", nargs="+", default=["left", "bottom"])
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--out", type=Path, default=Path("runs/optimal-reach"))
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows, paths = [], {}
    for cost in COSTS:
        reach = make_optimal_reach(replace(OptimalReachConfig(cost=cost), iterations=args.iterations))
        for target in args.targets:   # one compiled program per cost; the target is traced
            xy = Target.named(target).xy_m
            t0 = time.perf_counter()
            r = reach(xy)
            wall = time.perf_counter() - t0
            every = int(round(SAMPLE_S / r.dt_s))
            hand = np.concatenate([[r.hand_m[0]], r.hand_m[every - 1::every]])
            m = reach_metrics(hand, xy, SAMPLE_S)
            speed = np.linalg.norm(np.diff(hand, axis=0), axis=-1) / SAMPLE_S
            row = {"target": target, "cost": cost, "final_loss": float(r.loss[-1]), "first_loss": float(r.loss[0]),
                   "final_distance_cm": 100 * float(m.final_distance_m), "min_distance_cm": 100 * float(m.min_distance_m),
                   "first_entry_ms": 1000 * float(m.first_entry_s), "time_inside_ms": 1000 * float(m.time_inside_s),
                   "peak_speed_m_s": float(speed.max()), "speed_after_m_s": float(m.speed_after_m_s),
                   "distance_after_cm": 100 * float(m.distance_after_m),
                   "dimensionless_jerk": float(dimensionless_jerk(hand, SAMPLE_S)),
                   "peak_force_n": float(r.muscle_force_n.max()), "mean_excitation": float(r.excitations.mean()),
                   "wall_s": round(wall, 1)}
            rows.append(row)
            paths[f"{target}/{cost}"] = {"hand_m": hand.tolist(), "excitations": r.excitations[::every].tolist(),
                                          "loss": r.loss.tolist()}
            print(json.dumps(row))
    meta = {"command": "python experiments/optimal_reach.py " + " ".join(argv or []),
            "date": datetime.now(timezone.utc).isoformat(timespec="minutes"), "machine": platform.platform(),
            "iterations": args.iterations}
    (args.out / "optimal_reach.json").write_text(json.dumps({"meta": meta, "rows": rows, "paths": paths}))
    _figure(paths, args.targets, args.out / "optimal_reach.png")
    return 0


def _figure(paths, targets, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for target in targets:
        xy = Target.named(target).xy_m
        axes[0].add_patch(plt.Circle(xy, 0.04, fill=False, ls="--", color="grey"))
        for cost, ls in zip(COSTS, ("-", ":")):
            p = paths[f"{target}/{cost}"]
            hand = np.asarray(p["hand_m"])
            axes[0].plot(hand[:, 0], hand[:, 1], ls, label=f"{target}, {cost}")
            t = np.arange(len(hand) - 1) * SAMPLE_S
            axes[1].plot(t, np.linalg.norm(np.diff(hand, axis=0), axis=-1) / SAMPLE_S, ls, label=f"{target}, {cost}")
            if cost == "min-effort":
                u = np.asarray(p["excitations"])
                for g, name in enumerate(("sh-ext", "sh-flex", "el-ext", "el-flex")):
                    axes[2].plot(np.arange(len(u)) * SAMPLE_S, u[:, g], label=f"{target} {name}")
    axes[0].set(xlabel="x (m)", ylabel="y (m)", title="hand paths", aspect="equal")
    axes[1].set(xlabel="time (s)", ylabel="hand speed (m/s)", title="speed")
    axes[2].set(xlabel="time (s)", ylabel="excitation", title="min-effort excitations")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    raise SystemExit(main())
