"""Network throughput: network-seconds simulated per wall-second at 1, 60 and 300 networks (plasticity bookkeeping
on), compile time, peak memory, capacity counters.

    python benchmarks/network.py --json                 # default dt, 1/60/300 networks, 3 repeats each (medians)
    python benchmarks/network.py --dt 0.5 --networks 60 --repeats 5

Each network size runs in its own process (so peak RSS is that size's, and compile time is a cold compile). The
drive is the training drive of experiments/network_rates.py (simple arm in closed loop, motor babbling, no
plasticity), with plasticity bookkeeping (tags on every postsynaptic spike) on; every network has its own wiring and
noise. The networks first run ``--warmup`` simulated seconds (untimed: the start of every run is a synchronous
transient — all P cells fire at 1 ms — that costs extra spike-list passes; it is timed separately as
``transient_network_s_per_s``), then timed runs continue from there. Throughput = networks x simulated seconds /
wall seconds of the compiled run (median over repeats), compile excluded and reported separately.

The Brian2 C++-standalone comparison asked for by the issue is not implemented: the JSON's "brian2" field says so
(and whether brian2 is installed), and no "brian2_network_s_per_s"/"ratio_vs_brian2" keys are emitted.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_SECONDS = {1: 2.0, 60: 1.0, 300: 0.5}


def worker(n_networks: int, dt_ms: float | None, seconds: float, repeats: int, seed: int, warmup: float) -> dict:
    """Time one network count in this process."""
    sys.path.insert(0, REPO)
    import jax

    from experiments.network_rates import make_training_drive
    from jaxarm.network import Network, NetworkConfig

    config = NetworkConfig() if dt_ms is None else NetworkConfig(dt_ms=dt_ms)
    assert config.plasticity_bookkeeping
    net = Network(config)
    keys = jax.random.split(jax.random.key(seed), 2 * n_networks)
    wirings = jax.jit(jax.vmap(net.make_wiring))(keys[:n_networks])
    start = jax.jit(jax.vmap(make_training_drive(net, warmup)))
    go_on = jax.jit(jax.vmap(make_training_drive(net, seconds, from_state=True)))
    t0 = time.perf_counter()
    state, _ = start(wirings, keys[n_networks:])
    jax.block_until_ready(state)
    first_call_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    compiled = go_on.lower(wirings, keys[n_networks:], state).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(start(wirings, keys[n_networks:]))   # the start transient alone, already compiled
    transient_s = time.perf_counter() - t0
    walls, cpus = [], []
    passes0 = np.asarray(state.net.counters.extra_passes).sum()
    for r in range(repeats):
        run_keys = jax.random.split(jax.random.key(seed + 1 + r), n_networks)
        t0, c0 = time.perf_counter(), time.process_time()
        state, _ = compiled(wirings, run_keys, state)
        jax.block_until_ready(state)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    counters = state.net.counters
    spikes = np.asarray(state.net.spike_count)
    return {
        "networks": n_networks, "dt_ms": config.dt_ms, "simulated_s": seconds, "repeats": repeats,
        "warmup_s": warmup,
        "network_s_per_s": n_networks * seconds / float(np.median(walls)),
        "network_s_per_cpu_s": n_networks * seconds / float(np.median(cpus)),
        "transient_network_s_per_s": n_networks * warmup / transient_s,
        "wall_s": walls, "compile_s": compile_s, "first_call_s_warmup_compile_and_run": first_call_s,
        "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2,
        "lost_spikes": int(np.sum(counters.lost_spikes)),
        "wiring_out_overflow": int(np.sum(wirings.out_overflow)),
        "extra_passes_per_network_s": float(np.sum(counters.extra_passes) - passes0) / (n_networks * seconds * repeats),
        "mean_rate_hz": float(spikes[:, :config.n_cells].mean() / (warmup + seconds * repeats)),
        "block_steps": net.block_steps, "spike_capacity": list(config.spike_capacity),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", default="1,60,300", help="comma-separated network counts")
    ap.add_argument("--dt", type=float, default=None, help="clock step, ms (default: NetworkConfig's)")
    ap.add_argument("--seconds", type=float, default=None, help="simulated seconds per timed run (default by size)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=float, default=1.0, help="untimed simulated seconds before timing")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker is not None:
        seconds = args.seconds or DEFAULT_SECONDS.get(args.worker, 1.0)
        print(json.dumps(worker(args.worker, args.dt, seconds, args.repeats, args.seed, args.warmup)))
        return 0

    runs = {}
    for n in (int(x) for x in args.networks.split(",")):
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", str(n), "--repeats", str(args.repeats),
               "--seed", str(args.seed), "--warmup", str(args.warmup)]
        if args.dt is not None:
            cmd += ["--dt", str(args.dt)]
        if args.seconds is not None:
            cmd += ["--seconds", str(args.seconds)]
        out = subprocess.run(cmd, capture_output=True, text=True, check=True)
        runs[n] = json.loads(out.stdout.strip().splitlines()[-1])
        if not args.json:
            r = runs[n]
            print(f"{n:4d} networks: {r['network_s_per_s']:7.2f} network-s/s (wall, median of {r['repeats']}), "
                  f"{r['network_s_per_cpu_s']:7.2f} per CPU-s, compile {r['compile_s']:.1f} s, "
                  f"peak RSS {r['peak_rss_gb']:.2f} GB, lost spikes {r['lost_spikes']}", flush=True)
    any_run = next(iter(runs.values()))
    result = {
        "network_s_per_s": {str(n): r["network_s_per_s"] for n, r in runs.items()},
        "network_s_per_cpu_s": {str(n): r["network_s_per_cpu_s"] for n, r in runs.items()},
        "transient_network_s_per_s": {str(n): r["transient_network_s_per_s"] for n, r in runs.items()},
        "peak_rss_gb": {str(n): r["peak_rss_gb"] for n, r in runs.items()},
        "compile_s": {str(n): r["compile_s"] for n, r in runs.items()},
        "overflows": sum(r["lost_spikes"] + r["wiring_out_overflow"] for r in runs.values()),
        "extra_passes_per_network_s": {str(n): r["extra_passes_per_network_s"] for n, r in runs.items()},
        "dt_ms": any_run["dt_ms"], "block_steps": any_run["block_steps"], "spike_capacity": any_run["spike_capacity"],
        "cpu_count": os.cpu_count(), "load_average_at_end": os.getloadavg(),
        "brian2": _brian2_status(),
        "runs": runs,
    }
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(f"overflows {result['overflows']}; load average {result['load_average_at_end']}; "
              f"brian2: {result['brian2']}")
    return 0


def _brian2_status() -> str:
    try:
        import brian2  # noqa: F401
    except ImportError:
        return "absent (install the 'bench' extra to compare)"
    return "installed, but the Brian2 port of the network is not implemented yet"


if __name__ == "__main__":
    sys.exit(main())
