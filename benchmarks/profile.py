"""Where a closed-loop network-second goes: one thread, both arms, 1 and 64 networks.

    python benchmarks/profile.py [--json-out docs/results/profile.json] [--networks 1 64] [--arm simple musculoskeletal]
        [--seconds 2 0.5] [--repeats 3]
    python benchmarks/profile.py --table-from docs/results/profile.json     # the table of a saved run

The process pins itself to one CPU and the native kernel to one thread. For each arm and network count it times,
as medians of ``--repeats`` compiled runs of ``--seconds`` simulated seconds (one per network count), starting
from the training state of networks 0..N-1 (the authors' metaparameters, babbling on), in groups of
``--networks-at-once`` one after the other as the commands run them (default 1 on a CPU since 2026-12-07, 8 before; 0: one vmap of all):

* ``train``: the closed loop as training runs it (network, readout, arm, critic, R-STDP, babbling, scaling);
* ``test``: the same loop without learning; ``learning`` = train - test;
* ``arm``: the arm alone for the same intervals (its excitations fixed); for the musculoskeletal arm also with one
  and with two linearly-implicit muscle steps per skeleton step (times T1, T2), which splits it into
  ``arm skeleton`` (2 T1 - T2: the second muscle step costs what the first does) and ``arm muscles`` (the rest);
* ``readout``: the EM window and excitations alone;
* the native kernel's phases inside ``test``, from its profiling build (``jaxarm.network.native.enable_profiling``:
  the same kernel with phase timers; its overhead is printed): copy-in and set-up, the generators' (P) input,
  noise draws, the cells' update (decay, input jumps and threshold test: one phase since 2026-12-05, three phases
  before), spike bookkeeping (spike times, counts, P trains), delivery, plasticity tags; and, per run, the share of
  the blocks of eight cells with input at each receptor (``block_input_share``);
* ``XLA between kernel calls`` = test - kernel - arm - readout (state plumbing, P code update, the loop's scans);
* ``host round trip``: one call of a compiled epoch function from Python per epoch (30 s), measured on an empty
  jitted call.

Prints a markdown table (ms per network-second and share of ``train``) and writes JSON with the date, machine and
command.
"""
from __future__ import annotations

import os

if hasattr(os, "sched_setaffinity"):       # one CPU before XLA starts its thread pools
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from profile_table import table  # noqa: E402  (benchmarks/profile_table.py, beside this script)

EPOCH_S = 30.0


def _median_time(fn, args, repeats: int) -> float:
    compiled = jax.jit(fn).lower(*args).compile()
    jax.block_until_ready(compiled(*args))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def profile_one(arm: str, n: int, seconds: float, repeats: int, at_once: int) -> dict:
    from jaxarm.arm import make_arm
    from jaxarm.config.arm import MusculoskeletalArmConfig
    from jaxarm.config.network import NetworkConfig
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.network import native
    from jaxarm.network import readout as ro
    from jaxarm.parallel import map_networks
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    config = LoopConfig(arm=arm, network=NetworkConfig(native_threads=1),
                        task=TaskConfig(epochs=1, epoch_duration_s=seconds))
    fns = make_train(config)
    loop = fns.loop
    mp = MetaParams.original()
    intervals = round(seconds / config.task.update_interval_s)
    keys = jax.random.split(jax.random.PRNGKey(0), n)
    carry = jax.jit(jax.vmap(fns.init))(keys)

    def start(tr):
        run, em_rates_hz = loop.rule.begin_epoch(tr.rule, tr.wgain, mp)
        return loop.init(tr.noise_key, tr.wgain, run, em_rates_hz)

    state = jax.jit(jax.vmap(start))(carry.trained)
    run_keys = jax.random.split(jax.random.PRNGKey(1), n)
    net_s = n * seconds
    out = {}

    def closed(learn):
        def f(tr, st, k):
            return map_networks(lambda t, s, kk: loop.run(t.wiring, s, kk, mp, intervals, learn)[0].net.spike_count,
                                at_once)(tr, st, k)
        return f

    out["train"] = _median_time(closed(True), (carry.trained, state, run_keys), repeats)
    out["test"] = _median_time(closed(False), (carry.trained, state, run_keys), repeats)

    # the arm alone, with excitations that move it (the start of a babbling reach)
    u = jnp.tile(jnp.asarray([0.3, 0.1, 0.2, 0.4], jnp.float32), (n, 1))

    def arm_only(arm_model):
        def f(s0, uu):
            def interval(s, _):     # the loop's arm steps of one interval (ClosedLoop._move_arm)
                return jax.lax.scan(lambda x, _: (arm_model.step(x, uu), None), s, None, length=loop.arm_steps)[0], None
            return jax.lax.scan(interval, s0, None, length=intervals)[0]
        return map_networks(f, at_once)

    arm_state = jax.vmap(lambda _: loop.arm.init(loop.start_q))(jnp.arange(n))
    out["arm"] = _median_time(arm_only(loop.arm), (arm_state, u), repeats)
    if arm == "musculoskeletal":
        # The skeleton's share (geometry, torques, limits, the skeleton step: all but the muscle step) from the arm
        # with one and with two linearly-implicit muscle steps, whatever integrator the loop's arm uses: the second
        # muscle step costs what the first does, so the skeleton is 2 t1 - t2; the muscles are the rest of the arm.
        t1, t2 = (_median_time(arm_only(make_arm("musculoskeletal", config=MusculoskeletalArmConfig(
            muscle_integrator="linearly_implicit", muscle_substeps=k))), (arm_state, u), repeats) for k in (1, 2))
        out["arm skeleton"] = max(2.0 * t1 - t2, 0.0)
        out["arm muscles"] = out["arm"] - out["arm skeleton"]

    counts = jax.random.poisson(jax.random.PRNGKey(2), 3.0, (n, intervals, 4)).astype(jnp.float32)

    def readout_only(c):
        def one(cs):
            def body(r, x):
                r = ro.push(r, x)
                return r, ro.excitation(config.network, r, v_em_max=mp.v_em_max, window_ms=mp.mcmd_spk_wd_ms)
            return jax.lax.scan(body, ro.init_readout(config.network), cs)[1]
        return map_networks(one, at_once)(c)

    out["readout"] = _median_time(readout_only, (counts,), repeats)

    phases = {}
    if loop.net.uses_native_kernel:
        native.enable_profiling(True)
        try:
            compiled = jax.jit(closed(False)).lower(carry.trained, state, run_keys).compile()
            jax.block_until_ready(compiled(carry.trained, state, run_keys))
            walls = []
            native.profile_counters(reset=True)
            for _ in range(repeats):
                t0 = time.perf_counter()
                jax.block_until_ready(compiled(carry.trained, state, run_keys))
                walls.append(time.perf_counter() - t0)
            counters = native.profile_counters(reset=True)
        finally:
            native.enable_profiling(False)
        phases = {p: counters[p] / repeats for p in native.PROFILE_PHASES}
        out["profiled test (timer overhead)"] = statistics.median(walls)
        events = {c: counters[c] / repeats / net_s for c in native.PROFILE_COUNTERS}
    else:
        events = {}
    kernel = sum(phases.values())
    out["kernel"] = kernel
    out["learning"] = out["train"] - out["test"]
    out["XLA between kernel calls"] = out["test"] - kernel - out["arm"] - out["readout"]

    empty = jax.jit(lambda x: x + 1).lower(jnp.zeros(())).compile()
    t0 = time.perf_counter()
    for _ in range(200):
        jax.block_until_ready(empty(jnp.zeros(())))
    out["host round trip"] = (time.perf_counter() - t0) / 200 * seconds / EPOCH_S   # one call per 30 s epoch

    per_net_s = {k: v / net_s * 1000.0 for k, v in out.items()}        # ms per network-second
    per_net_s.update({f"kernel: {p}": v / net_s * 1000.0 for p, v in phases.items()})
    return {"arm": arm, "networks": n, "seconds": seconds, "intervals": intervals,
            "network_s_per_s": {"train": net_s / out["train"], "test": net_s / out["test"]},
            "ms_per_network_s": {k: round(v, 4) for k, v in per_net_s.items()},
            "events_per_network_s": {k: round(v, 1) for k, v in events.items()}}


