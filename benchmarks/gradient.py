"""Time and memory of one gradient step (a 1 s reach, forward and backward) at several batch sizes, beside the same
reach forward only.

    python benchmarks/gradient.py [--arm simple] [--networks 1 8 30] [--repeats 3]

For each batch size N: one gradient step of :mod:`jaxarm.learning.gradient` vmapped over N networks (surrogate
spikes, dense delivery, each 10 ms chunk rematerialised on the backward pass), and the same 1 s reach forward only
(``test``, no gradient) on the ordinary XLA kernel and on the native kernel, all compiled first, then timed in
turn ``--repeats`` times in one process (medians). Memory: XLA's own account of the compiled gradient step
(``memory_analysis()``: arguments, outputs and temporaries, MB), which is what the rematerialisation bounds. Prints
one JSON object with the date and machine.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import jax
import jax.numpy as jnp


def _timed(f, *args) -> float:
    t0 = time.perf_counter()
    jax.block_until_ready(f(*args))
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--networks", type=int, nargs="+", default=[1, 8, 30])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)

    from jaxarm import parallel
    parallel.start()
    import dataclasses

    from jaxarm.config.gradient import GradientConfig
    from jaxarm.learning.gradient import differentiable_config
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    base = LoopConfig(arm=args.arm, task=TaskConfig(epochs=1, epoch_duration_s=1.0, test_duration_s=1.0))
    mp = MetaParams.original()
    grad_fns = make_train(differentiable_config(base, GradientConfig()))
    forward = {kernel: make_train(dataclasses.replace(base, network=dataclasses.replace(base.network, kernel=kernel)))
               for kernel in ("xla", "native")}
    rows = []
    for n in args.networks:
        keys = jax.random.split(jax.random.key(0), n)
        carry = jax.jit(jax.vmap(grad_fns.init))(keys)
        step = jax.jit(jax.vmap(lambda c: grad_fns.step(c, mp, None, jnp.zeros((), jnp.int32))))
        compiled = step.lower(carry).compile()
        mem = compiled.memory_analysis()
        mb = None if mem is None else round((mem.argument_size_in_bytes + mem.output_size_in_bytes
                                             + mem.temp_size_in_bytes) / 2 ** 20, 1)
        tests = {k: jax.jit(jax.vmap(lambda key, t, f=f: f.test(key, t, mp))) for k, f in forward.items()}
        trained = carry.trained
        for f in tests.values():
            jax.block_until_ready(f(keys, trained))                      # compile
        jax.block_until_ready(compiled(carry))
        times = {"gradient_step": [], "forward_xla": [], "forward_native": []}
        for _ in range(args.repeats):
            times["gradient_step"].append(_timed(compiled, carry))
            times["forward_xla"].append(_timed(tests["xla"], keys, trained))
            times["forward_native"].append(_timed(tests["native"], keys, trained))
        med = {k: statistics.median(v) for k, v in times.items()}
        rows.append({"networks": n, "gradient_step_s": round(med["gradient_step"], 3),
                     "gradient_network_s_per_s": round(n / med["gradient_step"], 3),
                     "forward_xla_s": round(med["forward_xla"], 3), "forward_native_s": round(med["forward_native"], 3),
                     "gradient_over_forward_xla": round(med["gradient_step"] / med["forward_xla"], 2),
                     "gradient_over_forward_native": round(med["gradient_step"] / med["forward_native"], 2),
                     "gradient_step_memory_mb": mb})
        print(json.dumps(rows[-1]), flush=True)
    print(json.dumps({"date": time.strftime("%Y-%m-%d %H:%M"), "machine": f"{platform.machine()}, "
                      f"{os.cpu_count()} CPUs, {jax.device_count()} {jax.default_backend()} devices",
                      "arm": args.arm, "reach_s": 1.0, "repeats": args.repeats, "rows": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
