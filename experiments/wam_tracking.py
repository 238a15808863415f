"""Offline reproduction of the paper's robot tracking numbers (§3.3, Figs. 9-10) with the simulated WAM.

    python experiments/wam_tracking.py [--seeds 0 1 2] [--duration 50] [--figures DIR] [--k K]
    python experiments/wam_tracking.py --network msarm-cmaes-2cm-rerank [--arm musculoskeletal] [--target left]
        [--seeds 0 1 2] [--duration 50] [--save-trajectories DIR] [--figures DIR]

Two trajectory sources, one per seed s:

* default: the stand-in ``synthetic:s`` (jaxarm.robot.synthetic: seeded minimum-jerk reach chain in the task's joint
  ranges, scaled to the paper-implied 1947 deg / 1450 deg total displacement);
* ``--network PRESET``: what the paper streamed, a spiking network's arm during training ("a 50-s training
  trajectory, with enforced exploratory movements", §3.3). Network ``PRNGKey(s)`` with the preset's best
  metaparameters is trained in closed loop (babbling + reward-modulated STDP, the ``jaxarm train`` protocol) for
  ``--duration`` s as one continuous run, i.e. without the arm reset that starts each 30-s training epoch, so the
  robot gets a continuous trajectory; joint angles are sampled every 10 ms (rad).

The trajectory is exported offline with the Gamma packet timing (jitter seed s) to the default simulated WAM
(PosToVel K from jaxarm.robot.config, libbarrett wam4 jv chain, 500 Hz) for ``--duration`` s of robot time. Prints
one JSON object: per-seed metrics, their mean, the paper's values, the ratio to the paper and whether each is
within 25 %, the delay beside the paper's 312 ms with the explanation (wam.md §6), the trajectory's joint
ranges and speeds beside the paper's description ("joint angles varied over 100 deg at angular velocities above
60 deg/s"), and per seed what the robot's safety envelope did with the packets (accepted, rejected by reason,
holds).
"""
from __future__ import annotations

import argparse
import json
import statistics
from dataclasses import replace
from pathlib import Path

import numpy as np

from jaxarm.robot.config import ControllerConfig, WamSimConfig
from jaxarm.robot.exporter import Trajectory, load_trajectory, simulate
from jaxarm.robot.metrics import PAPER, tracking_report

DELAY_NOTE = (
    "The paper's 312 ms (SD 127.64 ms) delay cannot go with its 1.85 deg / 1.74 deg mean errors: a robot that were "
    "a perfect copy of the target 312 ms late would already have the mean error given in "
    "error_if_pure_312ms_lag_deg (computed on these trajectories; wam.md §6 found ~10 deg). The same controller "
    "that reproduces the errors lags by tens of ms. Unverified guesses for the paper's number: a per-window average, "
    "or a lag counted in samples of another period (312 ms / 15.09 ms = 20.7 packets; 20.7 x 2 ms = 41 ms, close to "
    "the lag here). We report the whole-signal and windowed argmax-correlation lags as measured.")


def network_trajectory(preset: str, arm: str, target: str, seed: int, duration_s: float) -> Trajectory:
    """The first ``duration_s`` s of closed-loop training of network ``PRNGKey(seed)`` (one continuous run)."""
    import jax

    from jaxarm.paper import presets
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    p = presets.load(preset)
    if arm not in p.arms:
        import sys
        print(f"note: preset {p.name!r} was tuned for the {'/'.join(p.arms)} arm; running it on the {arm} arm",
              file=sys.stderr)
    mp = p.best_metaparams()
    config = LoopConfig(arm=arm, task=TaskConfig(target=target))
    fns = make_train(config)
    loop = fns.loop
    n = int(round(duration_s / config.task.update_interval_s))
    carry = fns.init(jax.random.PRNGKey(seed))
    tr = carry.trained
    rule_run, em_rates_hz = loop.rule.begin_epoch(tr.rule, tr.wgain, mp)
    state = loop.init(tr.noise_key, tr.wgain, rule_run, em_rates_hz)
    q0 = loop.arm.observe(state.arm).q
    run = jax.jit(loop.run, static_argnames=("n_intervals", "learn"))
    _, rec = run(tr.wiring, state, jax.random.fold_in(carry.key, 0), mp, n_intervals=n, learn=True)
    q = np.concatenate([np.asarray(q0)[None], np.asarray(rec.q_rad)]).astype(float)
    t = np.arange(n + 1) * config.task.update_interval_s
    return Trajectory(t, q)


