"""Is the gradient that gradient learning descends the slope of the loss it means to descend?

    python experiments/reach_gradient_check.py [--arm simple] [--streams 64] [--directions 4] [--reach-s 0.5]
        [--scales 0.03] [--h 0.05 0.1 0.2] [--seed 0] [--pathways]

One network (key ``--seed``), untrained. The loss is gradient learning's: the mean hand-target distance (m) of one
reach of ``--reach-s`` from the start posture (``TrainFns.reach_loss``). For one background-noise stream it is a
step function of the gains (spikes are discrete); its mean over ``--streams`` streams is smooth, and that mean is
what the training steps, each on a fresh stream, descend on average. Along each direction v the reference is the
central difference of the stream-averaged loss (the same streams on both sides) at steps h = ``--h``; the checked
quantity is the stream-averaged surrogate gradient projected on v. Directions: ``--directions`` random ones over
the plastic gains (normal, scaled to root-mean-square 1, so a step h moves every gain by about h), or with
``--pathways`` one per plastic pathway, every gain of that pathway scaled together (d/d alpha of the loss with the
pathway's gains times alpha), where the loss moves most and the reference is least noisy.

The ratio gradient / reference says how far the surrogate's blind spots bias it: spike resets, the proprioceptive
code's dependence on the arm (the P trains switch on and off with muscle length: no derivative flows from the arm
back into the network) and the readout clip are not differentiated through, and the surrogate itself is dampened.

Prints a markdown table and a JSON line with the date and machine.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=("simple", "musculoskeletal"), default="simple")
    ap.add_argument("--target", default="left")
    ap.add_argument("--streams", type=int, default=64)
    ap.add_argument("--directions", type=int, default=4)
    ap.add_argument("--reach-s", type=float, default=0.5)
    ap.add_argument("--scales", type=float, nargs="+", default=[0.03])
    ap.add_argument("--h", type=float, nargs="+", default=[0.05, 0.1, 0.2])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--pathways", action="store_true", help="one direction per plastic pathway (its gains scaled)")
    ap.add_argument("--json-out", default=None, help="also write the JSON line to this file")
    args = ap.parse_args(argv)

    from jaxarm.config.gradient import GradientConfig
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    task = TaskConfig(target=args.target, epochs=1, epoch_duration_s=args.reach_s, test_duration_s=args.reach_s)
    mp = MetaParams.original()
    key = jax.random.PRNGKey(args.seed)
    streams = jax.random.split(jax.random.PRNGKey(10_000 + args.seed), args.streams)
    t0 = time.time()

    def fns_for(scale):
        grad = GradientConfig(reach_s=args.reach_s, scale=scale)
        return make_train(LoopConfig(arm=args.arm, task=task, gradient=grad))

    base = fns_for(args.scales[0])
    trained = base.init(key).trained
    n_train = base.loop.net.layout.n_plastic
    gains = trained.wgain[:n_train]
    layout = base.loop.net.layout
    if args.pathways:
        names = [pw.name for pw in layout.pathways if pw.plastic]
        dirs = np.zeros((len(names), n_train), np.float32)
        for j, name in enumerate(names):
            dirs[j, layout.synapses(name)] = np.asarray(gains)[layout.synapses(name)]
    else:
        rng = np.random.default_rng(args.seed)
        dirs = rng.normal(size=(args.directions, n_train)).astype(np.float32)
        dirs /= np.sqrt(np.mean(dirs ** 2, axis=1, keepdims=True))   # every gain moves by about h
        names = [str(j) for j in range(args.directions)]

    # The reference's forward passes: the training loop with spikes delivered by lists instead of densely (the same
    # spikes and arm to the bit, tests/test_gradient_learning.py, and several times faster), the same loss.
    from jaxarm.learning import babbling as bab
    from jaxarm.loop import ClosedLoop

    fwd_cfg = base.loop.config
    fwd = ClosedLoop(dataclasses.replace(fwd_cfg, network=dataclasses.replace(fwd_cfg.network, spike_gradient="none")))
    reach = round(args.reach_s / task.update_interval_s)

    def loss(g, k):
        state = fwd.init(k, trained.wgain.at[:n_train].set(g), None, bab.em_noise_rates_in_test(mp))
        state, rec = fwd.run(trained.wiring, state, jax.random.key(0), mp, reach, learn=False)
        return jnp.mean(jnp.linalg.norm(rec.hand_m - state.target.xy_m, axis=-1))

    per_stream = jax.jit(lambda g: jax.vmap(lambda k: loss(g, k))(streams))
    check = jax.jit(lambda g, k: (loss(g, k), base.reach_loss(g, trained, mp, k)[0]))(gains, streams[0])
    assert float(check[0]) == float(check[1]), check      # the same loss as the one differentiated
    loss0 = float(per_stream(gains).mean())
    # central differences per stream (the same stream on both sides), their mean and its standard error
    diffs = {h: [np.asarray(per_stream(gains + h * d) - per_stream(gains - h * d)) / (2 * h) for d in dirs]
             for h in args.h}
    reference = {h: [float(x.mean()) for x in v] for h, v in diffs.items()}
    reference_se = {h: [float(x.std() / np.sqrt(len(x))) for x in v] for h, v in diffs.items()}
    rows = []
    for scale in args.scales:
        fns = fns_for(scale)
        per_stream = jax.jit(jax.vmap(jax.grad(lambda g, k: fns.reach_loss(g, trained, mp, k)[0]), (None, 0)))
        g = np.asarray(per_stream(gains, streams))                      # (streams, n_train)
        finite = np.all(np.isfinite(g), axis=1)
        proj = g[finite] @ dirs.T                                       # (finite streams, directions)
        rows.append({"scale": scale, "finite": int(finite.sum()),
                     "grad": proj.mean(axis=0).tolist(),
                     "grad_se": (proj.std(axis=0) / np.sqrt(max(1, len(proj)))).tolist()})
    href = args.h[len(args.h) // 2]
    print(f"{args.arm} arm, {args.target} target, {args.reach_s:g} s reach, {args.streams} streams, mean loss "
          f"{loss0 * 100:.2f} cm")
    print("| g | direction | reference (± se) " + " | ".join(f"h={h:g}" for h in args.h) + " | surrogate (± se) | "
          f"surrogate / reference (h={href:g}) |")
    print("|---|---|" + "---|" * len(args.h) + "---|---|")
    for r in rows:
        for j, name in enumerate(names):
            ref = reference[href][j]
            print(f"| {r['scale']:g} | {name} | " + " | ".join(f"{reference[h][j]:.2g} ± {reference_se[h][j]:.1g}"
                                                              for h in args.h)
                  + f" | {r['grad'][j]:.3g} ± {r['grad_se'][j]:.2g} | {r['grad'][j] / ref:.2f} |")
    out = {"date": time.strftime("%Y-%m-%d %H:%M"), "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
           "command": "python experiments/reach_gradient_check.py " + " ".join(argv if argv is not None
                                                                                else __import__("sys").argv[1:]),
           "arm": args.arm, "target": args.target, "reach_s": args.reach_s, "streams": args.streams,
           "seed": args.seed, "directions": names, "mean_loss_m": loss0, "reference": {str(h): v for h, v in reference.items()},
           "reference_se": {str(h): v for h, v in reference_se.items()},
           "rows": rows, "wall_s": round(time.time() - t0, 1)}
    print(json.dumps(out))
    if args.json_out:
        with open(args.json_out, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
