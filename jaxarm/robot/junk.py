"""Junk datagrams for testing a robot link's robustness (the robot page's safety envelope), and a sender.

:func:`junk_datagrams` cycles through the kinds of junk a link meets: random bytes (1-64 of them), an empty
datagram, NaN doubles (16 bytes), infinite doubles (32 bytes), two doubles of +-1e9 (16 bytes), a 4000-byte blob
and the 16 bytes ``GET / HTTP/1.1\\r\\n``. Seeded: the same seed gives the same datagrams.

    python -m jaxarm.robot.junk --to udp://127.0.0.1:5005 --period 0.05 --duration 7 [--seed 0] [--start-delay S]

sends one every ``--period`` seconds for ``--duration`` seconds and prints one JSON line: how many of each kind
it sent. Loopback by default; it refuses other hosts unless given ``--any-host``.
"""
from __future__ import annotations

import argparse
import json
import math
import socket
import struct
import time

import numpy as np

#: The kinds of junk, in the order :func:`junk_datagrams` cycles through them.
KINDS = ("random_bytes", "empty", "nan_doubles", "inf_doubles", "huge_doubles", "blob_4000", "http_request")


def junk_datagrams(n: int, seed: int = 0) -> list[tuple[str, bytes]]:
    """``n`` (kind, datagram) pairs cycling through :data:`KINDS`."""
    rng = np.random.Generator(np.random.PCG64(seed))
    make = {
        "random_bytes": lambda: rng.bytes(int(rng.integers(1, 65))),
        "empty": lambda: b"",
        "nan_doubles": lambda: struct.pack("<2d", math.nan, math.nan),
        "inf_doubles": lambda: struct.pack("<4d", math.inf, -math.inf, math.inf, -math.inf),
        "huge_doubles": lambda: struct.pack("<2d", 1e9, -1e9),
        "blob_4000": lambda: rng.bytes(4000),
        "http_request": lambda: b"GET / HTTP/1.1\r\n",
    }
    return [(KINDS[k % len(KINDS)], make[KINDS[k % len(KINDS)]]()) for k in range(n)]


def send_junk(host: str, port: int, period_s: float, duration_s: float, seed: int = 0,
              start_delay_s: float = 0.0) -> dict[str, int]:
    """Send junk to (host, port) every ``period_s`` for ``duration_s`` (wall clock); return counts per kind."""
    n = int(math.floor(duration_s / period_s)) + 1
    counts = dict.fromkeys(KINDS, 0)
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM) as sock:
        t0 = time.perf_counter() + start_delay_s
        for k, (kind, data) in enumerate(junk_datagrams(n, seed)):
            time.sleep(max(0.0, t0 + k * period_s - time.perf_counter()))
            try:
                sock.sendto(data, (host, port))
            except OSError:   # e.g. nothing listening yet (ICMP port unreachable): not sent, not counted
                continue
            counts[kind] += 1
    return counts


def main(argv=None) -> int:
    from jaxarm.robot.protocol import parse_udp_url

    ap = argparse.ArgumentParser(prog="python -m jaxarm.robot.junk", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--to", required=True, metavar="udp://HOST:PORT")
    ap.add_argument("--period", type=float, default=0.05, metavar="SECONDS")
    ap.add_argument("--duration", type=float, default=5.0, metavar="SECONDS")
    ap.add_argument("--start-delay", type=float, default=0.0, metavar="SECONDS")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--any-host", action="store_true", help="allow a destination that is not loopback")
    args = ap.parse_args(argv)
    try:
        host, port = parse_udp_url(args.to)
    except ValueError as err:
        ap.error(f"--to: {err}")
    if host not in ("127.0.0.1", "localhost", "::1") and not args.any_host:
        ap.error(f"--to {args.to}: not loopback; add --any-host to send junk to another machine")
    for flag, value, lo, hi in (("--period", args.period, 1e-4, 60.0), ("--duration", args.duration, 0.0, 3600.0),
                                ("--start-delay", args.start_delay, 0.0, 3600.0)):
        if not (math.isfinite(value) and lo <= value <= hi):
            ap.error(f"{flag} {value}: must be in [{lo}, {hi}]")
    counts = send_junk(host, port, args.period, args.duration, args.seed, args.start_delay)
    print(json.dumps({"sent": sum(counts.values()), "by_kind": counts, "to": f"udp://{host}:{port}"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
