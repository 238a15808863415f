"""The 500 Hz chain: libbarrett filter/PID formulas and the Network System's verdicts, without physics."""
import math

import numpy as np
import pytest

from jaxarm.robot.config import ControllerConfig, JointMap, ReceiverConfig, SafetyConfig, WamSimConfig, joint_limits
from jaxarm.robot.controller import control_init, control_params, control_step, lowpass, pid
from jaxarm.robot.protocol import encode, encode_raw
from jaxarm.robot.receiver import HOLD_TIMEOUT, judge, receive, receiver_init
from jaxarm.robot.safety import envelope

T = 0.002


def test_lowpass_matches_backward_euler_and_continuous_step_response():
    # libbarrett first_order_filter-inl.h with a = 0, b = c = w: y[n] = (y[n-1] + wT x[n]) / (1 + wT).
    w = 56.0
    y, ys = 0.0, []
    for _ in range(500):
        y = lowpass(y, 1.0, w * T)
        ys.append(y)
    expected = 1.0 - (1.0 / (1.0 + w * T)) ** np.arange(1, 501)      # closed form of the recursion
    np.testing.assert_allclose(ys, expected, rtol=1e-12)
    # And close to the continuous 1 - exp(-w t) (backward Euler lags it slightly).
    assert abs(ys[99] - (1 - math.exp(-w * 0.2))) < 0.01


def test_pid_matches_libbarrett_on_a_step():
    kp, ki, kd, limit = 900.0, 2.5, 10.0, 25.0
    integ, e_prev = 0.0, 0.0
    # e = 0.01 rad from n = 0: u0 = kp e + kd e / T (D kick), then I grows by ki T e per tick.
    u0, integ = pid(integ, e_prev, 0.01, kp, ki * T, kd / T, 1e9)
    assert u0 == pytest.approx(900 * 0.01 + 10 * 0.01 / T)
    u1, integ = pid(integ, 0.01, 0.01, kp, ki * T, kd / T, 1e9)
    assert u1 == pytest.approx(900 * 0.01 + 2.5 * T * 0.01)
    # Clamped to the control_signal_limit.
    assert pid(0.0, 0.0, 1.0, kp, ki * T, kd / T, limit)[0] == limit
    assert pid(0.0, 0.0, -1.0, kp, ki * T, kd / T, limit)[0] == -limit


def test_velocity_chain_is_postovel_then_jv_p_then_lowpass():
    cfg = WamSimConfig()
    p = control_params(cfg)
    q0 = JointMap().to_wam(cfg.initial_virtual_rad)
    s = control_init(q0)
    target = q0 + np.array([0.1, 0.0, 0.0, -0.05])
    s, tau = control_step(p, s, q0, target)
    k = cfg.controller.pos_to_vel_gain_per_s
    v_ref = np.clip(k * (target - q0), -math.pi, math.pi)
    u = np.clip(np.array([42, 42, 18, 18]) * v_ref, -np.array([25, 20, 15, 15]), [25, 20, 15, 15])
    lp = np.array([180, 180, 56, 56]) * T
    expected = u * lp / (1 + lp)
    np.testing.assert_allclose(tau[[0, 3]], expected[[0, 3]])        # driven joints: the jv chain
    assert tau[1] == 0.0 and tau[2] == 0.0                           # held joints at their target: jp PID, e = 0


def test_position_mode_rate_limiter_steps_at_most_limit_times_t():
    cfg = WamSimConfig(controller=ControllerConfig(mode="position", rate_limit_rad_s=1.0))
    p = control_params(cfg)
    q0 = JointMap().to_wam(cfg.initial_virtual_rad)
    s = control_init(q0)
    target = q0 + 1.0
    for n in range(1, 4):
        s, tau = control_step(p, s, q0, target)
        np.testing.assert_allclose(s.ref, q0 + n * 1.0 * T)           # y += sign(x - y) min(|x - y|, limit T)
    assert np.all(np.abs(tau) <= np.array([25, 20, 15, 15]))


def _rx(cfg=None):
    cfg = cfg or WamSimConfig()
    return cfg, envelope(cfg), receiver_init(cfg.joint_map.to_wam(cfg.initial_virtual_rad))


