"""How far the surrogate spike gradient can be trusted: against finite differences of the noise-averaged spike count,
and where it explodes (jaxarm.network.surrogate).

    python experiments/surrogate_gradient.py [--scales 0.01 0.02 0.03 0.05 0.07 0.1 0.2] [--width-mv 2] [--seeds 32]
        [--ms 200]
        [--block-steps 1]

One network wiring (key 0), the P code held at fixed muscle lengths, ``--seeds`` background-noise streams. The
quantity: EM spikes in the first ``--ms`` ms, as a function of a factor alpha on every ES->EM gain. For one stream
it is a step function of alpha; its mean over streams is smooth, and its slope at alpha = 1 by central differences
(h = 0.05, 0.1, 0.2) is the reference. For each dampening g of the surrogate (``NetworkConfig.surrogate_scale``)
the table gives the surrogate gradient's mean over streams, its standard deviation and the ratio to the reference.
``--block-steps 1`` delivers every step's derivative at its own step (the exact timing, about 4x slower) instead of
once per delivery block (each cell's derivatives of the block at its spike or nearest-to-threshold step).
Prints a markdown table and a JSON line with the date and machine.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scales", type=float, nargs="+", default=[0.01, 0.02, 0.03, 0.05, 0.07, 0.1, 0.2])
    ap.add_argument("--width-mv", type=float, default=2.0)
    ap.add_argument("--seeds", type=int, default=32)
    ap.add_argument("--ms", type=float, default=200.0)
    ap.add_argument("--json-out", default=None, help="also write the JSON line to this file")
    ap.add_argument("--block-steps", type=int, default=0, help="NetworkConfig.block_steps (0: the default block)")
    args = ap.parse_args(argv)

    from jaxarm.config.network import NetworkConfig
    from jaxarm.network.network import Network, NetworkParams
    from jaxarm.network.populations import Populations

    def make(scale: float):
        net = Network(NetworkConfig(kernel="xla", spike_gradient="fast_sigmoid", surrogate_width_mv=args.width_mv,
                                    surrogate_scale=scale, block_steps=args.block_steps))
        es_em, em = net.layout.synapses("ES->EM"), Populations(net.config).slice("EM")
        wiring = net.make_wiring(jax.random.key(0))
        steps = net.config.steps(args.ms)

        def count(alpha, key):
            state = net.set_lengths(net.init(key), jnp.array([0.10, 0.12, 0.10, 0.14]))
            state = state._replace(wgain=state.wgain.at[es_em].multiply(alpha))
            _, spikes = net.run(wiring, state, NetworkParams.original(), steps)
            return spikes[:, em].sum()
        return count

    keys = jax.random.split(jax.random.key(5), args.seeds)
    count = jax.jit(jax.vmap(make(args.scales[0]), (None, 0)))      # the forward pass does not depend on g
    reference = {h: float(count(1 + h, keys).mean() - count(1 - h, keys).mean()) / (2 * h) for h in (0.05, 0.1, 0.2)}
    ref = reference[0.1]
    rows = []
    for g in args.scales:
        grads = np.asarray(jax.jit(jax.vmap(jax.grad(make(g)), (None, 0)))(1.0, keys))
        finite = np.isfinite(grads)
        rows.append({"scale": g, "finite": int(finite.sum()), "mean": float(grads[finite].mean()) if finite.any()
                     else None, "sd": float(grads[finite].std()) if finite.any() else None})
    print(f"reference d(mean EM count)/d alpha: {', '.join(f'h={h}: {v:.1f}' for h, v in reference.items())}")
    print(f"| dampening g | finite ({args.seeds} streams) | mean surrogate gradient | sd | mean / reference |")
    print("|---|---|---|---|---|")
    for r in rows:
        if r["mean"] is None:
            print(f"| {r['scale']:g} | 0 | – | – | – |")
        else:
            print(f"| {r['scale']:g} | {r['finite']} | {r['mean']:.3g} | {r['sd']:.3g} | {r['mean'] / ref:.2g} |")
    out = {"date": time.strftime("%Y-%m-%d %H:%M"), "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
           "command": "python experiments/surrogate_gradient.py " + " ".join(argv if argv is not None else
                                                                              __import__("sys").argv[1:]),
           "width_mv": args.width_mv, "block_steps": args.block_steps, "seeds": args.seeds, "ms": args.ms,
           "reference": reference, "rows": rows}
    print(json.dumps(out))
    if args.json_out:
        with open(args.json_out, "w") as f:
            f.write(json.dumps(out) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
