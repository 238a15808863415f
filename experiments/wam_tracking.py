"""Offline reproduction of the paper's robot tracking numbers (§3.3, Figs. 9-10) with the simulated WAM.

    python experiments/wam_tracking.py [--seeds 0 1 2] [--duration 50] [--figures DIR] [--k K]

For each seed s: the stand-in trajectory ``synthetic:s`` (jaxarm.robot.synthetic: seeded minimum-jerk reach chain
in the task's joint ranges, scaled to the paper-implied 1947 deg / 1450 deg total displacement; a stand-in until
trained network trajectories exist) is exported offline with the Gamma packet timing (jitter seed s) to the
default simulated WAM (PosToVel K from jaxarm.robot.config, libbarrett wam4 jv chain, 500 Hz) for ``--duration``
s of robot time. Prints one JSON object: per-seed metrics, their mean, the paper's values, the ratio to the paper
and whether each is within 25 %, and the delay beside the paper's 312 ms with the explanation (wam.md §6).
"""
from __future__ import annotations

import argparse
import json
import statistics
from dataclasses import replace
from pathlib import Path

import numpy as np

from jaxarm.robot.config import ControllerConfig, WamSimConfig
from jaxarm.robot.exporter import load_trajectory, simulate
from jaxarm.robot.metrics import PAPER, tracking_report

DELAY_NOTE = (
    "The paper's 312 ms (SD 127.64 ms) delay cannot go with its 1.85 deg / 1.74 deg mean errors: a robot that were "
    "a perfect copy of the target 312 ms late would already have the mean error given in "
    "error_if_pure_312ms_lag_deg (computed on these trajectories; wam.md §6 found ~10 deg). The same controller "
    "that reproduces the errors lags by tens of ms. Unverified guesses for the paper's number: a per-window average, "
    "or a lag counted in samples of another period (312 ms / 15.09 ms = 20.7 packets; 20.7 x 2 ms = 41 ms, close to "
    "the lag here). We report the whole-signal and windowed argmax-correlation lags as measured.")


def run_seed(seed: int, duration_s: float, config: WamSimConfig) -> dict:
    log = simulate(load_trajectory(f"synthetic:{seed}"), config, timing="jitter", seed=seed, duration_s=duration_s)
    cols = log.columns()
    r = tracking_report(cols)
    r.pop("paper")
    # The error a pure 312 ms delay alone would cause: the target against itself 156 ticks later.
    lag = int(round(0.312 / 0.002))
    r["error_if_pure_312ms_lag_deg"] = {
        j: float(np.degrees(np.abs(cols[f"target_{j}"][lag:] - cols[f"target_{j}"][:-lag])).mean())
        for j in ("shoulder", "elbow")}
    r["real_time_factor"] = log.summary()["real_time_factor"]
    return r, log


def summarise(per_seed: list[dict]) -> dict:
    def mean(path):
        vals = []
        for r in per_seed:
            v = r
            for key in path:
                v = v[key]
            vals.append(v)
        return statistics.fmean(vals)

    out = {}
    for metric in ("mean_abs_error_deg", "sd_abs_error_deg", "error_over_displacement"):
        out[metric] = {}
        for joint in ("shoulder", "elbow"):
            ours, paper = mean((metric, joint)), PAPER[metric][joint]
            out[metric][joint] = {"ours": ours, "paper": paper, "ratio": ours / paper,
                                  "within_25_percent": abs(ours / paper - 1) <= 0.25}
    out["delay_ms"] = {
        "paper": PAPER["delay_ms"],
        "whole_signal": {j: mean(("delay_ms", "whole_signal", j)) for j in ("shoulder", "elbow")},
        "windowed_5s": {j: {"mean": mean(("delay_ms", "windowed", j, "mean")),
                            "sd": mean(("delay_ms", "windowed", j, "sd"))} for j in ("shoulder", "elbow")},
        "error_if_pure_312ms_lag_deg": {j: mean(("error_if_pure_312ms_lag_deg", j)) for j in ("shoulder", "elbow")},
        "note": DELAY_NOTE,
    }
    out["packet_interval_ms"] = {"ours": {k: mean(("packet_intervals", k)) for k in ("mean_ms", "sd_ms", "max_ms",
                                                                                     "p2_5_ms", "p97_5_ms")},
                                 "paper": PAPER["packet_interval_ms"]}
    out["samples"] = {"virtual": mean(("samples", "virtual")), "robot": mean(("samples", "robot")),
                      "paper_fig10": {"virtual": 3297, "robot": 24997}}
    out["dimensionless_jerk"] = {k: mean(("dimensionless_jerk", k)) for k in ("virtual", "robot")}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--duration", type=float, default=50.0, help="robot seconds (paper: 50)")
    ap.add_argument("--k", type=float, default=None, help="PosToVel gain, 1/s (default: the calibrated one)")
    ap.add_argument("--figures", type=Path, default=None, help="write Fig. 9/10-style PNGs of the first seed here")
    args = ap.parse_args(argv)
    config = WamSimConfig()
    if args.k is not None:
        config = replace(config, controller=replace(ControllerConfig(), pos_to_vel_gain_per_s=args.k))
    per_seed = []
    for i, seed in enumerate(args.seeds):
        r, log = run_seed(seed, args.duration, config)
        per_seed.append(r)
        if args.figures and i == 0:
            from jaxarm.robot.figures import fig9_hand_xy, fig10_jerk

            fig9_hand_xy(log.columns(), args.figures / "wam_fig9_hand_xy.png",
                         title=f"synthetic:{seed} stand-in trajectory, simulated WAM")
            fig10_jerk(log.columns(), args.figures / "wam_fig10_jerk.png")
    result = {
        "command": "python experiments/wam_tracking.py " + " ".join(argv if argv is not None else []),
        "trajectory": "synthetic:SEED (stand-in until trained network trajectories exist)",
        "seeds": args.seeds, "duration_s": args.duration,
        "pos_to_vel_gain_per_s": config.controller.pos_to_vel_gain_per_s,
        "summary": summarise(per_seed), "per_seed": per_seed,
    }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    import sys

    raise SystemExit(main(sys.argv[1:]))
