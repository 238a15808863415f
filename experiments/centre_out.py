"""Eight-target centre-out reaching from one network (issue 32 item 4): the paper's network plus a plastic target
code, trained with the eight targets alternating epoch by epoch, tested on every target; beside it the control,
the paper's network without the target code, trained and tested the same way.

    python experiments/centre_out.py [--arm simple] [--networks 30] [--epochs-per-target 3] [--seed 0]
                                     [--preset NAME] [--conditions target-code,control] [--out runs/centre-out]

Every condition trains ``--networks`` networks (seeds SEED .. SEED + n - 1) in one batch of the runner
(``jaxarm.run.Runner``: every device, checkpoints in OUT/CONDITION), epoch e toward target e % 8
(``jaxarm.task.centre_out``), then tests each network on all eight targets (1 s, no learning), and each untrained
network the same way (naive). Prints the success count per target and the distribution of targets reached per
network, and writes OUT/centre_out.json after each condition (a rerun skips the finished ones and resumes a killed
one). The same as ``jaxarm reproduce --task centre-out-8``, with the target code's options and ``--plastic`` to
choose which pathways learn.
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
from datetime import datetime, timezone
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--networks", type=int, default=30)
    ap.add_argument("--epochs-per-target", type=int, default=3)
    ap.add_argument("--epoch-s", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="original", help="metaparameters (jaxarm reproduce --list-presets)")
    ap.add_argument("--conditions", default="target-code,control")
    ap.add_argument("--cells-per-target", type=int, default=8)
    ap.add_argument("--code-rate-hz", type=float, default=100.0)
    ap.add_argument("--code-posts", default="EM", help="populations the target code projects to (comma-separated)")
    ap.add_argument("--code-pmat", type=float, default=0.2)
    ap.add_argument("--code-weight-mv", type=float, default=2.0)
    ap.add_argument("--plastic", default=None,
                    help="the target-code network's only plastic pathways, comma-separated (e.g. T->EM; default: "
                         "the paper's plastic pathways and the code's)")
    ap.add_argument("--out", type=Path, default=Path("runs/centre-out"))
    args = ap.parse_args(argv)

    from jaxarm.config.network import NetworkConfig
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.paper import presets
    from jaxarm.run_centre_out import run_with_control, table_markdown
    from jaxarm.task.centre_out import CentreOut

    mp = MetaParams.from_dict(presets.load(args.preset).best) if args.preset != "original" else MetaParams.original()

    task = CentreOut(epochs_per_target=args.epochs_per_target, epoch_duration_s=args.epoch_s)
    meta = {"command": "python experiments/centre_out.py " + " ".join(argv or __import__("sys").argv[1:]),
            "date": datetime.now(timezone.utc).strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, "
            f"{os.cpu_count()} cores", "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"],
                                                                capture_output=True, text=True).stdout.strip(),
            "config": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()}}
    code = dict(cells_per_target=args.cells_per_target, rate_hz=args.code_rate_hz,
                posts=tuple(args.code_posts.split(",")), pmat=args.code_pmat, weight_mv=args.code_weight_mv)
    config = LoopConfig(arm=args.arm, network=NetworkConfig(native_threads=os.cpu_count() or 1),
                        task=task.task_config())
    result = run_with_control(config, task, range(args.seed, args.seed + args.networks), mp, args.out,
                              conditions=tuple(args.conditions.split(",")), code=code,
                              plastic=None if args.plastic is None else tuple(args.plastic.split(",")), meta=meta,
                              progress=True)
    print(table_markdown(result))
    print("->", args.out / "centre_out.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