def by_run(results: list[dict]) -> dict:
    """The runs' milliseconds per network-second by "ARM N", the kernel's phases as "kernel_PHASE" (so a page can
    name one: docs/hooks.py takes dict paths without colons)."""
    return {f"{r['arm']} {r['networks']}": {k.replace("kernel: ", "kernel_"): v for k, v in r["ms_per_network_s"].items()}
            for r in results}


def block_input_share(results: list[dict]) -> dict:
    """Per run ("ARM N"), the share of the native kernel's blocks of eight cells with input at each receptor in a
    step (the blocks whose jumps the kernel computes), from the profiling build's counters."""
    share = {}
    for r in results:
        ev = r.get("events_per_network_s", {})
        if ev.get("cell_blocks"):
            share[f"{r['arm']} {r['networks']}"] = {
                rec: round(ev[f"blocks_{rec}"] / ev["cell_blocks"], 3)
                for rec in ("ampa", "nmda", "gaba_prox", "gaba_dist")}
    return share


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--networks", type=int, nargs="+", default=[1, 64])
    ap.add_argument("--seconds", type=float, nargs="+", default=[2.0, 0.5],
                    help="simulated seconds per timed run, one per --networks entry (or one for all)")
    ap.add_argument("--arm", nargs="+", default=["simple", "musculoskeletal"], choices=["simple", "musculoskeletal"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--networks-at-once", type=int, default=None, metavar="K",
                    help="networks stepped together, groups one after the other (default: the commands' default on "
                         "this backend, 1 on a CPU; 0: one vmap of all)")
    ap.add_argument("--json-out", default=None)
    ap.add_argument("--table-from", default=None, metavar="JSON",
                    help="print the table of a saved result file (e.g. docs/results/profile.json) and exit")
    args = ap.parse_args(argv)
    if args.table_from:
        with open(args.table_from) as f:
            print(table(json.load(f)["results"]))
        return 0
    seconds = args.seconds if len(args.seconds) == len(args.networks) else args.seconds[:1] * len(args.networks)
    if args.networks_at_once is None:
        from jaxarm.parallel import networks_at_once

        args.networks_at_once = networks_at_once()
    results = [profile_one(arm, n, s, args.repeats, args.networks_at_once)
               for arm in args.arm for n, s in zip(args.networks, seconds)]
    print(table(results))
    out = {"date": time.strftime("%Y-%m-%d %H:%M"), "machine": f"{platform.machine()}, {os.cpu_count()} CPUs "
           "(pinned to one)", "command": "python benchmarks/profile.py " + " ".join(sys.argv[1:] if argv is None
                                                                                   else argv),
           "jax": jax.__version__, "networks_at_once": args.networks_at_once,
           "block_input_share": block_input_share(results), "by_run": by_run(results),
           "results": results}
    if args.json_out:
        with open(args.json_out, "w") as f:
            json.dump(out, f, indent=1)
            f.write("\n")
    else:
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
