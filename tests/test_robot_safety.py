"""The safety envelope (jaxarm.robot.safety): verdicts against hand-computed cases, and property-based tests
(hypothesis) over arbitrary bytes for the decoder and the receiver: never an exception, never an accepted target
outside the envelope."""
import math
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxarm.robot.config import ReceiverConfig, SafetyConfig, WamSimConfig
from jaxarm.robot.protocol import MAX_PACKET_BYTES, DecodeError, decode, encode, encode_raw
from jaxarm.robot.receiver import REJECTION_KINDS, receive, receiver_init
from jaxarm.robot.safety import check_target, envelope, inside, jump_dt

# The WAM's joint ranges (manual Table 6), written out here as the independent reference.
RANGE = np.array([(-2.6, 2.6), (-2.0, 2.0), (-2.8, 2.8), (-0.9, 3.1)])
Q0 = np.array([0.62, math.pi / 2, math.pi / 2, 1.53])


def test_allowed_range_and_rejection_band_by_hand():
    env = envelope(WamSimConfig())                                     # inset 0.05 rad, clamp margin 0.05 rad
    np.testing.assert_allclose(env.lo, RANGE[:, 0] + 0.05)
    np.testing.assert_allclose(env.hi, RANGE[:, 1] - 0.05)
    assert check_target(env, [2.59, 1.5, 1.5, 1.0], None)[0] == "clamped"      # 0.04 past 2.55: clamped
    assert check_target(env, [2.59, 1.5, 1.5, 1.0], None)[1][0] == pytest.approx(2.55)
    assert check_target(env, [2.61, 1.5, 1.5, 1.0], None)[0] == "out_of_range"  # 0.06 past: rejected
    assert check_target(env, [0.0, 1.5, 1.5, -0.86], None)[0] == "clamped"     # J4 lower: -0.85 allowed
    assert check_target(env, [0.0, 1.5, 1.5, -0.91], None)[0] == "out_of_range"
    for bad in (math.nan, math.inf, -math.inf):
        assert check_target(env, [0.0, bad, 1.5, 1.0], None)[0] == "nonfinite"
    assert check_target(env, [1e98, 1.5, 1.5, 1.0], None)[0] == "out_of_range"  # "GET / HTTP/1.1\r\n" as raw


def test_jump_limit_is_speed_over_elapsed_time_with_the_sender_clock_capped():
    env = envelope(WamSimConfig())                                     # 10 rad/s, 20 ms slack, 2 ms floor
    assert jump_dt(env, robot_elapsed_s=0.015, sender_elapsed_s=0.010) == pytest.approx(0.010)
    assert jump_dt(env, robot_elapsed_s=0.015, sender_elapsed_s=5.0) == pytest.approx(0.035)   # forged: capped
    assert jump_dt(env, robot_elapsed_s=0.015, sender_elapsed_s=None) == pytest.approx(0.035)  # raw: robot clock
    assert jump_dt(env, robot_elapsed_s=0.0, sender_elapsed_s=0.0) == pytest.approx(0.002)    # floor: one tick
    last = Q0.copy()
    step = np.array([0.0, 0.0, 0.0, 0.095])                            # 9.5 rad/s over 10 ms: allowed
    assert check_target(env, last + step, last, 0.010)[0] == "ok"
    assert check_target(env, last + 1.1 * step, last, 0.010)[0] == "jump"      # 10.45 rad/s
    assert check_target(env, last + 1.1 * step, last, 0.020)[0] == "ok"        # same step over 20 ms
    assert check_target(env, last + 3 * step, None)[0] == "ok"                 # first of a link: no jump check


def test_safety_config_errors_name_the_field():
    from jaxarm.config.validate import ConfigError

    for kwargs, field in ((dict(velocity_limit_rad_s=(10, 10, 10)), "velocity_limit_rad_s"),
                          (dict(velocity_limit_rad_s=(10, 10, 10, math.nan)), "velocity_limit_rad_s"),
                          (dict(clamp_margin_rad=-0.1), "clamp_margin_rad"),
                          (dict(target_inset_rad=1.0), "target_inset_rad"),
                          (dict(max_consecutive_rejections=0), "max_consecutive_rejections"),
                          (dict(jump_clock_slack_s=math.inf), "jump_clock_slack_s"),
                          (dict(accept_raw="yes"), "accept_raw")):
        with pytest.raises(ConfigError, match=f"SafetyConfig.{field}"):
            SafetyConfig(**kwargs)


# --- property-based -------------------------------------------------------------------------------------------

FAST = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@FAST
@given(st.binary(max_size=200))
def test_decoder_never_raises_anything_but_decode_error(data):
    try:
        packet = decode(data)
    except DecodeError as err:
        assert err.kind in ("oversize", "malformed", "truncated", "nonfinite")
        return
    assert len(data) <= MAX_PACKET_BYTES and len(packet.angles) in (2, 4)
    assert all(math.isfinite(a) for a in packet.angles)


