"""Reaching against staying over a ranked pool of sets, and which metaparameters move along it (issue 49 item 1).

    python experiments/stay_frontier.py --ranking runs/rerank-msarm-left-2000 [--figure F.png] [--json-out F.json]

Reads a ``jaxarm rerank`` folder (its ranking.json: every set of the pool trained with the same fresh seeds at the
full protocol, each network's success and distance after first entry). Per set: the fraction of its networks that
reached, and over those the mean distance to the target centre from first entry to the end of the test. The
figure plots one point per set beside the paper's (29/30 and 3.87 cm for the left target) and the adoption box of
the issue (at least 29/30, at most 4.8 cm after entry); the 30 sets a preset made from the ranking would train in
(b) are marked. Printed and written: the pooled count and distance after entry of those 30 over the ranking's own
seeds (a forecast of (b), not the measurement, which trains other seeds), and, over the sets whose every network
reached, Spearman's rank correlation of each searched metaparameter with the distance after entry.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

#: Paper, Results 3.2 (musculoskeletal arm): successes of the 30 best sets and the mean distance to the centre after
#: first entry, cm (SD).
PAPER = {"left": {"reached": 29 / 30, "distance_after_cm": 3.87, "sd": 0.78},
         "bottom": {"reached": 26 / 30, "distance_after_cm": 3.20, "sd": 0.69}}
#: The issue's adoption rule for left (b): at least 29 of 30 reach, at most 4.8 cm after entry.
ADOPT = {"reached": 29 / 30, "distance_after_cm": 4.8}


def _ranks(x: np.ndarray) -> np.ndarray:
    """Average ranks (ties share their mean rank)."""
    order = np.argsort(x, kind="stable")
    ranks = np.empty(len(x))
    ranks[order] = np.arange(len(x), dtype=float)
    for v in np.unique(x):
        tie = x == v
        ranks[tie] = ranks[tie].mean()
    return ranks


def spearman(x, y) -> float | None:
    """Spearman's rank correlation (None when either side is constant)."""
    rx, ry = _ranks(np.asarray(x, float)), _ranks(np.asarray(y, float))
    if rx.std() == 0 or ry.std() == 0:
        return None
    return float(np.corrcoef(rx, ry)[0, 1])


