"""Reaching against staying across a search's best sets: for each of a preset's top sets, several networks trained
with it, their success count and their after-entry measures (issue 34 item 4).

    python experiments/stay_tradeoff.py [--preset msarm-cmaes-2cm-rerank] [--target left] [--sets 10] [--seeds 3]
                                        [--first-seed 1000] [--epochs 12] [--out runs/stay-tradeoff] [--figure F.png]

Every set trains the same ``--seeds`` networks (seeds ``--first-seed``, +1, ...: fresh, and common to all sets so
the sets are compared on the same networks), all of them in one batch over every device (checkpointed in ``--out``:
a rerun resumes), with the preset's protocol (``--epochs`` x 30 s, 1 s test). Per set it reports the count of
networks whose hand entered the 4 cm circle, and over those the paper's after-entry measures
(jaxarm.analysis.reach): mean distance to the target centre from first entry to the end of the test, mean speed
after entry, time inside. The figure plots, one point per set, the fraction that reached against the mean distance
after entry, with the paper's value and the 25 % bound the issue asks for; a JSON beside it holds every number.

How much of the distance after entry belongs to the set and how much to the network: the one-way intraclass
correlation over the networks that reached (sets as groups; ICC(1) from the ANOVA mean squares, the average group
size for unequal groups), and from it the reliability of a set's mean over k networks, k ICC / (1 + (k - 1) ICC)
(Spearman-Brown): how well a ranking on k seeds orders the sets by what they would do on other seeds.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

#: Paper, Results 3.2 (musculoskeletal arm): mean distance to the centre after first entry, cm (SD), and successes.
PAPER = {"left": {"distance_after_cm": 3.87, "sd": 0.78, "reached": 29 / 30},
         "bottom": {"distance_after_cm": 3.20, "sd": 0.69, "reached": 26 / 30}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="msarm-cmaes-2cm-rerank")
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="musculoskeletal")
    ap.add_argument("--target", choices=tuple(PAPER), default="left")
    ap.add_argument("--sets", type=int, default=10, help="the preset's best sets used, in its order")
    ap.add_argument("--seeds", type=int, default=3, help="networks per set")
    ap.add_argument("--first-seed", type=int, default=1000, help="the first network key (default 1000)")
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--epoch-s", type=float, default=30.0)
    ap.add_argument("--out", type=Path, default=Path("runs/stay-tradeoff"))
    ap.add_argument("--figure", type=Path, default=None, help="the PNG (default OUT/stay_tradeoff.png)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="give every set this metaparameter value (repeatable): the same sets with one change")
    args = ap.parse_args(argv)

    from jaxarm import parallel

    parallel.start()
    import jax

    from jaxarm.analysis.reach import reach_metrics
    from jaxarm.analysis.stats import intraclass_correlation, set_mean_reliability
    from jaxarm.config.validate import ConfigError
    from jaxarm.experiment import parse_overrides
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.paper import presets
    from jaxarm.run import Batch, stack_rows
    from jaxarm.task.config import Target, TaskConfig

    preset = presets.load(args.preset)
    try:
        overrides = parse_overrides(args.set)   # jaxarm train's --set: known names, within their bounds
    except ConfigError as e:
        raise SystemExit(f"stay_tradeoff: {e}") from None
    sets = [MetaParams.from_dict({**row["metaparams"], **overrides}) for row in preset.top[: args.sets]]
    if len(sets) < args.sets:
        raise SystemExit(f"--sets {args.sets}: the preset has {len(sets)} top sets")
    task = TaskConfig(target=args.target, epochs=args.epochs, epoch_duration_s=args.epoch_s)
    config = LoopConfig(arm=args.arm, task=task)
    seeds = [args.first_seed + s for s in range(args.seeds)] * len(sets)
    mps = stack_rows([m for m in sets for _ in range(args.seeds)])
    targets = Target.stack([task.target] * len(seeds))
    batch = Batch(config, seeds, mps, targets, args.out,
                  {"experiment": "stay_tradeoff", "preset": args.preset, "sets": args.sets, "seeds": args.seeds,
                   "target": args.target, "epochs": args.epochs, "epoch_s": args.epoch_s, "set": overrides,
                   "label": f"{args.sets} sets x {args.seeds} networks"})
    t0 = time.perf_counter()
    carry, *_ = batch.train()
    result = batch.test(carry.trained)
    wall = time.perf_counter() - t0
    target_xy = np.asarray(task.target_params.xy_m)
    m = jax.vmap(lambda xy: reach_metrics(xy, target_xy, task.update_interval_s, task.success_radius_m))(
        np.asarray(result.hand_m))
    m = {k: np.asarray(v).reshape(len(sets), args.seeds) for k, v in m._asdict().items()}
    rows = []
    for i in range(len(sets)):
        ok = m["success"][i]
        mean = (lambda v: float(np.nanmean(v[i][ok])) if ok.any() else None)
        rows.append({"set": i, "reached": int(ok.sum()), "networks": args.seeds,
                     "distance_after_cm": None if mean(m["distance_after_m"]) is None else
                     round(100 * mean(m["distance_after_m"]), 2),
                     "speed_after_m_s": mean(m["speed_after_m_s"]), "time_inside_ms":
                     None if mean(m["time_inside_s"]) is None else round(1000 * mean(m["time_inside_s"]), 1),
                     "min_distance_cm": [round(100 * float(d), 2) for d in m["min_distance_m"][i]]})
    paper = PAPER[args.target]
    print(f"{args.preset}, {args.arm} arm, {args.target} target: {args.sets} sets x {args.seeds} networks, "
          f"{args.epochs} x {args.epoch_s:g} s; {wall:.0f} s")
    print("set  reached  distance after entry (cm)  speed after (m/s)  time inside (ms)")
    for r in rows:
        d = "-" if r["distance_after_cm"] is None else f"{r['distance_after_cm']:.2f}"
        s = "-" if r["speed_after_m_s"] is None else f"{r['speed_after_m_s']:.3f}"
        ti = "-" if r["time_inside_ms"] is None else f"{r['time_inside_ms']:.0f}"
        print(f"{r['set']:>3}  {r['reached']}/{r['networks']:<5}  {d:>25}  {s:>17}  {ti:>16}")
    all_ok = m["success"]
    pooled = float(np.nanmean(m["distance_after_m"][all_ok])) * 100 if all_ok.any() else float("nan")
    print(f"all: {int(all_ok.sum())}/{all_ok.size} reached; distance after entry {pooled:.2f} cm "
          f"(paper {paper['distance_after_cm']} cm, bound {1.25 * paper['distance_after_cm']:.2f} cm)")
    groups = [100 * m["distance_after_m"][i][m["success"][i]] for i in range(len(sets))]
    icc = intraclass_correlation([g[np.isfinite(g)] for g in groups])
    reliability = None if icc is None else {k: round(set_mean_reliability(icc, k), 3) for k in (1, 3, 4, 8, 16, 32)}
    if icc is not None:
        print(f"distance after entry: intraclass correlation (sets) {icc:.3f}; reliability of a set's mean over k "
              f"networks: " + ", ".join(f"k={k}: {r:.2f}" for k, r in reliability.items()))
    out = {"config": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
           "wall_s": round(wall, 1), "rows": rows, "pooled_distance_after_cm": round(pooled, 2), "paper": paper,
           "distance_after_icc": None if icc is None else round(icc, 4), "set_mean_reliability": reliability}
    (args.out / "stay_tradeoff.json").write_text(json.dumps(out, indent=1))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for r in rows:
        if r["distance_after_cm"] is not None:
            ax.plot(r["reached"] / r["networks"], r["distance_after_cm"], "o", color="tab:blue")
            ax.annotate(str(r["set"]), (r["reached"] / r["networks"], r["distance_after_cm"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
    ax.errorbar([paper["reached"]], [paper["distance_after_cm"]], yerr=[paper["sd"]], fmt="s", color="tab:red",
                label="paper (30 best sets, one network each)")
    ax.axhline(1.25 * paper["distance_after_cm"], color="tab:red", ls=":", lw=1, label="paper + 25 %")
    ax.set(xlabel=f"fraction of a set's {args.seeds} networks that reached", xlim=(-0.05, 1.05),
           ylabel="mean distance to the centre after entry (cm)",
           title=f"{args.preset}: {args.target} target, set index = rank in the preset")
    ax.legend(fontsize=8)
    fig.tight_layout()
    figure = args.figure or args.out / "stay_tradeoff.png"
    fig.savefig(figure, dpi=120)
    print("->", figure)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
