"""``jaxarm demo``: both arms from the start posture, each muscle group excited alone; a plot and a summary.

Each condition drives one group with a constant excitation for ``--drive-s`` seconds, then lets go, for
``--duration-s`` in all. The simple arm steps every 10 ms, the musculoskeletal arm every 1 ms; all conditions run
as one ``vmap`` under one ``jit`` per arm.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.arm import GROUPS, make_arm
from jaxarm.arm.registry import BACKENDS

CONDITIONS = ("none",) + GROUPS


def rollout(arm, excitation: float, drive_s: float, duration_s: float):
    """Hand paths (C, T, 2) m and joint angles (C, T, 2) rad for the 5 conditions (no drive, then each group)."""
    n_steps = int(round(duration_s / arm.dt_s))
    n_drive = int(round(drive_s / arm.dt_s))
    drives = jnp.concatenate([jnp.zeros((1, 4)), excitation * jnp.eye(4)])

    def one(u_on):
        def body(state, k):
            state = arm.step(state, jnp.where(k < n_drive, u_on, 0.0))
            obs = arm.observe(state)
            return state, (obs.hand, obs.q)

        _, (hand, q) = jax.lax.scan(body, arm.init(), jnp.arange(n_steps))
        return hand, q

    return jax.jit(jax.vmap(one))(drives)


def plot(results: dict, path: Path, dt: dict) -> None:
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:   # a notebook's own backend stays (a switch closes its figures)
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(results), figsize=(5.5 * len(results), 8), squeeze=False)
    colors = ["0.5", "tab:red", "tab:blue", "tab:orange", "tab:green"]
    for col, (name, (hand, q)) in enumerate(results.items()):
        ax = axes[0, col]
        t = np.arange(1, q.shape[1] + 1) * dt[name]
        for c, label in enumerate(CONDITIONS):
            ax.plot(hand[c, :, 0] * 100, hand[c, :, 1] * 100, color=colors[c], label=label.replace("_", " "))
            axes[1, col].plot(t, np.degrees(q[c, :, 0]), color=colors[c], ls="-")
            axes[1, col].plot(t, np.degrees(q[c, :, 1]), color=colors[c], ls="--")
        ax.plot(hand[0, 0, 0] * 100, hand[0, 0, 1] * 100, "ko")
        ax.set(title=f"{name} arm: hand paths", xlabel="x (cm)", ylabel="y (cm)", aspect="equal")
        ax.legend(fontsize=8)
        axes[1, col].set(title="joint angles (solid shoulder, dashed elbow)", xlabel="time (s)", ylabel="angle (deg)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="jaxarm demo", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("runs/demo"), help="output folder (default runs/demo)")
    ap.add_argument("--excitation", type=float, default=0.5, help="group excitation in [0, 1] (default 0.5)")
    ap.add_argument("--drive-s", type=float, default=0.3, help="seconds of drive (default 0.3)")
    ap.add_argument("--duration-s", type=float, default=1.0, help="seconds simulated (default 1.0)")
    ap.add_argument("--backend", choices=BACKENDS, default="fast", help="musculoskeletal backend")
    args = ap.parse_args(argv)
    if not 0.0 <= args.excitation <= 1.0:
        ap.error(f"--excitation = {args.excitation}: must be in [0, 1]")
    if not 0.0 < args.duration_s <= 60.0:
        ap.error(f"--duration-s = {args.duration_s}: must be in (0, 60]")
    if not 0.0 <= args.drive_s <= args.duration_s:
        ap.error(f"--drive-s = {args.drive_s}: must be in [0, --duration-s]")
    args.out.mkdir(parents=True, exist_ok=True)

    arms = {"simple": make_arm("simple"), "musculoskeletal": make_arm("musculoskeletal", backend=args.backend)}
    results, summary = {}, {"excitation": args.excitation, "drive_s": args.drive_s, "duration_s": args.duration_s,
                            "backend": args.backend, "arms": {}}
    for name, arm in arms.items():
        t0 = time.perf_counter()
        hand, q = jax.block_until_ready(rollout(arm, args.excitation, args.drive_s, args.duration_s))
        hand, q = np.asarray(hand), np.asarray(q)
        results[name] = (hand, q)
        start = np.asarray(arm.observe(arm.init()).hand)
        summary["arms"][name] = {
            "wall_s_incl_compile": round(time.perf_counter() - t0, 2),
            "conditions": {c: {"final_q_deg": np.degrees(q[i, -1]).round(2).tolist(),
                               "hand_displacement_cm": round(float(np.linalg.norm(hand[i, -1] - start)) * 100, 2)}
                           for i, c in enumerate(CONDITIONS)}}
    plot(results, args.out / "arms.png", {n: a.dt_s for n, a in arms.items()})
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(f"final joint angles (shoulder, elbow) in deg after {args.duration_s} s; group driven at "
          f"{args.excitation} for {args.drive_s} s")
    print(f"{'condition':<20}" + "".join(f"{n:>22}" for n in arms))
    for c in CONDITIONS:
        cells = "".join("{:>22}".format("({:7.1f}, {:6.1f})".format(*summary["arms"][n]["conditions"][c]["final_q_deg"]))
                        for n in arms)
        print(f"{c:<20}{cells}")
    print(f"wrote {args.out / 'arms.png'} and {args.out / 'summary.json'}")
    return 0