def _datagram():
    """Arbitrary bytes, and well-formed packets carrying arbitrary numbers (so the envelope, not only the decoder,
    is exercised): extended with any seq/time/angles, raw with any doubles."""
    extended = st.builds(encode,
                         st.one_of(st.lists(floats, min_size=2, max_size=2), st.lists(floats, min_size=4, max_size=4)),
                         st.integers(0, 2 ** 32 - 1), floats)
    near = st.builds(lambda d, seq: encode(Q0[[0, 3]] + np.asarray(d), seq, 0.01 * seq),
                     st.lists(st.floats(-0.3, 0.3), min_size=2, max_size=2), st.integers(0, 50))
    edge = st.builds(lambda d, seq: encode([2.55 + d, 3.05 - d], seq, 0.01 * seq),     # at the clamp band
                     st.floats(-0.1, 0.1), st.integers(0, 50))
    raw = st.one_of(st.lists(floats, min_size=2, max_size=2), st.lists(floats, min_size=4, max_size=4)).map(
        lambda a: struct.pack(f"<{len(a)}d", *a))
    return st.one_of(st.binary(max_size=60), st.binary(min_size=MAX_PACKET_BYTES + 1, max_size=200), extended,
                     near, edge, raw)


@FAST
@given(ticks=st.lists(st.lists(_datagram(), max_size=6), min_size=1, max_size=12), accept_raw=st.booleans(),
       gap_ticks=st.integers(1, 200), judged=st.sampled_from([2, 16]))
def test_receiver_never_raises_and_never_accepts_a_target_outside_the_envelope(ticks, accept_raw, gap_ticks, judged):
    cfg = WamSimConfig(receiver=ReceiverConfig(max_judged_per_tick=judged), safety=SafetyConfig(accept_raw=accept_raw))
    env = envelope(cfg)
    limit = np.asarray(cfg.safety.velocity_limit_rad_s)
    state = receiver_init(Q0)
    for n, datagrams in enumerate(ticks):
        now = n * gap_ticks * 0.002
        before = state
        state, accepted = receive(cfg, env, state, datagrams, now, Q0)
        assert inside(env, state.target)
        assert np.all(state.target >= RANGE[:, 0]) and np.all(state.target <= RANGE[:, 1])
        c = state.counters
        assert c.received == c.ok + c.rejected + c.flood_dropped
        assert c.rejected == sum(getattr(c, k) for k in REJECTION_KINDS)
        held = c.rejection_holds > before.counters.rejection_holds
        if accepted and before.linked and not held:
            # No accepted target moved faster than the limit allows over the robot's elapsed time + slack
            # (a hold unlinks, and the first target of a new link is only range-checked).
            elapsed = now - before.last_accept_s + cfg.safety.jump_clock_slack_s
            assert np.all(np.abs(state.target - before.target) <= limit * max(elapsed, 0.002) * accepted + 1e-9)
    if not accept_raw and state.linked:
        assert state.seq is not None                                    # only extended packets link


@FAST
@given(st.lists(st.binary(max_size=64), min_size=1, max_size=40))
def test_junk_bytes_never_move_the_target(junk):
    # Bytes that do not start with the magic (random junk, as in issue 26) are never accepted by default.
    junk = [d for d in junk if d[:4] != b"WAMJ"]
    cfg = WamSimConfig()
    state = receiver_init(Q0)
    state, accepted = receive(cfg, envelope(cfg), state, junk, 0.1, Q0)
    assert accepted == 0 and np.array_equal(state.target, Q0)
    assert state.counters.rejected + state.counters.flood_dropped == len(junk)


def test_raw_http_request_is_refused_and_with_accept_raw_rejected_as_out_of_range():
    data = b"GET / HTTP/1.1\r\n"
    assert len(data) == 16 and abs(decode(data).angles[0]) > 1e90          # what the old robot followed
    for accept_raw, kind in ((False, "raw_refused"), (True, "out_of_range")):
        cfg = WamSimConfig(safety=SafetyConfig(accept_raw=accept_raw))
        state, accepted = receive(cfg, envelope(cfg), receiver_init(Q0), [data], 0.0, Q0)
        assert accepted == 0 and getattr(state.counters, kind) == 1
        assert np.array_equal(state.target, Q0)
    assert decode(encode_raw([1e9, -1e9])).angles == (1e9, -1e9)            # decodes, then out of range


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(datagrams=st.lists(_datagram(), min_size=1, max_size=40), gaps=st.lists(st.floats(0.0, 0.1), min_size=40,
       max_size=40), accept_raw=st.booleans(), mode=st.sampled_from(["velocity", "position"]))
def test_simulated_robot_stays_in_its_limits_under_any_input(datagrams, gaps, accept_raw, mode):
    from jaxarm.robot.config import ControllerConfig, PhysicsConfig
    from jaxarm.robot.simulator import run_offline, within_joint_range

    cfg = WamSimConfig(controller=ControllerConfig(mode=mode), safety=SafetyConfig(accept_raw=accept_raw))
    arrivals = np.cumsum(gaps[:len(datagrams)])
    log = run_offline(cfg, arrivals, datagrams, float(arrivals[-1]) + 0.5)
    q, tau, qd = log.rows[:, 10:14], log.rows[:, 14:18], log.rows[:, 18:22]
    assert np.all(np.isfinite(log.rows[:, 10:22])) and within_joint_range(q)
    assert np.all(np.abs(tau) <= np.asarray(PhysicsConfig().torque_limit_nm) + 1e-9)
    assert np.all(np.abs(qd) <= np.asarray(cfg.safety.velocity_limit_rad_s))
    c = log.counters
    assert c.received == len(datagrams) == c.ok + c.rejected + c.flood_dropped
