"""The same sets and networks with one metaparameter changed: two `experiments/stay_tradeoff.py` runs compared set by
set (an intervention on what experiments/stay_frontier.py finds only correlated).

    python experiments/paired_sets.py runs/stay-ee-left-base runs/stay-ee-left-low \
        [--json-out docs/results/stay_ee_left.json]

Both runs must train the same preset's sets on the same seeds and protocol and differ only in ``--set``. Per set:
the networks that reached and the mean distance after entry in each run; over the sets: the counts, the pooled
distance and the Wilcoxon signed-rank test of the per-set differences (two-sided; sets that entered in both).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import shlex
import sys
from pathlib import Path

import numpy as np
from scipy import stats as sps

SAME = ("preset", "arm", "target", "sets", "seeds", "first_seed", "epochs", "epoch_s")


def compare(base: dict, changed: dict) -> dict:
    for key in SAME:
        if base["config"][key] != changed["config"][key]:
            raise SystemExit(f"paired_sets: the runs differ in {key} ({base['config'][key]!r} against "
                             f"{changed['config'][key]!r}); only --set may differ")
    pairs = [(a["distance_after_cm"], b["distance_after_cm"]) for a, b in zip(base["rows"], changed["rows"])
             if a["distance_after_cm"] is not None and b["distance_after_cm"] is not None]
    diff = np.array([b - a for a, b in pairs])
    test = sps.wilcoxon(diff) if len(diff) >= 5 and np.any(diff != 0) else None
    reached = lambda run: sum(r["reached"] for r in run["rows"])   # noqa: E731
    networks = sum(r["networks"] for r in base["rows"])
    return {
        "change": changed["config"].get("set", []), "protocol": {k: base["config"][k] for k in SAME},
        "base": {"reached": reached(base), "networks": networks,
                 "distance_after_cm": base["pooled_distance_after_cm"]},
        "changed": {"reached": reached(changed), "networks": networks,
                    "distance_after_cm": changed["pooled_distance_after_cm"]},
        "per_set": [{"set": a["set"], "base_reached": a["reached"], "changed_reached": b["reached"],
                     "base_distance_after_cm": a["distance_after_cm"],
                     "changed_distance_after_cm": b["distance_after_cm"]}
                    for a, b in zip(base["rows"], changed["rows"])],
        "sets_compared": len(diff),
        "sets_closer": int(np.sum(diff < 0)),
        "median_difference_cm": round(float(np.median(diff)), 3) if len(diff) else None,
        "wilcoxon_p": None if test is None else float(f"{test.pvalue:.3g}"),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("base", type=Path, help="a stay_tradeoff.py --out folder")
    ap.add_argument("changed", type=Path, help="the same with --set")
    ap.add_argument("--json-out", type=Path, default=None)
    args = ap.parse_args(argv)
    base, changed = (json.loads((d / "stay_tradeoff.json").read_text()) for d in (args.base, args.changed))
    result = compare(base, changed)
    result = {"command": "python experiments/paired_sets.py " + shlex.join(argv if argv is not None else sys.argv[1:]),
              "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
              "wall_s": {"base": base["wall_s"], "changed": changed["wall_s"]}, **result}
    b, c = result["base"], result["changed"]
    print(f"change {result['change']}: reached {b['reached']}/{b['networks']} -> {c['reached']}/{c['networks']}; "
          f"distance after entry {b['distance_after_cm']} -> {c['distance_after_cm']} cm pooled; "
          f"{result['sets_closer']} of {result['sets_compared']} sets closer, median change "
          f"{result['median_difference_cm']} cm, Wilcoxon p = {result['wilcoxon_p']}")
    if args.json_out:
        args.json_out.parent.mkdir(parents=True, exist_ok=True)
        args.json_out.write_text(json.dumps(result, indent=1) + "\n")
        print("->", args.json_out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
