"""A search's best sets counted on the evaluations that selected them: the paper's statistic, and its bias.

    python experiments/selection_counts.py runs/evolve-simple-left-fixedseed runs/evolve-simple-bottom-fixedseed
    python experiments/selection_counts.py runs/evolve-simple-left-long --markdown

The paper's counts (28/30, 27/30 on the simple arm) are "the best 30 metaparameter configurations" of its
evolutionary search. The original model is deterministic with fixed seeds (one wiring, one noise stream; spec
§6), so each of those 30 networks is the very run that ranked its set among the best: the count is taken on the
selection evaluations. ``jaxarm evolve --seed-mode fixed --seeds-per-candidate 1`` searches that way (every candidate
trains the same network), and this script reads what the search recorded for its top ``--top`` sets (``top_k.json``,
mean ``success_rate`` over each set's selection seeds and targets): how many reached, i.e. the paper's count made
the paper's way; and, from ``history.json``, how many of *all* the candidates reached (the pool the top sets were
drawn from; networks-equivalent when a candidate has several evaluations). ``jaxarm reproduce`` (b) instead trains each of those sets with a new seed, which is what a user
who takes a set away gets; the difference between the two is the selection bias.

For a search with several seeds per candidate or several targets the count is the sum over sets of the fraction of
their selection evaluations that reached (networks-equivalent out of ``--top``). When the search was re-ranked
(``--reevaluate-seeds``), its ``top_k.json`` is ordered by the re-evaluation and the rows still hold the *search's*
own metrics; the script reports them under the search's ranking (``search_rank``) so the count is of the sets the
search itself ranked best.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def selection_count(search_dir: Path, top: int = 30) -> dict:
    """The top ``top`` sets of a finished ``jaxarm evolve`` folder, counted on their selection evaluations."""
    try:
        top_k = json.loads((search_dir / "top_k.json").read_text())
        history = json.loads((search_dir / "history.json").read_text())
    except FileNotFoundError:
        raise SystemExit(f"{search_dir}: not a finished `jaxarm evolve` folder (needs top_k.json and history.json)")
    rows = [r for r in top_k.get("top_k", []) if "metrics" in r and "success_rate" in r["metrics"]]
    if not rows:
        raise SystemExit(f"{search_dir / 'top_k.json'}: no candidates with a success_rate metric")
    rows = sorted(rows, key=lambda r: r.get("search_rank", r["rank"]))[:top]
    cfg, fit = history["config"], history["fitness"]
    evaluations = int(history["generations_done"]) * int(cfg["population_size"])
    reached = sum(float(r["metrics"]["success_rate"]) for r in rows)
    # every candidate of the search, from the per-generation mean success (NaN-free generations only)
    means = [m for m in history["history"]["metrics_mean"].get("success_rate", []) if m is not None and m == m]
    pool = sum(means) * int(cfg["population_size"]) if means else None
    return {"search": str(search_dir), "fitness": fit["name"], "arm": fit["arm"], "targets": fit["targets"],
            "seed_mode": cfg["seed_mode"], "seeds_per_candidate": int(cfg["seeds_per_candidate"]),
            "candidates_evaluated": evaluations, "candidates_reached": None if pool is None else round(pool, 2),
            "top": len(rows), "reached": round(reached, 2), "fraction": round(reached / len(rows), 4)}


def markdown(rows: list[dict]) -> str:
    lines = ["| search | fitness | targets | seeds per candidate (mode) | candidates evaluated | of which reached | "
             "top sets reaching, on their selection runs |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        pool = "–" if r["candidates_reached"] is None else f"{r['candidates_reached']:g}"
        lines.append(f"| {r['search']} | {r['fitness']} | {', '.join(r['targets'])} | {r['seeds_per_candidate']} "
                     f"({r['seed_mode']}) | {r['candidates_evaluated']} | {pool} | {r['reached']:g}/{r['top']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("searches", nargs="+", type=Path, help="`jaxarm evolve --out` folders")
    ap.add_argument("--top", type=int, default=30, help="how many of the best sets (default 30)")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    if not 1 <= args.top <= 1000:
        ap.error(f"--top = {args.top}: must be in [1, 1000]")
    rows = [selection_count(d, args.top) for d in args.searches]
    print(markdown(rows) if args.markdown else "\n".join(json.dumps(r) for r in rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
