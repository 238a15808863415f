"""Receiver robustness: sequence-number wrap-around, a flood (bounded work per tick, newest valid packet wins,
the rest counted), oversize datagrams, holds after consecutive rejections. Sockets on 127.0.0.1 only."""
import math
import socket
import time

import numpy as np
import pytest

from jaxarm.robot import receiver as receiver_mod
from jaxarm.robot.config import ReceiverConfig, SafetyConfig, WamSimConfig
from jaxarm.robot.protocol import MAX_PACKET_BYTES, SEQ_MODULUS, encode
from jaxarm.robot.receiver import HOLD_REJECTIONS, receive, receiver_init
from jaxarm.robot.safety import envelope
from jaxarm.robot.simulator import SocketReader, open_receiver_socket

Q0 = np.array([0.62, math.pi / 2, math.pi / 2, 1.53])


def _setup(**receiver):
    cfg = WamSimConfig(receiver=ReceiverConfig(**receiver))
    return cfg, envelope(cfg), receiver_init(Q0)


def test_sequence_number_wraps_around_without_rejection():
    cfg, env, s = _setup()
    seqs = [SEQ_MODULUS - 3, SEQ_MODULUS - 2, SEQ_MODULUS - 1, 0, 1, 2]
    for k, seq in enumerate(seqs):
        s, n = receive(cfg, env, s, [encode([0.62 + 0.01 * k, 1.53], seq, 100.0 + 0.01 * k)], 0.01 * k, Q0)
        assert n == 1, seq
    assert s.seq == 2 and s.counters.ok == 6 and s.counters.rejected == 0
    # Across the wrap the older side is still older: 2**32 - 1 after 2 is out of order, 2 again a duplicate.
    s, _ = receive(cfg, env, s, [encode([0.7, 1.53], SEQ_MODULUS - 1, 99.0)], 0.06, Q0)
    s, _ = receive(cfg, env, s, [encode([0.7, 1.53], 2, 100.05)], 0.07, Q0)
    assert (s.counters.out_of_order, s.counters.duplicate) == (1, 1)
    # The sender encodes the wrap itself (seq mod 2**32).
    assert encode([0.0, 0.0], SEQ_MODULUS + 5, 0.0) == encode([0.0, 0.0], 5, 0.0)


def test_flood_judges_only_the_newest_the_newest_valid_wins_and_the_rest_are_counted(monkeypatch):
    cfg, env, s = _setup()                                           # max_judged_per_tick = 16
    rng = np.random.Generator(np.random.PCG64(1))
    junk = [rng.bytes(int(n)) for n in rng.integers(1, 65, size=4995)]
    valid = [encode([0.62, 1.53 + 0.001 * k], k, 0.001 * k) for k in range(5)]
    flood = junk[:2000] + valid[:2] + junk[2000:] + valid[2:]          # the newest 3 are valid
    calls = []
    real_decode = receiver_mod.decode
    monkeypatch.setattr(receiver_mod, "decode", lambda d: calls.append(1) or real_decode(d))
    s, n = receive(cfg, env, s, flood, 0.0, Q0)
    assert len(calls) == 16                                            # work per tick bounded
    assert n == 3 and s.seq == 4                                       # the newest valid packet wins
    np.testing.assert_allclose(s.target[3], 1.53 + 0.004)
    c = s.counters
    assert c.received == 5000 and c.flood_dropped == 5000 - 16
    assert c.ok == 3 and c.superseded == 2 and c.rejected == 13
    assert c.received == c.ok + c.rejected + c.flood_dropped


def test_socket_reads_are_bounded_per_tick_and_nothing_read_is_lost():
    rx = open_receiver_socket("127.0.0.1", 0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sent = [encode([0.62, 1.53], k, 0.01 * k) for k in range(300)]
        for d in sent:
            tx.sendto(d, rx.getsockname())
        time.sleep(0.05)
        reader = SocketReader(rx, max_reads=64)
        batches = [reader.read() for _ in range(6)]
        assert [len(b) for b in batches] == [64, 64, 64, 64, 44, 0]
        assert [d for b in batches for d in b] == sent                 # in order, byte for byte
    finally:
        rx.close()
        tx.close()


@pytest.mark.parametrize("size", [MAX_PACKET_BYTES + 1, 4000, 65000])
def test_oversize_datagrams_are_counted_and_not_held_in_memory(size):
    rx = open_receiver_socket("127.0.0.1", 0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        tx.sendto(encode([0.62, 1.53], 0, 0.0) + bytes(size - 36), rx.getsockname())   # a valid head, then more
        tx.sendto(encode([0.63, 1.53], 1, 0.01), rx.getsockname())
        time.sleep(0.05)
        got = SocketReader(rx, max_reads=16).read()
    finally:
        rx.close()
        tx.close()
    assert [len(d) for d in got] == [MAX_PACKET_BYTES + 1, 36]          # the big one cut to what the verdict needs
    cfg, env, s = _setup()
    s, n = receive(cfg, env, s, got, 0.0, Q0)
    assert s.counters.oversize == 1 and n == 1 and s.seq == 1


def test_consecutive_rejections_hold_position_and_the_stream_resumes():
    cfg = WamSimConfig(safety=SafetyConfig(max_consecutive_rejections=10))
    env, s = envelope(cfg), receiver_init(Q0)
    s, _ = receive(cfg, env, s, [encode([0.62, 1.53], 0, 0.0)], 0.0, Q0)
    q_now = Q0 + np.array([0.05, 0.0, 0.0, -0.05])                     # where the robot is when it holds
    s, _ = receive(cfg, env, s, [b"junk"] * 9, 0.002, q_now)
    assert s.hold == 0 and s.counters.rejection_holds == 0              # 9 in a row: still following
    s, _ = receive(cfg, env, s, [b"junk"], 0.004, q_now)
    assert s.hold == HOLD_REJECTIONS and s.counters.rejection_holds == 1 and not s.linked
    np.testing.assert_allclose(s.target, q_now)                         # holds where it is
    s, _ = receive(cfg, env, s, [b"junk"] * 5, 0.006, q_now)
    assert s.counters.rejection_holds == 1                              # one hold per streak
    s, n = receive(cfg, env, s, [encode([0.9, 1.2], 7, 0.07)], 0.008, q_now)   # next valid packet relinks
    assert n == 1 and s.hold == 0 and s.linked and s.rejections_in_row == 0
