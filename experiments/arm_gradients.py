"""Can the musculoskeletal arm's gradient be trusted? jvp against finite differences, and the smooth arm's cost.

    python experiments/arm_gradients.py [--seeds 7 8] [--directions 3] [--ablation] [--mjx] [--compare-seeds 7 ... 12]

Input: smooth random excitations (:func:`jaxarm.arm.inputs.smooth_random_excitations`, 1 s) from the start posture;
output: the hand position (m) after T = 30, 100, 300, 1000 ms. Directions: the excitation times a smooth random
factor in [-1, 1] (same construction, other seeds), so that excitation + h direction stays in [0, 1] and the
input clip is never met. For each arm, horizon and direction it prints, as relative errors of the 2-vector
derivative (m per unit step):

* ``fd(1e-2)``, ``fd(1e-3)``, ``fd(1e-4)``: central differences at those steps against the Richardson extrapolation
  ``R = (4 fd(h/2) - fd(h)) / 3`` at h = 1e-4 — a rough map shows as steps that disagree;
* ``jvp``: ``jax.jvp`` against R;
* ``fd32(h)``, ``jvp32``: the same with the arm in float32 (its default).

R and the other columns are float64 (x64 on: the finite differences need it; the arm's constants stay float32). Arms: the
default (piecewise smooth), ``smooth=True``, and with ``--ablation`` the smooth arm with one kink restored at a time
(``all but <kink>``); with ``--mjx`` also the MJX-geometry backend, default and smooth (``mjx default``, ``mjx
smooth``: the same muscles, MuJoCo's tendon paths and joint dynamics). Then, in float32 as the arm runs by default: the joint paths of the smooth and the default
arm over 1 s on ``--compare-seeds``, against the default arm's own integration error (vs a 0.05 ms run).
"""
from __future__ import annotations

import argparse
import json

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from jaxarm.arm.inputs import smooth_random_excitations  # noqa: E402
from jaxarm.arm.musculoskeletal import MusculoskeletalArm  # noqa: E402
from jaxarm.config.arm import SMOOTH_KINKS, MusculoskeletalArmConfig  # noqa: E402

HORIZONS_MS = (30, 100, 300, 1000)
FD_STEPS = (1e-2, 1e-3, 1e-4)


def direction(us: np.ndarray, seed: int) -> np.ndarray:
    """A smooth perturbation of ``us`` that keeps ``us + h d`` in [0, 1] for |h| <= 0.6: us times a factor in [-1, 1]."""
    return us * (2.0 * smooth_random_excitations(seed, seconds=len(us) / 1000.0, high=1.0) - 1.0)


def hand_paths(arm: MusculoskeletalArm):
    """us (T, 4) -> (T, 2) hand positions, m, jitted."""
    def run(us):
        def body(s, u):
            s = arm.step(s, u)
            return s, arm.observe(s).hand
        return jax.lax.scan(body, arm.init(), us)[1]
    return jax.jit(run)


def derivative_errors(runs64, runs32, us: np.ndarray, d: np.ndarray) -> dict:
    """Relative errors of fd at FD_STEPS and of jvp against Richardson, at each horizon; runs: :func:`_runs` of the
    arm traced in float64 and in float32."""
    run, tangent_of = runs64
    idx = np.asarray(HORIZONS_MS) - 1
    us, d = jnp.asarray(us, jnp.float64), jnp.asarray(d, jnp.float64)
    fd = {h: np.asarray((run(us + h * d) - run(us - h * d)) / (2 * h))[idx] for h in FD_STEPS + (FD_STEPS[-1] / 2,)}
    h = FD_STEPS[-1]
    rich = (4 * fd[h / 2] - fd[h]) / 3
    tangent = np.asarray(tangent_of(us, d))[idx]
    scale = np.linalg.norm(rich, axis=-1)
    err = {f"fd({s:g})": np.linalg.norm(fd[s] - rich, axis=-1) / scale for s in FD_STEPS}
    err["jvp"] = np.linalg.norm(tangent - rich, axis=-1) / scale
    with jax.enable_x64(False):  # the same in float32, as the arm runs by default
        run32, tangent32_of = runs32
        us32, d32 = jnp.asarray(us, jnp.float32), jnp.asarray(d, jnp.float32)
        for s in FD_STEPS:
            fd32 = np.asarray((run32(us32 + s * d32) - run32(us32 - s * d32)) / (2 * s))[idx]
            err[f"fd32({s:g})"] = np.linalg.norm(fd32 - rich, axis=-1) / scale
        err["jvp32"] = np.linalg.norm(np.asarray(tangent32_of(us32, d32))[idx] - rich, axis=-1) / scale
    err["|R| m"] = scale
    return err


