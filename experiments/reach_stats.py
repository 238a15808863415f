"""The paper's reach statistics (§3.2, Fig. 7) of trained networks, ours beside the paper's.

    python experiments/reach_stats.py runs/repro-msarm-cmaes-4seeds --markdown
    python experiments/reach_stats.py runs/repro-msarm-original/left/seeds runs/x/bottom/seeds --json out.json

Each argument is a ``jaxarm train`` / ``jaxarm reproduce`` output: a folder holding ``results.json`` and
``trajectories.npz`` (one target), or a ``reproduce`` folder (its ``<target>/seeds`` sub-folders are used).
What is computed, and the paper's values: :mod:`jaxarm.paper.comparison`.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from jaxarm.paper.comparison import markdown, run_folders, target_stats


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="run folders (results.json + trajectories.npz) or reproduce folders")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    ap.add_argument("--json", type=Path, help="write the statistics as JSON here")
    args = ap.parse_args(argv)
    try:
        stats = [target_stats(f) for f in run_folders(args.runs)]
    except FileNotFoundError as e:
        raise SystemExit(str(e)) from None
    if args.json:
        args.json.write_text(json.dumps(stats, indent=1) + "\n")
    if args.markdown:
        print(markdown(stats))
    else:
        for s in stats:
            print(json.dumps(s))


if __name__ == "__main__":
    main()
