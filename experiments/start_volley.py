"""The start-of-run volley: spikes per cell of every population in short time bins after a run starts.

    python experiments/start_volley.py --networks 8 [--crossing per_event] [--network NET.npz] [--markdown]

Every run (epoch or test) starts with all 192 P cells firing at t = 1 ms; each ES cell receives 22 of those spikes
at once at t = 2 ms, and the volley runs through the network. The original fires every ES cell at 2 ms (its threshold
is tested after every event). A clock step sums its input first and finds many cells past Vblock, so with
``NetworkConfig.crossing = "after_step"`` (the default) the ES spikes spread over 2-10 ms and IS fires twice;
``"per_event"`` fires them as the original does (docs/results.md, "The original model over 30 seeds").

The network runs from rest with the test's inputs (EM noise at the test rate, the P code of the start posture, arm
still; it does not move before ~130 ms) for ``--ms`` ms, ``--networks`` times with different noise keys. The wiring
is drawn from ``--seed`` (gains 1) or read from an edge-list NPZ (``experiments/transplant.py``).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.learning import babbling as bab
from jaxarm.learning.metaparams import MetaParams
from jaxarm.loop import LoopConfig, ClosedLoop

BINS_MS = (0, 2, 4, 6, 10, 20, 50, 100, 200)
POPULATIONS = ("P", "ES", "IS", "ISL", "EM", "IM", "IML")


def volley(crossing: str, networks: int, seed: int, network_npz: Path | None = None, dt_ms: float = 0.25) -> dict:
    """{population: (n_bins,) mean spikes per cell in each of :data:`BINS_MS`'s bins}, averaged over noise keys."""
    cfg = LoopConfig(arm="simple", network=NetworkConfig(crossing=crossing, dt_ms=dt_ms))
    loop = ClosedLoop(cfg)
    if network_npz is not None:
        from transplant import load_network

        wiring, wgain = load_network(network_npz, cfg.network)
    else:
        wiring, wgain = loop.net.make_wiring(jax.random.PRNGKey(seed)), None
    mp = MetaParams.original()
    n_steps = int(round(BINS_MS[-1] / cfg.network.dt_ms))

    first = cfg.network.steps_per_interface
    proprio = loop.arm.observe(loop.arm.init(loop.start_q)).proprio

    @jax.jit
    def spikes(key):
        # as the closed loop: the start volley at 1 ms, the first P update (arm still) after the first interval
        st = loop.init(key, wgain, bab.init_babbling(cfg.babbling), bab.em_noise_rates_in_test(mp))
        net, a = loop.net.run(wiring, st.net, loop.net_params(mp), first, collect=True)
        net = loop.net.set_lengths(net, proprio)
        return jax.numpy.concatenate([a, loop.net.run(wiring, net, loop.net_params(mp), n_steps - first,
                                                      collect=True)[1]])

    pops = loop.pops
    out = {p: np.zeros(len(BINS_MS) - 1) for p in POPULATIONS}
    for j in range(networks):
        step, cell = np.nonzero(np.asarray(spikes(jax.random.PRNGKey(1000 + j))))
        t_ms = (step + 1) * cfg.network.dt_ms
        for p in POPULATIONS:
            ids = pops.ids(p)
            keep = (cell >= ids[0]) & (cell <= ids[-1])
            out[p] += np.histogram(t_ms[keep], BINS_MS)[0] / len(ids) / networks
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--crossing", choices=("after_step", "per_event"), default="after_step")
    ap.add_argument("--networks", type=int, default=8, help="noise keys averaged over")
    ap.add_argument("--seed", type=int, default=0, help="wiring key (without --network)")
    ap.add_argument("--network", type=Path, default=None, help="an edge-list NPZ (experiments/transplant.py)")
    ap.add_argument("--dt-ms", type=float, default=NetworkConfig().dt_ms)
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args(argv)
    if args.networks < 1:
        ap.error(f"--networks = {args.networks}: must be >= 1")
    v = volley(args.crossing, args.networks, args.seed, args.network, args.dt_ms)
    if not args.markdown:
        print(json.dumps({"bins_ms": BINS_MS, "spikes_per_cell": {p: x.round(4).tolist() for p, x in v.items()}}))
        return
    heads = [f"{a}–{b}" for a, b in zip(BINS_MS[:-1], BINS_MS[1:])]
    print(f"spikes per cell, crossing={args.crossing}, mean of {args.networks} noise keys\n")
    print("| ms | " + " | ".join(heads) + " |\n|---|" + "---|" * len(heads))
    for p, x in v.items():
        print(f"| {p} | " + " | ".join(f"{y:.2f}" for y in x) + " |")


if __name__ == "__main__":
    main()
