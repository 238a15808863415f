"""How often the critic acts, and how fast the hand moves, in finished `jaxarm train` runs.

The critic rewards or punishes when the hand got at least 1 mm closer or farther over the last 10 ms (spec §4), so
an arm whose hand moves >= 1 mm per 10 ms more often drives the (asymmetric, soft-bounded) learning rule more often.
This compares runs, e.g. the simple and the musculoskeletal arm under the same network and metaparameters:

    python experiments/critic_activity.py runs/simple_left runs/ms_left

For each run folder (a `jaxarm train --out` folder with results.json and trajectories.npz) it prints:
* the fraction of 10 ms test intervals, after the readout starts (t >= 130 ms), in which the hand moved >= 1 mm,
  for the naive and the trained networks, and the median displacement per interval (mm);
* the critic's rewards and punishments per network per epoch, as a fraction of the critic updates of an epoch
  (one per 60 ms with the original rl_dt).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

CRITIC_THRESHOLD_M = 0.001
READOUT_START_INTERVAL = 13   # t = 130 ms: the readout window (t-130, t-60] is full


def displacement_stats(hand_m) -> dict:
    """hand_m (networks, T + 1, 2) at 10 ms intervals -> fraction of steps >= 1 mm and the median step, mm."""
    steps = np.linalg.norm(np.diff(np.asarray(hand_m), axis=1), axis=-1)[:, READOUT_START_INTERVAL:]
    return {"fraction_steps_ge_1mm": float(np.mean(steps >= CRITIC_THRESHOLD_M)),
            "median_step_mm": float(np.median(steps) * 1000.0)}


def summarize(run_dir: Path) -> dict:
    results = json.loads((run_dir / "results.json").read_text())
    traj = np.load(run_dir / "trajectories.npz")
    out = {"run": str(run_dir), "arm": results.get("config", {}).get("arm"),
           "trained": displacement_stats(traj["hand"])}
    if "naive_hand" in traj:
        out["naive"] = displacement_stats(traj["naive_hand"])
    history = results.get("history", {})
    n = results.get("n_networks") or len(results.get("networks", []))
    epoch_s = float(results.get("config", {}).get("epoch_s", 30.0))
    rl_dt = float(results.get("config", {}).get("metaparams", {}).get("rl_dt_ms", 55.55))
    updates = epoch_s * 1000.0 / (10.0 * np.floor(rl_dt / 10.0 + 1.0))   # checked every 10 ms: t - last > rl_dt
    if "rewards" in history and n:
        r = np.asarray(history["rewards"], float) / n
        p = np.asarray(history["punishments"], float) / n
        out["critic_updates_per_epoch"] = updates
        out["critic_acts_fraction_per_epoch"] = ((r + p) / updates).round(3).tolist()
        out["reward_share_per_epoch"] = (r / np.maximum(r + p, 1)).round(3).tolist()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="`jaxarm train --out` folders")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    rows = [summarize(r) for r in args.runs]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    for row in rows:
        print(f"{row['run']} ({row['arm']})")
        for which in ("naive", "trained"):
            if which in row:
                s = row[which]
                print(f"  {which:8} test: hand moved >= 1 mm in {100 * s['fraction_steps_ge_1mm']:.1f} % of 10 ms "
                      f"intervals; median {s['median_step_mm']:.2f} mm")
        if "critic_acts_fraction_per_epoch" in row:
            acts = row["critic_acts_fraction_per_epoch"]
            print(f"  critic acted at {100 * acts[0]:.0f} % of updates in epoch 1, {100 * acts[-1]:.0f} % in the last "
                  f"(of {row['critic_updates_per_epoch']:.0f} per epoch); reward share epoch 1 "
                  f"{100 * row['reward_share_per_epoch'][0]:.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
