"""Training throughput by group size: ``jaxarm train`` over every core with ``--networks-at-once K``, alternated.

    python benchmarks/group_size.py [--arm simple musculoskeletal] [--k 1 2 4 8] [--networks 32] [--epochs 2]
        [--epoch-s 15] [--rounds 3] [--json-out FILE]

Each round runs, for every arm and every K in turn, ``jaxarm train --arm ARM --target left --networks N --epochs E
--epoch-s S --networks-at-once K`` (the command as a user runs it: every device of this machine, seed 0, the
authors' metaparameters) in a fresh process, and reads the training throughput its ``results.json`` reports
(``timing.network_s_per_s``: network-seconds trained per wall-clock second of the epochs, compilation excluded).
Alternating the K values round by round puts the machine's load on all of them alike; the figure per K is the
median over the rounds, and the ratios are against K = 8 (the default until 2026-12-07). It also checks that every
K gave every network the same result (``results.json``'s per-network rows, trained and naive).

Prints and writes JSON: ``network_s_per_s[arm][K]`` (median), ``over_k8[arm][K]``, every round's figure
(``rounds``), ``same_results_across_k[arm]``, with the command, date, machine and commit.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from arm import commit  # benchmarks/arm.py, beside this script: the commit, marked when the tree has changes

ROOT = Path(__file__).resolve().parents[1]


def train_once(arm: str, k: int, args, folder: Path) -> tuple[float, list]:
    """(training network-s per s, the per-network result rows) of one ``jaxarm train`` run."""
    out = folder / f"{arm}-k{k}"
    cmd = [str(Path(sys.executable).with_name("jaxarm")), "train", "--arm", arm, "--target", "left", "--networks",
           str(args.networks), "--epochs", str(args.epochs), "--epoch-s", str(args.epoch_s), "--networks-at-once",
           str(k), "--no-progress", "--out", str(out)]
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    res = json.loads((out / "results.json").read_text())
    rows = [res["networks"], res["naive"]]
    shutil.rmtree(out, ignore_errors=True)
    return float(res["timing"]["network_s_per_s"]), rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", nargs="+", default=["simple", "musculoskeletal"], choices=["simple", "musculoskeletal"])
    ap.add_argument("--k", type=int, nargs="+", default=[1, 2, 4, 8], help="--networks-at-once values")
    ap.add_argument("--networks", type=int, default=32)
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--epoch-s", type=float, default=15.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json-out", default=None)
    args = ap.parse_args(argv)
    if 8 not in args.k:
        ap.error("--k must include 8 (the ratios are against it)")
    rates = {arm: {k: [] for k in args.k} for arm in args.arm}
    rows = {arm: {} for arm in args.arm}
    started = time.strftime("%Y-%m-%d %H:%M", time.gmtime())
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for arm in args.arm:
                for k in args.k:
                    rate, got = train_once(arm, k, args, Path(tmp))
                    rates[arm][k].append(rate)
                    rows[arm].setdefault(k, got)
                    print(f"round {r + 1}: {arm:16s} K={k}: {rate:7.1f} network-s/s", file=sys.stderr, flush=True)
    med = {arm: {str(k): round(statistics.median(v), 1) for k, v in per.items()} for arm, per in rates.items()}
    out = {
        "what": "jaxarm train's training throughput by --networks-at-once K, every device of the machine, "
                "alternated rounds, medians",
        "command": "python benchmarks/group_size.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "train_command": f"jaxarm train --arm ARM --target left --networks {args.networks} --epochs {args.epochs} "
                         f"--epoch-s {args.epoch_s:g} --networks-at-once K --no-progress --out DIR",
        "date": started, "machine": f"{platform.machine()}, {os.cpu_count()} cores", "commit": commit(),
        "network_s_per_s": med,
        "over_k8": {arm: {k: round(v / per["8"], 3) for k, v in per.items()} for arm, per in med.items()},
        "rounds": {arm: {str(k): [round(x, 1) for x in v] for k, v in per.items()} for arm, per in rates.items()},
        "same_results_across_k": {arm: all(got == per[8] for got in per.values()) for arm, per in rows.items()},
    }
    text = json.dumps(out, indent=1)
    print(text)
    if args.json_out:
        Path(args.json_out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
