"""Arm throughput: arm-steps per second for both musculoskeletal backends at 1, 60 and 300 arms.

    python benchmarks/arm.py --json [--batches 1 60 300] [--steps 1000] [--repeats 5]

One arm-step = 1 ms of one arm. Each measurement jits ``vmap`` over arms of a ``lax.scan`` over ``--steps`` steps
with random excitations (seed 0), then times ``--repeats`` runs and reports the median. Compile time is the first
call minus the median run. Reported as JSON: {"fast": {"1": steps_per_s, ...}, "mjx": {...}, "compile_s": {...}}.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import sys
import time

import jax
import jax.numpy as jnp


def measure(arm, batch: int, steps: int, repeats: int) -> tuple[float, float]:
    u = jax.random.uniform(jax.random.PRNGKey(0), (batch, steps, 4))

    def run(us):
        def body(s, u_t):
            return arm.step(s, u_t), None

        final, _ = jax.lax.scan(body, arm.init(), us)
        return final.q

    f = jax.jit(jax.vmap(run))
    t0 = time.perf_counter()
    jax.block_until_ready(f(u))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(u))
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    return batch * steps / med, max(first - med, 0.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print only the JSON result")
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 60, 300])
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--mjx-steps", type=int, default=200, help="steps per run for the slower MJX backend")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--backends", nargs="+", default=["fast", "mjx"], choices=["fast", "mjx"])
    args = ap.parse_args(argv)
    from jaxarm import make_arm

    result = {"compile_s": {}, "config": vars(args) | {"cpu_count": os.cpu_count(), "machine": platform.machine(),
                                                       "jax": jax.__version__, "backend": jax.default_backend()}}
    for backend in args.backends:
        with contextlib.redirect_stdout(sys.stderr):  # importing MJX prints optional-backend notices on stdout
            arm = make_arm("musculoskeletal", backend=backend)
        steps = args.steps if backend == "fast" else args.mjx_steps
        result[backend] = {}
        for b in args.batches:
            rate, compile_s = measure(arm, b, steps, args.repeats)
            result[backend][str(b)] = round(rate)
            result["compile_s"][f"{backend}_{b}"] = round(compile_s, 2)
            if not args.json:
                print(f"{backend:5s} batch {b:4d}: {rate:12,.0f} arm-steps/s (compile {compile_s:.1f} s)", file=sys.stderr)
    print(json.dumps(result, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
