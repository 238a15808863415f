"""The result file of an alternated comparison (benchmarks/alternate.sh): the rounds, their medians and the ratios.

    python benchmarks/ab_summary.py OUT_DIR BEFORE_DIR --command "benchmarks/alternate.sh ..." > docs/results/kernel_ab.json

OUT_DIR holds alternate.sh's {net,train}-{before,now}-R.json; BEFORE_DIR is the tree it compared with (its commit is
recorded, as is this tree's). Prints JSON: date, machine, command, the two commits, every round's figures, the
medians over the rounds (network-s/s) and now / before; the medians and ratios also as lines on stderr.
"""
from __future__ import annotations

import argparse
import datetime
import glob
import json
import os
import platform
import statistics
import subprocess
import sys



def commit(tree: str) -> str:
    def git(*args):
        return subprocess.run(["git", "-C", tree, *args], capture_output=True, text=True).stdout.strip()
    head = git("rev-parse", "--short", "HEAD")
    return head + ("-dirty" if git("status", "--porcelain", "--untracked-files=no") else "")


def summarise(out: str) -> dict:
    rounds, median, ratio = {}, {}, {}
    for bench in ("net", "train"):
        for side in ("before", "now"):
            files = sorted(glob.glob(os.path.join(out, f"{bench}-{side}-*.json")),
                           key=lambda f: int(f.rsplit("-", 1)[1].split(".")[0]))
            rounds[f"{bench}-{side}"] = [json.load(open(f))["network_s_per_s"] for f in files]
        if not rounds[f"{bench}-now"]:
            raise SystemExit(f"{out}: no {bench}-now-*.json (run benchmarks/alternate.sh first)")
        for key in rounds[f"{bench}-now"][0]:
            med = {side: statistics.median(r[key] for r in rounds[f"{bench}-{side}"]) for side in ("before", "now")}
            median[f"{bench} {key}"] = med
            ratio[f"{bench} {key}"] = round(med["now"] / med["before"], 3)
    return {"rounds": rounds, "median": median, "ratio_now_over_before": ratio}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir")
    ap.add_argument("before_dir")
    ap.add_argument("--command", required=True, help="the command that made OUT_DIR, recorded as is")
    ap.add_argument("--now", help="the commit measured as 'now' (default: this tree's, '-dirty' with changes)")
    ap.add_argument("--machine", default=f"{platform.machine()}, {os.cpu_count()} CPUs",
                    help="the machine, in words (default: architecture and CPU count)")
    args = ap.parse_args(argv)
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    mtime = max(os.path.getmtime(f) for f in glob.glob(os.path.join(args.out_dir, "*-*-*.json")))   # the rounds
    result = {"date": datetime.datetime.fromtimestamp(mtime, datetime.timezone.utc).strftime("%Y-%m-%d %H:%M"),
              "machine": args.machine, "command": args.command, "before": commit(args.before_dir),
              "now": args.now or commit(here), **summarise(args.out_dir)}
    for key, med in result["median"].items():
        print(f"{key}: now {med['now']:.2f}, before {med['before']:.2f} network-s/s, "
              f"now/before {result['ratio_now_over_before'][key]:.3f}", file=sys.stderr)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
