"""Network throughput: network-seconds simulated per wall-second at 1, 60 and 300 networks (plasticity bookkeeping
on), compile time, peak memory, capacity counters.

    python benchmarks/network.py --json                 # default dt, 1/60/300 networks, 3 repeats each (medians)
    python benchmarks/network.py --dt 0.5 --networks 60 --repeats 5
    python benchmarks/network.py --json --networks 1,60 --brian2    # with the Brian2 comparison (needs '.[bench]')

Each network size runs in its own process (so peak RSS is that size's, and compile time is a cold compile). The
drive is the training drive of experiments/network_rates.py (simple arm in closed loop, motor babbling, no
plasticity), with plasticity bookkeeping (tags on every postsynaptic spike) on; every network has its own wiring and
noise. The networks run in groups of ``--networks-at-once`` one after the other, as the commands run them on one
device (default: theirs, 1 on a CPU since 2026-12-07, 8 before; 0: one vmap of all). The networks first run ``--warmup`` simulated seconds
(untimed: the start of every run is a synchronous transient — all P cells fire at 1 ms — that costs extra
spike-list passes; it is timed separately as ``transient_network_s_per_s``), then timed runs continue from there.
Throughput = networks x simulated seconds / wall seconds of the compiled run (median over repeats), compile
excluded and reported separately.

Brian2 comparison (``--brian2``; done by default whenever brian2 is installed, ``--no-brian2`` skips it): the same
network in Brian2's C++ standalone mode (benchmarks/brian2_network.py: same cells, same synapses as the wiring of
``--seed``, same background, same dt; fixed drive — P cells coding the arm's start posture — and no plasticity, so
Brian2 gets the lighter job), one network, ``--brian2-seconds`` simulated, its compiled binary run ``--repeats``
times (median), build (code generation + C++ compile) excluded and reported separately. Added to the JSON:
``brian2_network_s_per_s`` (one network, single-threaded), ``brian2_build_s``, ``brian2_rates_hz`` and, for
comparison, ``jaxarm_fixed_drive_rates_hz`` (jaxarm under the same fixed drive, 8 noise realisations) and
``ratio_vs_brian2``: jaxarm's network-seconds per second at each network count (its batched throughput, what a user
running that many networks gets) divided by Brian2's for one network — key "1" is jaxarm one network against Brian2
one network. A 1-network jaxarm run is added to ``--networks`` when missing. Without brian2 the "brian2" field says
it is absent and those keys are left out.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Simulated seconds of each timed run, at every network count: the run length of the Brian2 comparison, and a
#: third of a training epoch. Each call of a map over networks copies every network's wiring and state in and out
#: (about 2.3 ms per network per call on this project's 2-core machine, 2026-12-08: 64 networks ran 86.5 network-s/s
#: in 1 s runs and 106 in 10 s runs), which training pays once per 30 s epoch; until 2026-12-08 the runs were 2 / 1 /
#: 0.5 s at 1 / 60 / 300 networks, and at 60 and 300 networks the figures were largely that copy.
DEFAULT_SECONDS = 10.0


def worker(n_networks: int, dt_ms: float | None, seconds: float, repeats: int, seed: int, warmup: float,
           kernel: str = "auto", threads: int = 1, at_once: int | None = None,
           same_step_inhibition: str | None = None) -> dict:
    """Time one network count in this process."""
    sys.path.insert(0, REPO)
    import jax

    from experiments.network_rates import make_training_drive
    from jaxarm.network import Network, NetworkConfig
    from jaxarm.parallel import map_networks, networks_at_once

    if at_once is None:
        at_once = networks_at_once()

    config = NetworkConfig(kernel=kernel, native_threads=threads)
    if dt_ms is not None:
        config = dataclasses.replace(config, dt_ms=dt_ms)
    if same_step_inhibition is not None:
        config = dataclasses.replace(config, same_step_inhibition=same_step_inhibition)
    assert config.plasticity_bookkeeping
    net = Network(config)
    keys = jax.random.split(jax.random.key(seed), 2 * n_networks)
    wirings = jax.jit(jax.vmap(net.make_wiring))(keys[:n_networks])
    start = jax.jit(map_networks(make_training_drive(net, warmup), at_once))
    go_on = jax.jit(map_networks(make_training_drive(net, seconds, from_state=True), at_once))
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
        "networks": n_networks, "dt_ms": config.dt_ms, "same_step_inhibition": config.same_step_inhibition,
        "simulated_s": seconds, "repeats": repeats,
        "kernel": "native" if net.uses_native_kernel else "xla", "native_threads": config.native_threads,
        "warmup_s": warmup, "networks_at_once": at_once,
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


def brian2_installed() -> bool:
    """Whether brian2 is importable (without importing it here: it runs in its own process)."""
    import importlib.util

    return importlib.util.find_spec("brian2") is not None


def run_brian2(dt_ms: float | None, seconds: float, repeats: int, seed: int, jaxarm_noise: int = 4) -> dict:
    """benchmarks/brian2_network.py in its own process; its JSON result."""
    cmd = [sys.executable, os.path.join(REPO, "benchmarks", "brian2_network.py"), "--json", "--seconds", str(seconds),
           "--repeats", str(repeats), "--seed", str(seed), "--jaxarm-rates", str(jaxarm_noise)]
    if dt_ms is not None:
        cmd += ["--dt", str(dt_ms)]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(f"Brian2 benchmark failed ({' '.join(cmd)}):\n{out.stderr[-4000:]}")
    text = out.stdout
    return json.loads(text[text.index("{"):])


def main(argv=None) -> int:
    sys.path.insert(0, REPO)
    from jaxarm.config.network import SAME_STEP_INHIBITION

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", default="1,60,300", help="comma-separated network counts")
    ap.add_argument("--dt", type=float, default=None, help="clock step, ms (default: NetworkConfig's)")
    ap.add_argument("--seconds", type=float, default=None,
                    help=f"simulated seconds per timed run (default {DEFAULT_SECONDS:g} at every network count)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=float, default=1.0, help="untimed simulated seconds before timing")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    b2 = ap.add_mutually_exclusive_group()
    b2.add_argument("--brian2", dest="brian2", action="store_true", default=None,
                    help="compare with Brian2 C++ standalone (default: when brian2 is installed)")
    b2.add_argument("--no-brian2", dest="brian2", action="store_false", help="skip the Brian2 comparison")
    ap.add_argument("--brian2-seconds", type=float, default=10.0, help="simulated seconds of each Brian2 run")
    ap.add_argument("--kernel", default="auto", choices=["auto", "native", "xla"],
                    help="NetworkConfig.kernel (auto: the native CPU kernel when it builds)")
    ap.add_argument("--threads", type=int, default=1, help="NetworkConfig.native_threads")
    ap.add_argument("--networks-at-once", type=int, default=None, metavar="K",
                    help="networks stepped together, groups one after the other (default: the commands' default on "
                         "this backend, 1 on a CPU; 0: one vmap of all)")
    ap.add_argument("--same-step-inhibition", choices=SAME_STEP_INHIBITION, default=None,
                    help="NetworkConfig.same_step_inhibition (default: NetworkConfig's)")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker is not None:
        seconds = args.seconds or DEFAULT_SECONDS
        print(json.dumps(worker(args.worker, args.dt, seconds, args.repeats, args.seed, args.warmup, args.kernel,
                                args.threads, args.networks_at_once, args.same_step_inhibition)))
        return 0

    installed = brian2_installed()
    compare = installed if args.brian2 is None else args.brian2
    if compare and not installed:
        ap.error("--brian2: brian2 is not installed: install the benchmark extra with `pip install -e '.[bench]'`")
    counts = [int(x) for x in args.networks.split(",")]
    if compare and 1 not in counts:
        counts = [1] + counts
    runs = {}
    for n in counts:
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", str(n), "--repeats", str(args.repeats),
               "--seed", str(args.seed), "--warmup", str(args.warmup), "--kernel", args.kernel,
               "--threads", str(args.threads)]
        if args.networks_at_once is not None:
            cmd += ["--networks-at-once", str(args.networks_at_once)]
        if args.dt is not None:
            cmd += ["--dt", str(args.dt)]
        if args.same_step_inhibition is not None:
            cmd += ["--same-step-inhibition", args.same_step_inhibition]
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
        "kernel": any_run["kernel"], "native_threads": any_run["native_threads"],
        "dt_ms": any_run["dt_ms"], "same_step_inhibition": any_run["same_step_inhibition"],
        "block_steps": any_run["block_steps"], "spike_capacity": any_run["spike_capacity"],
        "cpu_count": os.cpu_count(), "load_average_at_end": os.getloadavg(),
        "brian2": ("compared: benchmarks/brian2_network.py" if compare else
                   "installed; comparison skipped (--no-brian2)" if installed else
                   "absent (install the 'bench' extra to compare: pip install -e '.[bench]')"),
        "runs": runs,
    }
    if compare:
        b2r = run_brian2(args.dt, args.brian2_seconds, args.repeats, args.seed, jaxarm_noise=8)
        b = b2r["brian2"]
        result.update({
            "brian2_network_s_per_s": b["network_s_per_s"],
            "brian2_build_s": b["build_s"],
            "brian2_rates_hz": b["rates_hz"],
            "jaxarm_fixed_drive_rates_hz": b2r["jaxarm_fixed_drive"]["rates_hz"],
            "ratio_vs_brian2": {str(n): r["network_s_per_s"] / b["network_s_per_s"] for n, r in runs.items()},
            "brian2_detail": b2r,
            "load_average_at_end": os.getloadavg(),
        })
        if not args.json:
            print(f"Brian2 {b['brian2_version']} C++ standalone, 1 network, {b['simulated_s']:g} s: "
                  f"{b['network_s_per_s']:.2f} network-s/s (median of {b['repeats']}), build {b['build_s']:.1f} s; "
                  "jaxarm / Brian2: " + ", ".join(f"{n} networks {v:.2f}"
                                                  for n, v in result["ratio_vs_brian2"].items()))
            print("rates Hz, Brian2 / jaxarm (same fixed drive): " + ", ".join(
                f"{p} {b['rates_hz'][p]:.2f}/{result['jaxarm_fixed_drive_rates_hz'][p]:.2f}" for p in b["rates_hz"]))
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(f"overflows {result['overflows']}; load average {result['load_average_at_end']}; "
              f"brian2: {result['brian2']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
