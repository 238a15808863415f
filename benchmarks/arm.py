"""Arm throughput: arm-steps per second for both musculoskeletal backends and muscle integrators at 1, 60, 300 arms.

    python benchmarks/arm.py --json [--batches 1 60 300] [--steps 1000] [--repeats 5]
        [--integrators linearly_implicit backward_euler] [--newton-iterations 3] [--backends fast mjx]
        [--threads N] [--json-out FILE]

One arm-step = 1 ms of one arm. Each measurement jits ``vmap`` over arms of a ``lax.scan`` over ``--steps`` steps
(``--mjx-steps`` for MJX) with random excitations (seed 0). Every (integrator, backend, batch) is compiled first;
then ``--repeats`` rounds time each of them once, in turn, so that load from other work on the machine falls on all
of them alike; each rate is the median over the rounds. Compile time is the first call minus the median run.
Each batch runs as one program on one device, which XLA:CPU's thread pool spreads over ``--threads`` cores (default:
every usable core; ``import jaxarm`` alone would leave it one thread, a device's worth since 2026-12-07).

Reported as JSON: ``{"fast": {"1": steps_per_s, ...}, "mjx": {...}}`` for the default integrator (wall clock, as
before), and per integrator ``integrators[name][backend][batch]`` with ``arm_steps_per_wall_s`` and
``arm_steps_per_cpu_s`` (per second of this process's CPU time, steadier on a shared machine), ``speedup`` (each
integrator against the default, and the fast path against MJX with the same integrator and with the default one,
from the wall-clock medians), ``compile_s`` and every round's times (``rounds``, s).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import jax

from jaxarm.config.arm import MUSCLE_INTEGRATORS, MusculoskeletalArmConfig


def compiled(arm, batch: int, steps: int):
    """The jitted batch run and its inputs; returns (run, inputs, first-call seconds)."""
    u = jax.random.uniform(jax.random.PRNGKey(0), (batch, steps, 4))

    def run(us):
        def body(s, u_t):
            return arm.step(s, u_t), None

        final, _ = jax.lax.scan(body, arm.init(), us)
        return final.q

    f = jax.jit(jax.vmap(run))
    t0 = time.perf_counter()
    jax.block_until_ready(f(u))
    return f, u, time.perf_counter() - t0


def timed(f, u) -> tuple[float, float]:
    """(wall s, process CPU s) of one call."""
    t0, c0 = time.perf_counter(), time.process_time()
    jax.block_until_ready(f(u))
    return time.perf_counter() - t0, time.process_time() - c0


def measure(arm, batch: int, steps: int, repeats: int) -> tuple[float, float]:
    """(arm-steps per wall second, median over ``repeats``; compile seconds) of one arm alone."""
    f, u, first = compiled(arm, batch, steps)
    med = statistics.median(timed(f, u)[0] for _ in range(repeats))
    return batch * steps / med, max(first - med, 0.0)


def commit() -> str | None:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=root,
                             timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "jaxarm", "benchmarks"], capture_output=True,
                               text=True, cwd=root, timeout=10).stdout.strip()
        return out.stdout.strip() + (" (uncommitted changes)" if dirty else "") if out.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print only the JSON result")
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 60, 300])
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--mjx-steps", type=int, default=200, help="steps per run for the slower MJX backend")
    ap.add_argument("--repeats", type=int, default=5, help="alternated rounds")
    ap.add_argument("--backends", nargs="+", default=["fast", "mjx"], choices=["fast", "mjx"])
    default = MusculoskeletalArmConfig().muscle_integrator
    ap.add_argument("--integrators", nargs="+", default=list(MUSCLE_INTEGRATORS), choices=MUSCLE_INTEGRATORS,
                    help=f"muscle integrators to measure (the default one, {default!r}, is always measured)")
    ap.add_argument("--newton-iterations", type=int, default=MusculoskeletalArmConfig().muscle_newton_iterations,
                    help="MusculoskeletalArmConfig.muscle_newton_iterations of the backward_euler integrator")
    ap.add_argument("--json-out", help="also write the JSON to this file")
    ap.add_argument("--threads", type=int, default=None,
                    help="XLA:CPU's thread pool, which splits a batch of arms over cores (default: every usable core)")
    args = ap.parse_args(argv)
    from jaxarm import cpu_dispatch, make_arm
    from jaxarm.parallel import usable_cores

    # one jit over a batch on one device: XLA's pool is what spreads it over the cores (import jaxarm sizes the
    # pool to one thread, one device's worth; set before JAX's CPU backend starts)
    args.threads = args.threads or usable_cores()
    if not cpu_dispatch.pool_threads(args.threads):   # the user's own size wins: recorded as theirs
        args.threads = None
        args.pool_from_user_env = os.environ.get("PJRT_NPROC", os.environ.get("NPROC"))

    integrators = [default] + [i for i in args.integrators if i != default]
    result = {"compile_s": {}, "config": vars(args) | {
        "cpu_count": os.cpu_count(), "machine": platform.machine(), "jax": jax.__version__,
        "backend": jax.default_backend(), "date": time.strftime("%Y-%m-%d %H:%M"), "commit": commit(),
        "load_average_at_start": list(os.getloadavg()), "default_integrator": default,
        "command": "python benchmarks/arm.py " + " ".join(sys.argv[1:] if argv is None else argv)}}
    runs = {}
    for integrator in integrators:
        config = MusculoskeletalArmConfig(muscle_integrator=integrator, muscle_newton_iterations=args.newton_iterations)
        for backend in args.backends:
            with contextlib.redirect_stdout(sys.stderr):  # importing MJX prints optional-backend notices on stdout
                arm = make_arm("musculoskeletal", backend=backend, config=config)
            steps = args.steps if backend == "fast" else args.mjx_steps
            for b in args.batches:
                runs[(integrator, backend, b)] = compiled(arm, b, steps) + (b * steps,)
    rounds = {key: [] for key in runs}
    for _ in range(args.repeats):
        for key, (f, u, _, _) in runs.items():
            rounds[key].append(timed(f, u))
    per = {}
    for (integrator, backend, b), (_, _, first, n) in runs.items():
        wall = statistics.median(w for w, _ in rounds[(integrator, backend, b)])
        cpu = statistics.median(c for _, c in rounds[(integrator, backend, b)])
        rates = {"arm_steps_per_wall_s": round(n / wall), "arm_steps_per_cpu_s": round(n / cpu)}
        per.setdefault(integrator, {}).setdefault(backend, {})[str(b)] = rates
        result["compile_s"][f"{integrator}_{backend}_{b}"] = round(max(first - wall, 0.0), 2)
        if not args.json:
            print(f"{integrator:17s} {backend:4s} batch {b:4d}: {n / wall:12,.0f} arm-steps/s wall, {n / cpu:12,.0f} "
                  f"per CPU second (compile {first - wall:.1f} s)", file=sys.stderr)
    for backend in args.backends:  # the default integrator's wall rates, as this script always reported them
        result[backend] = {b: v["arm_steps_per_wall_s"] for b, v in per[default][backend].items()}
    result["integrators"] = per
    speedup = {}
    wall = {(i, bk, b): v["arm_steps_per_wall_s"]
            for i, r in per.items() for bk, rb in r.items() for b, v in rb.items()}
    for integrator in integrators:
        for b in map(str, args.batches):
            ratios = []
            if integrator != default and "fast" in args.backends:
                ratios.append((f"fast {integrator} / fast {default}", ("fast", integrator), ("fast", default)))
            if {"fast", "mjx"} <= set(args.backends):
                ratios.append((f"fast {integrator} / mjx {integrator}", ("fast", integrator), ("mjx", integrator)))
                if integrator != default:
                    ratios.append((f"fast {integrator} / mjx {default}", ("fast", integrator), ("mjx", default)))
            for name, (bk1, i1), (bk2, i2) in ratios:
                speedup.setdefault(name, {})[b] = round(wall[(i1, bk1, b)] / wall[(i2, bk2, b)], 2)
    result["speedup"] = speedup
    result["rounds"] = {f"{i} {bk} {b}": {"wall_s": [round(w, 4) for w, _ in r], "cpu_s": [round(c, 4) for _, c in r]}
                        for (i, bk, b), r in rounds.items()}
    text = json.dumps(result, indent=None if args.json else 1)
    print(text)
    if args.json_out:
        with open(args.json_out, "w") as f:
            f.write(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
