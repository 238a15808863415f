"""Packet format: round trips and every rejection kind."""
import math
import struct

import pytest

from jaxarm.robot.protocol import HEADER, DecodeError, Packet, decode, encode, encode_raw, parse_udp_url


def test_extended_round_trip_is_exact():
    data = encode([0.62, 1.53], seq=7, t=0.07)
    assert len(data) == 20 + 16 and data[:4] == b"WAMJ"
    assert decode(data) == Packet((0.62, 1.53), 7, 0.07)
    four = encode([0.1, math.pi / 2, math.pi / 2, 2.0], seq=2 ** 32 + 3, t=1.5)   # seq wraps mod 2**32
    assert decode(four) == Packet((0.1, math.pi / 2, math.pi / 2, 2.0), 3, 1.5)


def test_raw_libbarrett_doubles_accepted():
    assert decode(encode_raw([0.5, 1.0])) == Packet((0.5, 1.0))
    assert decode(struct.pack("<4d", 0, 1, 2, 3)).angles == (0, 1, 2, 3)


@pytest.mark.parametrize("data, kind", [
    (b"hello", "malformed"),
    (b"", "malformed"),
    (struct.pack("<3d", 1, 2, 3), "malformed"),                            # 24 bytes: not 2 or 4 doubles
    (HEADER.pack(b"WAMJ", 9, 2, 0, 0.0) + struct.pack("<2d", 1, 2), "malformed"),   # unknown version
    (HEADER.pack(b"WAMJ", 1, 3, 0, 0.0) + struct.pack("<3d", 1, 2, 3), "malformed"),  # 3 angles
    (encode([1, 2], 0, 0.0) + b"x", "malformed"),                          # trailing bytes
    (encode([1, 2], 0, 0.0)[:-3], "truncated"),
    (b"WAMJ\x01", "truncated"),
    (encode([float("nan"), 1], 0, 0.0), "nonfinite"),
    (encode([1, 2], 0, float("inf")), "nonfinite"),
    (encode_raw([1, float("-inf")]), "nonfinite"),
])
def test_bad_packets_say_why(data, kind):
    with pytest.raises(DecodeError) as err:
        decode(data)
    assert err.value.kind == kind


def test_parse_udp_url():
    assert parse_udp_url("udp://127.0.0.1:5005") == ("127.0.0.1", 5005)
    assert parse_udp_url("5006") == ("127.0.0.1", 5006)
    with pytest.raises(ValueError):
        parse_udp_url("udp://host:http")
