"""Is the musculoskeletal arm's integration converged, and do its two backends agree on smooth inputs?

    python experiments/arm_convergence.py [--seeds 7 ... 26] [--muscle-substeps 10] [--newton-iterations 3]
        [--integrators linearly_implicit backward_euler] [--inputs step ramp random held maximal]
        [--backends fast mjx] [--sweep] [--json-out FILE]

Inputs (1 s each, 1 ms arm steps, from the start posture; excitations of the 4 groups):

* ``step``: one group (each in turn), then all four, from 0 to 0.6 at 0.1 s;
* ``ramp``: one group (each in turn), then all four, from 0 to 0.6 over the second;
* ``random``: smooth random excitations (:func:`jaxarm.arm.inputs.smooth_random_excitations`: 11 knots U(0, 0.6)
  per group over 1 s, linearly interpolated), one per seed;
* ``held``: U(0, 1) per group held for 10 ms (as the network's readout updates it), numpy ``default_rng(seed)``;
* ``maximal``: every combination of groups at full excitation (15; the joints run into their limits).

References, per backend, run in float64 (float32 rounding over 20,000 or more short steps moves a path by up to
0.09 deg, more than the schemes' own errors; the arm at 1 ms is within 0.012 deg of its float64 self):

* ``converged``: skeleton steps of 0.05 ms, each with 5 linearly-implicit muscle steps of 0.01 ms (halving both
  moves the path by < 0.01 deg on the random inputs);
* ``muscles_converged``: the arm's own 1 ms skeleton step with 100 linearly-implicit muscle steps of 0.01 ms: only
  the muscles converged (the skeleton's coupling as ``linearly_implicit``'s: the mean of the sub-steps' forces).

For each integrator under test (float32, the arm's own precision: ``linearly_implicit`` with ``--muscle-substeps``,
``backward_euler`` with ``--newton-iterations``) prints JSON with, per input set, the median and max over its inputs
of each path's largest joint-angle error (deg) against both references, the largest change of PECM1's tendon force
(N) from one 1 ms step to the next (chatter shows as thousands of newtons; the references' too), and on the random
inputs how far a 1e-4 rad move of the start shoulder angle moves the path (``start_perturbation``). With both
backends, ``fast_vs_mjx``: the two backends' paths on the random inputs, per integrator. ``--sweep`` adds
:func:`pecm1_slack_sweep` (the muscles alone, PECM1 taking up slack fast).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.arm.inputs import smooth_random_excitations
from jaxarm.arm.muscle import tendon_force
from jaxarm.arm.musculoskeletal import MusculoskeletalArm
from jaxarm.config.arm import MUSCLE_INTEGRATORS, START_POSTURE_RAD, MusculoskeletalArmConfig

INPUTS = ("step", "ramp", "random", "held", "maximal")
#: The references' configurations: (skeleton substeps per 1 ms, muscle substeps per skeleton substep).
REFERENCES = {"converged": (20, 5), "muscles_converged": (1, 100)}


def excitations(name: str, seeds=range(7, 27), seconds: float = 1.0, dt_s: float = 0.001) -> np.ndarray:
    """(inputs, T, 4) float32 excitations of one input set (see the module docstring)."""
    n = int(round(seconds / dt_s))
    t = np.arange(n) * dt_s
    one_then_all = [np.eye(4)[g] for g in range(4)] + [np.ones(4)]
    if name == "step":
        out = [np.where(t[:, None] >= 0.1, 0.6 * m, 0.0) for m in one_then_all]
    elif name == "ramp":
        out = [(0.6 * t / seconds)[:, None] * m for m in one_then_all]
    elif name == "random":
        out = [smooth_random_excitations(s, seconds=seconds, dt_s=dt_s) for s in seeds]
    elif name == "held":
        hold = int(round(0.01 / dt_s))
        out = [np.repeat(np.random.default_rng(s).uniform(0.0, 1.0, (-(-n // hold), 4)), hold, axis=0)[:n]
               for s in seeds]
    elif name == "maximal":
        out = [np.tile([(c >> g) & 1 for g in range(4)], (n, 1)) for c in range(1, 16)]
    else:
        raise ValueError(f"unknown input set {name!r}; choose from {', '.join(INPUTS)}")
    return np.stack(out).astype(np.float32)


def paths(arm: MusculoskeletalArm, q0, us, pecm1: bool = False):
    """(inputs, T, 2) joint angles, rad, of one arm from q0 under each (T, 4) excitation of ``us``, vmapped over
    inputs; with ``pecm1`` also PECM1's tendon force (N) after each step, (inputs, T)."""
    m = list(arm.muscle_names).index("PECM1")
    dtype = jnp.zeros(()).dtype  # float64 under jax_enable_x64, float32 otherwise

    def one(u_t):
        def body(s, u):
            s = arm.step(s, u)
            if not pecm1:
                return s, s.q
            lmt = arm._lanes(arm.mtu_lengths(s.q))
            return s, (s.q, tendon_force(arm.lane_params, s.muscle.fiber_length_m, lmt)[m])
        return jax.lax.scan(body, arm.init(jnp.asarray(q0, dtype)), jnp.asarray(u_t, dtype))[1]

    return jax.tree.map(np.asarray, jax.jit(jax.vmap(one))(jnp.asarray(us)))


