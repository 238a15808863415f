"""Gradient learning beside R-STDP on the paper's task: the same networks (seeds), arm, targets and test (issue 30
item 3).

    python experiments/gradient_vs_rstdp.py [--arm simple] [--networks 30] [--seed 0] [--out runs/gradient-vs-rstdp]
                                            [--conditions rstdp-360 rstdp-30 rstdp-preset gradient-30]

Each condition is ``jaxarm train`` (commands printed; checkpointed in OUT/ARM/<condition>, so a rerun resumes) on
both paper targets with ``--test-each-epoch``, then ``jaxarm test --from ... --fresh-noise 0``: the trained
networks re-tested on background noise streams neither learner trained on (both restart the network's own stream
for every epoch, reach and test, as the original does). Conditions: ``rstdp-N`` = R-STDP with babbling, the
authors' metaparameters, N s of training in 30 s epochs (360 = the paper's 12 epochs); ``rstdp-preset`` = R-STDP
with the metaparameters and epochs of the arm's headline preset for each target (what ``jaxarm reproduce --arm
ARM`` trains in its mode (a); same seeds); ``gradient-N`` = Adam on the mean hand-target distance of 1 s reaches
(N reaches, N network-seconds) in epochs of 5 s, so the per-epoch test times its criterion to 5 s. The table
(OUT/table_ARM.md, numbers in OUT/table_ARM.json) gives per condition and target: success (4 cm circle) on the
training stream and on a fresh one, median closest approach, network-seconds of training until a network's test
first succeeded (median over those that got there), median time of first entry and distance after entry over the
networks that entered, median dimensionless jerk of the trained test paths (Fig. 7's measure), and the training
wall time with its network-seconds per second (this machine, this run). OUT/curves_ARM.png: networks reaching
after every epoch against the network-seconds trained, per target and condition.
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

    def median(key, subset):
        vals = [r[key] for r in subset if r.get(key) is not None]
        return float(np.median(vals)) if vals else None

    criterion = [c for c in res["learning_curve"]["criterion_s"] if c is not None]
    traj = np.load(folder / "trajectories.npz")
    jerk = dimensionless_jerk(traj["hand"], float(traj["t"][1] - traj["t"][0]))
    return {"success": res["success_count"], "n": res["n_networks"],
            "min_distance_cm": 100 * median("min_distance_m", rows),
            "criterion_n": len(criterion), "criterion_s": float(np.median(criterion)) if criterion else None,
            "dimensionless_jerk": float(np.nanmedian(jerk)) if np.isfinite(jerk).any() else None,
            "success_per_epoch": res["learning_curve"]["success_count"],
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
    lines = ["| learning | target | reached (training noise) | reached (fresh noise) | naive | median closest (cm) | "
             "network-s to criterion (median, n) | median first entry (s) | median distance after entry (cm) | "
             "median dimensionless jerk | training wall (s) | network-s/s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for condition, c in table["conditions"].items():
        for target, r in c["targets"].items():
            n = r["n"]
            jerk = "–" if r["dimensionless_jerk"] is None else f"{r['dimensionless_jerk']:.2g}"
            lines.append(f"| {condition} | {target} | {r['success']}/{n} | {r['fresh_noise_success']}/{n} | "
                         f"{r['naive_success']}/{n} | {fmt(r['min_distance_cm'])} | "
                         f"{fmt(r['criterion_s'], 0)} ({r['criterion_n']}) | {fmt(r['first_entry_s'], 2)} | "
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

    fig, axes = plt.subplots(1, len(TARGETS), figsize=(4.2 * len(TARGETS), 3.4), sharey=True, layout="constrained")
    for ax, target in zip(axes, TARGETS):
        for condition in conditions:
            res = json.loads((out / arm / condition / target / "results.json").read_text())
            curve = res["learning_curve"]
            x = [0.0] + [e * curve["epoch_s"] for e in curve["epochs"]]
            y = [res["naive"]["success_count"]] + curve["success_count"]
            ax.plot(x, y, marker="o", ms=3, label=condition)
        ax.set_xscale("symlog", linthresh=5.0)     # linear to 5 s (the naive point at 0), logarithmic beyond
        ticks = [0, 5, 10, 30, 60, 120, 360, 720]
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.minorticks_off()
        ax.set_xlabel("training per network (network-s)")
        ax.set_title(f"{arm} arm, {target} target")
    axes[0].set_ylabel(f"networks reaching (of {res['n_networks']})")
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
    ap.add_argument("--conditions", nargs="+", default=["rstdp-360", "rstdp-30", "rstdp-preset", "gradient-30"])
    ap.add_argument("--out", type=Path, default=Path("runs/gradient-vs-rstdp"))
    args = ap.parse_args(argv)
    table = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {platform.node()}",
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
        for cmd, line in zip(cmds, shown):
            print("$", line, flush=True)
            subprocess.run(cmd, check=True)
        rows = {}
        for target in TARGETS:
            fresh = out / target / "fresh-noise"
            subprocess.run([sys.executable, "-m", "jaxarm.cli", "test", "--from", str(out / target), "--out",
                            str(fresh), "--fresh-noise", "0"], check=True, stdout=subprocess.DEVNULL)
            res = json.loads((out / target / "results.json").read_text())
            rows[target] = summarise(res, out / target) | {
                "naive_success": res["naive"]["success_count"],
                "fresh_noise_success": json.loads((fresh / "results.json").read_text())["success_count"]}
        table["conditions"][condition] = {"commands": shown, "targets": rows}
        write_table(table, args.out)     # after every condition: a long run killed keeps what it finished
    plot_curves(args.out, args.arm, list(table["conditions"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
