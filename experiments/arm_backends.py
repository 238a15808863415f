"""Fast path vs MJX on the same inputs: how far apart are the two backends?

    python experiments/arm_backends.py [--seeds 0 1 2 3 4] [--seconds 1.0]

Each seed draws piecewise-constant random excitations (new values every 10 ms, like the network's readout) and
runs both backends from the start posture. Prints JSON: per seed, the worst joint-angle difference (deg), the worst
muscle-tendon length difference (mm) and the worst fibre length difference of the 4 proprioceptive muscles (mm).
"""
from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import make_arm


def rollout(arm, us):
    def body(s, u):
        s = arm.step(s, u)
        o = arm.observe(s)
        return s, (o.q, o.muscles.mtu_length_m, o.proprio)

    return jax.lax.scan(body, arm.init(), us)[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--seconds", type=float, default=1.0)
    args = ap.parse_args(argv)
    arms = {b: make_arm("musculoskeletal", backend=b) for b in ("fast", "mjx")}
    runs = {b: jax.jit(lambda us, a=a: rollout(a, us)) for b, a in arms.items()}
    n = int(round(args.seconds * 100))
    out = {"seconds": args.seconds, "per_seed": {}}
    for seed in args.seeds:
        us = jnp.repeat(jax.random.uniform(jax.random.PRNGKey(seed), (n, 4)), 10, axis=0)
        (qf, lf, pf), (qm, lm, pm) = (runs[b](us) for b in ("fast", "mjx"))
        out["per_seed"][seed] = {
            "max_joint_diff_deg": round(float(np.degrees(np.abs(qf - qm).max())), 4),
            "max_mtu_length_diff_mm": round(float(np.abs(lf - lm).max() * 1e3), 4),
            "max_proprio_fiber_diff_mm": round(float(np.abs(pf - pm).max() * 1e3), 4),
            "joint_excursion_deg": np.degrees(np.ptp(np.asarray(qm), axis=0)).round(1).tolist(),
        }
    worst = {k: max(v[k] for v in out["per_seed"].values())
             for k in ("max_joint_diff_deg", "max_mtu_length_diff_mm", "max_proprio_fiber_diff_mm")}
    out["worst"] = worst
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
