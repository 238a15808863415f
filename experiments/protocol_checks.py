"""Train and test a preset's best set with one protocol change, to see what that change does to the success count.

    python experiments/protocol_checks.py --preset simple-cmaes-shortfall-rerank --target left \
        --change angle-critic --out runs/exp-critic-angle-left

Changes (each one :class:`jaxarm.loop.LoopConfig` field; ``none`` is the original's protocol, what ``jaxarm
reproduce`` runs):

* ``paper-babbling``: ``BabblingConfig(variant="paper")``, one muscle group at a time for up to 1.5 s, as the paper
  describes it (the code babbles single groups or pairs for 100-624 ms);
* ``reseed-noise``: ``reseed_noise_each_epoch=True``, fresh background-noise streams every epoch (the original
  restarts them identically);
* ``angle-critic``: ``critic_error="angle"``, the critic compares joint-space distances to the target posture (rad)
  instead of hand-target distances (m); a diagnostic, not the original's setting.

``--set NAME=VALUE`` (repeatable) changes one of the preset's metaparameters instead (or as well), within its
bounds, e.g. ``--set explore_tot=8`` (the code's babbling without pairs); ``--change none --set ...`` is the
original's protocol with that set.

Network i uses ``PRNGKey(seed + i)`` as in ``jaxarm reproduce`` (a); ``none`` therefore reproduces its (a) count.
The output folder is an ordinary ``jaxarm train`` folder (results.json, trajectories.npz, reach.png, checkpoints;
a rerun resumes it), which ``experiments/joint_excursions.py`` and ``experiments/reach_stats.py`` read.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

CHANGES = ("none", "paper-babbling", "reseed-noise", "angle-critic")


def loop_config(arm: str, target: str, change: str, epochs: int | None = None):
    """The closed-loop configuration of ``change`` (see the module docstring)."""
    from jaxarm.learning.babbling import BabblingConfig
    from jaxarm.learning.rstdp import RSTDPConfig
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig

    if change not in CHANGES:
        raise ValueError(f"change = {change!r}: must be one of {', '.join(CHANGES)}")
    task = TaskConfig(target=target) if epochs is None else TaskConfig(target=target, epochs=epochs)
    extra = {"paper-babbling": {"rule": RSTDPConfig(babbling=BabblingConfig(variant="paper"))},
             "reseed-noise": {"reseed_noise_each_epoch": True},
             "angle-critic": {"critic_error": "angle"}}.get(change, {})
    return LoopConfig(arm=arm, task=task, **extra)


def main(argv=None) -> int:
    from jaxarm.paper import presets
    from jaxarm.experiment import write_outputs
    from jaxarm.run import Run

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", required=True, help="preset name or .json path; its best set is trained")
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--target", default="left")
    ap.add_argument("--change", choices=CHANGES, required=True)
    ap.add_argument("--networks", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0, help="network i uses PRNGKey(seed + i)")
    ap.add_argument("--epochs", type=int, default=None, help="training epochs (default: the task's 12)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="change one of the preset's metaparameters (repeatable)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    if not 1 <= args.networks <= 4096:
        ap.error(f"--networks = {args.networks}: must be in [1, 4096]")
    # Run's checkpoint identity does not hold the LoopConfig: keep one folder to one change, so a rerun resumes it
    from jaxarm.config.validate import ConfigError
    from jaxarm.experiment import parse_overrides
    from jaxarm.learning.metaparams import MetaParams

    try:
        overrides = parse_overrides(args.set)
    except ConfigError as e:
        ap.error(str(e))
    marker = args.out / "protocol_check.json"
    identity = {"preset": args.preset, "change": args.change, **({"set": overrides} if overrides else {})}
    if marker.exists() and json.loads(marker.read_text()) != identity:
        ap.error(f"--out {args.out} holds a run of {json.loads(marker.read_text())}; use another folder")
    mp = MetaParams.from_dict({**presets.load(args.preset).best_metaparams().to_dict(), **overrides})
    args.out.mkdir(parents=True, exist_ok=True)
    marker.write_text(json.dumps(identity))
    run = Run(loop_config(args.arm, args.target, args.change, args.epochs), args.networks, args.seed, args.out, mp)
    carry, history, wall, epochs_run, compile_s = run.train(progress=False)
    res = write_outputs(run, run.test(carry.trained), run.test(run.naive()), history, wall, epochs_run, compile_s)
    changed = "".join(f", {k}={v:g}" for k, v in overrides.items())
    print(f"{args.preset}{changed}, {args.arm} arm, {args.target} target, change {args.change}: {res['success_count']}/"
          f"{args.networks} reached (naive {res['naive']['success_count']}/{args.networks}) -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
