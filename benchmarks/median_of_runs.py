"""The medians of several runs of ``benchmarks/network.py --json --brian2`` (one after another), as one result file.

    for r in 1 2 3; do python benchmarks/network.py --json --networks 1,60,300 --brian2 > run-$r.json; done
    python benchmarks/median_of_runs.py run-*.json --what "..." > docs/results/network_brian2.json

Prints JSON: what, command, date (of the last run's file), machine, commit, the median over the runs of
network-s/s per network count, Brian2's network-s/s, the ratio per network, peak memory and compile time, and each
run's own figures.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess

FIELDS = ("network_s_per_s", "network_s_per_cpu_s", "ratio_vs_brian2", "peak_rss_gb", "compile_s")


def summarise(runs: list[dict]) -> dict:
    med = {f: {n: round(statistics.median(r[f][n] for r in runs), 2) for n in runs[0][f]}
           for f in FIELDS if f in runs[0]}
    if "brian2_network_s_per_s" in runs[0]:
        med["brian2_network_s_per_s"] = round(statistics.median(r["brian2_network_s_per_s"] for r in runs), 2)
    keep = FIELDS + ("brian2_network_s_per_s", "brian2_build_s", "brian2_rates_hz", "load_average_at_end")
    return {"median": med, "runs": [{k: r[k] for k in keep if k in r} for r in runs]}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", help="network.py --json outputs")
    ap.add_argument("--what", required=True, help="what was measured, in words")
    ap.add_argument("--command", default="python benchmarks/network.py --json --networks 1,60,300 --brian2")
    ap.add_argument("--machine", default=f"{platform.machine()}, {os.cpu_count()} CPUs")
    args = ap.parse_args(argv)
    runs = [json.load(open(f)) for f in args.files]
    last = max(os.path.getmtime(f) for f in args.files)
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    commit = subprocess.run(["git", "-C", here, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    print(json.dumps({"what": args.what, "command": args.command,
                      "date": datetime.datetime.fromtimestamp(last, datetime.timezone.utc).strftime("%Y-%m-%d"),
                      "time": datetime.datetime.fromtimestamp(last, datetime.timezone.utc).strftime("%H:%M"),
                      "machine": args.machine, "commit": commit, **summarise(runs)}, indent=1))


if __name__ == "__main__":
    main()
