"""Gradient learning beside R-STDP on the paper's task: the same networks (seeds), arm, targets and test (issue 30
item 3).

    python experiments/gradient_vs_rstdp.py [--arm simple] [--networks 8] [--seed 0] [--out runs/gradient-vs-rstdp]
                                            [--conditions rstdp-360 rstdp-30 gradient-30]

Each condition is one ``jaxarm train`` command (printed; checkpointed in OUT/<condition>, so a rerun resumes) on
both paper targets, then ``jaxarm test --from ... --fresh-noise 0``: the trained networks re-tested on background
noise streams neither learner trained on (both restart the network's own stream for every epoch, reach and test,
as the original does). Conditions: ``rstdp-N`` = R-STDP with babbling, the authors' metaparameters, N s of
training in 30 s epochs (360 = the paper's 12 epochs); ``gradient-N`` = Adam on the mean hand-target distance of
1 s reaches (N reaches, N network-seconds). The table (OUT/table.md, numbers in OUT/table.json) gives per
condition and target: success (4 cm circle) on the training stream and on a fresh one, median closest approach,
median time of first entry and distance after entry over the networks that entered, and the training wall time
with its network-seconds per second (this machine, this run).
"""
from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

TARGETS = ("left", "bottom")


def command(condition: str, args, out: Path) -> list[str]:
    kind, seconds = condition.rsplit("-", 1)
    seconds = int(seconds)
    cmd = [sys.executable, "-m", "jaxarm.cli", "train", "--arm", args.arm, "--target", *TARGETS,
           "--networks", str(args.networks), "--seed", str(args.seed), "--out", str(out), "--no-progress"]
    if kind == "rstdp":
        if seconds % 30:
            raise SystemExit(f"{condition}: R-STDP trains in 30 s epochs")
        return cmd + ["--epochs", str(seconds // 30), "--epoch-s", "30"]
    if kind == "gradient":
        epoch_s = 30 if seconds % 30 == 0 else seconds
        return cmd + ["--learning", "gradient", "--epochs", str(seconds // epoch_s), "--epoch-s", str(epoch_s)]
    raise SystemExit(f"unknown condition {condition!r}: rstdp-N or gradient-N")


def summarise(res: dict) -> dict:
    rows = res["networks"]
    entered = [r for r in rows if r["success"]]

    def median(key, subset):
        vals = [r[key] for r in subset if r.get(key) is not None]
        return float(np.median(vals)) if vals else None

    return {"success": res["success_count"], "n": res["n_networks"],
            "min_distance_cm": 100 * median("min_distance_m", rows),
            "first_entry_s": median("first_entry_s", entered),
            "distance_after_cm": None if median("distance_after_m", entered) is None
            else 100 * median("distance_after_m", entered),
            "train_wall_s": res["timing"]["train_wall_s_this_invocation"],
            "network_s_per_s": res["timing"]["network_s_per_s"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--networks", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--conditions", nargs="+", default=["rstdp-360", "rstdp-30", "gradient-30"])
    ap.add_argument("--out", type=Path, default=Path("runs/gradient-vs-rstdp"))
    args = ap.parse_args(argv)
    table = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {platform.node()}",
             "arm": args.arm, "networks": args.networks, "seed": args.seed, "conditions": {}}
    for condition in args.conditions:
        out = args.out / args.arm / condition
        cmd = command(condition, args, out)
        print("$", " ".join(cmd[2:]).replace("jaxarm.cli", "jaxarm"), flush=True)
        subprocess.run(cmd, check=True)
        rows = {}
        for target in TARGETS:
            fresh = out / target / "fresh-noise"
            subprocess.run([sys.executable, "-m", "jaxarm.cli", "test", "--from", str(out / target), "--out",
                            str(fresh), "--fresh-noise", "0"], check=True, stdout=subprocess.DEVNULL)
            trained = summarise(json.loads((out / target / "results.json").read_text()))
            trained["naive_success"] = json.loads((out / target / "results.json").read_text())["naive"]["success_count"]
            trained["fresh_noise_success"] = json.loads((fresh / "results.json").read_text())["success_count"]
            rows[target] = trained
        table["conditions"][condition] = {"command": " ".join(cmd[2:]).replace("jaxarm.cli", "jaxarm"),
                                          "targets": rows}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"table_{args.arm}.json").write_text(json.dumps(table, indent=1))
    fmt = lambda x, d=1: "–" if x is None else f"{x:.{d}f}"  # noqa: E731
    lines = ["| learning | target | reached (training noise) | reached (fresh noise) | naive | median closest (cm) | "
             "median first entry (s) | median distance after entry (cm) | training wall (s) | network-s/s |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for condition, c in table["conditions"].items():
        for target, r in c["targets"].items():
            lines.append(f"| {condition} | {target} | {r['success']}/{r['n']} | {r['fresh_noise_success']}/{r['n']} | "
                         f"{r['naive_success']}/{r['n']} | {fmt(r['min_distance_cm'])} | {fmt(r['first_entry_s'], 2)} | "
                         f"{fmt(r['distance_after_cm'])} | {fmt(r['train_wall_s'], 0)} | {fmt(r['network_s_per_s'], 2)} |")
    (args.out / f"table_{args.arm}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
