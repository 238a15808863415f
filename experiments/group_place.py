"""Does a network's result depend on where it sits in its group of 8 (docs/scaling.md, jaxarm.cpu_arithmetic)?

    python experiments/group_place.py --arm simple --epochs 4 --train-s 30 --compare copies  # key 0 at all 8 places
    JAXARM_XLA_FMA=1 python experiments/group_place.py --arm simple --epochs 4 --train-s 30 --compare copies
    python experiments/group_place.py --arm musculoskeletal --train-s 10 --compare place   # key 0 at place 0 vs 4
    python experiments/group_place.py --arm musculoskeletal --train-s 20 --compare mates   # key 0 beside 1-7 vs 9-15
    python experiments/group_place.py --arm musculoskeletal --target bottom --preset msarm-rerank-bottom-stay \
        --train-s 60 --compare place                                      # key k with the preset's top[k], as (b)

Trains one group of 8 networks (one device; the authors' metaparameters, or with --preset key k trained with the
preset's k-th top set as in a reproduction's (b)) twice and prints which keys' whole training state differs in any
bit between the two batches; ``--compare copies`` trains one group holding key 0 eight times and prints the places
whose state differs from place 1's. ``JAXARM_XLA_FMA=1`` keeps XLA's fused multiply-add (jaxarm.cpu_arithmetic),
under which the copies differ at place 0 (simple arm, 4 x 30 s, 2026-12-05).
"""
import argparse
import tempfile

import jax
import numpy as np

from jaxarm import parallel

BATCHES = {"place": ([0, 1, 2, 3, 4, 5, 6, 7], [4, 5, 6, 7, 0, 1, 2, 3]),
           "mates": ([0, 1, 2, 3, 4, 5, 6, 7], [0, 9, 10, 11, 12, 13, 14, 15]),
           "copies": ([0] * 8,)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="musculoskeletal")
    ap.add_argument("--train-s", type=float, default=10.0, help="each epoch this many seconds (s)")
    ap.add_argument("--epochs", type=int, default=1)
    ap.add_argument("--compare", choices=tuple(BATCHES), default="place")
    ap.add_argument("--target", choices=("left", "bottom"), default="left")
    ap.add_argument("--preset", default=None, help="key k trains with this preset's top[k] (default: the authors')")
    args = ap.parse_args()
    parallel.start(devices=1)
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.paper import presets
    from jaxarm.run import Batch, stack_rows
    from jaxarm.task.config import Target, TaskConfig

    task = TaskConfig(target=args.target, epochs=args.epochs, epoch_duration_s=args.train_s, test_duration_s=0.2)
    config = LoopConfig(arm=args.arm, task=task)
    top = presets.load(args.preset).top_metaparams() if args.preset else None
    states = []
    for seeds in BATCHES[args.compare]:
        mps = [top[s] if top else MetaParams.original() for s in seeds]
        with tempfile.TemporaryDirectory() as d:
            batch = Batch(config, seeds, stack_rows(mps),
                          Target.stack([config.task.target] * 8), d, {"seeds": seeds})
            carry = batch.train(progress=False)[0]
        leaves = [np.asarray(x) for x in jax.tree.leaves(parallel.host(carry))]
        if args.compare == "copies":
            differ = [r for r in range(8) if any(np.any(x[r] != x[1]) for x in leaves)]
            print(f"{args.arm}, {args.target}, {args.preset or 'original'}, {args.epochs} x {args.train_s:g} s, key 0 "
                  f"at every place of one group: places whose training state differs from place 1's: "
                  f"{differ or 'none'}")
            return
        states.append({s: [x[r] for x in leaves] for r, s in enumerate(seeds)})
    common = sorted(set(states[0]) & set(states[1]))
    differ = [s for s in common if any(np.any(a != b) for a, b in zip(states[0][s], states[1][s]))]
    print(f"{args.arm}, {args.target}, {args.preset or 'original'}, {args.epochs} x {args.train_s:g} s, "
          f"compare {args.compare}: keys in both batches {common}; whole training state differs for {differ or 'none'}")


if __name__ == "__main__":
    main()
