"""``jaxarm wam-sim`` (the simulated robot, live over UDP) and ``jaxarm export`` (stream a trajectory to it,
simulate offline, or write a rosbag2). Both print one JSON summary on stdout when they finish; ``wam-sim`` first
prints one line ``wam-sim: listening on udp://HOST:PORT`` (flushed) once its socket is bound, so scripts can wait
for it, and one line on stderr each time the robot starts holding position.

User errors (a bad flag value, an unreadable file, a port in use) end with one line naming the flag or the file
and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import replace
from pathlib import Path

from jaxarm.config.validate import ConfigError
from jaxarm.robot.config import (ControllerConfig, JitterConfig, PhysicsConfig, ReceiverConfig, SafetyConfig,
                                 WamSimConfig, values_markdown)

DEFAULT_PORT = 5005
ROSBAG_PREFIX = "rosbag2:"
ACCEPT_RAW_HELP = (
    "accept headerless libbarrett-ex11 packets (2 or 4 float64, no magic, no sequence number). UNSAFE: their "
    "only framing is their length, so any 16- or 32-byte datagram on the port (a port scan, an HTTP request, "
    "another program's data) decodes as a joint target, and duplicates, reordering and replays cannot be "
    "detected. The envelope still rejects out-of-range and jumping targets. Default: refused and counted "
    "(raw_refused)")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (naming the flag or file), not the usage block."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _number(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(text)
    return value


def _per_joint(text: str) -> tuple[float, ...]:
    """``V`` (all four joints) or ``V1,V2,V3,V4``."""
    values = tuple(_number(v) for v in text.split(","))
    if len(values) == 1:
        return values * 4
    if len(values) != 4:
        raise ValueError(text)
    return values


_per_joint.__name__ = "one number or four comma-separated numbers"   # argparse names the type in its error
_number.__name__ = "finite number"


def _add_sim_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("simulated robot")
    g.add_argument("--mode", choices=("velocity", "position"), default="velocity",
                   help="velocity: the paper's PosToVel -> jv loop (default); position: libbarrett jp PID")
    g.add_argument("--k", type=_number, default=None, metavar="PER_S",
                   help=f"PosToVel gain K, 1/s (default {ControllerConfig().pos_to_vel_gain_per_s})")
    g.add_argument("--variant", choices=("wam4", "wam7_wrist_locked"), default="wam4",
                   help="robot model (default wam4)")
    g.add_argument("--substeps", type=int, default=None, help="MuJoCo steps per 2 ms tick (default 2)")
    r = p.add_argument_group("receiver (jaxarm.robot.receiver)")
    r.add_argument("--timeout", type=_number, default=None, metavar="SECONDS",
                   help=f"hold after this long without an accepted packet, s (default {ReceiverConfig().timeout_s})")
    r.add_argument("--on-timeout", choices=("hold_position", "hold_target"), default="hold_position")
    r.add_argument("--stale-after", type=_number, default=None, metavar="SECONDS",
                   help="a packet whose time is older than the held target's by more than this is stale, s "
                        f"(default {ReceiverConfig().stale_after_s})")
    r.add_argument("--max-reads-per-tick", type=int, default=None, metavar="N",
                   help=f"datagrams read per 2 ms tick at most (default {ReceiverConfig().max_reads_per_tick})")
    r.add_argument("--max-judged-per-tick", type=int, default=None, metavar="N",
                   help="only the newest N datagrams of a tick are judged; older ones are counted flood_dropped "
                        f"(default {ReceiverConfig().max_judged_per_tick})")
    s = p.add_argument_group("safety envelope (jaxarm.robot.safety; --print-config lists every default and source)")
    s.add_argument("--accept-raw", action="store_true", help=ACCEPT_RAW_HELP)
    s.add_argument("--velocity-limit", type=_per_joint, default=None, metavar="RAD_S",
                   help="joint speed limit, rad/s, one value or J1,J2,J3,J4: targets implying more are rejected "
                        f"(jump), the robot never moves faster (default {SafetyConfig().velocity_limit_rad_s[0]:g})")
    s.add_argument("--velocity-warning-fraction", type=_number, default=None, metavar="F",
                   help="the velocity guard brakes a joint faster than this fraction of its limit "
                        f"(default {SafetyConfig().velocity_warning_fraction})")
    s.add_argument("--target-inset", type=_number, default=None, metavar="RAD",
                   help=f"targets stay this far inside the joint range, rad (default {SafetyConfig().target_inset_rad})")
    s.add_argument("--clamp-margin", type=_number, default=None, metavar="RAD",
                   help="targets at most this far outside the allowed range are clamped, farther rejected, rad "
                        f"(default {SafetyConfig().clamp_margin_rad})")
    s.add_argument("--jump-clock-slack", type=_number, default=None, metavar="SECONDS",
                   help="the jump check trusts the sender's clock up to the robot's elapsed time plus this, s "
                        f"(default {SafetyConfig().jump_clock_slack_s})")
    s.add_argument("--max-rejections", type=int, default=None, metavar="N",
                   help="hold position after N datagrams rejected in a row "
                        f"(default {SafetyConfig().max_consecutive_rejections})")


def _set(obj, **changes):
    """``dataclasses.replace`` with only the changes that were given (not None)."""
    changes = {k: v for k, v in changes.items() if v is not None}
    return replace(obj, **changes) if changes else obj


def _sim_config(args) -> WamSimConfig:
    controller = _set(ControllerConfig(mode=args.mode), pos_to_vel_gain_per_s=args.k)
    receiver = _set(ReceiverConfig(on_timeout=args.on_timeout), timeout_s=args.timeout,
                    stale_after_s=args.stale_after, max_reads_per_tick=args.max_reads_per_tick,
                    max_judged_per_tick=args.max_judged_per_tick)
    safety = _set(SafetyConfig(accept_raw=args.accept_raw), velocity_limit_rad_s=args.velocity_limit,
                  velocity_warning_fraction=args.velocity_warning_fraction, target_inset_rad=args.target_inset, clamp_margin_rad=args.clamp_margin,
                  jump_clock_slack_s=args.jump_clock_slack, max_consecutive_rejections=args.max_rejections)
    physics = _set(PhysicsConfig(variant=args.variant), substeps=args.substeps)
    return WamSimConfig(controller=controller, receiver=receiver, safety=safety, physics=physics)


def _config_or_exit(p: argparse.ArgumentParser, args) -> WamSimConfig:
    try:
        return _sim_config(args)
    except ConfigError as err:
        p.error(str(err))


def _check_writable(p: argparse.ArgumentParser, flag: str, path: Path | None, directory: bool = False) -> None:
    """Before a run, not after it: the folder that will hold ``path`` (or ``path`` itself, a directory to
    create) can be created and written to."""
    if path is None:
        return
    folder = path if directory else path.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        p.error(f"{flag} {path}: cannot create {folder}: {err.strerror or err}")
    if not os.access(folder, os.W_OK):
        p.error(f"{flag} {path}: {folder} is not writable")


def _write_json(p: argparse.ArgumentParser, flag: str, path: Path, data: dict) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=1, default=_json_default))
    except OSError as err:
        p.error(f"{flag} {path}: {err.strerror or err}")


def wam_sim_main(argv: list[str]) -> int:
    p = _Parser(prog="jaxarm wam-sim", description=(
        "Run the simulated Barrett WAM (MuJoCo, libbarrett-like 500 Hz chain) behind a UDP receiver and a safety "
        "envelope, paced to the wall clock, for --duration seconds; write a 500 Hz CSV log and print a JSON "
        "summary. SIGTERM or SIGINT end the run early and still write both (exit status 0)."))
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"UDP port (default {DEFAULT_PORT}; 0 = any free)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1, loopback only)")
    p.add_argument("--duration", type=_number, default=None, metavar="SECONDS",
                   help="simulated = wall seconds to run")
    p.add_argument("--log", type=Path, default=None, metavar="FILE.csv", help="500 Hz CSV log")
    p.add_argument("--summary", type=Path, default=None, metavar="FILE.json", help="also write the summary here")
    p.add_argument("--print-config", action="store_true",
                   help="print every default with its source, then the configuration these flags give, and exit")
    _add_sim_options(p)
    args = p.parse_args(argv)
    config = _config_or_exit(p, args)
    from jaxarm.robot.simulator import StopSignals, config_dict, open_receiver_socket, run_live

    if args.print_config:
        print(values_markdown())
        print("\nConfiguration with these flags:\n" + json.dumps(config_dict(config), indent=1))
        return 0
    if args.duration is None or not (0 < args.duration <= 86400):
        p.error("--duration SECONDS is required (0 < SECONDS <= 86400)")
    if not 0 <= args.port < 65536:
        p.error(f"--port {args.port}: must be in 0..65535")
    _check_writable(p, "--log", args.log)
    _check_writable(p, "--summary", args.summary)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"wam-sim: warning: binding {args.host}, not loopback; anyone who can reach it can move the robot",
              file=sys.stderr)
    # Signals are handled from before the socket opens until the log is written, so a SIGTERM at any point of
    # the run ends it cleanly with a complete log.
    with StopSignals() as stop:
        try:
            sock = open_receiver_socket(args.host, args.port)
        except (OSError, ValueError) as err:
            p.error(f"--host {args.host} --port {args.port}: cannot bind: {getattr(err, 'strerror', None) or err}")
        host, port = sock.getsockname()[:2]
        print(f"wam-sim: listening on udp://{host}:{port}", flush=True)

        def on_event(t, message):
            print(f"wam-sim: t = {t:.3f} s: {message}", file=sys.stderr, flush=True)

        try:
            log = run_live(config, sock, args.duration, on_event=on_event, stop=stop)
        finally:
            sock.close()
        if log.stopped_by:
            print(f"wam-sim: {log.stopped_by} at t = {len(log.rows) * config.controller.control_period_s:.3f} s: "
                  "stopping, writing the log", file=sys.stderr, flush=True)
        if args.log:
            try:
                log.to_csv(args.log)
            except OSError as err:
                p.error(f"--log {args.log}: {err.strerror or err}")
        summary = dict(log.summary(), log=str(args.log) if args.log else None, config=config_dict(config))
        if args.summary:
            _write_json(p, "--summary", args.summary, summary)
        print(json.dumps(summary, default=_json_default), flush=True)
    return 0


def export_main(argv: list[str]) -> int:
    p = _Parser(prog="jaxarm export", description=(
        "Stream a joint trajectory (shoulder, elbow; rad) to a WAM over UDP, one packet per 10 ms of simulated "
        "time; or, with --to offline, run the simulated WAM in-process in simulated time; or, with --to "
        "rosbag2:DIR, write it as a ROS 2 bag (MCAP) without a ROS install."))
    p.add_argument("--trajectory", required=True, metavar="FILE",
                   help="CSV (t, shoulder, elbow), NPZ (t, q), a `jaxarm test` result folder (trajectories.npz) "
                        "or synthetic[:SEED]")
    p.add_argument("--network", type=int, default=0, help="which network of a multi-network NPZ (default 0)")
    p.add_argument("--to", default=f"udp://127.0.0.1:{DEFAULT_PORT}", metavar="udp://HOST:PORT|offline|rosbag2:DIR",
                   help=f"destination (default udp://127.0.0.1:{DEFAULT_PORT}); 'offline' simulates in-process; "
                        "'rosbag2:DIR' writes a new rosbag2 directory DIR (docs/robot.md)")
    p.add_argument("--live", action="store_true",
                   help="send every 10 ms of wall-clock time (simulated time paced 1:1); default: the seeded "
                        "Gamma jitter model of the paper's link (mean 15.09 ms, SD 5.65 ms)")
    p.add_argument("--seed", type=int, default=0, help="seed of the jitter model (default 0)")
    p.add_argument("--jitter-mean-ms", type=_number, default=JitterConfig().mean_ms)
    p.add_argument("--jitter-sd-ms", type=_number, default=JitterConfig().sd_ms)
    p.add_argument("--format", choices=("extended", "raw"), default="extended",
                   help="extended (magic, version, seq, time, angles; default) or raw float64s (libbarrett ex11; "
                        "the simulated robot refuses them unless given --accept-raw)")
    p.add_argument("--wam-joints", action="store_true",
                   help="send the 4 WAM joint angles (joint map applied here) instead of the 2 virtual angles")
    p.add_argument("--start-delay", type=_number, default=0.0, metavar="SECONDS",
                   help="wait before the first packet")
    p.add_argument("--duration", type=_number, default=None, metavar="SECONDS",
                   help="UDP: stop sending after this many seconds; offline: robot time to simulate (default: "
                        "the whole trajectory; offline adds 0.5 s after the last packet)")
    g = p.add_argument_group("offline (--to offline)")
    g.add_argument("--log", type=Path, default=None, metavar="FILE.csv", help="500 Hz CSV log")
    g.add_argument("--report", type=Path, default=None, metavar="FILE.json", help="tracking metrics (JSON)")
    g.add_argument("--figures", type=Path, default=None, metavar="DIR",
                   help="write the robot following the virtual arm here: hand_xy.png, jerk_box.png")
    g.add_argument("--rosbag2", type=Path, default=None, metavar="DIR",
                   help="also write a rosbag2 (MCAP) with the trajectory, the packets and the simulated robot's "
                        "joint states at 500 Hz")
    b = p.add_argument_group("ROS 2 (--to rosbag2:DIR, --rosbag2 DIR)")
    b.add_argument("--joint-names", default=None, metavar="J1,J2,J3,J4",
                   help="joint names in the bag, WAM J1..J4 (default wam/j1_joint,...,wam/j4_joint)")
    _add_sim_options(p)
    args = p.parse_args(argv)

    from jaxarm.robot.exporter import load_trajectory, packets, resample, send_times, simulate
    from jaxarm.robot.rosbag import DEFAULT_JOINT_NAMES, check_joint_names

    try:
        traj = load_trajectory(args.trajectory, network=args.network)
    except (OSError, ValueError, KeyError, IndexError) as err:
        p.error(f"--trajectory {args.trajectory}: {err}")
    try:
        jitter = JitterConfig(args.jitter_mean_ms, args.jitter_sd_ms)
    except ConfigError as err:
        p.error(str(err))
    config = _config_or_exit(p, args)
    try:
        names = check_joint_names(args.joint_names.split(",") if args.joint_names else DEFAULT_JOINT_NAMES)
    except ValueError as err:
        p.error(f"--joint-names: {err}")
    timing = "live" if args.live else "jitter"
    if args.duration is not None and not args.duration > 0:
        p.error(f"--duration {args.duration}: must be > 0")
    if args.start_delay < 0:
        p.error(f"--start-delay {args.start_delay}: must be >= 0")
    if args.rosbag2 is not None and args.to != "offline":
        p.error("--rosbag2 DIR records the offline simulation: use it with --to offline "
                "(or --to rosbag2:DIR for the trajectory and packets alone)")
    if args.to.startswith(ROSBAG_PREFIX):
        return _export_rosbag(p, args, traj, config, jitter, timing, names)
    if args.to == "offline":
        if args.format == "raw" and not args.accept_raw:
            p.error("--format raw --to offline: the simulated robot refuses raw packets; add --accept-raw")
        if args.rosbag2 is not None and args.rosbag2.exists():
            p.error(f"--rosbag2 {args.rosbag2}: exists already; a rosbag2 is written to a new directory")
        _check_writable(p, "--log", args.log)
        _check_writable(p, "--report", args.report)
        _check_writable(p, "--figures", args.figures, directory=True)
        _check_writable(p, "--rosbag2", args.rosbag2)
        log = simulate(traj, config, timing=timing, seed=args.seed, duration_s=args.duration, jitter=jitter,
                       fmt=args.format, wam_joints=args.wam_joints, first_arrival_s=args.start_delay)
        from jaxarm.robot.metrics import tracking_report

        try:
            report = tracking_report(log.columns())
        except ValueError as err:
            counts = log.summary().get("packets", {})
            why = ", ".join(f"{k} {v}" for k, v in counts.items() if v and k not in ("received", "ok"))
            p.error(f"--trajectory {args.trajectory}: the simulated robot took none of its "
                    f"{counts.get('received', 0)} packets ({why or err}); angles must lie within the WAM's joint "
                    "ranges (jaxarm wam-sim --print-config)")
        if args.log:
            try:
                log.to_csv(args.log)
            except OSError as err:
                p.error(f"--log {args.log}: {err.strerror or err}")
        if args.report:
            _write_json(p, "--report", args.report, report)
        if args.figures:
            from jaxarm.robot.figures import hand_xy_figure, jerk_box_figure

            cols = log.columns()
            hand_xy_figure(cols, args.figures / "hand_xy.png")
            jerk_box_figure(cols, args.figures / "jerk_box.png")
        out = {"simulation": log.summary(), "tracking": report}
        if args.rosbag2:
            out["rosbag2"] = _write_bag(p, "--rosbag2", args.rosbag2, traj, config, jitter, timing, args, names,
                                        robot_log=log.columns())
        report.pop("paper")
        print(json.dumps(out, default=_json_default))
        return 0
    from jaxarm.robot.exporter import stream_udp
    from jaxarm.robot.protocol import parse_udp_url

    try:
        host, port = parse_udp_url(args.to)
    except ValueError as err:
        p.error(f"--to: {err}")
    grid = resample(traj)
    data = packets(grid, args.format, args.wam_joints)
    times = send_times(len(data), timing, args.seed, jitter)
    if args.duration is not None:
        keep = times <= args.duration
        data, times = [d for d, k in zip(data, keep) if k], times[keep]
    try:
        stats = stream_udp(host, port, data, times, start_delay_s=args.start_delay)
    except OSError as err:
        p.error(f"--to {args.to}: {err.strerror or err}")
    print(json.dumps(dict(stats, to=f"udp://{host}:{port}", timing=timing, format=args.format)))
    return 0


def _write_bag(p, flag, path, traj, config, jitter, timing, args, names, robot_log=None) -> dict:
    """The rosbag2 of an export: the trajectory, each packet's targets at its send time, optionally the robot."""
    from jaxarm.robot.exporter import resample, send_times
    from jaxarm.robot.rosbag import write_bag

    grid = resample(traj)
    q_wam = config.joint_map.to_wam(grid.q)
    times = args.start_delay + send_times(len(grid.t), timing, args.seed, jitter)
    keep = slice(None) if args.duration is None else times <= args.duration
    try:
        counts = write_bag(path, grid.t, q_wam, times[keep], q_wam[keep], names, robot_log=robot_log)
    except (OSError, ValueError) as err:
        p.error(f"{flag}: {err}")
    return {"path": str(path), "messages": counts, "joint_names": list(names)}


def _export_rosbag(p, args, traj, config, jitter, timing, names) -> int:
    path = Path(args.to[len(ROSBAG_PREFIX):])
    if not str(path) or str(path) == ".":
        p.error(f"--to {args.to}: name the new bag directory, e.g. --to rosbag2:runs/wam_bag")
    out = _write_bag(p, "--to", path, traj, config, jitter, timing, args, names)
    print(json.dumps(dict(out, timing=timing)))
    return 0


def _json_default(x):
    try:
        value = float(x)
    except (TypeError, ValueError):
        return str(x)
    return value if math.isfinite(value) else None
