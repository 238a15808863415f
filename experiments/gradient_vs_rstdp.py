"""Gradient learning beside R-STDP on the paper's task: the same networks (seeds), arm, targets and test, scored on
held-out noise (issue 46 item 3).

    python experiments/gradient_vs_rstdp.py [--arm simple] [--networks 30] [--seed 0] [--out runs/gradient-vs-rstdp]
                                            [--conditions rstdp-360 rstdp-preset gradient-30]

Each condition is ``jaxarm train --test-each-epoch`` (commands printed; checkpointed in OUT/ARM/<condition>, so a
rerun resumes) on both paper targets: after every epoch each network is tested twice, on its own noise stream (the
one R-STDP trains on; the original tests on it) and on a held-out stream no rule trains on (the key folded with
1000, what ``jaxarm test --fresh-noise 0`` tests; gradient learning's training reaches draw from a domain of their
own). Conditions: ``rstdp-N`` = R-STDP with babbling, the authors' metaparameters, N s of training in 30 s epochs
(360 = the paper's 12 epochs; its curve's first epoch is the 30 s condition); ``rstdp-preset`` = R-STDP with the
metaparameters and epochs of the arm's headline preset for each target (what ``jaxarm reproduce --arm ARM`` trains
in its mode (a); same seeds); ``gradient-N`` = Adam on the mean hand-target distance of 1 s reaches (N reaches, N
network-seconds) in epochs of 5 s, so its curve has a point every 5 s. The table (OUT/table_ARM.md, numbers in
OUT/table_ARM.json) gives per condition and target, on held-out noise: successes (4 cm circle) at the end, the best
epoch's successes and its training time, median closest approach at the end, network-seconds of training until a
network's held-out test first succeeded (median over those that got there); then the end's successes on the
training stream, the naive count, median first entry and distance after entry over the networks that entered and
the median dimensionless jerk of the trained paths (Fig. 7's measure; all three on the training stream), and the
training wall time with its network-seconds per second (this machine, this run). OUT/curves_ARM.png: networks
reaching on held-out noise after every epoch against the network-seconds trained, per target and condition.
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

TARGETS = ("left", "bottom")


def preset_commands(args, out: Path) -> dict[str, list[str]]:
    """target -> the ``jaxarm train`` command of what ``jaxarm reproduce --arm ARM`` trains in its mode (a) for that
    target (``reproduction_plan``: the headline preset's best set with the protocol's ``--set``, and the
    protocol's epochs), its metaparameters passed as ``--set``."""
    from jaxarm.paper import presets
    from jaxarm.paper.reproduce import reproduction_plan

    plan = reproduction_plan(None, args.arm, list(TARGETS), None, 1, {}, presets.PRESET_DIR)
    cmds = {}
    for target in TARGETS:
        step = plan[target]["seeds"]
        sets = [f"--set={k}={float(v)!r}" for k, v in step["sets"][0].to_dict().items() if k != "epochs"]
        cmds[target] = [sys.executable, "-m", "jaxarm.cli", "train", "--arm", args.arm, "--target", target,
                        "--networks", str(args.networks), "--seed", str(args.seed), "--out", str(out / target),
                        "--no-progress", "--test-each-epoch", "--epochs", str(step["epochs"]), "--epoch-s", "30",
                        *sets]
    return cmds


def command(condition: str, args, out: Path) -> list[str]:
    kind, seconds = condition.rsplit("-", 1)
    seconds = int(seconds)
    cmd = [sys.executable, "-m", "jaxarm.cli", "train", "--arm", args.arm, "--target", *TARGETS,
           "--networks", str(args.networks), "--seed", str(args.seed), "--out", str(out), "--no-progress",
           "--test-each-epoch"]
    if kind == "rstdp":
        if seconds % 30:
            raise SystemExit(f"{condition}: R-STDP trains in 30 s epochs")
        return cmd + ["--epochs", str(seconds // 30), "--epoch-s", "30"]
    if kind == "gradient":
        epoch_s = 5 if seconds % 5 == 0 else seconds
        return cmd + ["--learning", "gradient", "--epochs", str(seconds // epoch_s), "--epoch-s", str(epoch_s)]
    raise SystemExit(f"unknown condition {condition!r}: rstdp-N, rstdp-preset or gradient-N")


def summarise(res: dict, folder: Path) -> dict:
    from jaxarm.analysis.jerk import dimensionless_jerk

    rows = res["networks"]
    entered = [r for r in rows if r["success"]]
    curve = res["learning_curve"]
    if "fresh_noise_success_count" not in curve:
        raise SystemExit(f"{folder}: its learning curve has no held-out tests (trained before they existed): "
                         "train into a new --out")

    def median(key, subset):
        vals = [r[key] for r in subset if r.get(key) is not None]
        return float(np.median(vals)) if vals else None

    held = curve["fresh_noise_success_count"]
    best = int(np.argmax(held))                  # the first epoch with the most held-out successes
    criterion = [c for c in curve["fresh_noise_criterion_s"] if c is not None]
    traj = np.load(folder / "trajectories.npz")
    jerk = dimensionless_jerk(traj["hand"], float(traj["t"][1] - traj["t"][0]))
    return {"held_out_success": held[-1], "n": res["n_networks"],
            "held_out_best": held[best], "held_out_best_s": curve["epochs"][best] * curve["epoch_s"],
            "held_out_min_distance_cm": 100 * curve["fresh_noise_median_min_distance_m"][-1],
            "criterion_n": len(criterion), "criterion_s": float(np.median(criterion)) if criterion else None,
            "held_out_per_epoch": held, "success_per_epoch": curve["success_count"], "epoch_s": curve["epoch_s"],
            "success": res["success_count"], "naive_success": res["naive"]["success_count"],
            "dimensionless_jerk": float(np.nanmedian(jerk)) if np.isfinite(jerk).any() else None,
            "first_entry_s": median("first_entry_s", entered),
            "distance_after_cm": None if median("distance_after_m", entered) is None
            else 100 * median("distance_after_m", entered),
            "train_wall_s": res["timing"]["train_wall_s_this_invocation"],
            "network_s_per_s": res["timing"]["network_s_per_s"]}


def write_table(table: dict, out: Path) -> None:
    """OUT/table_ARM.json and the Markdown table OUT/table_ARM.md (also printed)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"table_{table['arm']}.json").write_text(json.dumps(table, indent=1))
    fmt = lambda x, d=1: "–" if x is None else f"{x:.{d}f}"  # noqa: E731
    lines = ["| learning | target | reached, held-out noise | best epoch, held-out (after network-s) | "
             "median closest, held-out (cm) | network-s to criterion, held-out (median, n) | "
             "reached, training stream | naive | median first entry (s) | median distance after entry (cm) | "
             "median dimensionless jerk | training wall (s) | network-s/s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for condition, c in table["conditions"].items():
        for target, r in c["targets"].items():
            n = r["n"]
            jerk = "–" if r["dimensionless_jerk"] is None else f"{r['dimensionless_jerk']:.2g}"
            lines.append(f"| {condition} | {target} | **{r['held_out_success']}/{n}** | "
                         f"{r['held_out_best']}/{n} ({r['held_out_best_s']:g}) | "
                         f"{fmt(r['held_out_min_distance_cm'])} | {fmt(r['criterion_s'], 0)} ({r['criterion_n']}) | "
                         f"{r['success']}/{n} | {r['naive_success']}/{n} | {fmt(r['first_entry_s'], 2)} | "
                         f"{fmt(r['distance_after_cm'])} | {jerk} | "
                         f"{fmt(r['train_wall_s'], 0)} | {fmt(r['network_s_per_s'], 2)} |")
    (out / f"table_{table['arm']}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines), flush=True)


def plot_curves(out: Path, arm: str, conditions) -> Path:
    """OUT/curves_ARM.png: networks whose test reaches after each epoch against the network-seconds trained, one
    panel per target, one line per condition (from the conditions' results.json learning curves)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(TARGETS), figsize=(4.2 * len(TARGETS), 3.4), sharey=True, layout="constrained",
                             squeeze=False)
    axes = axes[0]
    for ax, target in zip(axes, TARGETS):
        for condition in conditions:
            res = json.loads((out / arm / condition / target / "results.json").read_text())
            curve = res["learning_curve"]
            x = [0.0] + [e * curve["epoch_s"] for e in curve["epochs"]]
            y = [res["naive"]["success_count"]] + curve["fresh_noise_success_count"]
            ax.plot(x, y, marker="o", ms=3, label=condition)
        ax.set_xscale("symlog", linthresh=5.0)     # linear to 5 s (the naive point at 0), logarithmic beyond
        ticks = [0, 5, 10, 30, 60, 120, 360, 720]
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.minorticks_off()
        ax.set_xlabel("training per network (network-s)")
        ax.set_title(f"{arm} arm, {target} target")
    axes[0].set_ylabel(f"networks reaching, held-out noise (of {res['n_networks']})")
    axes[-1].legend(fontsize=8)
    path = out / f"curves_{arm}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--networks", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--conditions", nargs="+", default=["rstdp-360", "rstdp-preset", "gradient-30"])
    ap.add_argument("--out", type=Path, default=Path("runs/gradient-vs-rstdp"))
    args = ap.parse_args(argv)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    table = {"date": time.strftime("%Y-%m-%d"), "commit": commit,
             "machine": f"{platform.machine()}, {len(os.sched_getaffinity(0))} cores",
             "arm": args.arm, "networks": args.networks, "seed": args.seed, "conditions": {}}
    saved = args.out / f"table_{args.arm}.json"
    if saved.exists():     # conditions run by earlier invocations with the same networks and seed stay in the table
        old = json.loads(saved.read_text())
        if (old["networks"], old["seed"]) == (args.networks, args.seed):
            table["conditions"] = old["conditions"]
    for condition in args.conditions:
        out = args.out / args.arm / condition
        cmds = list(preset_commands(args, out).values()) if condition == "rstdp-preset" else \
            [command(condition, args, out)]
        shown = [" ".join(c[2:]).replace("jaxarm.cli", "jaxarm") for c in cmds]
        if all((out / target / "results.json").is_file() for target in TARGETS):
            # finished earlier (jaxarm train writes results.json after its last epoch): run again, it would only
            # re-test and record this invocation's training time, none
            print(f"{condition}: finished earlier in {out}, reused", flush=True)
        else:
            for cmd, line in zip(cmds, shown):
                print("$", line, flush=True)
                subprocess.run(cmd, check=True)
        rows = {target: summarise(json.loads((out / target / "results.json").read_text()), out / target)
                for target in TARGETS}
        table["conditions"][condition] = {"commands": shown, "targets": rows}
        write_table(table, args.out)     # after every condition: a long run killed keeps what it finished
    plot_curves(args.out, args.arm, list(table["conditions"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