def input_sets(inputs, seeds) -> tuple[np.ndarray, dict]:
    """All input sets stacked (one compilation per arm) and each set's slice of them."""
    sets = {name: excitations(name, seeds) for name in inputs}
    bounds = np.cumsum([0] + [len(v) for v in sets.values()])
    return np.concatenate(list(sets.values())), {n: slice(a, b) for n, a, b in zip(sets, bounds[:-1], bounds[1:])}


def stats(deg: np.ndarray) -> dict:
    per_input = deg.reshape(deg.shape[0], -1).max(axis=1)
    return {"max_deg": round(float(per_input.max()), 4), "median_deg": round(float(np.median(per_input)), 4)}


def max_force_change_n(force: np.ndarray) -> float:
    return round(float(np.abs(np.diff(force, axis=1)).max()), 1)


def arm_for(backend: str, integrator: str, muscle_substeps: int, newton_iterations: int) -> MusculoskeletalArm:
    return MusculoskeletalArm(backend, MusculoskeletalArmConfig(
        muscle_integrator=integrator, muscle_substeps=muscle_substeps, muscle_newton_iterations=newton_iterations))


def reference_paths(backends, inputs, seeds) -> dict:
    """{(backend, reference): (q, PECM1 force)} over all input sets in float64, computed in a subprocess
    (``jax_enable_x64`` is global)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "references.npz")
        cmd = [sys.executable, os.path.abspath(__file__), "--references-out", out, "--backends", *backends,
               "--inputs", *inputs, "--seeds", *map(str, seeds)]
        subprocess.run(cmd, check=True, env=dict(os.environ, JAX_ENABLE_X64="1"), stdout=sys.stderr)
        with np.load(out) as data:
            return {tuple(k.split("/")): (data[k][..., :2], data[k][..., 2]) for k in data.files}


def write_references(path: str, backends, inputs, seeds) -> None:
    if jnp.zeros(()).dtype != jnp.float64:
        raise SystemExit("arm_convergence.py: the references run under JAX_ENABLE_X64=1")
    us, _ = input_sets(inputs, seeds)
    arrays = {}
    for b in backends:
        for ref, (substeps, muscle_substeps) in REFERENCES.items():
            arm = MusculoskeletalArm(b, MusculoskeletalArmConfig(
                substeps=substeps, muscle_integrator="linearly_implicit", muscle_substeps=muscle_substeps))
            q, force = paths(arm, START_POSTURE_RAD, us, pecm1=True)
            arrays[f"{b}/{ref}"] = np.concatenate([q, force[..., None]], axis=-1)
    np.savez(path, **arrays)


def convergence(backends=("fast", "mjx"), seeds=range(7, 27), muscle_substeps: int = 10, newton_iterations: int = 3,
                integrators=MUSCLE_INTEGRATORS, inputs=INPUTS) -> dict:
    seeds = list(seeds)
    refs = reference_paths(backends, inputs, seeds)
    us, where = input_sets(inputs, seeds)
    q0 = np.asarray(START_POSTURE_RAD)
    out = {"seeds": seeds, "muscle_substeps": muscle_substeps, "newton_iterations": newton_iterations,
           "references": {r: f"skeleton {1.0 / s:g} ms, muscles {1.0 / (s * m):g} ms (linearly implicit), float64"
                          for r, (s, m) in REFERENCES.items()}}
    random_paths = {}
    for b in backends:
        out[b] = {"references_pecm1_max_force_change_n": {
            r: {n: max_force_change_n(refs[(b, r)][1][w]) for n, w in where.items()} for r in REFERENCES}}
        for integrator in integrators:
            arm = arm_for(b, integrator, muscle_substeps, newton_iterations)
            q, force = paths(arm, q0, us, pecm1=True)
            row = {}
            for name, w in where.items():
                row[name] = {f"vs_{r}": stats(np.degrees(np.abs(q[w] - refs[(b, r)][0][w]))) for r in REFERENCES}
                row[name]["pecm1_max_force_change_n"] = max_force_change_n(force[w])
            if "random" in where:
                w = where["random"]
                random_paths[(b, integrator)] = q[w]
                moved = paths(arm, q0 + np.array([1e-4, 0.0]), us[w])
                row["random"]["start_perturbation"] = stats(np.degrees(np.abs(q[w] - moved)))
            out[b][integrator] = row
    if len(backends) == 2 and "random" in inputs:
        out["fast_vs_mjx"] = {i: stats(np.degrees(np.abs(random_paths[("fast", i)] - random_paths[("mjx", i)])))
                              for i in integrators}
    return out


def pecm1_slack_sweep(newton_iterations=(2, 8), muscle_substeps: int = 10, seconds: float = 0.5) -> dict:
    """The muscles alone (no skeleton) at excitation 0.5, each path length swept through +-10 % of its optimal fibre
    length at 4 Hz around its rest length (PECM1's tendon goes slack and taut every cycle, its path moving at up to
    0.36 m/s): the largest tendon-force error (of F_max) of each integrator at 1 ms against 0.01 ms linearly-implicit
    steps (float32), and the largest step-to-step force change (N), for PECM1 and the worst muscle."""
    from jaxarm.arm import muscle as mus

    arm = MusculoskeletalArm("fast")
    p, names = arm.params, arm.muscle_names
    m = names.index("PECM1")
    rest = p.optimal_fiber_length_m * jnp.cos(p.pennation_rad) + p.tendon_slack_length_m

    def lmt_at(t):
        return rest + 0.1 * p.optimal_fiber_length_m * jnp.sin(2 * jnp.pi * 4.0 * t)

    def run(dt_s, integrator, n_inner=1, iterations=2):
        u = jnp.full_like(rest, 0.5)
        s = mus.MuscleState(jnp.zeros_like(rest), mus.equilibrium_fiber_length(p, jnp.zeros_like(rest), lmt_at(0.0)))

        def body(s, i):
            t0, t1 = i * dt_s, (i + 1) * dt_s
            if integrator == "backward_euler":
                s = mus.step_backward_euler(p, s, u, lmt_at(t0), lmt_at(t1), dt_s, iterations)
            else:
                s = jax.lax.fori_loop(0, n_inner, lambda k, x: mus.step(
                    p, x, u, lmt_at(t0 + (k + 1.0) * dt_s / n_inner), dt_s / n_inner), s)
            return s, mus.tendon_force(p, s.fiber_length_m, lmt_at(t1))

        n = int(round(seconds / dt_s))
        return np.asarray(jax.jit(lambda s0: jax.lax.scan(body, s0, jnp.arange(n, dtype=jnp.float32))[1])(s))

    ref = run(1e-3, "linearly_implicit", 100)
    f_max = np.asarray(p.max_force_n)
    runs = {f"backward_euler, {k} iterations": run(1e-3, "backward_euler", iterations=k) for k in newton_iterations}
    runs[f"linearly_implicit, {muscle_substeps} sub-steps"] = run(1e-3, "linearly_implicit", muscle_substeps)
    runs["linearly_implicit, 1 sub-step"] = run(1e-3, "linearly_implicit", 1)
    out = {"reference": "linearly implicit, 0.01 ms steps (float32)",
           "reference_pecm1_max_force_change_n": max_force_change_n(ref[None, :, m])}
    for name, f in runs.items():
        err = np.abs(f - ref).max(axis=0) / f_max
        out[name] = {"pecm1_max_force_error_of_f_max": round(float(err[m]), 4),
                     "worst_muscle": names[int(err.argmax())],
                     "worst_max_force_error_of_f_max": round(float(err.max()), 4),
                     "pecm1_max_force_change_n": max_force_change_n(f[None, :, m])}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(7, 27)))
    ap.add_argument("--muscle-substeps", type=int, default=MusculoskeletalArmConfig().muscle_substeps)
    ap.add_argument("--newton-iterations", type=int, default=MusculoskeletalArmConfig().muscle_newton_iterations)
    ap.add_argument("--integrators", nargs="+", choices=MUSCLE_INTEGRATORS, default=list(MUSCLE_INTEGRATORS))
    ap.add_argument("--inputs", nargs="+", choices=INPUTS, default=list(INPUTS))
    ap.add_argument("--backends", nargs="+", choices=("fast", "mjx"), default=["fast", "mjx"])
    ap.add_argument("--json-out", help="also write the JSON to this file")
    ap.add_argument("--sweep", action="store_true", help="also the muscles alone in a fast slack-taut sweep "
                                                         "(pecm1_slack_sweep)")
    ap.add_argument("--references-out", help=argparse.SUPPRESS)  # internal: the float64 subprocess
    args = ap.parse_args(argv)
    if args.references_out:
        write_references(args.references_out, args.backends, args.inputs, args.seeds)
        return 0
    result = convergence(args.backends, args.seeds, args.muscle_substeps, args.newton_iterations, args.integrators,
                         args.inputs)
    if args.sweep:
        result["pecm1_slack_sweep"] = pecm1_slack_sweep(sorted({2, args.newton_iterations, 8}), args.muscle_substeps)
    text = json.dumps(result, indent=1)
    print(text)
    if args.json_out:
        with open(args.json_out, "w") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
