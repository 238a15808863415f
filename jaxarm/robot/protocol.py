"""Wire format of joint-angle packets sent to the WAM.

Extended packet (what :mod:`jaxarm.robot.exporter` sends by default), little-endian, 20 + 8 n bytes::

    offset  size  type      field
    0       4     bytes     magic b"WAMJ"
    4       2     uint16    version (1)
    6       2     uint16    n, number of angles: 2 = virtual arm (shoulder, elbow), 4 = WAM joints J1..J4
    8       4     uint32    seq, sequence number (starts at 0, +1 per packet, wraps at 2**32)
    12      8     float64   t, simulated time of the sample at the sender, s
    20      8 n   float64   angles, rad

Raw packet (libbarrett ``ex11_master_master.h`` style): ``n`` consecutive little-endian float64 and nothing else,
n = 2 (virtual arm) or n = 4 (WAM joints). It carries no sequence number or time, so duplicates, reordering and
staleness cannot be detected for it. A raw packet is recognised by its size (16 or 32 bytes) when it does not
start with the magic. Length is its only framing, so any 16- or 32-byte datagram decodes as one (the 16 bytes
``GET / HTTP/1.1\r\n`` give angles of about 1e98 rad); the robot refuses raw packets unless told otherwise
(:class:`~jaxarm.robot.config.SafetyConfig`).

A datagram longer than the largest valid packet (:data:`MAX_PACKET_BYTES`) is ``oversize`` whatever it holds.
"""
from __future__ import annotations

import math
import struct
from typing import NamedTuple, Optional

MAGIC = b"WAMJ"
VERSION = 1
HEADER = struct.Struct("<4sHHId")
ANGLE_COUNTS = (2, 4)
SEQ_MODULUS = 2 ** 32
#: The largest valid packet: an extended packet with 4 angles, bytes.
MAX_PACKET_BYTES = HEADER.size + 8 * max(ANGLE_COUNTS)


class Packet(NamedTuple):
    """A decoded packet. ``seq`` and ``t`` are None for raw packets."""

    angles: tuple[float, ...]   # rad; 2 = virtual (shoulder, elbow), 4 = WAM J1..J4
    seq: Optional[int] = None
    t: Optional[float] = None   # s, sender's simulated time


class DecodeError(ValueError):
    """A packet could not be decoded; ``kind`` is ``"oversize"``, ``"malformed"``, ``"truncated"`` or
    ``"nonfinite"``."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def encode(angles, seq: int, t: float) -> bytes:
    """Extended packet for ``angles`` (2 or 4 values, rad) with sequence number ``seq`` and time ``t`` (s)."""
    angles = tuple(float(a) for a in angles)
    if len(angles) not in ANGLE_COUNTS:
        raise ValueError(f"a packet carries 2 or 4 angles, got {len(angles)}")
    return HEADER.pack(MAGIC, VERSION, len(angles), int(seq) % SEQ_MODULUS, float(t)) + struct.pack(
        f"<{len(angles)}d", *angles)


def encode_raw(angles) -> bytes:
    """Raw libbarrett-example packet: the angles as consecutive little-endian float64."""
    angles = tuple(float(a) for a in angles)
    if len(angles) not in ANGLE_COUNTS:
        raise ValueError(f"a packet carries 2 or 4 angles, got {len(angles)}")
    return struct.pack(f"<{len(angles)}d", *angles)


def is_raw(data: bytes) -> bool:
    """True when ``data`` would be read as a raw packet (16 or 32 bytes, not starting with the magic), whatever
    its content."""
    return len(data) in (8 * n for n in ANGLE_COUNTS) and data[:4] != MAGIC


def decode(data: bytes) -> Packet:
    """Decode one datagram or raise :class:`DecodeError` saying why it is rejected."""
    if len(data) > MAX_PACKET_BYTES:
        raise DecodeError("oversize", f"{len(data)} bytes, longer than the largest packet ({MAX_PACKET_BYTES})")
    if data[:4] == MAGIC:
        if len(data) < HEADER.size:
            raise DecodeError("truncated", f"{len(data)} bytes, shorter than the {HEADER.size}-byte header")
        _, version, n, seq, t = HEADER.unpack_from(data)
        if version != VERSION:
            raise DecodeError("malformed", f"unsupported version {version}")
        if n not in ANGLE_COUNTS:
            raise DecodeError("malformed", f"{n} angles; expected 2 or 4")
        size = HEADER.size + 8 * n
        if len(data) < size:
            raise DecodeError("truncated", f"{len(data)} bytes; {size} expected for {n} angles")
        if len(data) > size:
            raise DecodeError("malformed", f"{len(data)} bytes; {size} expected for {n} angles")
        angles = struct.unpack_from(f"<{n}d", data, HEADER.size)
        if not (math.isfinite(t) and all(math.isfinite(a) for a in angles)):
            raise DecodeError("nonfinite", "NaN or infinite time or angle")
        return Packet(angles, seq, t)
    if len(data) in (8 * n for n in ANGLE_COUNTS):
        angles = struct.unpack(f"<{len(data) // 8}d", data)
        if not all(math.isfinite(a) for a in angles):
            raise DecodeError("nonfinite", "NaN or infinite angle")
        return Packet(angles)
    raise DecodeError("malformed", f"{len(data)} bytes: neither an extended packet nor 2/4 raw float64")


def parse_udp_url(url: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``udp://HOST:PORT`` (or ``HOST:PORT``, or ``PORT``) -> (host, port)."""
    rest = url[len("udp://"):] if url.startswith("udp://") else url
    host, _, port = rest.rpartition(":")
    host = host.strip("[]") or default_host
    try:
        port_n = int(port)
    except ValueError:
        raise ValueError(f"{url!r}: expected udp://HOST:PORT") from None
    if not 0 < port_n < 65536:
        raise ValueError(f"{url!r}: port must be in 1..65535")
    return host, port_n