def describe(traj: Trajectory) -> dict:
    """Joint ranges (deg) and speeds (deg/s, from 10 ms differences) of a trajectory, per joint."""
    out = {}
    for j, name in enumerate(("shoulder", "elbow")):
        qd = np.degrees(traj.q[:, j])
        speed = np.abs(np.diff(qd) / np.diff(traj.t))
        out[name] = {"range_deg": float(qd.max() - qd.min()), "min_deg": float(qd.min()), "max_deg": float(qd.max()),
                     "speed_p95_deg_s": float(np.percentile(speed, 95)), "speed_max_deg_s": float(speed.max()),
                     "fraction_above_60_deg_s": float(np.mean(speed > 60.0))}
    return out


def run_seed(seed: int, duration_s: float, config: WamSimConfig, traj: Trajectory) -> dict:
    log = simulate(traj, config, timing="jitter", seed=seed, duration_s=duration_s)
    cols = log.columns()
    r = tracking_report(cols)
    r.pop("paper")
    # The error a pure 312 ms delay alone would cause: the target against itself 156 ticks later.
    lag = int(round(0.312 / 0.002))
    r["error_if_pure_312ms_lag_deg"] = {
        j: float(np.degrees(np.abs(cols[f"target_{j}"][lag:] - cols[f"target_{j}"][:-lag])).mean())
        for j in ("shoulder", "elbow")}
    summary = log.summary()
    r["real_time_factor"] = summary["real_time_factor"]
    # What the robot's safety envelope made of the stream (jaxarm.robot.receiver counters; docs/robot.md).
    r["packets"] = {k: v for k, v in summary["packets"].items() if v or k in ("ok", "rejected")}
    r["trajectory"] = describe(traj)
    return r, log


