"""Reaching against staying over the sets of a `jaxarm rerank` ranking: how far the frontier is from the paper's point,
and which metaparameters move along it (issue 49 item 1).

    python experiments/stay_frontier.py runs/rerank-msarm-left-8 [--reproduced runs/repro-left-8/success_table.json]
        [--json-out docs/results/stay_frontier_left.json] [--figure docs/figures/stay_frontier_left.png]

Mode (b) of the reproduction trains one network with each of 30 sets, so what it can reach is a property of a
30-set selection: its expected count is the sum of the sets' success rates and its distance after entry the
rate-weighted mean of theirs. A set's rate and distance measured on a few seeds overstate the best sets (a set
chosen for its sample mean was partly lucky), so each is also given shrunk toward the pool's mean by its
reliability (:func:`jaxarm.analysis.stats.shrunk_means`, the one-way random-effects predictor with the measured
intraclass correlation): the forecast for fresh networks.

The frontier: for each trade-off weight lam (cm per unit of success rate), the 30 sets with the smallest
``distance - lam * rate``; every selection's expected (count, distance), raw and shrunk. Beside it: the ranking's
own 30 best (rate first, then distance), the paper's point (29/30 at 3.87 cm, SD 0.78) and, with ``--reproduced``,
what the selection did on seeds 0-29. The metaparameters that move along the frontier: each one's Spearman rank
correlation with the sets' shrunk distance and rate over the pool (metaparameters the searches kept fixed are
skipped).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import platform
import shlex
import sys
from pathlib import Path

import numpy as np
from scipy import stats as sps

from jaxarm.analysis.stats import intraclass_correlation, set_mean_reliability, shrunk_means

#: Paper, Results 3.2, musculoskeletal arm (b): successes of 30 and the distance after entry, cm (SD).
PAPER = {"left": {"reached": 29, "n": 30, "distance_after_cm": 3.87, "sd": 0.78},
         "bottom": {"reached": 26, "n": 30, "distance_after_cm": 3.20, "sd": 0.69}}
LAMBDAS_CM = (0.0, 0.5, 1, 2, 3, 5, 8, 12, 20, 40, 100, 1000)


def selection(rate, after, chosen) -> dict:
    """Expected count of 30 and distance after entry (cm) of one network per chosen set."""
    r, a = rate[chosen], after[chosen]
    return {"count": round(float(r.sum()), 2), "distance_after_cm": round(float((r * a).sum() / r.sum()), 3)}


def frontier(table: dict, top: int = 30) -> dict:
    sets = table["sets"]
    success = [np.array([x for r in s["runs"] for x in r["success"]], float) for s in sets]
    after = [100 * np.array([x for r in s["runs"] for x in r["distance_after_m"] if x is not None], float)
             for s in sets]
    icc_after = intraclass_correlation([a for a in after if len(a)])
    icc_success = intraclass_correlation(success)
    rate = np.array([s.mean() for s in success])
    raw_after = np.array([a.mean() if len(a) else np.nan for a in after])
    shrunk_rate = shrunk_means(success, icc_success)
    shrunk_after = shrunk_means(after, icc_after)
    usable = np.isfinite(raw_after)
    if usable.sum() < top:
        raise SystemExit(f"stay_frontier: only {int(usable.sum())} sets ever entered the circle; need {top}")

    def pick(score):
        order = np.argsort(np.where(usable, score, np.inf), kind="stable")
        return order[:top]

    curve = {}                     # lam (cm per unit rate, as text) -> the selection's measured and forecast point
    for lam in LAMBDAS_CM:
        raw_pick, shrunk_pick = pick(raw_after - lam * rate), pick(shrunk_after - lam * shrunk_rate)
        curve[f"{lam:g}"] = {"raw": selection(rate, raw_after, raw_pick),
                             "shrunk": selection(shrunk_rate, shrunk_after, shrunk_pick)}
    ranked = np.arange(top)        # the ranking's own order: rate first, then distance after entry
    names = sorted(sets[0]["metaparams"])
    correlations = {}
    for name in names:
        x = np.array([s["metaparams"][name] for s in sets], float)
        if np.ptp(x) == 0:
            continue
        rho_a, p_a = sps.spearmanr(x[usable], shrunk_after[usable])
        rho_r, p_r = sps.spearmanr(x, shrunk_rate)
        correlations[name] = {"distance_after": {"rho": round(float(rho_a), 3), "p": float(f"{p_a:.3g}")},
                              "rate": {"rho": round(float(rho_r), 3), "p": float(f"{p_r:.3g}")}}
    seeds_per_set = int(np.median([len(s) for s in success]))
    return {
        "sets": [{"source": s["source"], "rank": s["rank"], "rate": round(float(r), 4), "n": len(x),
                  "distance_after_cm": None if not np.isfinite(a) else round(float(a), 3), "entered": len(aa),
                  "shrunk_rate": round(float(sr), 4),
                  "shrunk_distance_after_cm": None if not np.isfinite(sa) else round(float(sa), 3)}
                 for s, r, x, a, aa, sr, sa in zip(sets, rate, success, raw_after, after, shrunk_rate, shrunk_after)],
        "icc": {"distance_after": round(icc_after, 4), "success": round(icc_success, 4)},
        "reliability_of_a_set_mean": {"distance_after": round(float(set_mean_reliability(icc_after, seeds_per_set)), 3),
                                      "success": round(float(set_mean_reliability(icc_success, seeds_per_set)), 3),
                                      "seeds": seeds_per_set},
        "frontier": curve,
        "ranking_top": {"raw": selection(rate, raw_after, ranked), "shrunk": selection(shrunk_rate, shrunk_after,
                                                                                        ranked)},
        "metaparameter_correlations": dict(sorted(correlations.items(),
                                                  key=lambda kv: -abs(kv[1]["distance_after"]["rho"]))),
    }


def reproduced_point(path: Path, target: str) -> dict:
    t = json.loads(Path(path).read_text())["targets"][target]
    d = t["measures"]["top30"]["distance_after_m"]   # the table's distances are in cm (its display unit)
    return {"file": str(path), "count": t["top30"], "n": t["top30_n"], "distance_after_cm": d["mean"],
            "sd": d["sd"]}


def plot(result: dict, paper: dict, target: str, figure: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.6))
    sources = sorted({s["source"].split(" ")[0] for s in result["sets"]})
    for k, src in enumerate(sources):
        pts = [(30 * s["rate"], s["distance_after_cm"]) for s in result["sets"]
               if s["source"].split(" ")[0] == src and s["distance_after_cm"] is not None]
        ax.plot(*zip(*pts), ".", color=f"C{k + 2}", alpha=0.5, label=f"one set, 30 x its rate ({src})")
    for kind, style in (("raw", "--"), ("shrunk", "-")):
        xs = [c[kind]["count"] for c in result["frontier"].values()]
        ys = [c[kind]["distance_after_cm"] for c in result["frontier"].values()]
        ax.plot(xs, ys, style, color="tab:blue", marker="o", ms=3,
                label=f"30-set selections, {'measured' if kind == 'raw' else 'forecast for fresh seeds'}")
    top = result["ranking_top"]["shrunk"]
    ax.plot(top["count"], top["distance_after_cm"], "D", color="tab:blue", mfc="white",
            label="the ranking's 30 best, forecast")
    ax.errorbar([paper["reached"]], [paper["distance_after_cm"]], yerr=[paper["sd"]], fmt="s", color="tab:red",
                label="paper")
    ax.axhline(1.25 * paper["distance_after_cm"], color="tab:red", ls=":", lw=1)
    ax.axvline(paper["reached"] - 0.5, color="tab:red", ls=":", lw=1)
    if result.get("reproduced"):
        r = result["reproduced"]
        ax.plot(r["count"], r["distance_after_cm"], "*", ms=12, color="black",
                label="the ranking's 30 best on seeds 0-29")
    ax.set(xlabel="networks of 30 that reach (one per set)", ylabel="mean distance after entry (cm)",
           title=f"musculoskeletal arm, {target} target: reaching against staying")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=120)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ranking", type=Path, help="a jaxarm rerank output folder (its ranking.json)")
    ap.add_argument("--reproduced", type=Path, default=None,
                    help="success_table.json of the ranking's preset reproduced on seeds 0-29")
    ap.add_argument("--top", type=int, default=30, help="sets per selection (mode (b): 30)")
    ap.add_argument("--json-out", type=Path, default=None, help="default RANKING/stay_frontier.json")
    ap.add_argument("--figure", type=Path, default=None, help="default RANKING/stay_frontier.png")
    args = ap.parse_args(argv)
    table = json.loads((args.ranking / "ranking.json").read_text())
    target = table["target"]
    result = frontier(table, args.top)
    if args.reproduced:
        result["reproduced"] = reproduced_point(args.reproduced, target)
    paper = PAPER[target]
    result = {"command": "python experiments/stay_frontier.py " + shlex.join(argv if argv is not None else sys.argv[1:]),
              "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
              "machine": f"{platform.machine()}, {platform.node()}", "ranking_command": table["command"],
              "ranking_seeds": table["protocol"]["seeds"], "target": target, "paper": paper, **result}
    json_out = args.json_out or args.ranking / "stay_frontier.json"
    json_out.parent.mkdir(parents=True, exist_ok=True)
    json_out.write_text(json.dumps(result, indent=1) + "\n")
    plot(result, paper, target, args.figure or args.ranking / "stay_frontier.png")
    print(f"{target} target, {len(result['sets'])} sets x {result['reliability_of_a_set_mean']['seeds']} seeds: "
          f"intraclass correlation {result['icc']['distance_after']:.2f} (distance after entry), "
          f"{result['icc']['success']:.2f} (success)")
    print("lambda (cm)  measured count, distance (cm)  forecast count, distance (cm)")
    for lam, c in result["frontier"].items():
        print(f"{lam:>11}  {c['raw']['count']:>14.1f}  {c['raw']['distance_after_cm']:>13.2f}  "
              f"{c['shrunk']['count']:>14.1f}  {c['shrunk']['distance_after_cm']:>13.2f}")
    t = result["ranking_top"]
    print(f"the ranking's 30 best: measured {t['raw']['count']:.1f} at {t['raw']['distance_after_cm']:.2f} cm, "
          f"forecast {t['shrunk']['count']:.1f} at {t['shrunk']['distance_after_cm']:.2f} cm; paper "
          f"{paper['reached']}/30 at {paper['distance_after_cm']} cm")
    if "reproduced" in result:
        r = result["reproduced"]
        print(f"reproduced on seeds 0-29: {r['count']}/{r['n']} at {r['distance_after_cm']:.2f} cm")
    print("metaparameter: Spearman rho with the distance after entry, with the success rate")
    for name, c in result["metaparameter_correlations"].items():
        print(f"  {name:<26} {c['distance_after']['rho']:+.2f} (p {c['distance_after']['p']:.2g})   "
              f"{c['rate']['rho']:+.2f} (p {c['rate']['p']:.2g})")
    print("->", json_out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
