"""The libbarrett-like 500 Hz chain: Network System (receiver), PosToVel, jv loop / jp PID.

Everything here is a pure function of (config, state, inputs) returning a new state; states are NamedTuples of
NumPy arrays and plain numbers. The chain runs in the simulator's own process, one call per 2 ms tick, beside the
MuJoCo C model, so it is NumPy on 4-vectors rather than JAX (a per-tick JAX dispatch would cost more than the
physics). Units: rad, rad/s, N m, s.

Receiver semantics (libbarrett ``ex11_master_master.h``, wam.md §4): every tick the socket is drained and each
datagram judged in arrival order; the newest accepted one sets the target. Verdicts:

* ``malformed`` / ``truncated`` / ``nonfinite``: decoding failed (see :mod:`jaxarm.robot.protocol`); dropped.
* ``duplicate``: same sequence number as the held target; dropped.
* ``out_of_order``: older sequence number than the held target (serial-number arithmetic mod 2**32); dropped.
* ``stale``: newer sequence number but a simulated time older than the held target's by more than
  ``ReceiverConfig.stale_after_s`` (content older than what the robot follows, e.g. a replayed or restarted
  sender); dropped.
* ``out_of_range``: decoded and in sequence but outside the joint range: clamped into the range (shrunk by
  ``limit_margin_rad``), counted, and accepted.
* accepted packets count as ``ok``; accepted packets overtaken within the same tick also count as ``superseded``.
  A raw packet (no sequence number) is judged on its content only and clears the sequence tracking.

No accepted packet for ``timeout_s`` -> one ``timeouts`` count, the link forgets its sequence tracking (the next
valid packet is accepted whatever its number, as after a sender restart) and, with ``on_timeout="hold_position"``,
the target becomes the robot's current position.

After the chain, a joint-limit guard (not libbarrett: it stands in for the WAM's mechanical stops and safety
module) brakes a joint at full control torque when its stopping distance reaches the distance to its range limit.
It never acts on a trajectory inside the task's ranges; it keeps absurd targets and jumps from driving a joint out.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import numpy as np

from jaxarm.robot.config import WamSimConfig, joint_limits
from jaxarm.robot.protocol import SEQ_MODULUS, DecodeError, decode
from jaxarm.robot.wam_model import JOINT_RANGE_RAD

#: Joint-limit guard (not libbarrett; stands in for the WAM's mechanical stops and safety module): the range it keeps
#: each joint inside is the joint range shrunk by this margin, rad ...
GUARD_MARGIN_RAD = 0.01
#: ... and it counts on this fraction of the control torque limit's deceleration (the rest covers the reaction and
#: centrifugal torques of the other joints: up to ~10 N m on J1 while J4 brakes). The model's joint stops
#: (wam_model.STOP_INSET_RAD) catch what is left.
BRAKE_FRACTION = 0.4

BAD_KINDS = ("malformed", "truncated", "nonfinite", "stale", "duplicate", "out_of_order")


class Counters(NamedTuple):
    ok: int = 0
    malformed: int = 0
    truncated: int = 0
    nonfinite: int = 0
    stale: int = 0
    duplicate: int = 0
    out_of_order: int = 0
    out_of_range: int = 0
    superseded: int = 0
    timeouts: int = 0

    @property
    def bad(self) -> int:
        return sum(getattr(self, k) for k in BAD_KINDS)


class ReceiverState(NamedTuple):
    target: np.ndarray               # (4,) WAM joint target, rad
    seq: Optional[int]               # sequence number of the held target (None: unlinked or raw)
    t: Optional[float]               # sender's simulated time of the held target, s
    last_accept_s: Optional[float]   # robot time of the last accepted packet (None: never)
    linked: bool                     # a packet was accepted and no timeout since
    counters: Counters


def receiver_init(target: np.ndarray) -> ReceiverState:
    return ReceiverState(np.asarray(target, dtype=float).copy(), None, None, None, False, Counters())


def _count(c: Counters, kind: str, n: int = 1) -> Counters:
    return c._replace(**{kind: getattr(c, kind) + n})


def judge(config: WamSimConfig, state: ReceiverState, data: bytes) -> tuple[ReceiverState, str]:
    """Judge one datagram; return the new state and the verdict (``"ok"``, ``"out_of_range"`` or a bad kind)."""
    c = state.counters
    try:
        packet = decode(data)
    except DecodeError as err:
        return state._replace(counters=_count(c, err.kind)), err.kind
    if packet.seq is not None and state.linked and state.seq is not None:
        diff = (packet.seq - state.seq) % SEQ_MODULUS
        if diff == 0:
            return state._replace(counters=_count(c, "duplicate")), "duplicate"
        if diff >= SEQ_MODULUS // 2:
            return state._replace(counters=_count(c, "out_of_order")), "out_of_order"
        if state.t is not None and packet.t < state.t - config.receiver.stale_after_s:
            return state._replace(counters=_count(c, "stale")), "stale"
    angles = np.asarray(packet.angles, dtype=float)
    target = config.joint_map.to_wam(angles) if angles.size == 2 else angles
    lo, hi = joint_limits(config)
    clamped = np.clip(target, lo, hi)
    verdict = "ok"
    c = _count(c, "ok")
    if np.any(clamped != target):
        verdict = "out_of_range"
        c = _count(c, "out_of_range")
    return ReceiverState(clamped, packet.seq, packet.t, state.last_accept_s, True, c), verdict


def receive(config: WamSimConfig, state: ReceiverState, datagrams, now_s: float,
            q: np.ndarray) -> tuple[ReceiverState, int]:
    """One tick of the Network System: judge every datagram that arrived since the last tick, keep the newest
    accepted target, handle timeouts. Returns the new state and the number of packets accepted this tick."""
    accepted = 0
    for data in datagrams:
        state, verdict = judge(config, state, data)
        accepted += verdict in ("ok", "out_of_range")
    if accepted:
        c = state.counters
        if accepted > 1:
            c = _count(c, "superseded", accepted - 1)
        return state._replace(last_accept_s=now_s, counters=c), accepted
    if state.linked and now_s - state.last_accept_s >= config.receiver.timeout_s - 1e-12:
        target = state.target
        if config.receiver.on_timeout == "hold_position":
            lo, hi = joint_limits(config)
            target = np.clip(np.asarray(q, dtype=float), lo, hi)
        state = state._replace(target=target, seq=None, t=None, linked=False,
                               counters=_count(state.counters, "timeouts"))
    return state, 0


class ControlState(NamedTuple):
    q_prev: np.ndarray       # (4,) joint position at the previous tick, rad
    v_filt: np.ndarray       # (4,) low-passed joint velocity, rad/s
    jv_int: np.ndarray       # (4,) jv PID integrator, N m
    jv_e_prev: np.ndarray    # (4,) previous jv error, rad/s
    tau_lp: np.ndarray       # (4,) jv torque low-pass output, N m
    jp_int: np.ndarray       # (4,) jp PID integrator, N m
    jp_e_prev: np.ndarray    # (4,) previous jp error, rad
    ref: np.ndarray          # (4,) rate-limited jp reference, rad


class ControlParams(NamedTuple):
    """Per-joint arrays precomputed once from a :class:`ControllerConfig` (so the tick does no conversion)."""

    period_s: float
    gain_k: float
    v_max: float
    chain_mask: np.ndarray      # (4,) bool: joint runs the selected chain (else the jp PID holds it)
    velocity_chain: bool        # True: chain = PosToVel + jv loop; False: chain = jp PID
    jp_kp: np.ndarray
    jp_ki_t: np.ndarray         # ki * T
    jp_kd_over_t: np.ndarray    # kd / T
    jp_limit: np.ndarray
    jv_kp: np.ndarray
    jv_ki_t: np.ndarray
    jv_kd_over_t: np.ndarray
    jv_limit: np.ndarray
    jv_lp_wt: np.ndarray        # omega_p * T of the torque low-pass
    vf_wt: np.ndarray           # omega_p * T of the velocity filter
    rate_step: float            # rate limit * T (0 = off)
    guard_lo: np.ndarray        # (4,) joint-limit guard: lower / upper range it never lets the joint pass, rad
    guard_hi: np.ndarray
    brake_accel: np.ndarray     # (4,) deceleration the guard counts on, rad/s^2
    brake_torque: np.ndarray    # (4,) torque it brakes with, N m


def control_params(config: WamSimConfig, max_inertia_kgm2=None) -> ControlParams:
    """Per-joint arrays for :func:`control_step`. ``max_inertia_kgm2`` (4,) is the largest diagonal of the joint
    mass matrix (armature included) over the reachable poses; the simulator passes its model's, and without it the
    joint-limit guard assumes 2 kg m^2 (more than any WAM joint but J1 of the 7-DOF arm)."""
    c = config.controller
    t = c.control_period_s
    arr = lambda v: np.asarray(v, dtype=float)  # noqa: E731
    mask = np.zeros(4, dtype=bool)
    mask[[config.joint_map.shoulder_joint, config.joint_map.elbow_joint]] = True
    if c.held_joints == "chain" or c.mode == "position":
        mask[:] = True
    return ControlParams(
        period_s=t, gain_k=c.pos_to_vel_gain_per_s, v_max=c.pos_to_vel_limit_rad_s, chain_mask=mask,
        velocity_chain=c.mode == "velocity",
        jp_kp=arr(c.jp_kp), jp_ki_t=arr(c.jp_ki) * t, jp_kd_over_t=arr(c.jp_kd) / t, jp_limit=arr(c.jp_limit_nm),
        jv_kp=arr(c.jv_kp), jv_ki_t=arr(c.jv_ki) * t, jv_kd_over_t=arr(c.jv_kd) / t, jv_limit=arr(c.jv_limit_nm),
        jv_lp_wt=arr(c.jv_torque_lowpass_rad_s) * t, vf_wt=arr(c.velocity_filter_rad_s) * t,
        rate_step=c.rate_limit_rad_s * t,
        guard_lo=np.asarray(JOINT_RANGE_RAD, float)[:, 0] + GUARD_MARGIN_RAD,
        guard_hi=np.asarray(JOINT_RANGE_RAD, float)[:, 1] - GUARD_MARGIN_RAD,
        brake_accel=BRAKE_FRACTION * arr(c.jp_limit_nm) / (arr(max_inertia_kgm2) if max_inertia_kgm2 is not None
                                                            else np.full(4, 2.0)),
        brake_torque=arr(c.jp_limit_nm))


def control_init(q0: np.ndarray) -> ControlState:
    z = np.zeros(4)
    q0 = np.asarray(q0, dtype=float).copy()
    return ControlState(q0, z, z, z, z, z, z, q0.copy())


def lowpass(y_prev, x, omega_t):
    """libbarrett FirstOrderFilter low_pass (a = 0, b = c = omega_p), backward Euler: (y + wT x) / (1 + wT)."""
    return (y_prev + omega_t * x) / (1.0 + omega_t)


def pid(integral, e_prev, e, kp, ki_t, kd_over_t, limit):
    """libbarrett PIDController: I += ki T e[n-1]; u = kp e + I + kd (e - e[n-1]) / T; clamp to +-limit.
    Returns (u, new integral)."""
    integral = integral + ki_t * e_prev
    u = kp * e + integral + kd_over_t * (e - e_prev)
    return _clip(u, limit), integral


def _clip(x, limit):
    """Symmetric clamp; np.minimum/np.maximum cost a third of np.clip on 4-vectors, which matters at 500 Hz."""
    return np.minimum(np.maximum(x, -limit), limit)


def control_step(p: ControlParams, s: ControlState, q: np.ndarray,
                 target: np.ndarray) -> tuple[ControlState, np.ndarray]:
    """One 2 ms tick: measured joint positions ``q`` and the receiver's ``target`` (rad) -> controller torque (N m),
    before gravity compensation (added by the model, as libbarrett adds it in ``jtSum``)."""
    v_filt = lowpass(s.v_filt, (q - s.q_prev) / p.period_s, p.vf_wt)
    # jp PID: holds the joints outside the chain (and is the chain in position mode).
    ref = target
    if p.rate_step > 0:
        ref = s.ref + _clip(target - s.ref, p.rate_step)
    e_p = ref - q
    u_p, jp_int = pid(s.jp_int, s.jp_e_prev, e_p, p.jp_kp, p.jp_ki_t, p.jp_kd_over_t, p.jp_limit)
    new_state, tau = _chain(p, s, q, target, v_filt, ref, e_p, u_p, jp_int)
    # Joint-limit guard: brake at full control torque once the stopping distance (plus two ticks of travel)
    # reaches the distance to the range limit, so no target or jump can drive a joint out of its range.
    v = (q - s.q_prev) / p.period_s
    stop = v * v / (2.0 * p.brake_accel) + np.abs(v) * 2.0 * p.period_s
    tau = np.where((v > 0) & (p.guard_hi - q <= stop), -p.brake_torque,
                   np.where((v < 0) & (q - p.guard_lo <= stop), p.brake_torque, tau))
    return new_state, tau


def _chain(p, s, q, target, v_filt, ref, e_p, u_p, jp_int):
    if p.velocity_chain:
        # PosToVel: the paper's custom system, v = K (q_target - q), clipped (wam.md §6).
        v_ref = _clip(p.gain_k * (target - q), p.v_max)
        e_v = v_ref - v_filt
        u_v, jv_int = pid(s.jv_int, s.jv_e_prev, e_v, p.jv_kp, p.jv_ki_t, p.jv_kd_over_t, p.jv_limit)
        tau_lp = lowpass(s.tau_lp, u_v, p.jv_lp_wt)
        tau = np.where(p.chain_mask, tau_lp, u_p)
        jp_mask = ~p.chain_mask
        new = ControlState(q.copy(), v_filt, jv_int, e_v, tau_lp,
                           np.where(jp_mask, jp_int, 0.0), np.where(jp_mask, e_p, 0.0), ref)
        return new, tau
    return s._replace(q_prev=q.copy(), v_filt=v_filt, jp_int=jp_int, jp_e_prev=e_p, ref=ref), u_p