def per_set(table: dict) -> list[dict]:
    """One row per set of the ranking, in rank order: reached / networks, mean distance after entry (cm) over the
    networks that reached (None if none did), the set's metaparameters."""
    rows = []
    for s in table["sets"]:
        success = [x for r in s["runs"] for x in r["success"]]
        after = [x for r in s["runs"] for x in r.get("distance_after_m", []) if x is not None]
        rows.append({"rank": s["rank"], "source": s["source"], "reached": int(sum(success)), "networks": len(success),
                     "distance_after_cm": round(100 * float(np.mean(after)), 3) if after else None,
                     "after_m": after, "metaparams": s["metaparams"]})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranking", type=Path, required=True, help="a `jaxarm rerank --out` folder")
    ap.add_argument("--top", type=int, default=30, help="the sets (b) would train (default 30)")
    ap.add_argument("--figure", type=Path, default=None, help="default RANKING/stay_frontier.png")
    ap.add_argument("--json-out", type=Path, default=None, help="default RANKING/stay_frontier.json")
    args = ap.parse_args(argv)

    table = json.loads((args.ranking / "ranking.json").read_text())
    target, paper = table["target"], PAPER[table["target"]]
    rows = per_set(table)
    top = rows[: args.top]
    top_after = [a for r in top for a in r["after_m"]]
    forecast = {"sets": len(top), "networks": sum(r["networks"] for r in top),
                "reached": sum(r["reached"] for r in top),
                "distance_after_cm": round(100 * float(np.mean(top_after)), 3) if top_after else None}
    forecast["rate"] = round(forecast["reached"] / forecast["networks"], 4) if forecast["networks"] else None
    certain = [r for r in rows if r["reached"] == r["networks"] and r["distance_after_cm"] is not None]
    names = sorted({k for r in rows for k in r["metaparams"]})
    moving = {n: {"spearman_with_distance_after": spearman([r["metaparams"][n] for r in certain],
                                                           [r["distance_after_cm"] for r in certain]),
                  "spearman_with_rate": spearman([r["metaparams"][n] for r in rows],
                                                 [r["reached"] / r["networks"] for r in rows])}
              for n in names}
    moving = {n: {k: (None if v is None else round(v, 3)) for k, v in c.items()} for n, c in moving.items()}
    seeds = table["protocol"]["seeds"]
    print(f"{table['arm']} arm, {target} target: {len(rows)} sets x {len(seeds)} seeds ({seeds[0]}..{seeds[-1]}), "
          f"{table['protocol']['epochs']} epochs; ranked by {table.get('rank_by', 'reach')}")
    print(f"sets whose every network reached: {len(certain)}; their distance after entry "
          f"{min(r['distance_after_cm'] for r in certain):.2f}-{max(r['distance_after_cm'] for r in certain):.2f} cm"
          if certain else "no set reached with every network")
    print(f"the top {forecast['sets']} on the ranking's own seeds: {forecast['reached']}/{forecast['networks']} "
          f"reached, {forecast['distance_after_cm']} cm after entry (paper {paper['distance_after_cm']} cm; "
          f"adoption: rate >= {ADOPT['reached']:.3f}, <= {ADOPT['distance_after_cm']} cm)")
    print("metaparameter                 rho(value, distance after | all reached)  rho(value, rate)")
    for n, c in sorted(moving.items(), key=lambda kv: -abs(kv[1]["spearman_with_distance_after"] or 0)):
        fmt = lambda v: "-" if v is None else f"{v:+.2f}"   # noqa: E731
        print(f"{n:<30}{fmt(c['spearman_with_distance_after']):>42}  {fmt(c['spearman_with_rate']):>16}")
    out = {"ranking": str(args.ranking), "command": table.get("command"), "date": table.get("date"),
           "protocol": {k: table["protocol"][k] for k in ("epochs", "epoch_s", "test_s", "seeds")},
           "paper": paper, "adoption_rule": ADOPT, "top_forecast": forecast,
           "sets": [{k: v for k, v in r.items() if k != "after_m"} for r in rows], "moving": moving}
    json_out = args.json_out or args.ranking / "stay_frontier.json"
    json_out.write_text(json.dumps(out, indent=1) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    jitter = np.random.default_rng(0).uniform(-0.012, 0.012, len(rows))   # sets of one rate side by side
    for r, j in zip(rows, jitter):
        if r["distance_after_cm"] is None:
            continue
        chosen = r["rank"] <= args.top
        ax.plot(r["reached"] / r["networks"] + j, r["distance_after_cm"], "o", ms=4,
                color="tab:blue" if chosen else "0.6", label=None)
    ax.plot([], [], "o", ms=4, color="tab:blue", label=f"the top {args.top} of the ranking ((b) would train them)")
    ax.plot([], [], "o", ms=4, color="0.6", label="the other sets of the pool")
    ax.errorbar([paper["reached"]], [paper["distance_after_cm"]], yerr=[paper["sd"]], fmt="s", color="tab:red",
                label="paper (30 best sets, one network each)")
    if forecast["distance_after_cm"] is not None:
        ax.plot([forecast["rate"]], [forecast["distance_after_cm"]], "D", color="tab:blue", mec="k",
                label=f"top {args.top} pooled (ranking's seeds)")
    ax.fill_between([ADOPT["reached"], 1.03], 0, ADOPT["distance_after_cm"], color="tab:green", alpha=0.12,
                    label="adoption rule")
    ax.set(xlabel=f"fraction of a set's networks that reached (seeds {seeds[0]}..{seeds[-1]})", xlim=(-0.05, 1.05),
           ylabel="mean distance to the centre after entry (cm)", ylim=(0, None),
           title=f"{table['arm']} arm, {target} target: {len(rows)} sets, {table['protocol']['epochs']} epochs")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    figure = args.figure or args.ranking / "stay_frontier.png"
    fig.savefig(figure, dpi=120)
    print("->", figure, "and", json_out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
