"""Our networks beside the original NEURON model's, both trained with the authors' metaparameters over many seeds.

    jaxarm train --arm simple --target left --networks 30 --seed 0 --out runs/orig-left
    jaxarm train --arm simple --target left --networks 30 --seed 30 --out runs/orig-left-s30
    for j in 1 2 3 4 5 6 7 8 9; do
        jaxarm test --from runs/orig-left --fresh-noise $j --out runs/orig-left-fresh/$j
        jaxarm test --from runs/orig-left-s30 --fresh-noise $j --out runs/orig-left-s30-fresh/$j
    done
    python experiments/original_seeds.py runs/orig-left runs/orig-left-s30 \
        --fresh runs/orig-left-fresh/* runs/orig-left-s30-fresh/* --markdown --figure docs/figures/original_seeds_left.png

The original model was run 60 times with different seeds (run k: inputseed 1235 + 17 k, dvseed 398115 + 1000 k),
each the full protocol on the simple arm; its outcomes, test trajectories and fresh-noise re-tests are reference
data in ``jaxarm/paper/data/original_seeds_<target>.json`` (how they were measured: its ``measured`` entry and
docs/results.md). Both models' tests re-use the training noise streams, as the original re-seeds its noise at every
run; ``--fresh`` adds our networks re-tested with other streams (``jaxarm test --fresh-noise J``), beside the
original's re-tests. Computed by :func:`jaxarm.paper.comparison.seed_distribution_comparison`.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxarm.paper.comparison import (EPOCH_COLUMNS, original_epoch_comparison, original_seed_runs,
                                   seed_distribution_comparison)


def _pct(c: dict) -> str:
    lo, hi = c["ci95"]
    return f"{c['k']}/{c['n']} ({100 * c['rate']:.0f} %, 95 % CI {100 * lo:.0f}–{100 * hi:.0f} %)"


def _range(s: dict) -> str:
    return f"{s['median_cm']:.1f} ({s['p10_cm']:.1f}–{s['p90_cm']:.1f})"


def markdown(c: dict) -> str:
    s = c["success"]
    lines = [f"{c['target']} target, simple arm, authors' metaparameters ({c['folder']} beside the original's runs)", "",
             "| | original NEURON model | jaxarm | p |", "|---|---|---|---|",
             f"| networks reaching, test with the training noise | {_pct(s['original'])} | {_pct(s['ours'])} | "
             f"{s['fisher_p']:.2f} (Fisher) |"]
    for key, label in (("closest", "closest approach, median (10–90 %), cm"), ("final", "final distance, cm")):
        r = c[key]
        lines.append(f"| {label} | {_range(r['original'])} | {_range(r['ours'])} | {r['mannwhitney_p']:.2f} (MW) |")
    for t, r in c["distance_at_ms"].items():
        lines.append(f"| distance at {t} ms, cm | {_range(r['original'])} | {_range(r['ours'])} | "
                     f"{r['mannwhitney_p']:.2f} (MW) |")
    for key, label, digits in (("distance_after_cm", "reached: distance to the centre after first entry, cm", 2),
                               ("time_inside_ms", "reached: time inside the circle, ms", 0),
                               ("first_entry_ms", "reached: first entry, ms", 0)):
        a = c["after_entry"][key]
        cell = lambda m: (f"{m['mean']:.{digits}f} (SD {m['sd']:.{digits}f}; median {m['median']:.{digits}f}, "  # noqa: E731
                          f"{m['p10']:.{digits}f}–{m['p90']:.{digits}f}; n {m['n']})")
        lines.append(f"| {label} | {cell(a['original'])} | {cell(a['ours'])} | {a['mannwhitney_p']:.2f} (MW) |")
    f = c["fresh"]
    if f:
        orig, ours = f.get("original"), f.get("ours")
        lines.append("| re-tested with fresh noise: tests reaching | "
                     + (f"{_pct(orig)}, {orig['networks']} networks × {orig['n'] // orig['networks']}" if orig else "–")
                     + " | " + (f"{_pct(ours)}, {ours['networks']} networks × {ours['tests_per_network']}"
                                if ours else "–") + " | |")
        if orig:
            lines.append(f"| the same {orig['networks']} networks, test with the training noise | "
                         f"{_pct(orig['own_noise'])} | | |")
    b = c.get("blocks", {})
    if len(b.get("original", [])) > 1 or len(b.get("ours", [])) > 1:
        def blk(x):
            return "; ".join(f"{e['own_noise']['k']}/{e['own_noise']['n']}"
                             + (f" ({100 * e['fresh']['rate']:.0f} % fresh)" if e["fresh"] else "") for e in x)
        lines.append(f"| per block of {c['goal']['n']} seeds: reaching (fresh-noise tests) | {blk(b['original'])} | "
                     f"{blk(b['ours'])} | |")
    g = c["goal"]
    if g["k"] <= g["n"]:
        lines += ["", f"{g['k']} or more of {g['n']} at the original's rate: probability {g['p_at_original_rate']:.2g} "
                      f"(at the upper end of its interval: {g['p_at_original_upper_ci']:.2g})."]
    return "\n".join(lines)


def epoch_markdown(rows: list[dict], epochs=(1, 2, 4, 8, 12)) -> str:
    """Median (10–90 %) per epoch: the original's runs with per-epoch records / ours."""
    n = (rows[0]["rewards"]["original"]["n"], rows[0]["rewards"]["ours"]["n"])
    lines = [f"Training epoch by epoch, original ({n[0]} runs) / jaxarm ({n[1]} networks), median (10–90 %)", "",
             "| epoch | " + " | ".join(EPOCH_COLUMNS) + " |", "|---|" + "---|" * len(EPOCH_COLUMNS)]
    for r in rows:
        if r["epoch"] not in epochs:
            continue
        cells = []
        for col in EPOCH_COLUMNS:
            digits = 0 if col in ("rewards", "punishments") else (2 if col == "EM_hz" else 3)
            o, u = r[col]["original"], r[col]["ours"]
            cells.append(f"{o['median']:.{digits}f} / {u['median']:.{digits}f} "
                         f"({o['p10']:.{digits}f}–{o['p90']:.{digits}f} / {u['p10']:.{digits}f}–{u['p90']:.{digits}f})")
        lines.append(f"| {r['epoch']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def pooled_history(folders) -> dict | None:
    """The runs' ``history.npz`` joined along the network axis (None if any run has none)."""
    paths = [Path(f) / "history.npz" for f in folders]
    if not all(p.exists() for p in paths):
        return None
    hs = [np.load(p) for p in paths]
    out = {}
    for key in ("rewards", "punishments", "rates_hz", "mean_wgain"):
        out[key] = np.concatenate([np.asarray(h[key]) for h in hs], axis=1)      # (epochs, networks, ...)
    out["populations"], out["pathways"] = hs[0]["populations"], hs[0]["pathways"]
    return out


def figure(folders, c: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = original_seed_runs(c["target"])["runs"]
    trajs = [np.load(Path(f) / "trajectories.npz") for f in folders]
    t_ms = 1000.0 * np.asarray(trajs[0]["t"], float)
    ours = 100.0 * np.concatenate([np.asarray(t["distance"], float) for t in trajs])
    orig = np.asarray([r["distance_cm"] for r in runs], float)
    t_orig = 10.0 * np.arange(orig.shape[1])
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for d, t, colour, label in ((orig, t_orig, "C3", "original NEURON model"), (ours, t_ms, "C0", "jaxarm")):
        a.fill_between(t, np.percentile(d, 10, axis=0), np.percentile(d, 90, axis=0), color=colour, alpha=0.15)
        a.plot(t, np.median(d, axis=0), color=colour, lw=2, label=f"{label}: median, 10–90 % ({len(d)} networks)")
        closest = np.sort(d.min(axis=1))
        b.step(closest, np.arange(1, len(closest) + 1), where="post", color=colour,
               label=f"{label}: {int(np.sum(closest <= 4.0))}/{len(closest)} within 4 cm")
    a.axhline(4.0, color="k", ls="--", lw=0.8)
    b.axvline(4.0, color="k", ls="--", lw=0.8)
    a.set(xlabel="test time, ms", ylabel="hand–target distance, cm", xlim=(0, 1000), ylim=(0, None))
    b.set(xlabel="closest approach in the test, cm", ylabel="networks (cumulative)", xlim=(0, None))
    a.legend(fontsize=7, loc="upper right")
    b.legend(fontsize=7, loc="lower right")
    fig.suptitle(f"Simple arm, {c['target']} target, authors' metaparameters: {len(orig)} runs of the original, "
                 f"{len(ours)} jaxarm networks", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, nargs="+",
                    help="jaxarm train output folder(s) (simple arm, one target; several are pooled, e.g. --seed 0 "
                         "and --seed 30)")
    ap.add_argument("--fresh", type=Path, nargs="*", default=[],
                    help="jaxarm test --fresh-noise outputs of the runs' networks (pooled by network seed)")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    ap.add_argument("--figure", type=Path, help="write the figure here (PNG)")
    ap.add_argument("--json", type=Path, help="write the comparison as JSON here")
    args = ap.parse_args(argv)
    try:
        c = seed_distribution_comparison(args.run, fresh_folders=args.fresh)
    except (FileNotFoundError, ValueError) as e:
        raise SystemExit(str(e)) from None
    epochs = None
    history = pooled_history(args.run)
    if history is not None:
        try:
            epochs = original_epoch_comparison(history, original_seed_runs(c["target"]))
        except ValueError:
            epochs = None
    if args.markdown:
        print(markdown(c) + ("\n\n" + epoch_markdown(epochs) if epochs else ""))
    else:
        print(json.dumps(c | {"epochs": epochs}))
    if args.json:
        args.json.write_text(json.dumps(c | {"epochs": epochs}, indent=1) + "\n")
    if args.figure:
        figure(args.run, c, args.figure)


if __name__ == "__main__":
    main()
