"""Offline WAM simulation speed as a real-time factor (simulated seconds per wall second), and the receiver's cost
per datagram.

    python benchmarks/wam.py --json [--duration 20] [--repeats 5] [--mode velocity position] [--variant wam4]
    python benchmarks/wam.py --receiver [--repeats 5]

Each repeat simulates ``--duration`` s of robot time (500 Hz ticks: receiver + libbarrett-like chain + MuJoCo C,
2 physics substeps) fed by the seeded stand-in trajectory (``synthetic:0``) at the paper's Gamma packet timing
(seed 0), and times only the tick loop (``SimLog.wall_s``; model compilation and packet encoding excluded). The
median over repeats is reported, with the min and max. The issue's bar: >= 10x real time on a 2-core machine.

``--receiver`` times the Network System instead (medians over repeats, microseconds per datagram): reading queued
datagrams from a loopback socket (``SocketReader``, 256 per call), judging valid extended packets and junk
(``receive``), and one flood tick (256 datagrams read, the newest 16 judged), in ms. It also counts, over the
50 s ``synthetic:0`` stream at the paper's packet timing, the most datagrams any tick receives.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print only the JSON result")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds per repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mode", nargs="+", default=["velocity", "position"], choices=["velocity", "position"])
    ap.add_argument("--variant", default="wam4", choices=["wam4", "wam7_wrist_locked"])
    ap.add_argument("--receiver", action="store_true", help="time the receiver instead of the simulation")
    args = ap.parse_args(argv)
    if args.receiver:
        print(json.dumps(receiver_costs(args.repeats)))
        return 0

    import mujoco
    import numpy as np

    from jaxarm.robot.config import ControllerConfig, PhysicsConfig, WamSimConfig
    from jaxarm.robot.exporter import load_trajectory, simulate

    traj = load_trajectory("synthetic:0")
    result = {"real_time_factor": {}, "config": vars(args) | {
        "cpu_count": os.cpu_count(), "machine": platform.machine(), "python": sys.version.split()[0],
        "mujoco": mujoco.__version__, "numpy": np.__version__, "trajectory": "synthetic:0", "seed": 0}}
    for mode in args.mode:
        cfg = WamSimConfig(controller=ControllerConfig(mode=mode), physics=PhysicsConfig(variant=args.variant))
        rtf = []
        for _ in range(args.repeats):
            log = simulate(traj, cfg, timing="jitter", seed=0, duration_s=args.duration)
            rtf.append(args.duration / log.wall_s)
        result["real_time_factor"][mode] = {"median": statistics.median(rtf), "min": min(rtf), "max": max(rtf),
                                            "ticks_per_s_median": statistics.median(rtf) * 500}
    if not args.json:
        for mode, r in result["real_time_factor"].items():
            print(f"{mode:>8}: {r['median']:.1f}x real time (min {r['min']:.1f}, max {r['max']:.1f})")
    print(json.dumps(result))
    return 0


def receiver_costs(repeats: int) -> dict:
    """Per-datagram costs of the receiver (us) and of one flood tick (ms); see the module docstring."""
    import socket
    import time

    import numpy as np

    from jaxarm.robot.config import WamSimConfig
    from jaxarm.robot.exporter import send_times
    from jaxarm.robot.protocol import encode
    from jaxarm.robot.receiver import receive, receiver_init
    from jaxarm.robot.safety import envelope
    from jaxarm.robot.simulator import SocketReader, open_receiver_socket

    cfg = WamSimConfig()
    env = envelope(cfg)
    q0 = cfg.joint_map.to_wam(cfg.initial_virtual_rad)
    rng = np.random.Generator(np.random.PCG64(0))
    valid = [encode([0.62 + 1e-4 * k, 1.53], k, 0.01 * k) for k in range(256)]
    junk = [rng.bytes(int(n)) for n in rng.integers(1, 65, size=256)]
    rx = open_receiver_socket("127.0.0.1", 0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    dest = rx.getsockname()
    out = {"read_us": [], "judge_valid_us": [], "judge_junk_us": [], "flood_tick_ms": []}
    for _ in range(repeats):
        for d in junk:
            tx.sendto(d, dest)
        time.sleep(0.05)
        reader = SocketReader(rx, 256)
        t0 = time.perf_counter()
        got = reader.read()
        out["read_us"].append((time.perf_counter() - t0) / max(len(got), 1) * 1e6)
        for key, data in (("judge_valid_us", valid), ("judge_junk_us", junk)):
            state = receiver_init(q0)
            t0 = time.perf_counter()
            for k, d in enumerate(data):   # one datagram per tick, 10 ms apart
                state, _ = receive(cfg, env, state, [d], 0.01 * k, q0)
            out[key].append((time.perf_counter() - t0) / len(data) * 1e6)
        for d in junk[:-1] + valid[-1:]:
            tx.sendto(d, dest)
        time.sleep(0.05)
        state = receiver_init(q0)
        t0 = time.perf_counter()
        state, _ = receive(cfg, env, state, reader.read(), 0.0, q0)
        out["flood_tick_ms"].append((time.perf_counter() - t0) * 1e3)
    rx.close()
    tx.close()
    arrivals = send_times(3315, "jitter", 0)
    per_tick = np.bincount(np.ceil(arrivals / 0.002 - 1e-9).astype(int))
    result = {k: statistics.median(v) for k, v in out.items()}
    result["max_datagrams_per_tick_clean_stream"] = int(per_tick.max())
    result["config"] = {"repeats": repeats, "cpu_count": os.cpu_count(), "python": sys.version.split()[0],
                        "trajectory": "synthetic:0 packet timing (jitter seed 0)"}
    return result


if __name__ == "__main__":
    raise SystemExit(main())
