"""Our trained networks' 1 s test beside the original NEURON model's one test (spec §10), with a figure.

    jaxarm train --arm simple --target left --networks 30 --seed 0 --out runs/orig-left   # the authors' set
    python experiments/original_test.py runs/orig-left --markdown --figure docs/figures/original_test_left.png

The original model was run once (its own seeds) with the authors' metaparameters on the simple arm and the left
target; the spec gives its hand–target distance at a few test times, its closest approach (1.59 cm), final distance
(3.31 cm), final joint angles and test firing rates. Our 30 networks (seeds ``seed .. seed+29``) are 30 draws of
wiring, noise and babbling; this places the original's one run in their distribution: at each time, the percentile
of the original's distance among ours. Computed by :func:`jaxarm.paper.comparison.original_test_comparison`.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxarm.paper.comparison import ORIGINAL_TEST_DISTANCE_CM, original_test_comparison


def markdown(c: dict) -> str:
    lines = [f"{c['success_count']}/{c['n']} of our networks reach the 4 cm circle ({c['folder']}).", "",
             "| test time, ms | original, cm | ours: median (10–90 %), cm | original's percentile among ours |",
             "|---|---|---|---|"]
    for r in c["distance"]:
        lines.append(f"| {r['t_ms']} | {r['original_cm']:.1f} | {r['median_cm']:.1f} ({r['p10_cm']:.1f}–"
                     f"{r['p90_cm']:.1f}) | {r['original_percentile']:.0f} |")
    for key, label in (("closest", "closest approach"), ("final", "final (1 s)")):
        r = c[key]
        lines.append(f"| {label} | {r['original_cm']:.2f} | {r['median_cm']:.1f} ({r['p10_cm']:.1f}–"
                     f"{r['p90_cm']:.1f}) | {r['original_percentile']:.0f} |")
    q = c["final_q_rad"]
    lines += ["", f"Final joint angles (shoulder, elbow), rad: original ({q['original'][0]:.3f}, {q['original'][1]:.3f}),"
              f" ours median ({q['median'][0]:.3f}, {q['median'][1]:.3f}); start (0.620, 1.530).", ""]
    rates = c["test_rates_hz"]
    if rates["ours"]:
        pops = list(rates["original"])
        lines += ["| test rates, Hz | " + " | ".join(pops) + " |", "|---|" + "---|" * len(pops),
                  "| original | " + " | ".join(f"{rates['original'][p]:.1f}" for p in pops) + " |",
                  "| ours (mean over networks) | " + " | ".join(f"{rates['ours'][p]:.1f}" for p in pops) + " |"]
        if rates["original_percentile"]:
            lines.append("| original's percentile among ours | "
                         + " | ".join(f"{rates['original_percentile'][p]:.0f}" for p in pops) + " |")
    return "\n".join(lines)


def figure(folder: Path, c: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    traj = np.load(folder / "trajectories.npz")
    t_ms = 1000.0 * np.asarray(traj["t"], float)
    d = 100.0 * np.asarray(traj["distance"], float)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for row in d:
        ax.plot(t_ms, row, color="0.75", lw=0.7)
    ax.fill_between(t_ms, np.percentile(d, 10, axis=0), np.percentile(d, 90, axis=0), color="C0", alpha=0.2,
                    label="ours, 10–90 %")
    ax.plot(t_ms, np.median(d, axis=0), color="C0", lw=2, label=f"ours, median ({c['n']} networks)")
    ts, ds = zip(*ORIGINAL_TEST_DISTANCE_CM.items())
    ax.plot(ts, ds, "o-", color="C3", lw=1.5, label="original NEURON model (one run)")
    ax.axhline(4.0, color="k", ls="--", lw=0.8, label="4 cm target circle")
    ax.set_xlabel("test time, ms")
    ax.set_ylabel("hand–target distance, cm")
    ax.set_title(f"Simple arm, left target, authors' metaparameters: {c['success_count']}/{c['n']} reach")
    ax.set_xlim(0, 1000)
    ax.set_ylim(0, None)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="jaxarm train output folder (simple arm, left target)")
    ap.add_argument("--markdown", action="store_true", help="print markdown tables")
    ap.add_argument("--figure", type=Path, help="write the distance-vs-time figure here (PNG)")
    ap.add_argument("--json", type=Path, help="write the comparison as JSON here")
    args = ap.parse_args(argv)
    try:
        c = original_test_comparison(args.run)
    except (FileNotFoundError, ValueError) as e:
        raise SystemExit(str(e)) from None
    if args.json:
        args.json.write_text(json.dumps(c, indent=1) + "\n")
    print(markdown(c) if args.markdown else json.dumps(c))
    if args.figure:
        figure(args.run, c, args.figure)


if __name__ == "__main__":
    main()
