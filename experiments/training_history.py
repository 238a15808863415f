"""Firing rates and mean weight gains per training epoch of a `jaxarm train` run, beside the original's.

    python experiments/training_history.py runs/simple_left/results.json [--markdown]
    python experiments/training_history.py runs/simple_left/results.json --percentiles [--markdown]

The reference row per epoch is the original NEURON model's run on the simple arm (left target, its seeds), as
measured for the spec (``../shared/spec/original_model.md`` §10): rates = mean over the last 10 s of each 30 s epoch,
gains = mean wgain of each pathway at the end of the epoch. Our numbers are the means over the run's networks.

The original is one network. ``--percentiles`` reads the run's per-network ``history.npz`` (written next to
results.json) and prints, per epoch and column, the original's value as a percentile among our networks (the
percentage of our networks below it, ties half; 0 or 100: outside all of them), with our 10-90 % range
(``jaxarm.paper.comparison.original_history_percentiles``).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxarm.paper.comparison import ORIGINAL_HISTORY as ORIGINAL
from jaxarm.paper.comparison import ORIGINAL_HISTORY_GAINS as GAINS
from jaxarm.paper.comparison import ORIGINAL_HISTORY_RATES as RATES
from jaxarm.paper.comparison import original_history_percentiles


def rows(results: dict):
    h = results["history"]
    n_epochs = len(h["final_distance_m"])
    for e in range(n_epochs):
        ours = [h["rates_last10s_hz"][p][e] for p in RATES] + [h["mean_wgain"][g][e] for g in GAINS]
        yield e + 1, ours, ORIGINAL.get(e + 1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", help="results.json of a `jaxarm train` run")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table (ours / original per cell)")
    ap.add_argument("--percentiles", action="store_true",
                    help="the original's percentile among our networks (needs history.npz beside results.json)")
    args = ap.parse_args(argv)
    header = ("epoch",) + RATES + GAINS
    if args.markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
    if args.percentiles:
        path = Path(args.results).parent / "history.npz"
        if not path.exists():
            ap.error(f"{path} not found: runs written before history.npz existed hold only the means")
        for epoch, cols in original_history_percentiles(dict(np.load(path))):
            if args.markdown:
                cells = [f"{p:.0f} ({lo:.2f}–{hi:.2f})" if j < len(RATES) else f"{p:.0f} ({lo:.3f}–{hi:.3f})"
                         for j, (p, lo, hi) in enumerate(cols)]
                print(f"| {epoch} | " + " | ".join(cells) + " |")
            else:
                print(json.dumps({"epoch": epoch, "original_percentile": [c[0] for c in cols],
                                  "ours_p10": [c[1] for c in cols], "ours_p90": [c[2] for c in cols]}))
        return 0
    results = json.loads(open(args.results).read())
    for epoch, ours, orig in rows(results):
        cells = [f"{o:.2f}" if i < len(RATES) else f"{o:.3f}" for i, o in enumerate(ours)]
        if orig is not None:
            cells = [f"{c} / {r:.2f}" if i < len(RATES) else f"{c} / {r:.3f}" for i, (c, r) in enumerate(zip(cells, orig))]
        if args.markdown:
            print(f"| {epoch} | " + " | ".join(cells) + " |")
        else:
            print(json.dumps({"epoch": epoch, "ours": ours, "original": orig}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
