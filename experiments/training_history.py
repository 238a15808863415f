"""Firing rates and mean weight gains per training epoch of a `jaxarm train` run, beside the original's.

    python experiments/training_history.py runs/simple_left/results.json [--markdown]

The reference row per epoch is the original NEURON model's run on the simple arm (left target, its seeds), as
measured for the spec (``../shared/spec/original_model.md`` §10): rates = mean over the last 10 s of each 30 s epoch,
gains = mean wgain of each pathway at the end of the epoch. Our numbers are the means over the run's networks.
"""
from __future__ import annotations

import argparse
import json

# spec §10 (original model, dummy arm): epoch -> (ES, IS, ISL, EM, IM, IML, ES->EM, ES->ES, EM->EM, EM->ES, ES->IS,
# EM->IM, IS->ES)
ORIGINAL = {
    1: (3.46, 2.07, 1.65, 0.78, 0.80, 0.68, 1.014, 1.046, 1.001, 1.015, 1.021, 0.994, 0.990),
    2: (2.94, 1.91, 1.31, 0.43, 0.64, 0.53, 1.029, 1.098, 1.003, 1.033, 1.047, 0.995, 0.978),
    3: (3.14, 2.00, 1.45, 0.52, 0.75, 0.57, 1.042, 1.126, 1.007, 1.040, 1.059, 0.992, 0.970),
    4: (3.50, 2.24, 1.59, 0.86, 0.81, 0.66, 1.047, 1.150, 1.007, 1.048, 1.071, 0.989, 0.966),
    5: (3.56, 2.45, 1.62, 1.07, 1.09, 0.68, 1.057, 1.177, 1.009, 1.060, 1.085, 0.985, 0.959),
    6: (3.66, 2.67, 1.59, 1.19, 1.13, 0.82, 1.080, 1.238, 1.015, 1.083, 1.117, 0.985, 0.943),
    7: (3.04, 2.25, 1.39, 0.93, 1.12, 0.78, 1.100, 1.274, 1.024, 1.099, 1.137, 0.995, 0.928),
    8: (3.18, 2.59, 1.58, 1.41, 1.51, 1.01, 1.138, 1.333, 1.049, 1.131, 1.170, 1.017, 0.904),
    9: (3.84, 3.35, 1.82, 2.55, 3.01, 1.54, 1.191, 1.377, 1.097, 1.164, 1.191, 1.074, 0.871),
    10: (2.04, 1.50, 1.02, 0.37, 0.67, 0.54, 1.196, 1.378, 1.103, 1.166, 1.188, 1.080, 0.867),
    11: (2.23, 1.58, 1.06, 0.44, 0.72, 0.53, 1.200, 1.377, 1.109, 1.168, 1.186, 1.087, 0.866),
    12: (2.74, 2.10, 1.25, 0.89, 0.95, 0.70, 1.204, 1.380, 1.114, 1.174, 1.186, 1.093, 0.862),
}
RATES = ("ES", "IS", "ISL", "EM", "IM", "IML")
GAINS = ("ES->EM", "ES->ES", "EM->EM", "EM->ES", "ES->IS", "EM->IM", "IS->ES")


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
