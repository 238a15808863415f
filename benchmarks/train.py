"""Closed-loop training throughput: network + arm + plasticity, in network-seconds simulated per wall-second.

    python benchmarks/train.py --json [--networks 60] [--arm simple] [--seconds 10] [--repeats 3] [--record-s S]

Each measurement compiles one training epoch of ``--seconds`` simulated seconds (original metaparameters, babbling,
R-STDP on) over ``--networks`` networks (keys 0..N-1), in groups of ``--networks-at-once`` one after the other as
the commands run them on one device (default: theirs, 1 on a CPU since 2026-12-07, 8 before; 0: one vmap of all), runs it ``--repeats`` times
and reports the median. Each call copies every network's wiring and state in and out once (about 2.3 ms per network
on this project's 2-core machine: ``benchmarks/network.py``'s ``DEFAULT_SECONDS``), which training pays once per 30 s
epoch: 10 s epochs keep it below 3 % (2 s until 2026-12-08).
With ``--record-s S`` the epoch records every cell's spikes over its last S seconds (``jaxarm.record``,
``jaxarm train --record-train-s``): the cost of recording. Prints JSON: {"network_s_per_s": {"60": ...}, "compile_s": {...}, "config": {...}}.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import jax


def measure(arm: str, n: int, seconds: float, repeats: int, kernel: str = "auto", threads: int | None = None,
            record_s: float = 0.0, at_once: int = 0):
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    from jaxarm.config.network import NetworkConfig
    from jaxarm.parallel import map_networks
    from jaxarm.record import RecordConfig

    fns = make_train(LoopConfig(arm=arm, task=TaskConfig(epochs=1, epoch_duration_s=seconds),
                                network=NetworkConfig(kernel=kernel) if threads is None else
                                NetworkConfig(kernel=kernel, native_threads=threads)),
                     record=RecordConfig(train_last_s=record_s) if record_s else None)
    mp = MetaParams.original()
    carry = jax.jit(jax.vmap(fns.init))(jax.random.split(jax.random.PRNGKey(0), n))
    t0 = time.perf_counter()
    epoch_fn = fns.epoch_recorded if record_s else fns.epoch
    epoch = jax.jit(lambda c, mp: map_networks(lambda ci: epoch_fn(ci, mp), at_once)(c)).lower(carry, mp).compile()
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(epoch(carry, mp))
        times.append(time.perf_counter() - t0)
    return n * seconds / statistics.median(times), compile_s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--networks", type=int, nargs="+", default=[60])
    ap.add_argument("--arm", nargs="+", default=["simple", "musculoskeletal"], choices=["simple", "musculoskeletal"])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--kernel", default="auto", choices=["auto", "native", "xla"], help="NetworkConfig.kernel")
    ap.add_argument("--threads", type=int, default=None,
                    help="NetworkConfig.native_threads (default: $JAXARM_NATIVE_THREADS, else 1)")
    ap.add_argument("--networks-at-once", type=int, default=None, metavar="K",
                    help="networks stepped together, groups one after the other (default: the commands' default on "
                         "this backend, 1 on a CPU; 0: one vmap of all)")
    ap.add_argument("--record-s", type=float, default=0.0,
                    help="record every cell's spikes over the epoch's last S seconds (default 0: no recording)")
    args = ap.parse_args(argv)
    from jaxarm.config.network import NetworkConfig

    from jaxarm.parallel import networks_at_once

    if args.threads is None:
        args.threads = NetworkConfig().native_threads
    if args.networks_at_once is None:
        args.networks_at_once = networks_at_once()
    out = {"network_s_per_s": {}, "compile_s": {},
           "config": vars(args) | {"cpu_count": os.cpu_count(), "machine": platform.machine(), "jax": jax.__version__,
                                   "backend": jax.default_backend()}}
    for arm in args.arm:
        for n in args.networks:
            rate, comp = measure(arm, n, args.seconds, args.repeats, args.kernel, args.threads, args.record_s,
                                 args.networks_at_once)
            key = str(n) if len(args.arm) == 1 else f"{arm}_{n}"
            out["network_s_per_s"][key] = round(rate, 2)
            out["compile_s"][key] = round(comp, 1)
            if not args.json:
                print(f"{arm:16s} {n:4d} networks: {rate:8.2f} network-s/s (compile {comp:.0f} s)")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
