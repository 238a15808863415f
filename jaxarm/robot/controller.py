"""The libbarrett-like 500 Hz chain: PosToVel, jv loop / jp PID, and the guards after it.

Everything here is a pure function of (params, state, inputs) returning a new state; states are NamedTuples of
NumPy arrays and plain numbers. The chain runs in the simulator's own process, one call per 2 ms tick, beside the
MuJoCo C model, so it is NumPy on 4-vectors rather than JAX (a per-tick JAX dispatch would cost more than the
physics). Units: rad, rad/s, N m, s. Its input, the target, comes from the Network System
(:mod:`jaxarm.robot.receiver`) through the safety envelope (:mod:`jaxarm.robot.safety`).

After the chain come two guards (not libbarrett: they stand in for the WAM's mechanical stops and safety board):

* joint-limit guard: brakes a joint at full control torque when its stopping distance reaches the distance to its
  range limit. It never acts on a trajectory inside the task's ranges; it keeps absurd targets and jumps from
  driving a joint out.
* velocity guard (:func:`jaxarm.robot.safety.velocity_guard`): brakes a joint moving faster than the warning
  fraction of ``SafetyConfig.velocity_limit_rad_s``.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxarm.robot import safety
from jaxarm.robot.config import WamSimConfig
from jaxarm.robot.wam_model import JOINT_RANGE_RAD

#: Joint-limit guard (not libbarrett; stands in for the WAM's mechanical stops and safety module): the range it keeps
#: each joint inside is the joint range shrunk by this margin, rad ...
GUARD_MARGIN_RAD = 0.01
#: ... and it counts on this fraction of the control torque limit's deceleration (the rest covers the reaction and
#: centrifugal torques of the other joints: up to ~10 N m on J1 while J4 brakes). The model's joint stops
#: (wam_model.STOP_INSET_RAD) catch what is left.
BRAKE_FRACTION = 0.4


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
    brake_torque: np.ndarray    # (4,) torque both guards brake with, N m
    guard_speed: np.ndarray     # (4,) the velocity guard brakes above this speed, rad/s
    guard_floor: float          # min(guard_speed), rad/s


def control_params(config: WamSimConfig, max_inertia_kgm2=None, min_inertia_kgm2=None) -> ControlParams:
    """Per-joint arrays for :func:`control_step`. ``max_inertia_kgm2`` and ``min_inertia_kgm2`` (4,) are the largest
    and smallest diagonal of the joint mass matrix (armature included) over the reachable poses; the simulator
    passes its model's. Without them the joint-limit guard assumes 2 kg m^2 (more than any WAM joint but J1 of the
    7-DOF arm) and the velocity guard 0.05 kg m^2 (less than any WAM joint's armature but J4's 0.0346 plus its
    link)."""
    c = config.controller
    t = c.control_period_s
    arr = lambda v: np.asarray(v, dtype=float)  # noqa: E731
    mask = np.zeros(4, dtype=bool)
    mask[[config.joint_map.shoulder_joint, config.joint_map.elbow_joint]] = True
    if c.held_joints == "chain" or c.mode == "position":
        mask[:] = True
    i_max = arr(max_inertia_kgm2) if max_inertia_kgm2 is not None else np.full(4, 2.0)
    i_min = arr(min_inertia_kgm2) if min_inertia_kgm2 is not None else np.full(4, 0.05)
    # The controller's torque is at most its control_signal_limit; gravity compensation cancels gravity.
    guard = safety.guard_speed(safety.envelope(config), arr(c.jp_limit_nm), i_min)
    return ControlParams(
        period_s=t, gain_k=c.pos_to_vel_gain_per_s, v_max=c.pos_to_vel_limit_rad_s, chain_mask=mask,
        velocity_chain=c.mode == "velocity",
        jp_kp=arr(c.jp_kp), jp_ki_t=arr(c.jp_ki) * t, jp_kd_over_t=arr(c.jp_kd) / t, jp_limit=arr(c.jp_limit_nm),
        jv_kp=arr(c.jv_kp), jv_ki_t=arr(c.jv_ki) * t, jv_kd_over_t=arr(c.jv_kd) / t, jv_limit=arr(c.jv_limit_nm),
        jv_lp_wt=arr(c.jv_torque_lowpass_rad_s) * t, vf_wt=arr(c.velocity_filter_rad_s) * t,
        rate_step=c.rate_limit_rad_s * t,
        guard_lo=np.asarray(JOINT_RANGE_RAD, float)[:, 0] + GUARD_MARGIN_RAD,
        guard_hi=np.asarray(JOINT_RANGE_RAD, float)[:, 1] - GUARD_MARGIN_RAD,
        brake_accel=BRAKE_FRACTION * arr(c.jp_limit_nm) / i_max,
        brake_torque=arr(c.jp_limit_nm),
        guard_speed=guard, guard_floor=float(guard.min()))


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


def control_step(p: ControlParams, s: ControlState, q: np.ndarray, target: np.ndarray,
                 qd: np.ndarray | None = None) -> tuple[ControlState, np.ndarray]:
    """One 2 ms tick: measured joint positions ``q`` and the receiver's ``target`` (rad) -> controller torque (N m),
    before gravity compensation (added by the model, as libbarrett adds it in ``jtSum``). ``qd``: the measured
    joint velocity (rad/s) the velocity guard reads; default the finite difference of ``q`` over the tick."""
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
    return new_state, safety.velocity_guard(p.guard_speed, p.guard_floor, v if qd is None else qd, tau,
                                            p.brake_torque)


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
