"""Eight-target centre-out reaching from one network (issue 32 item 4): the paper's network plus a plastic target
code, trained with the eight targets alternating epoch by epoch, tested on every target; beside it the control,
the paper's network without the target code, trained and tested the same way.

    python experiments/centre_out.py [--arm simple] [--networks 30] [--epochs-per-target 3] [--seed 0]
                                     [--preset NAME] [--conditions target-code,control] [--out runs/centre-out]

Every condition trains ``--networks`` networks (seeds SEED .. SEED + n - 1) in one batch (the native kernel's
threads over every core), epoch e toward target e % 8 (``jaxarm.task.centre_out``), then tests each network on
all eight targets (1 s, no learning), and each untrained network the same way (naive). Prints the success count
per target and the distribution of targets reached per network, and writes OUT/centre_out.json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np


def run_condition(name, args, mp):
    from jaxarm.config.network import NetworkConfig
    from jaxarm.config.spec import NetworkSpec
    from jaxarm.loop import LoopConfig
    from jaxarm.task.centre_out import CentreOut, train_and_test, with_target_code

    task = CentreOut(epochs_per_target=args.epochs_per_target, epoch_duration_s=args.epoch_s)
    spec = NetworkSpec.dura_bernal_2015()
    if name == "target-code":
        spec = with_target_code(spec, task, cells_per_target=args.cells_per_target, rate_hz=args.code_rate_hz,
                                posts=tuple(args.code_posts.split(",")), pmat=args.code_pmat,
                                weight_mv=args.code_weight_mv)
    net = NetworkConfig(spec=spec, native_threads=os.cpu_count() or 1)
    t0 = time.perf_counter()
    r = train_and_test(LoopConfig(arm=args.arm, network=net, task=task.task_config()), task,
                       range(args.seed, args.seed + args.networks), mp)
    for k in ("trained", "naive"):
        r[k].pop("hand_m")
    return {"condition": name, **r, "network_seconds": args.networks * task.task_config().epochs * args.epoch_s,
            "wall_s": round(time.perf_counter() - t0, 1)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--networks", type=int, default=30)
    ap.add_argument("--epochs-per-target", type=int, default=3)
    ap.add_argument("--epoch-s", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="original", help="metaparameters (jaxarm reproduce --list-presets)")
    ap.add_argument("--conditions", default="target-code,control")
    ap.add_argument("--cells-per-target", type=int, default=8)
    ap.add_argument("--code-rate-hz", type=float, default=100.0)
    ap.add_argument("--code-posts", default="EM", help="populations the target code projects to (comma-separated)")
    ap.add_argument("--code-pmat", type=float, default=0.2)
    ap.add_argument("--code-weight-mv", type=float, default=2.0)
    ap.add_argument("--out", type=Path, default=Path("runs/centre-out"))
    args = ap.parse_args(argv)

    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.paper import presets

    mp = MetaParams.from_dict(presets.load(args.preset).best) if args.preset != "original" else MetaParams.original()
    args.out.mkdir(parents=True, exist_ok=True)
    out = {"command": "python experiments/centre_out.py " + " ".join(argv or __import__("sys").argv[1:]),
           "date": datetime.now(timezone.utc).strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, "
           f"{os.cpu_count()} cores", "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"],
                                                               capture_output=True, text=True).stdout.strip(),
           "config": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()}, "conditions": {}}
    for name in args.conditions.split(","):
        r = run_condition(name, args, mp)
        out["conditions"][name] = r
        (args.out / "centre_out.json").write_text(json.dumps(out, indent=1))
        print(f"{name}: trained and tested in {r['wall_s']} s ({r['network_seconds']:g} network-s); lost spikes "
              f"{r['lost_spikes']}")
    conds = list(out["conditions"].values())
    print(f"\n| target (direction) | " + " | ".join(f"{c['condition']}: trained (naive)" for c in conds) + " |")
    print("|---|" + "---|" * len(conds))
    for k, t in enumerate(conds[0]["targets"]):
        cells = [f"{c['trained']['per_target'][t]}/{args.networks} ({c['naive']['per_target'][t]}/{args.networks})"
                 for c in conds]
        print(f"| {t} ({conds[0]['directions_deg'][k]:g} deg) | " + " | ".join(cells) + " |")
    for c in conds:
        print(f"{c['condition']}: networks by number of targets reached (0..8): "
              f"{c['trained']['targets_reached_per_network']} (naive {c['naive']['targets_reached_per_network']})")
    print("->", args.out / "centre_out.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
