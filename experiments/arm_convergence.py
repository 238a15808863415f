"""Is the musculoskeletal arm's integration converged, and do its two backends agree on smooth inputs?

    python experiments/arm_convergence.py [--seeds 7 ... 26] [--muscle-substeps 10] [--backends fast mjx]

Inputs: smooth random excitations (:func:`jaxarm.arm.inputs.smooth_random_excitations`: 11 knots U(0, 0.6) per group
over 1 s, linearly interpolated), from the start posture. For each backend, with the arm's default step (1 ms) and
``--muscle-substeps`` muscle steps per arm step, prints JSON with, over the seeds (max and median, deg):

* ``vs_converged``: the joint path against the same backend run at 0.05 ms throughout (20 substeps of everything);
* ``start_perturbation``: how far the path moves when the start shoulder angle moves by 1e-4 rad;
* ``fast_vs_mjx``: the two backends against each other.
"""
from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.arm.inputs import smooth_random_excitations
from jaxarm.arm.musculoskeletal import MusculoskeletalArm
from jaxarm.config.arm import START_POSTURE_RAD, MusculoskeletalArmConfig


def paths(arm: MusculoskeletalArm, q0, excitations):
    """(seeds, T, 2) joint angles, rad, of one arm from q0 under each (T, 4) excitation, vmapped over seeds."""
    def one(us):
        def body(s, u):
            s = arm.step(s, u)
            return s, s.q
        return jax.lax.scan(body, arm.init(jnp.asarray(q0, jnp.float32)), us)[1]

    return np.asarray(jax.jit(jax.vmap(one))(jnp.asarray(excitations)))


def stats(deg: np.ndarray) -> dict:
    per_seed = deg.reshape(deg.shape[0], -1).max(axis=1)
    return {"max_deg": round(float(per_seed.max()), 4), "median_deg": round(float(np.median(per_seed)), 4)}


def convergence(backends=("fast", "mjx"), seeds=range(7, 27), muscle_substeps: int = 10) -> dict:
    us = np.stack([smooth_random_excitations(s) for s in seeds])
    q0 = np.asarray(START_POSTURE_RAD)
    q0_moved = q0 + np.array([1e-4, 0.0])
    out, default = {"seeds": list(seeds), "muscle_substeps": muscle_substeps}, {}
    for b in backends:
        arm = MusculoskeletalArm(b, MusculoskeletalArmConfig(muscle_substeps=muscle_substeps))
        fine = MusculoskeletalArm(b, MusculoskeletalArmConfig(substeps=20, muscle_substeps=1))
        default[b] = paths(arm, q0, us)
        out[b] = {"vs_converged": stats(np.degrees(np.abs(default[b] - paths(fine, q0, us)))),
                  "start_perturbation": stats(np.degrees(np.abs(default[b] - paths(arm, q0_moved, us))))}
    if len(default) == 2:
        out["fast_vs_mjx"] = stats(np.degrees(np.abs(default["fast"] - default["mjx"])))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(7, 27)))
    ap.add_argument("--muscle-substeps", type=int, default=MusculoskeletalArmConfig().muscle_substeps)
    ap.add_argument("--backends", nargs="+", choices=("fast", "mjx"), default=["fast", "mjx"])
    args = ap.parse_args(argv)
    print(json.dumps(convergence(args.backends, args.seeds, args.muscle_substeps), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
