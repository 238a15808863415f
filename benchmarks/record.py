"""The cost of spike recording (jaxarm.record) in closed-loop training.

    python benchmarks/record.py [--networks 8] [--arm simple] [--seconds 2] [--record-s 2 0.5] [--pairs 7]
    python benchmarks/record.py --fingerprint        # run in two checkouts: equal hashes = the same programs

Default mode: compiles one training epoch of ``--seconds`` vmapped over ``--networks`` networks without recording
and, for each ``--record-s`` S, the epoch that records every cell's spikes over its last S seconds; then times them
alternately (plain, recorded, plain, ...) ``--pairs`` times in one process, so a machine whose load drifts slows
both alike, and reports each one's median network-seconds per second and the recorded/plain ratio of medians.

``--fingerprint``: the SHA-256 of the lowered (StableHLO) epoch and test programs without recording. Run in this
checkout and in a checkout of an earlier commit: equal hashes mean recording off compiles exactly the programs
the earlier commit did, so it costs nothing.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import statistics
import time

import jax


def _setup(arm: str, n: int, seconds: float):
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig

    config = LoopConfig(arm=arm, task=TaskConfig(epochs=1, epoch_duration_s=seconds, test_duration_s=1.0))
    return config, MetaParams.original(), jax.random.split(jax.random.PRNGKey(0), n)


def fingerprint(arm: str, n: int, seconds: float) -> dict:
    from jaxarm.train import make_train

    config, mp, keys = _setup(arm, n, seconds)
    fns = make_train(config)
    carry = jax.jit(jax.vmap(fns.init))(keys)
    out = {}
    for name, f, args in (("epoch", jax.vmap(fns.epoch, in_axes=(0, None)), (carry, mp)),
                          ("test", jax.vmap(fns.test, in_axes=(0, 0, None)), (keys, carry.trained, mp))):
        text = jax.jit(f).lower(*args).as_text(debug_info=False)
        out[name] = hashlib.sha256(text.encode()).hexdigest()[:16]
    return out


def compare(arm: str, n: int, seconds: float, record_s: list[float], pairs: int) -> dict:
    from jaxarm.record import RecordConfig
    from jaxarm.train import make_train

    config, mp, keys = _setup(arm, n, seconds)
    plain = make_train(config)
    carry = jax.jit(jax.vmap(plain.init))(keys)
    fns = {"off": jax.jit(jax.vmap(plain.epoch, in_axes=(0, None))).lower(carry, mp).compile()}
    for s in record_s:
        rec = make_train(config, RecordConfig(train_last_s=s))
        fns[f"record_{s:g}s"] = jax.jit(jax.vmap(rec.epoch_recorded, in_axes=(0, None))).lower(carry, mp).compile()
    times = {k: [] for k in fns}
    for k, f in fns.items():                       # warm-up
        jax.block_until_ready(f(carry, mp))
    for _ in range(pairs):
        for k, f in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(carry, mp))
            times[k].append(time.perf_counter() - t0)
    rate = {k: n * seconds / statistics.median(v) for k, v in times.items()}
    return {"network_s_per_s": {k: round(v, 2) for k, v in rate.items()},
            "ratio_to_off": {k: round(v / rate["off"], 3) for k, v in rate.items()},
            "times_s": {k: [round(t, 4) for t in v] for k, v in times.items()}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--networks", type=int, default=8)
    ap.add_argument("--arm", default="simple", choices=["simple", "musculoskeletal"])
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per epoch")
    ap.add_argument("--record-s", type=float, nargs="+", default=[2.0, 0.5],
                    help="recorded seconds at the end of the epoch, one program each (default 2 0.5)")
    ap.add_argument("--pairs", type=int, default=7, help="timed rounds of every program, alternated")
    ap.add_argument("--fingerprint", action="store_true", help="print the hashes of the unrecorded programs")
    args = ap.parse_args(argv)
    out = {"config": vars(args) | {"cpu_count": os.cpu_count(), "machine": platform.machine(), "jax": jax.__version__,
                                   "backend": jax.default_backend()}}
    if args.fingerprint:
        out["fingerprint"] = fingerprint(args.arm, args.networks, args.seconds)
    else:
        out |= compare(args.arm, args.networks, args.seconds, args.record_s, args.pairs)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