def summarise(per_seed: list[dict]) -> dict:
    def mean(path):
        vals = []
        for r in per_seed:
            v = r
            for key in path:
                v = v[key]
            vals.append(v)
        # a measure a seed's run has none of (e.g. a 5 s window in a shorter run: the report's null) is left out
        vals = [v for v in vals if v is not None]
        return statistics.fmean(vals) if vals else None

    out = {}
    for metric in ("mean_abs_error_deg", "sd_abs_error_deg", "error_over_displacement"):
        out[metric] = {}
        for joint in ("shoulder", "elbow"):
            ours, paper = mean((metric, joint)), PAPER[metric][joint]
            ratio = None if ours is None else ours / paper
            out[metric][joint] = {"ours": ours, "paper": paper, "ratio": ratio,
                                  "within_25_percent": ratio is not None and abs(ratio - 1) <= 0.25}
    out["delay_ms"] = {
        "paper": PAPER["delay_ms"],
        "whole_signal": {j: mean(("delay_ms", "whole_signal", j)) for j in ("shoulder", "elbow")},
        "windowed_5s": {j: {"mean": mean(("delay_ms", "windowed", j, "mean")),
                            "sd": mean(("delay_ms", "windowed", j, "sd"))} for j in ("shoulder", "elbow")},
        "error_if_pure_312ms_lag_deg": {j: mean(("error_if_pure_312ms_lag_deg", j)) for j in ("shoulder", "elbow")},
        "note": DELAY_NOTE,
    }
    out["packet_interval_ms"] = {"ours": {k: mean(("packet_intervals", k)) for k in ("mean_ms", "sd_ms", "max_ms",
                                                                                     "p2_5_ms", "p97_5_ms")},
                                 "paper": PAPER["packet_interval_ms"]}
    out["samples"] = {"virtual": mean(("samples", "virtual")), "robot": mean(("samples", "robot")),
                      "paper_fig10": {"virtual": 3297, "robot": 24997}}
    out["dimensionless_jerk"] = {k: mean(("dimensionless_jerk", k)) for k in ("virtual", "robot")}
    out["packets_per_seed"] = [r["packets"] for r in per_seed]
    out["trajectory"] = {j: {k: mean(("trajectory", j, k)) for k in per_seed[0]["trajectory"][j]}
                         for j in ("shoulder", "elbow")}
    out["trajectory"]["paper"] = "joint angles varied over 100 deg at angular velocities above 60 deg/s (§3.3)"
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--duration", type=float, default=50.0, help="robot seconds (paper: 50)")
    ap.add_argument("--k", type=float, default=None, help="PosToVel gain, 1/s (default: the calibrated one)")
    ap.add_argument("--figures", type=Path, default=None, help="write Fig. 9/10-style PNGs of the first seed here")
    ap.add_argument("--network", metavar="PRESET", default=None,
                    help="stream a spiking network's training trajectory (this preset's best set) instead of "
                         "synthetic:SEED")
    ap.add_argument("--arm", default="musculoskeletal", choices=("musculoskeletal", "simple"), help="with --network")
    ap.add_argument("--target", default="left", help="with --network: the target the network trains for")
    ap.add_argument("--save-trajectories", type=Path, default=None,
                    help="with --network: write each seed's trajectory as DIR/network_SEED.npz (t s, q rad), "
                         "readable by `jaxarm export --trajectory`")
    args = ap.parse_args(argv)
    if not 0 < args.duration <= 600:
        ap.error(f"--duration = {args.duration}: must be in (0, 600] s")
    config = WamSimConfig()
    if args.k is not None:
        config = replace(config, controller=replace(ControllerConfig(), pos_to_vel_gain_per_s=args.k))
    per_seed = []
    for i, seed in enumerate(args.seeds):
        if args.network:
            traj = network_trajectory(args.network, args.arm, args.target, seed, args.duration)
            if args.save_trajectories:
                args.save_trajectories.mkdir(parents=True, exist_ok=True)
                np.savez(args.save_trajectories / f"network_{seed}.npz", t=traj.t, q=traj.q)
            label = f"network {seed} ({args.network}, {args.arm} arm, {args.target} target), first {args.duration:g} s of training"
        else:
            traj = load_trajectory(f"synthetic:{seed}")
            label = f"synthetic:{seed} stand-in trajectory"
        r, log = run_seed(seed, args.duration, config, traj)
        per_seed.append(r)
        if args.figures and i == 0:
            from jaxarm.robot.figures import hand_xy_figure, jerk_box_figure

            hand_xy_figure(log.columns(), args.figures / "wam_fig9_hand_xy.png",
                           title=f"{label}, simulated WAM")
            jerk_box_figure(log.columns(), args.figures / "wam_fig10_jerk.png")
    result = {
        "command": "python experiments/wam_tracking.py " + " ".join(argv if argv is not None else []),
        "trajectory": (f"network PRNGKey(SEED), preset {args.network}, {args.arm} arm, {args.target} target: the first "
                       f"{args.duration:g} s of closed-loop training, one continuous run, 10 ms samples"
                       if args.network else "synthetic:SEED (seeded minimum-jerk stand-in)"),
        "seeds": args.seeds, "duration_s": args.duration,
        "pos_to_vel_gain_per_s": config.controller.pos_to_vel_gain_per_s,
        "summary": summarise(per_seed), "per_seed": per_seed,
    }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    import sys

    raise SystemExit(main(sys.argv[1:]))
