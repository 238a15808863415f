"""Firing rates and mean weight gains per training epoch of a `jaxarm train` run, beside the original's.

    python experiments/training_history.py runs/simple_left/results.json [--markdown]

The reference row per epoch is the original NEURON model's run on the simple arm (left target, its seeds), as
measured for the spec (``../shared/spec/original_model.md`` §10): rates = mean over the last 10 s of each 30 s epoch,
gains = mean wgain of each pathway at the end of the epoch. Our numbers are the means over the run's networks.
"""
from __future__ import annotations

import argparse
import json

from jaxarm.analysis.paper import ORIGINAL_HISTORY as ORIGINAL
from jaxarm.analysis.paper import ORIGINAL_HISTORY_GAINS as GAINS
from jaxarm.analysis.paper import ORIGINAL_HISTORY_RATES as RATES


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
    args = ap.parse_args(argv)
    results = json.loads(open(args.results).read())
    header = ("epoch",) + RATES + GAINS
    if args.markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
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
