"""The safety envelope: which decoded targets the robot may follow, and the velocity guard.

Modelled on libbarrett's ``SafetyModule`` (``include/barrett/products/safety_module.h``), which faults the WAM
when a speed or torque exceeds a limit, but applied to the *targets* before they reach the controller: a target
that could move the robot somewhere it must not go is rejected, not clamped. Every default and its source is in
:data:`jaxarm.robot.config.VALUES` (``jaxarm wam-sim --print-config``); the configuration is
:class:`~jaxarm.robot.config.SafetyConfig`.

A target (4 WAM joint angles, rad, after the joint map) is judged in this order:

1. ``nonfinite``: any NaN or infinity -> rejected.
2. ``out_of_range``: any joint farther than ``clamp_margin_rad`` outside the allowed range (the joint range of
   the WAM manual's Table 6 shrunk by ``target_inset_rad``) -> rejected.
3. ``clamped``: a joint outside the allowed range by at most ``clamp_margin_rad`` -> clamped into it, accepted
   and counted.
4. ``jump``: while the link is up, a target whose distance from the last accepted target, divided by the time
   since it, exceeds ``velocity_limit_rad_s`` on any joint -> rejected. That time is the sender's clock
   difference (extended packets) but never more than the robot's own elapsed time plus ``jump_clock_slack_s``
   (raw packets, having no clock, get the robot's elapsed time plus the slack), and never less than one control
   tick. The first target of a link (at start, after a timeout or a hold) is only range-checked: the controller
   then moves there at its own speed limit (PosToVel clips at ``pos_to_vel_limit_rad_s``).

Why reject rather than clamp: a clamped absurd target is still followed, to the joint limit (16 bytes of HTTP
drove the robot to its stops in a test). A rejected one leaves the robot on its last good target.

The velocity guard (:func:`velocity_guard`) is the envelope's second half, on the robot's motion: a joint
moving faster than its guard speed (:func:`guard_speed`: ``velocity_warning_fraction`` of its limit, lower still
where one tick of full torque could carry it past the limit) is braked at full control torque, whatever the
controller asks (libbarrett's safety board idles the WAM at its velocity fault; we brake instead so the run goes
on). With the default chain it never acts (PosToVel commands at most pi rad/s); it bounds position mode and any
configuration whose limit is below the chain's speed.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import numpy as np

from jaxarm.robot.config import WamSimConfig, joint_limits

#: Verdicts of :func:`check_target` that accept the target.
ACCEPTED = ("ok", "clamped")
#: Verdicts of :func:`check_target` that reject it.
REJECTED = ("nonfinite", "out_of_range", "jump")


class Envelope(NamedTuple):
    """The envelope as arrays, precomputed once from a :class:`~jaxarm.robot.config.WamSimConfig`."""

    lo: np.ndarray                  # (4,) allowed target range, rad
    hi: np.ndarray
    reject_lo: np.ndarray           # (4,) beyond these a target is rejected, rad
    reject_hi: np.ndarray
    velocity_limit: np.ndarray      # (4,) rad/s
    warning_fraction: float
    clock_slack_s: float
    min_dt_s: float                 # one control tick


def envelope(config: WamSimConfig) -> Envelope:
    s = config.safety
    lo, hi = joint_limits(config)
    v = np.asarray(s.velocity_limit_rad_s, dtype=float)
    return Envelope(lo, hi, lo - s.clamp_margin_rad, hi + s.clamp_margin_rad, v, s.velocity_warning_fraction,
                    s.jump_clock_slack_s, config.controller.control_period_s)


def jump_dt(env: Envelope, robot_elapsed_s: float, sender_elapsed_s: Optional[float]) -> float:
    """Time (s) over which a jump from the last accepted target is judged: the sender's elapsed time if it has
    a clock, capped at the robot's elapsed time plus the slack, floored at one control tick."""
    bound = robot_elapsed_s + env.clock_slack_s
    dt = bound if sender_elapsed_s is None else min(sender_elapsed_s, bound)
    return max(dt, env.min_dt_s)


def check_target(env: Envelope, target: np.ndarray, last_target: Optional[np.ndarray],
                 dt_s: float = 0.0) -> tuple[str, np.ndarray]:
    """Judge a target (4 WAM joint angles, rad). ``last_target`` is the last accepted target while the link is
    up (None: first target of a link, no jump check); ``dt_s`` the time from :func:`jump_dt`.

    Returns ``(verdict, target)``: the verdict is one of :data:`ACCEPTED` (the target, clamped if so) or
    :data:`REJECTED` (the target returned unchanged, not to be used).
    """
    # Array methods (.all(), .any()) rather than np.all/np.any: this runs once per packet, ~70 times a second,
    # and the function forms add a microsecond each.
    target = np.asarray(target, dtype=float)
    if not np.isfinite(target).all():
        return "nonfinite", target
    if (target < env.reject_lo).any() or (target > env.reject_hi).any():
        return "out_of_range", target
    clamped = np.minimum(np.maximum(target, env.lo), env.hi)
    if last_target is not None and (np.abs(clamped - last_target) > env.velocity_limit * dt_s).any():
        return "jump", target
    return ("clamped" if (clamped != target).any() else "ok"), clamped


def inside(env: Envelope, target: np.ndarray) -> bool:
    """True when ``target`` (rad) is finite and inside the allowed range: what every accepted target satisfies."""
    target = np.asarray(target, dtype=float)
    return bool(np.all(np.isfinite(target)) and np.all(target >= env.lo) and np.all(target <= env.hi))


def guard_speed(env: Envelope, max_torque_nm: np.ndarray, min_inertia_kgm2: np.ndarray) -> np.ndarray:
    """Speed (rad/s, per joint) above which the velocity guard brakes: the warning fraction of the limit, but at
    least two ticks of the largest acceleration (``max_torque_nm / min_inertia_kgm2``) below the limit, as the
    torque of the tick in which the guard sees the speed still acts for a whole tick (floored at 0)."""
    headroom = 2.0 * env.min_dt_s * np.asarray(max_torque_nm, float) / np.asarray(min_inertia_kgm2, float)
    return np.maximum(np.minimum(env.warning_fraction * env.velocity_limit, env.velocity_limit - headroom), 0.0)


def velocity_guard(speed: np.ndarray, floor: float, v: np.ndarray, tau: np.ndarray,
                   brake_torque: np.ndarray) -> np.ndarray:
    """Torque (N m) after the velocity guard: a joint whose velocity ``v`` (rad/s) exceeds ``speed`` (from
    :func:`guard_speed`) in magnitude gets ``brake_torque`` against its motion instead of ``tau``. ``floor`` is
    ``min(speed)``."""
    # The usual case (every joint slower than the lowest guard speed) first, in plain Python: this runs every 2 ms
    # tick, and NumPy's per-call overhead on 4-vectors (~1 us per call) would be a tenth of the tick's Python.
    vs = v.tolist()
    if max(vs) <= floor and min(vs) >= -floor:
        return tau
    return np.where(np.abs(v) > speed, -np.sign(v) * brake_torque, tau)