def test_receiver_verdicts_for_every_kind():
    cfg, env, s = _rx(WamSimConfig(safety=SafetyConfig(accept_raw=True)))
    steps = [
        (encode([0.5, 1.0], 0, 0.00), "ok"),                       # first of a link: range check only
        (encode([0.5, 1.09], 1, 0.01), "ok"),                      # 0.09 rad in 10 ms = 9 rad/s < 10 rad/s
        (b"garbage!", "malformed"),
        (encode([0.5, 1.1], 2, 0.02)[:-1], "truncated"),
        (bytes(53), "oversize"),
        (encode([math.nan, 1.0], 2, 0.02), "nonfinite"),
        (encode([0.5, 1.09], 1, 0.01), "duplicate"),
        (encode([0.5, 1.2], 5, 0.05), "ok"),
        (encode([0.5, 1.15], 4, 0.04), "out_of_order"),
        (encode([0.5, 1.3], 6, 0.00), "stale"),                    # new seq, older content
        (encode([10.0, -5.0], 7, 0.07), "out_of_range"),           # rejected, not clamped
        (encode([0.5, 1.6], 8, 0.08), "jump"),                     # 0.4 rad in 30 ms: 13 rad/s > 10 rad/s
        (encode([0.5, 3.07], 9, 0.50), "jump"),                    # 1.87 rad: the sender claims 0.45 s, but
        #                                                            the robot saw 0.05 s (+ 0.02 s slack) pass
        (encode([0.5, 3.07], 9, 0.50), "clamped"),                 # 0.4 s later: 0.02 rad past 3.05, clamped
        (encode_raw([0.4, 2.9]), "ok"),                            # raw accepted when enabled
    ]
    now = 0.01 * np.arange(len(steps))
    now[-2:] += 0.4
    for k, (data, want) in enumerate(steps):
        s, verdict = judge(cfg, env, s, data, now_s=now[k])
        assert verdict == want, (k, data, verdict)
    c = s.counters
    assert (c.ok, c.clamped, c.malformed, c.truncated, c.oversize, c.nonfinite, c.duplicate, c.out_of_order,
            c.stale, c.out_of_range, c.jump) == (5, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2)
    assert c.rejected == 10
    np.testing.assert_allclose(s.target, JointMap().to_wam([0.4, 2.9]))


def test_raw_packets_refused_by_default():
    cfg, env, s = _rx()
    for data in (encode_raw([0.5, 1.0]), b"GET / HTTP/1.1\r\n", encode_raw([0.1, 1.5, 1.5, 1.0])):
        s, verdict = judge(cfg, env, s, data, now_s=0.0)
        assert verdict == "raw_refused"
    assert s.counters.raw_refused == 3 and s.counters.ok == 0 and not s.linked


def test_targets_beyond_the_margin_are_rejected_inside_it_clamped():
    cfg, env, s = _rx()
    lo, hi = joint_limits(cfg)                                    # joint range shrunk by target_inset_rad
    margin = cfg.safety.clamp_margin_rad
    s, verdict = judge(cfg, env, s, encode([hi[0] + 0.9 * margin, 1.53], 0, 0.0), now_s=0.0)
    assert verdict == "clamped" and s.target[0] == hi[0]
    s, verdict = judge(cfg, env, s, encode([hi[0] + 1.1 * margin, 1.53], 1, 1.0), now_s=1.0)
    assert verdict == "out_of_range" and s.target[0] == hi[0]      # the last good target stays
    # WAM-joint packets too (J2 beyond its range by more than the margin).
    s, verdict = judge(cfg, env, s, encode([hi[0], 3.0, math.pi / 2, 1.53], 2, 2.0), now_s=2.0)
    assert verdict == "out_of_range"


def test_newest_packet_per_tick_and_timeout_holds_position():
    cfg, env, s = _rx(WamSimConfig(receiver=ReceiverConfig(timeout_s=0.02)))
    q = np.array([0.3, math.pi / 2, math.pi / 2, 1.0])
    s, n = receive(cfg, env, s, [encode([0.5, 1.0], 0, 0.0), encode([0.55, 1.05], 1, 0.01)], 0.0, q)
    assert n == 2 and s.counters.superseded == 1
    np.testing.assert_allclose(s.target[[0, 3]], [0.55, 1.05])
    for k in range(1, 10):                                             # 18 ms: not yet
        s, _ = receive(cfg, env, s, [], k * T, q)
    assert s.counters.timeouts == 0 and s.linked
    s, _ = receive(cfg, env, s, [], 10 * T, q)                         # 20 ms: timeout -> hold where the robot is
    assert s.counters.timeouts == 1 and not s.linked and s.hold == HOLD_TIMEOUT
    np.testing.assert_allclose(s.target, q)
    s, _ = receive(cfg, env, s, [], 11 * T, q)                         # counted once per silence
    assert s.counters.timeouts == 1
    s, n = receive(cfg, env, s, [encode([0.1, 0.2], 0, 0.0)], 12 * T, q)   # restarted sender: seq 0 accepted
    assert n == 1 and s.linked and s.hold == 0


def test_hold_target_keeps_following_last_target():
    cfg, env, s = _rx(WamSimConfig(receiver=ReceiverConfig(timeout_s=0.01, on_timeout="hold_target")))
    s, _ = receive(cfg, env, s, [encode([0.5, 1.0], 0, 0.0)], 0.0, np.zeros(4))
    s, _ = receive(cfg, env, s, [], 0.02, np.zeros(4))
    assert s.counters.timeouts == 1
    np.testing.assert_allclose(s.target[[0, 3]], [0.5, 1.0])
