"""Networks built (and trained) elsewhere, run in jaxarm: test them, or train them from their wiring.

    python experiments/transplant.py test  NET.npz [NET2.npz ...] --noise-seeds 10 --json out.json
    python experiments/transplant.py train NET.npz [...] --networks 10 --json out.json

Each NET.npz is an edge list of one network in jaxarm's global-id numbering (which is the original NEURON
model's: ES 0-191, IS 192-235, ISL 236-255, EM 256-447, IM 448-491, IML 492-511, P 512-703):

* ``pre``, ``post`` (int), ``delay_ms`` (float, ms), ``wgain`` (float, dimensionless): the 46,440 synapses between
  network cells, in any order;
* ``p_pre``, ``p_post``, ``p_delay_ms``: the 4,224 P -> ES synapses (gain 1).

The edges must be exactly the model's synapses (pathways and in-degrees of spec §2;
:func:`jaxarm.network.wiring.wiring_from_edges` says which do not fit). Base weights and receptors come from the
pathway, as in a drawn wiring; delays are rounded to the clock step.

``test``: each network, with its gains, runs the 1 s test (simple arm by default, authors' metaparameters) with
``--noise-seeds`` different noise streams (keys ``PRNGKey(seed + j)``): does it reach? ``train``: each network's
wiring, with the given gains as the start (1 for a naive export), is trained ``--networks`` times with different
noise and babbling streams and then tested. Comparing the two isolates where two implementations differ: a network
that reaches when trained by the original but not when trained here points at training, not at the network's
test-time dynamics.

Used to test networks exported from the original model (docs/results.md, "The original model over 30 seeds"); the
export (read with NEURON from the original's cells, `getdvi`) is not part of jaxarm.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.learning.metaparams import MetaParams
from jaxarm.loop import LoopConfig
from jaxarm.network.wiring import wiring_from_edges
from jaxarm.task.config import TaskConfig
from jaxarm.train import EpochCarry, Trained, make_train


def load_network(path: Path, config) -> tuple:
    """(Wiring, wgain (n_syn,) float32) of an edge-list NPZ (see the module docstring)."""
    d = np.load(path)
    pre = np.concatenate([d["pre"], d["p_pre"]])
    post = np.concatenate([d["post"], d["p_post"]])
    delay = np.concatenate([d["delay_ms"], d["p_delay_ms"]])
    gain = np.concatenate([d["wgain"], np.ones(len(d["p_pre"]))])
    wiring, order = wiring_from_edges(config, pre, post, delay)
    return wiring, jnp.asarray(gain[order], jnp.float32)


def _stack(tree, n):
    return jax.tree.map(lambda x: jnp.broadcast_to(x, (n,) + jnp.shape(x)), tree)


def _summary(res, n_per_net):
    closest = 100.0 * np.asarray(res.min_distance_m).reshape(-1, n_per_net)
    success = np.asarray(res.success).reshape(-1, n_per_net)
    return {"success": success.tolist(), "closest_cm": np.round(closest, 3).tolist(),
            "success_count": int(success.sum()), "n": int(success.size),
            "closest_median_cm": float(np.median(closest)),
            "test_rates_hz": np.round(np.asarray(res.rates_hz).mean(axis=0), 3).tolist(),
            "final_q_rad_mean": np.round(np.asarray(res.q_rad)[:, -1].mean(axis=0), 4).tolist()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=("test", "train"))
    ap.add_argument("networks_npz", type=Path, nargs="+", help="edge-list NPZ files, one network each")
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--target", default="left")
    ap.add_argument("--noise-seeds", type=int, default=10, help="test: noise streams per network")
    ap.add_argument("--networks", type=int, default=10, help="train: trainings per wiring")
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--crossing", choices=("after_step", "per_event"), default="after_step",
                    help="NetworkConfig.crossing (how a step that lifts a cell past Vblock is tested)")
    ap.add_argument("--dt-ms", type=float, default=NetworkConfig().dt_ms, help="network clock step, ms")
    ap.add_argument("--json", type=Path, help="write the results here")
    args = ap.parse_args(argv)
    cfg = LoopConfig(arm=args.arm, task=TaskConfig(target=args.target, epochs=args.epochs),
                     network=NetworkConfig(crossing=args.crossing, dt_ms=args.dt_ms))
    fns = make_train(cfg)
    mp = MetaParams.original()
    nets = [load_network(p, cfg.network) for p in args.networks_npz]
    n_rep = args.noise_seeds if args.mode == "test" else args.networks
    keys = jnp.stack([jax.random.PRNGKey(args.seed + j) for j in range(n_rep)])
    test = jax.jit(jax.vmap(fns.test, in_axes=(0, 0, None)))
    epoch = jax.jit(jax.vmap(fns.epoch, in_axes=(0, None)))
    results = []
    t0 = time.perf_counter()
    for path, (wiring, wgain) in zip(args.networks_npz, nets):
        k_noise, k_babble = jax.vmap(lambda k: jax.random.split(k, 2))(keys).transpose(1, 0, 2)
        trained = Trained(wiring=_stack(wiring, n_rep), wgain=_stack(wgain, n_rep),
                          rule=_stack(fns.loop.rule.init(None), n_rep), noise_key=k_noise)
        if args.mode == "train":
            carry = EpochCarry(trained=trained, key=k_babble, epoch=jnp.zeros((n_rep,), jnp.int32))
            for _ in range(args.epochs):
                carry, _summary_epoch = epoch(carry, mp)
            trained = carry.trained
        res = test(jax.vmap(lambda k: jax.random.fold_in(k, 7))(keys), trained, mp)
        row = {"network": str(path)} | _summary(res, n_rep)
        results.append(row)
        print(f"{path}: {row['success_count']}/{row['n']} reach, median closest {row['closest_median_cm']:.2f} cm "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    total = sum(r["success_count"] for r in results), sum(r["n"] for r in results)
    print(f"all: {total[0]}/{total[1]}")
    if args.json:
        args.json.write_text(json.dumps({"mode": args.mode, "arm": args.arm, "target": args.target,
                                         "epochs": args.epochs, "seed": args.seed, "crossing": args.crossing, "dt_ms": args.dt_ms, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
