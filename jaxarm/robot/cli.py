"""``jaxarm wam-sim`` (the simulated robot, live over UDP) and ``jaxarm export`` (stream a trajectory to it, or
simulate offline). Both print one JSON summary on stdout when they finish; ``wam-sim`` first prints one line
``wam-sim: listening on udp://HOST:PORT`` (flushed) once its socket is bound, so scripts can wait for it.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

from jaxarm.config.validate import ConfigError
from jaxarm.robot.config import (ControllerConfig, JitterConfig, PhysicsConfig, ReceiverConfig, WamSimConfig,
                                 values_markdown)

DEFAULT_PORT = 5005


def _add_sim_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("simulated robot")
    g.add_argument("--mode", choices=("velocity", "position"), default="velocity",
                   help="velocity: the paper's PosToVel -> jv loop (default); position: libbarrett jp PID")
    g.add_argument("--k", type=float, default=None, metavar="PER_S",
                   help=f"PosToVel gain K, 1/s (default {ControllerConfig().pos_to_vel_gain_per_s})")
    g.add_argument("--variant", choices=("wam4", "wam7_wrist_locked"), default="wam4",
                   help="robot model (default wam4)")
    g.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help=f"receiver timeout, s (default {ReceiverConfig().timeout_s})")
    g.add_argument("--on-timeout", choices=("hold_position", "hold_target"), default="hold_position")
    g.add_argument("--substeps", type=int, default=None, help="MuJoCo steps per 2 ms tick (default 2)")


def _sim_config(args) -> WamSimConfig:
    c = ControllerConfig(mode=args.mode)
    if args.k is not None:
        c = replace(c, pos_to_vel_gain_per_s=args.k)
    r = ReceiverConfig(on_timeout=args.on_timeout)
    if args.timeout is not None:
        r = replace(r, timeout_s=args.timeout)
    ph = PhysicsConfig(variant=args.variant)
    if args.substeps is not None:
        ph = replace(ph, substeps=args.substeps)
    return WamSimConfig(controller=c, receiver=r, physics=ph)


def wam_sim_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="jaxarm wam-sim", description=(
        "Run the simulated Barrett WAM (MuJoCo, libbarrett-like 500 Hz chain) behind a UDP receiver, paced to the "
        "wall clock, for --duration seconds; write a 500 Hz CSV log and print a JSON summary."))
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"UDP port (default {DEFAULT_PORT}; 0 = any free)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1, loopback only)")
    p.add_argument("--duration", type=float, default=None, metavar="SECONDS", help="simulated = wall seconds to run")
    p.add_argument("--log", type=Path, default=None, metavar="FILE.csv", help="500 Hz CSV log")
    p.add_argument("--summary", type=Path, default=None, metavar="FILE.json", help="also write the summary here")
    p.add_argument("--print-config", action="store_true", help="print every value with its source and exit")
    _add_sim_options(p)
    args = p.parse_args(argv)
    if args.print_config:
        print(values_markdown())
        return 0
    if args.duration is None or not (0 < args.duration <= 86400):
        p.error("--duration SECONDS is required (0 < SECONDS <= 86400)")
    if not 0 <= args.port < 65536:
        p.error("--port must be in 0..65535")
    try:
        config = _sim_config(args)
    except ConfigError as err:
        p.error(str(err))
    from jaxarm.robot.simulator import config_dict, open_receiver_socket, run_live

    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"wam-sim: warning: binding {args.host}, not loopback; anyone who can reach it can move the robot",
              file=sys.stderr)
    sock = open_receiver_socket(args.host, args.port)
    host, port = sock.getsockname()[:2]
    print(f"wam-sim: listening on udp://{host}:{port}", flush=True)
    try:
        log = run_live(config, sock, args.duration)
    finally:
        sock.close()
    if args.log:
        log.to_csv(args.log)
    summary = dict(log.summary(), log=str(args.log) if args.log else None, config=config_dict(config))
    if args.summary:
        args.summary.parent.mkdir(parents=True, exist_ok=True)
        args.summary.write_text(json.dumps(summary, indent=1))
    print(json.dumps(summary), flush=True)
    return 0


def export_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="jaxarm export", description=(
        "Stream a joint trajectory (shoulder, elbow; rad) to a WAM over UDP, one packet per 10 ms of simulated "
        "time; or, with --to offline, run the simulated WAM in-process in simulated time."))
    p.add_argument("--trajectory", required=True, metavar="FILE",
                   help="CSV (t, shoulder, elbow), NPZ (t, q), a `jaxarm test` result folder (trajectories.npz) "
                        "or synthetic[:SEED]")
    p.add_argument("--network", type=int, default=0, help="which network of a multi-network NPZ (default 0)")
    p.add_argument("--to", default=f"udp://127.0.0.1:{DEFAULT_PORT}", metavar="udp://HOST:PORT|offline",
                   help=f"destination (default udp://127.0.0.1:{DEFAULT_PORT}); 'offline' simulates in-process")
    p.add_argument("--live", action="store_true",
                   help="send every 10 ms of wall-clock time (simulated time paced 1:1); default: the seeded "
                        "Gamma jitter model of the paper's link (mean 15.09 ms, SD 5.65 ms)")
    p.add_argument("--seed", type=int, default=0, help="seed of the jitter model (default 0)")
    p.add_argument("--jitter-mean-ms", type=float, default=JitterConfig().mean_ms)
    p.add_argument("--jitter-sd-ms", type=float, default=JitterConfig().sd_ms)
    p.add_argument("--format", choices=("extended", "raw"), default="extended",
                   help="extended (magic, version, seq, time, angles; default) or raw float64s (libbarrett ex11)")
    p.add_argument("--wam-joints", action="store_true",
                   help="send the 4 WAM joint angles (joint map applied here) instead of the 2 virtual angles")
    p.add_argument("--start-delay", type=float, default=0.0, metavar="SECONDS", help="wait before the first packet")
    p.add_argument("--duration", type=float, default=None, metavar="SECONDS",
                   help="UDP: stop sending after this many seconds; offline: robot time to simulate (default: "
                        "the whole trajectory; offline adds 0.5 s after the last packet)")
    g = p.add_argument_group("offline (--to offline)")
    g.add_argument("--log", type=Path, default=None, metavar="FILE.csv", help="500 Hz CSV log")
    g.add_argument("--report", type=Path, default=None, metavar="FILE.json", help="tracking metrics (JSON)")
    g.add_argument("--figures", type=Path, default=None, metavar="DIR", help="write Fig. 9/10-style PNGs here")
    _add_sim_options(p)
    args = p.parse_args(argv)

    from jaxarm.robot.exporter import load_trajectory, packets, resample, send_times, simulate

    try:
        traj = load_trajectory(args.trajectory, network=args.network)
    except (OSError, ValueError, KeyError) as err:
        p.error(str(err))
    try:
        jitter = JitterConfig(args.jitter_mean_ms, args.jitter_sd_ms)
        config = _sim_config(args)
    except ConfigError as err:
        p.error(str(err))
    timing = "live" if args.live else "jitter"
    if args.duration is not None and not args.duration > 0:
        p.error("--duration must be > 0")
    if args.to == "offline":
        log = simulate(traj, config, timing=timing, seed=args.seed, duration_s=args.duration, jitter=jitter,
                       fmt=args.format, wam_joints=args.wam_joints, first_arrival_s=args.start_delay)
        from jaxarm.robot.metrics import tracking_report

        report = tracking_report(log.columns())
        if args.log:
            log.to_csv(args.log)
        if args.report:
            args.report.parent.mkdir(parents=True, exist_ok=True)
            args.report.write_text(json.dumps(report, indent=1))
        if args.figures:
            from jaxarm.robot.figures import fig9_hand_xy, fig10_jerk

            cols = log.columns()
            fig9_hand_xy(cols, args.figures / "fig9_hand_xy.png")
            fig10_jerk(cols, args.figures / "fig10_jerk.png")
        report.pop("paper")
        print(json.dumps({"simulation": log.summary(), "tracking": report}, default=_json_default))
        return 0
    from jaxarm.robot.protocol import parse_udp_url
    from jaxarm.robot.exporter import stream_udp

    try:
        host, port = parse_udp_url(args.to)
    except ValueError as err:
        p.error(str(err))
    grid = resample(traj)
    data = packets(grid, args.format, args.wam_joints)
    times = send_times(len(data), timing, args.seed, jitter)
    if args.duration is not None:
        keep = times <= args.duration
        data, times = [d for d, k in zip(data, keep) if k], times[keep]
    stats = stream_udp(host, port, data, times, start_delay_s=args.start_delay)
    print(json.dumps(dict(stats, to=f"udp://{host}:{port}", timing=timing, format=args.format)))
    return 0


def _json_default(x):
    try:
        return float(x)
    except (TypeError, ValueError):
        return str(x) if not isinstance(x, float) or math.isfinite(x) else None
