"""Accelerator throughput: the pure-JAX (XLA) network kernel and the closed loop at 60 / 300 / 1000 / 3000 networks.

    python benchmarks/accelerator.py --json [--networks 60 300 1000 3000] [--seconds 1] [--budget-s 420]

One prepared script for a borrowed GPU or TPU (also runs on a CPU, with the XLA kernel, for a same-run ratio). For
each network count, in this process: the network alone under the training drive (closed loop of the simple arm,
babbling, plasticity bookkeeping; ``experiments/network_rates.py``) and a closed-loop training epoch of the
musculoskeletal arm with R-STDP (:mod:`jaxarm.train`), each compiled once and timed over ``--repeats`` runs of
``--seconds`` simulated seconds (median), plus peak device memory where the device reports it
(``memory_stats()["peak_bytes_in_use"]``). Sizes are tried in order and skipped once the elapsed time passes
``--budget-s`` (the script must end inside a device lease) or a size fails (out of memory: reported, not fatal).
Prints one JSON line: {"device": ..., "network_s_per_s": {"network_60": .., "loop_60": ..}, "peak_bytes": {...},
"compile_s": {...}, "skipped": {...}, "config": {...}}.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def peak_bytes(device) -> int | None:
    try:
        return int(device.memory_stats()["peak_bytes_in_use"])
    except Exception:   # noqa: BLE001 - CPU devices report no memory statistics
        return None


def timed(fn, args, repeats: int):
    import jax

    t0 = time.perf_counter()
    compiled = fn.lower(*args).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(*args))            # warm-up run
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls), compile_s


def network_alone(n: int, seconds: float, repeats: int):
    import jax

    sys.path.insert(0, REPO)
    from experiments.network_rates import make_training_drive
    from jaxarm.network import Network, NetworkConfig

    net = Network(NetworkConfig(kernel="xla"))
    keys = jax.random.split(jax.random.key(0), 2 * n)
    wirings = jax.jit(jax.vmap(net.make_wiring))(keys[:n])
    state, _ = jax.jit(jax.vmap(make_training_drive(net, 0.2)))(wirings, keys[n:])
    go_on = jax.jit(jax.vmap(make_training_drive(net, seconds, from_state=True)))
    wall, compile_s = timed(go_on, (wirings, keys[n:], state), repeats)
    return n * seconds / wall, compile_s


def closed_loop(n: int, seconds: float, repeats: int):
    import jax

    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.network import NetworkConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    fns = make_train(LoopConfig(arm="musculoskeletal", network=NetworkConfig(kernel="xla"),
                                task=TaskConfig(epochs=1, epoch_duration_s=seconds)))
    carry = jax.jit(jax.vmap(fns.init))(jax.random.split(jax.random.PRNGKey(0), n))
    epoch = jax.jit(jax.vmap(fns.epoch, in_axes=(0, None)))
    wall, compile_s = timed(epoch, (carry, MetaParams.original()), repeats)
    return n * seconds / wall, compile_s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print only the JSON line")
    ap.add_argument("--networks", type=int, nargs="+", default=[60, 300, 1000, 3000])
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated seconds per timed run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--budget-s", type=float, default=420.0, help="start no new size after this many seconds")
    ap.add_argument("--parts", nargs="+", default=["network", "loop"], choices=["network", "loop"])
    args = ap.parse_args(argv)
    import jax

    device = jax.devices()[0]
    out = {"device": {"platform": device.platform, "kind": device.device_kind, "count": jax.device_count()},
           "network_s_per_s": {}, "compile_s": {}, "peak_bytes": {}, "skipped": {},
           "config": vars(args) | {"jax": jax.__version__, "machine": platform.machine(),
                                   "date": time.strftime("%Y-%m-%d")}}
    t_start = time.perf_counter()
    for n in args.networks:
        for part in args.parts:
            key = f"{part}_{n}"
            if time.perf_counter() - t_start > args.budget_s:
                out["skipped"][key] = "time budget spent"
                continue
            try:
                rate, compile_s = (network_alone if part == "network" else closed_loop)(n, args.seconds, args.repeats)
            except Exception as e:   # noqa: BLE001 - e.g. out of device memory at this size: report, go on
                out["skipped"][key] = f"{type(e).__name__}: {str(e).splitlines()[0][:200]}"
                continue
            out["network_s_per_s"][key] = round(rate, 2)
            out["compile_s"][key] = round(compile_s, 1)
            out["peak_bytes"][key] = peak_bytes(device)
            if not args.json:
                print(f"{key:14s} {rate:10.2f} network-s/s  compile {compile_s:5.1f} s", flush=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