def _runs(arm):
    """(hand path, its jvp) jitted for the current float type."""
    run = hand_paths(arm)
    return run, jax.jit(lambda u, v: jax.jvp(run, (u,), (v,))[1])


def gradient_table(variants: dict, seeds, n_directions: int) -> dict:
    """{variant: {horizon_ms: {column: max over seeds and directions}}}."""
    out = {}
    for name, smooth in variants.items():
        backend = "mjx" if name.startswith("mjx") else "fast"
        arm = MusculoskeletalArm(backend, MusculoskeletalArmConfig(smooth=smooth))
        runs64 = _runs(arm)
        with jax.enable_x64(False):
            runs32 = _runs(arm)
        rows = []
        for seed in seeds:
            us = smooth_random_excitations(seed)
            for k in range(n_directions):
                rows.append(derivative_errors(runs64, runs32, us, direction(us, 1000 + 10 * seed + k)))
        out[name] = {t: {c: float(np.max([r[c][i] for r in rows])) for c in rows[0]} for i, t in enumerate(HORIZONS_MS)}
    return out


def joint_paths(arm: MusculoskeletalArm, excitations: np.ndarray) -> np.ndarray:
    """(seeds, T, 2) joint angles, rad, float32."""
    def one(us):
        def body(s, u):
            s = arm.step(s, u)
            return s, s.q
        return jax.lax.scan(body, arm.init(), us)[1]
    return np.asarray(jax.jit(jax.vmap(one))(jnp.asarray(excitations, jnp.float32)))


def smooth_vs_default(seeds) -> dict:
    """Max |joint angle difference| (deg) over 1 s per seed: smooth vs default, and default vs a converged run."""
    us = np.stack([smooth_random_excitations(s) for s in seeds])
    with jax.enable_x64(False):
        default = joint_paths(MusculoskeletalArm("fast", MusculoskeletalArmConfig()), us)
        smooth = joint_paths(MusculoskeletalArm("fast", MusculoskeletalArmConfig(smooth=True)), us)
        fine = joint_paths(MusculoskeletalArm("fast", MusculoskeletalArmConfig(
            substeps=20, muscle_integrator="linearly_implicit", muscle_substeps=1)), us)
    per_seed = lambda a, b: np.degrees(np.abs(a - b)).reshape(len(seeds), -1).max(axis=1).round(4).tolist()  # noqa: E731
    return {"seeds": list(seeds), "smooth_vs_default_deg": per_seed(smooth, default),
            "default_vs_converged_deg": per_seed(default, fine), "smooth_vs_converged_deg": per_seed(smooth, fine)}


def print_table(table: dict) -> None:
    cols = [f"fd({s:g})" for s in FD_STEPS] + ["jvp"] + [f"fd32({s:g})" for s in FD_STEPS] + ["jvp32", "|R| m"]
    print(f"{'arm':<22}{'T ms':>6}" + "".join(f"{c:>11}" for c in cols))
    for name, rows in table.items():
        for t, r in rows.items():
            print(f"{name:<22}{t:>6}" + "".join(f"{r[c]:>11.2e}" for c in cols))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[7, 8])
    ap.add_argument("--directions", type=int, default=3)
    ap.add_argument("--ablation", action="store_true", help="also the smooth arm with one kink restored at a time")
    ap.add_argument("--mjx", action="store_true", help="also the MJX backend, default and smooth")
    ap.add_argument("--compare-seeds", type=int, nargs="*", default=list(range(7, 13)))
    args = ap.parse_args(argv)
    variants = {"default": False, "smooth": True}
    if args.mjx:
        variants.update({"mjx default": False, "mjx smooth": True})
    if args.ablation:
        variants.update({f"all but {k}": tuple(n for n in SMOOTH_KINKS if n != k) for k in SMOOTH_KINKS})
    table = gradient_table(variants, args.seeds, args.directions)
    print("relative error against Richardson-extrapolated central differences (max over seeds and directions)")
    print_table(table)
    if args.compare_seeds:
        print(json.dumps(smooth_vs_default(args.compare_seeds)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
