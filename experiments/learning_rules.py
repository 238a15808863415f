"""The registered learning rules on one task and budget (issue 47): docs/extending.md's table.

    python experiments/learning_rules.py [--networks 8] [--seed 0] [--budgets 60 360] [--out runs/learning-rules]
                                         [--json docs/results/learning_rules.json]

Each (rule, budget) is ``jaxarm train --learning RULE`` on the simple arm and the left target with the authors'
metaparameters, ``--networks`` networks of seeds seed.., BUDGET network-seconds of training per network in 30 s
epochs (gradient learning: 1 s reaches, one Adam step each), checkpointed in OUT/RULE-BUDGET (a rerun resumes). A
seed gives the same wiring and background noise under every rule. ``--skip RULE-BUDGET`` leaves a condition out
(gradient learning costs about 100 times an R-STDP network-second). The JSON holds, per condition, the networks
whose 1 s test entered the 4 cm circle, the naive ones, the median closest approach and the training's wall time.
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

RULES = ("rstdp", "gradient", "weight-perturbation")


def condition_command(rule: str, budget_s: int, args, out: Path) -> list[str]:
    if budget_s % 30:
        raise SystemExit(f"--budgets {budget_s}: must be a multiple of the 30 s epoch")
    return [sys.executable, "-m", "jaxarm.cli", "train", "--learning", rule, "--arm", "simple", "--target", "left",
            "--networks", str(args.networks), "--seed", str(args.seed), "--epochs", str(budget_s // 30),
            "--epoch-s", "30", "--no-progress", "--out", str(out)]


def summary(out: Path, budget_s: int, wall_s: float) -> dict:
    res = json.loads((out / "results.json").read_text())
    n = res["n_networks"]
    closest_cm = [100 * net["min_distance_m"] for net in res["networks"]]
    return {"budget_s": budget_s, "reached": res["success_count"], "reached_n": n,
            "naive": res["naive"]["success_count"], "naive_n": n,
            "median_closest_cm": round(float(np.median(closest_cm)), 1),
            "training_wall_s": res["timing"]["train_wall_s_this_invocation"],
            "network_s_per_s": res["timing"]["network_s_per_s"], "command_wall_s": round(wall_s, 1)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--budgets", type=int, nargs="+", default=[60, 360], help="network-seconds of training")
    ap.add_argument("--skip", nargs="*", default=[], metavar="RULE-BUDGET")
    ap.add_argument("--out", type=Path, default=Path("runs/learning-rules"))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = {}
    for budget in args.budgets:
        for rule in RULES:
            name = f"{rule}-{budget}"
            if name in args.skip:
                continue
            out = args.out / name
            cmd = condition_command(rule, budget, args, out)
            print(" ".join(cmd[2:]), flush=True)
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True)
            rows[name] = {"rule": rule} | summary(out, budget, time.perf_counter() - t0)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    report = {"command": "python experiments/learning_rules.py " + " ".join(argv if argv is not None else sys.argv[1:]),
              "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {len(os.sched_getaffinity(0))} cores",
              "commit": commit, "seeds": f"{args.seed}-{args.seed + args.networks - 1}",
              "task": "simple arm, left target, the authors' metaparameters, 1 s test, 4 cm circle",
              "conditions": rows}
    print(json.dumps(report, indent=1))
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
