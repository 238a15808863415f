"""The paper's network at 1x, 2x and 4x its size (``NetworkConfig.scaled``): population rates in closed-loop
training and in the test, per size, and their ratio to 1x.

    python experiments/network_scaling.py [--factors 1 2 4] [--networks 8] [--epoch-s 10] [--arm simple] [--json F]

Each size trains ``--networks`` networks (seeds 0..N-1) for one epoch of ``--epoch-s`` seconds with the published
metaparameters (babbling, R-STDP, the left target) and tests them for 1 s. ``scaled`` keeps every cell's in-degree,
the P code's positions and the readout's drive per EM cell, so the rates should not depend on the size; the
spread of 8 networks at 1x is printed beside them to judge the differences.
"""
from __future__ import annotations

import argparse
import json
import time

import jax
import numpy as np

RATE_POPS = ("ES", "IS", "ISL", "EM", "IM", "IML")


def measure(factor: int, networks: int, epoch_s: float, arm: str) -> dict:
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.network import NetworkConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    net = NetworkConfig().scaled(factor) if factor > 1 else NetworkConfig()
    fns = make_train(LoopConfig(arm=arm, network=net, task=TaskConfig(epochs=1, epoch_duration_s=epoch_s)))
    keys = jax.vmap(jax.random.PRNGKey)(np.arange(networks))
    mp = MetaParams.original()
    t0 = time.perf_counter()
    trained, history = jax.jit(jax.vmap(fns.train, in_axes=(0, None)))(keys, mp)
    result = jax.jit(jax.vmap(fns.test, in_axes=(0, 0, None)))(keys, trained, mp)
    train_rates = np.asarray(history.rates_hz)[:, 0]          # (networks, 6)
    test_rates = np.asarray(result.rates_hz)                   # (networks, 6)
    return {"factor": factor, "n_all": net.n_all, "wall_s": round(time.perf_counter() - t0, 1),
            "lost_spikes": int(np.sum(history.lost_spikes)) + int(np.sum(result.lost_spikes)),
            "train_hz": dict(zip(RATE_POPS, train_rates.mean(0).round(3).tolist())),
            "train_sd_hz": dict(zip(RATE_POPS, train_rates.std(0, ddof=1).round(3).tolist())),
            "test_hz": dict(zip(RATE_POPS, test_rates.mean(0).round(3).tolist())),
            "test_sd_hz": dict(zip(RATE_POPS, test_rates.std(0, ddof=1).round(3).tolist())),
            "mean_excitation_test": float(np.asarray(result.u).mean()) if hasattr(result, "u") else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--factors", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--networks", type=int, default=8)
    ap.add_argument("--epoch-s", type=float, default=10.0)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--json", default=None, help="also write the results here")
    args = ap.parse_args(argv)
    from jaxarm import parallel

    parallel.start()
    rows = [measure(f, args.networks, args.epoch_s, args.arm) for f in args.factors]
    base = rows[0]
    print(f"{args.networks} networks, 1 epoch of {args.epoch_s:g} s ({args.arm} arm, published metaparameters), "
          "then a 1 s test; rates in Hz (mean over networks), ratio to the first size")
    for phase in ("train", "test"):
        print(f"\n{phase}: " + "  ".join(f"{p:>14}" for p in RATE_POPS))
        for r in rows:
            cells = [f"{r[phase + '_hz'][p]:6.2f} ({r[phase + '_hz'][p] / base[phase + '_hz'][p]:4.2f})"
                     if base[phase + '_hz'][p] > 0 else f"{r[phase + '_hz'][p]:6.2f}   (-)" for p in RATE_POPS]
            print(f"{r['factor']}x ({r['n_all']:>5} cells): " + "  ".join(f"{c:>14}" for c in cells))
        print("1x spread (sd over networks): " + "  ".join(f"{base[phase + '_sd_hz'][p]:>14.2f}" for p in RATE_POPS))
    print("\nlost spikes:", [r["lost_spikes"] for r in rows], "| wall s:", [r["wall_s"] for r in rows])
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"config": vars(args), "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
