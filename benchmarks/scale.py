"""Scale-out: closed-loop training throughput of one batch on three layouts of this machine, and whether they agree.

    python benchmarks/scale.py --json [--networks 16] [--arm simple] [--seconds 5] [--repeats 3]

Layouts (each in fresh processes, so JAX's devices are set before it starts):

* ``1proc_2threads``: one process, one CPU device, the native network kernel splitting the batch over 2 threads (the
  way jaxarm scaled before);
* ``2proc_1thread``: two processes joined by ``jax.distributed`` on 127.0.0.1 (gloo), one device each;
* ``1proc_2devices``: one process, two CPU devices (the default of every command on a 2-core machine).

Each trains the same ``--networks`` networks (keys 0..N-1, the authors' metaparameters) for ``--repeats`` + 1
epochs of ``--seconds`` s with :class:`jaxarm.run.Run` (the code of ``jaxarm train``), drops the first epoch (warm-up)
and reports the median epoch's network-seconds per wall-second. ``efficiency`` = throughput / the
``1proc_2threads`` throughput of the same invocation; ``identical``: the trained gains and the epoch summaries of
every layout are the same bits. Also printed: the bytes that cross processes per epoch (the gathered epoch summary)
and a projection to N hosts (see ``--hosts``), then one JSON line.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

LAYOUTS = ("1proc_2threads", "2proc_1thread", "1proc_2devices")


def worker(args) -> None:
    """One process of one layout: train, time the epochs, print a JSON line (process 0 only)."""
    from jaxarm import parallel

    parallel.start(args.devices, args.coordinator, args.num_processes, args.process_id)
    import jax
    import numpy as np

    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.network import NetworkConfig
    from jaxarm.run import Run
    from jaxarm.task.config import TaskConfig

    cfg = LoopConfig(arm=args.arm, network=NetworkConfig(native_threads=args.threads),
                     task=TaskConfig(epochs=args.repeats + 1, epoch_duration_s=args.seconds))
    run = Run(cfg, args.networks, 0, Path(args.out), MetaParams.original())
    mps, targets = run.batched_inputs()
    carry = run.init_fn(run.keys())
    epoch = run.epoch_fn.lower(carry, mps, targets).compile()
    times, gather_s, digest = [], [], hashlib.sha256()
    for _ in range(args.repeats + 1):
        t0 = time.perf_counter()
        carry, summary = epoch(carry, mps, targets)
        jax.block_until_ready(summary)
        t1 = time.perf_counter()
        summary = parallel.host(summary)          # what crosses processes every epoch
        gather_s.append(time.perf_counter() - t1)
        times.append(time.perf_counter() - t0)
        for leaf in jax.tree.leaves(summary):
            digest.update(np.asarray(leaf)[: args.networks].tobytes())
    digest.update(np.asarray(parallel.host(carry.trained.wgain))[: args.networks].tobytes())
    summary_bytes = sum(np.asarray(x).nbytes for x in jax.tree.leaves(summary))
    if parallel.is_main_process():
        print(json.dumps({"network_s_per_s": args.networks * args.seconds / statistics.median(times[1:]),
                          "gather_s": statistics.median(gather_s[1:]), "summary_bytes": summary_bytes,
                          "digest": digest.hexdigest(), "layout": parallel.describe()}), flush=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_layout(layout: str, args) -> dict:
    base = [sys.executable, __file__, "--worker", "--arm", args.arm, "--networks", str(args.networks),
            "--seconds", str(args.seconds), "--repeats", str(args.repeats)]
    env = dict(os.environ)
    env.pop("JAXARM_NATIVE_THREADS", None)
    with tempfile.TemporaryDirectory() as tmp:
        if layout == "2proc_1thread":
            port = free_port()
            cmds = [base + ["--devices", "1", "--threads", "1", "--coordinator", f"127.0.0.1:{port}",
                            "--num-processes", "2", "--process-id", str(i), "--out", tmp] for i in range(2)]
        else:
            devices, threads = (1, 2) if layout == "1proc_2threads" else (2, 1)
            cmds = [base + ["--devices", str(devices), "--threads", str(threads), "--out", tmp]]
        procs = [subprocess.Popen(c, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for c in cmds]
        outs = [p.communicate(timeout=3600) for p in procs]
    for p, (out, err) in zip(procs, outs):
        if p.returncode != 0:
            raise RuntimeError(f"{layout} failed:\n{err[-3000:]}")
    return json.loads(outs[0][0].strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print only the final JSON line")
    ap.add_argument("--arm", default="simple", choices=["simple", "musculoskeletal"])
    ap.add_argument("--networks", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per epoch")
    ap.add_argument("--repeats", type=int, default=3, help="timed epochs (after one warm-up epoch)")
    ap.add_argument("--hosts", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32],
                    help="host counts of the projection table")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--devices", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--threads", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--coordinator", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--num-processes", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--process-id", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(args)
        return 0
    results = {layout: run_layout(layout, args) for layout in LAYOUTS}
    base = results["1proc_2threads"]["network_s_per_s"]
    rates = {k: round(v["network_s_per_s"], 2) for k, v in results.items()}
    efficiency = {k: round(v / base, 3) for k, v in rates.items() if k != "1proc_2threads"}
    identical = len({v["digest"] for v in results.values()}) == 1
    # Projection to N hosts of 2 cores (weak scaling): every process keeps the measured share of the batch
    # (networks / 2), so an epoch's compute time stays the measured one; the per-epoch gather of the summary, all
    # that crosses processes in training, is taken to grow with the number of processes as an all-gather's volume
    # does (measured at 2 processes on loopback; a network between hosts adds latency this does not model).
    two = results["2proc_1thread"]
    epoch_s = args.networks * args.seconds / two["network_s_per_s"]
    gather = two["gather_s"]
    projection = []
    for hosts in args.hosts:
        procs = 2 * hosts
        t = epoch_s - gather + gather * procs / 2
        projection.append({"hosts": hosts, "processes": procs, "networks_per_batch": args.networks * hosts,
                           "network_s_per_s": round(args.networks * hosts * args.seconds / t, 1)})
    out = {"network_s_per_s": rates, "efficiency": efficiency, "identical": identical,
           "summary_bytes_per_epoch": results["2proc_1thread"]["summary_bytes"],
           "gather_s_per_epoch": round(gather, 4), "projection": projection,
           "config": {"arm": args.arm, "networks": args.networks, "seconds": args.seconds, "repeats": args.repeats,
                      "cpu_count": os.cpu_count(), "machine": platform.machine(),
                      "date": time.strftime("%Y-%m-%d")}}
    if not args.json:
        for k, v in rates.items():
            print(f"{k:16s} {v:8.2f} network-s/s" + (f"  efficiency {efficiency[k]:.2f}" if k in efficiency else ""))
        print(f"identical across layouts: {identical}; {out['summary_bytes_per_epoch']} bytes gathered per epoch "
              f"in {gather * 1e3:.1f} ms")
        print("projection (hosts of 2 cores, the measured per-process rate and gather):")
        for row in projection:
            print(f"  {row['hosts']:3d} hosts  {row['network_s_per_s']:9.1f} network-s/s  "
                  f"({row['networks_per_batch']} networks per batch)")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
