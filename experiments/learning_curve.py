"""Success count after every training epoch: how long the networks should train.

    python experiments/learning_curve.py --preset simple-cmaes-shortfall-long --arm simple --targets left,bottom \
        --epochs 24 --out runs/curve-simple-shortfall-long
    python experiments/learning_curve.py --from runs/curve-simple-shortfall-long --markdown   # print a finished one

A preset's best set (with ``--set NAME=VALUE`` changes, if any) is trained with ``--networks`` seeds per target (network i uses ``PRNGKey(seed + i)``, as
``jaxarm reproduce`` (a)); after every epoch the networks are tested exactly as ``jaxarm train`` tests them (1 s,
learning off, same test keys), so the count after epoch 12 is the 12-epoch reproduction's count to the network, and
the count after epoch E is what ``jaxarm reproduce --epochs E`` would report. Epoch 0 is the naive network.

Per target and epoch it records: networks reaching the 4 cm circle, median closest approach (cm), how many of the
misses moved the elbow further than the shoulder ("elbow-led", see ``experiments/joint_excursions.py``), the median
largest excursion of each joint (rad), and the critic's rewards and punishments in the epoch (mean per network).

Outputs in ``--out``: ``learning_curve.json`` (the command, preset, metaparameters, seeds and the curves),
``learning_curve.png`` and, per target, an orbax checkpoint after every epoch (a killed run started again with the
same command resumes from its last completed epoch with the same results; ``jaxarm train --test-each-epoch``
keeps the same tests in its checkpoints).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

FIELDS = ("success", "closest_median_cm", "misses_elbow_led", "excursion_median_rad", "rewards_mean",
          "punishments_mean")


def summarize(test, start_rad) -> dict:
    """One epoch's test of N networks -> the curve's entries (host numbers)."""
    success = np.asarray(test.success, bool)
    dq = np.abs(np.asarray(test.q_rad) - np.asarray(start_rad)).max(axis=1)          # (N, 2) rad
    elbow_led = dq[:, 1] > dq[:, 0]
    return {"success": int(success.sum()),
            "closest_median_cm": round(100 * float(np.median(np.asarray(test.min_distance_m))), 3),
            "misses_elbow_led": int((elbow_led & ~success).sum()),
            "excursion_median_rad": [round(float(x), 4) for x in np.median(dq, axis=0)]}


def curve_for_target(arm: str, target: str, mp, epochs: int, n: int, seed: int, out: Path, epoch_s: float = 30.0,
                     log=print, stop_after: int | None = None) -> dict:
    """Train ``n`` networks on ``target`` for ``epochs`` epochs of ``epoch_s`` s, testing after each (and before the
    first). ``stop_after``: return after that many epochs of this call, as a kill would (tests use it)."""
    from jaxarm.loop import LoopConfig
    from jaxarm.run import Run
    from jaxarm.task.config import START_POSTURE_RAD, TaskConfig

    config = LoopConfig(arm=arm, task=TaskConfig(target=target, epochs=epochs, epoch_duration_s=epoch_s))
    # jaxarm train's networks, keys, test and checkpoints (out/TARGET/checkpoints; a rerun resumes)
    run = Run(config, n, seed, out / target, mp)
    t0 = time.perf_counter()
    _, history, *_ = run.train(progress=False, stop_after=stop_after,
                               test_each_epoch=lambda test: summarize(test, START_POSTURE_RAD))
    rows = [dict(epoch=0, **summarize(run.test(run.naive()), START_POSTURE_RAD), rewards_mean=None,
                 punishments_mean=None)]
    for e in sorted(run.learning_curve):
        rows.append(dict(epoch=e, **run.learning_curve[e],
                         rewards_mean=round(float(np.mean(history.rewards[e - 1])), 2),
                         punishments_mean=round(float(np.mean(history.punishments[e - 1])), 2)))
    last = rows[-1]
    log(f"{arm}/{target} {last['epoch']}/{epochs} epochs: {last['success']}/{n} reached, median closest "
        f"{last['closest_median_cm']:.1f} cm, {last['misses_elbow_led']} elbow-led misses "
        f"({time.perf_counter() - t0:.0f} s)")
    return {"target": target, "rows": rows}


def markdown(result: dict) -> str:
    targets = [c["target"] for c in result["curves"]]
    n = result["networks"]
    head = "| epoch | " + " | ".join(f"{t}: reached / median closest cm / elbow-led misses" for t in targets) + " |"
    lines = [head, "|---|" + "---|" * len(targets)]
    for e in range(len(result["curves"][0]["rows"])):
        cells = []
        for c in result["curves"]:
            r = c["rows"][e]
            cells.append(f"{r['success']}/{n} / {r['closest_median_cm']:.1f} / {r['misses_elbow_led']}")
        lines.append(f"| {e} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(result: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for c in result["curves"]:
        ep = [r["epoch"] for r in c["rows"]]
        axes[0].plot(ep, [r["success"] for r in c["rows"]], marker="o", ms=3, label=c["target"])
        axes[1].plot(ep, [r["closest_median_cm"] for r in c["rows"]], marker="o", ms=3, label=c["target"])
    xlabel = f"epochs trained ({result['epoch_s']:g} s each)"
    axes[0].set(xlabel=xlabel, ylabel=f"networks reaching (of {result['networks']})",
                ylim=(0, result["networks"] + 1))
    axes[1].axhline(4.0, color="k", lw=0.8, ls=":")
    axes[1].set(xlabel=xlabel, ylabel="median closest approach, cm")
    axes[0].legend(title="target")
    changed = "".join(f", {k}={v:g}" for k, v in result.get("set", {}).items())
    fig.suptitle(f"{result['preset']}{changed}, {result['arm']} arm, seeds {result['seed']}–{result['seed'] + result['networks'] - 1}",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="original", help="preset name or .json path; its best set is trained")
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--targets", default="left,bottom", help="comma-separated targets")
    ap.add_argument("--epochs", type=int, default=24, help="epochs of 30 s to train (the paper's protocol: 12)")
    ap.add_argument("--epoch-s", type=float, default=30.0, help="seconds per epoch (paper: 30)")
    ap.add_argument("--networks", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0, help="network i uses PRNGKey(seed + i)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="change one of the preset's metaparameters (repeatable)")
    ap.add_argument("--out", type=Path, help="output folder (a rerun resumes it)")
    ap.add_argument("--from", dest="from_", type=Path, help="print a finished run's curve instead of training")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    if args.from_ is not None:
        result = json.loads((args.from_ / "learning_curve.json").read_text())
        print(markdown(result) if args.markdown else json.dumps(result, indent=1))
        return 0
    if args.out is None:
        ap.error("--out is required (or --from a finished run)")
    if not 1 <= args.epochs <= 200:
        ap.error(f"--epochs = {args.epochs}: must be in [1, 200]")
    if not 1 <= args.networks <= 4096:
        ap.error(f"--networks = {args.networks}: must be in [1, 4096]")
    if not 0.01 <= args.epoch_s <= 600:
        ap.error(f"--epoch-s = {args.epoch_s}: must be in [0.01, 600] s")
    from jaxarm.config.validate import ConfigError
    from jaxarm.paper import presets
    from jaxarm.experiment import parse_overrides
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.task.config import TARGET_ANGLES_RAD

    try:
        overrides = parse_overrides(args.set)
    except ConfigError as e:
        ap.error(str(e))

    targets = [t.strip() for t in args.targets.split(",") if t.strip()]
    for t in targets:
        if t not in TARGET_ANGLES_RAD:
            ap.error(f"--targets: unknown target {t!r}; known: {', '.join(TARGET_ANGLES_RAD)}")
    mp = MetaParams.from_dict({**presets.load(args.preset).best_metaparams().to_dict(), **overrides})
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    curves = [curve_for_target(args.arm, t, mp, args.epochs, args.networks, args.seed, args.out, args.epoch_s)
              for t in targets]
    result = {"command": "python " + " ".join([sys.argv[0]] + list(argv if argv is not None else sys.argv[1:])),
              "preset": args.preset, "set": overrides, "arm": args.arm, "networks": args.networks, "seed": args.seed,
              "epochs": args.epochs, "epoch_s": args.epoch_s, "metaparams": mp.to_dict(), "fields": FIELDS, "curves": curves,
              "wall_s_this_invocation": round(time.perf_counter() - t0, 1)}
    (args.out / "learning_curve.json").write_text(json.dumps(result, indent=1))
    plot(result, args.out / "learning_curve.png")
    print(markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
