"""Every value of the simulated WAM, its controller, receiver and link model, with where it comes from.

One table, :data:`VALUES`, lists each number with its unit and its source (libbarrett file and key, Barrett manual,
the paper, or our own calibration/assumption, said as such). The frozen configuration dataclasses below take their
defaults from that table, so changing a default means changing the table and its source together.
Units: SI (s, rad, rad/s, N m); packet statistics in ms where the paper quotes ms.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from jaxarm.config.arm import START_POSTURE_RAD
from jaxarm.config.validate import ConfigError, check_choice, check_range


class Sourced(NamedTuple):
    """A value with its unit and where it comes from."""

    value: object
    unit: str
    source: str


_WAM4 = "libbarrett config/wam4.conf"
#: The one table of robot values (4-DOF order J1..J4 where a value is per joint).
VALUES: dict[str, Sourced] = {
    # --- libbarrett -------------------------------------------------------------------------------------------
    "control_period_s": Sourced(0.002, "s", "libbarrett include/barrett/products/product_manager.h "
                                            "DEFAULT_LOOP_PERIOD (500 Hz)"),
    "jp_kp": Sourced((900.0, 2500.0, 600.0, 500.0), "N m/rad", f"{_WAM4} joint_position_control.kp"),
    "jp_ki": Sourced((2.5, 5.0, 2.5, 0.5), "N m/(rad s)", f"{_WAM4} joint_position_control.ki"),
    "jp_kd": Sourced((10.0, 20.0, 10.0, 2.5), "N m s/rad", f"{_WAM4} joint_position_control.kd"),
    "jp_limit_nm": Sourced((25.0, 20.0, 15.0, 15.0), "N m", f"{_WAM4} joint_position_control.control_signal_limit"),
    "jv_kp": Sourced((42.0, 42.0, 18.0, 18.0), "N m s/rad", f"{_WAM4} joint_velocity_control[0].kp"),
    "jv_ki": Sourced((0.0, 0.0, 0.0, 0.0), "N m/rad", f"{_WAM4} joint_velocity_control[0].ki"),
    "jv_kd": Sourced((0.0, 0.0, 0.0, 0.0), "N m s^2/rad", f"{_WAM4} joint_velocity_control[0].kd"),
    "jv_limit_nm": Sourced((25.0, 20.0, 15.0, 15.0), "N m",
                           f"{_WAM4} joint_velocity_control[0].control_signal_limit"),
    "jv_torque_lowpass_rad_s": Sourced((180.0, 180.0, 56.0, 56.0), "rad/s",
                                       f"{_WAM4} joint_velocity_control[1] low_pass omega_p"),
    "velocity_filter_rad_s": Sourced((180.0, 180.0, 180.0, 180.0), "rad/s",
                                     f"{_WAM4} joint_velocity_filter low_pass omega_p"),
    "pid_form": Sourced("e=ref-fb; I+=ki*T*e[n-1]; u=kp*e+I+kd*(e-e[n-1])/T; clamp", "-",
                        "libbarrett include/barrett/systems/detail/pid_controller-inl.h"),
    "lowpass_form": Sourced("y[n]=(y[n-1]+b*T*x[n])/(1+c*T), b=c=omega_p", "-",
                            "libbarrett include/barrett/math/detail/first_order_filter-inl.h (backward Euler)"),
    "rate_limiter_form": Sourced("y+=sign(x-y)*min(|x-y|, limit*T)", "-",
                                 "libbarrett include/barrett/systems/detail/rate_limiter-inl.h"),
    "rate_limit_rad_s": Sourced(0.0, "rad/s", "off by default; libbarrett ex06_realtime_move uses 1 rad/s "
                                              "(wam.md §2); position mode only"),
    "receiver_newest_packet": Sourced(True, "-", "libbarrett examples/ex11_master_master.h: drain the socket "
                                                 "each tick, keep only the newest packet"),
    "receiver_timeout_s": Sourced(0.3, "s", "Barrett ROS driver wam_node.cpp rt_msg_timeout (ex11 uses 10 ticks)"),
    "raw_packet_format": Sourced("DOF x float64, little-endian, no header", "-",
                                 "libbarrett examples/ex11_master_master.h"),
    # --- Barrett hardware (model) ------------------------------------------------------------------------------
    "joint_range_rad": Sourced(((-2.6, 2.6), (-2.0, 2.0), (-2.8, 2.8), (-0.9, 3.1)), "rad",
                               "WAM User Manual D1001 Table 6 (wam.md §1.1)"),
    "armature_kgm2": Sourced((0.2052, 0.0944, 0.0944, 0.0346), "kg m^2",
                             "Barrett inertial spec reflected rotor inertia (wam.md §1.2)"),
    "torque_limit_nm": Sourced((62.6, 84.2, 50.1, 26.8), "N m",
                               "derived: total joint torque (control + gravity) <= motor max continuous torque "
                               "1.49 N m (wam.md §1.2) x transmission (wam4.conf j2mp: 42; 2x28.25 and 2x16.8155 "
                               "for the J2/J3 differential; 18)"),
    "joint_damping_nms": Sourced((0.0, 0.0, 0.0, 2.5), "N m s/rad",
                                 "assumption, set by experiments/wam_calibrate.py: Barrett publishes no friction; "
                                 "without damping the libbarrett J4 jv loop (kp 18, 56 rad/s low-pass, 2 ms) "
                                 "limit-cycles on the 4-DOF elbow inertia (0.076 kg m^2); 2.5 is the smallest "
                                 "scanned value with robot/target elbow displacement < 1.05"),
    # --- the paper's custom systems (unpublished; wam.md §6) ---------------------------------------------------
    "pos_to_vel_gain_per_s": Sourced(20.0, "1/s",
                                     "calibrated once: experiments/wam_calibrate.py (PosToVel v=K(q_t-q); paper's "
                                     "mean errors; wam.md §6 found K~20 on another model)"),
    "pos_to_vel_limit_rad_s": Sourced(math.pi, "rad/s", "assumption of wam.md §6 (clip at 180 deg/s)"),
    "update_period_s": Sourced(0.010, "s", "paper §2.5/§3.3: packets every 10 ms of simulated time"),
    "packet_interval_mean_ms": Sourced(15.09, "ms", "paper §3.3"),
    "packet_interval_sd_ms": Sourced(5.65, "ms", "paper §3.3"),
    # --- joint map (wam.md §1.3) -------------------------------------------------------------------------------
    "joint_map": Sourced("shoulder->J1, elbow->J4, J2=J3=pi/2 held", "-",
                         "wam.md §1.3 (the paper does not say; J1 and J4 vertical => planar arm)"),
    "initial_virtual_rad": Sourced(START_POSTURE_RAD, "rad", "paper §2.3 start posture (0.62, 1.53)"),
    # --- receiver robustness (jaxarm.robot.controller) -----------------------------------------------------------
    "max_reads_per_tick": Sourced(256, "datagrams", "own choice: ex11 drains the whole queue each tick; we read at "
                                                    "most this many per 2 ms tick so a flood cannot stall the loop "
                                                    "(a read costs ~1.5 us: benchmarks/wam.py --receiver, "
                                                    "docs/robot.md)"),
    "max_judged_per_tick": Sourced(16, "datagrams", "own choice: only the newest this many datagrams of a tick are "
                                                    "judged (older ones are counted flood_dropped); a flood tick "
                                                    "(256 read, 16 judged) costs under 1 ms of the 2 ms tick, a "
                                                    "clean stream brings 1 per tick (benchmarks/wam.py --receiver)"),
    # --- safety envelope (jaxarm.robot.safety; modelled on libbarrett's SafetyModule) ------------------------------
    "accept_raw": Sourced(False, "-", "the headerless ex11 format (DOF x float64) is framed by length "
                                      "only, so any 16- or 32-byte datagram parses as a target (the 16 bytes "
                                      "'GET / HTTP/1.1\\r\\n' give ~1e98 rad); refused unless --accept-raw"),
    "target_inset_rad": Sourced(0.05, "rad", "own choice (the receiver's former clamp margin): accepted targets "
                                             "are kept this far inside the joint range (manual Table 6), clear of "
                                             "the model's stops (0.02 rad inside)"),
    "clamp_margin_rad": Sourced(0.05, "rad", "own choice: a target at most this far outside the allowed range "
                                             "(joint range shrunk by target_inset_rad) is clamped and counted; "
                                             "farther is a wrong unit, map or garbage and is rejected"),
    "velocity_limit_rad_s": Sourced((10.0, 10.0, 10.0, 10.0), "rad/s",
                                    "own choice, measured: the fastest 10 ms step of the clean network streams of "
                                    "the tracking table is 7.3 rad/s (docs/robot.md), the chain commands at most "
                                    "pi rad/s; libbarrett's SafetyModule limits Cartesian speed instead "
                                    "(setVelocityLimit, m/s; Barrett's default fault VL2 = 1.0 m/s at 350 mm from the "
                                    "elbow: support.barrett.com wiki WAM/SafetyFeaturesPrecautions)"),
    "velocity_warning_fraction": Sourced(0.9, "-", "libbarrett src/products/safety_module.cpp setVelocityLimit: "
                                                   "warning = 0.9 x fault by default; here the speed at which the "
                                                   "velocity guard starts braking"),
    "jump_clock_slack_s": Sourced(0.02, "s", "own choice: a sender's claimed elapsed time is trusted up to the "
                                             "robot's own elapsed time plus this (packet jitter, paper: 95 % of "
                                             "intervals 6-26 ms; 2 ms tick quantisation)"),
    "max_consecutive_rejections": Sourced(10, "datagrams", "libbarrett examples/ex11_master_master.h "
                                                           "NUM_MISSED_LIMIT = 10 (there: missed cycles before "
                                                           "unlinking and holding)"),
}


def _v(name: str):
    return VALUES[name].value


def _check_per_joint(owner, name: str, lo: float, hi: float, n: int = 4) -> None:
    value = getattr(owner, name)
    ok = isinstance(value, tuple) and len(value) == n and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and lo <= v <= hi
        for v in value)
    if not ok:
        raise ConfigError(f"{type(owner).__name__}.{name} = {value!r}: must be a tuple of {n} numbers in [{lo}, {hi}]")


@dataclass(frozen=True)
class JointMap:
    """Affine map between the virtual arm's (shoulder, elbow) and the WAM's four joints.

    ``q[shoulder_joint] = shoulder_scale * shoulder + shoulder_offset_rad``, likewise for the elbow; the other
    joints are held at ``hold_pose_rad``. Indices are 0-based (J1 = 0).
    """

    shoulder_joint: int = 0
    elbow_joint: int = 3
    shoulder_scale: float = 1.0
    shoulder_offset_rad: float = 0.0
    elbow_scale: float = 1.0
    elbow_offset_rad: float = 0.0
    hold_pose_rad: tuple[float, float, float, float] = (0.0, math.pi / 2, math.pi / 2, 0.0)

    def __post_init__(self):
        check_range(self, "shoulder_joint", 0, 3, integer=True)
        check_range(self, "elbow_joint", 0, 3, integer=True)
        if self.shoulder_joint == self.elbow_joint:
            raise ConfigError(f"JointMap.elbow_joint = {self.elbow_joint!r}: must differ from shoulder_joint")
        for name in ("shoulder_scale", "elbow_scale"):
            check_range(self, name, -10.0, 10.0)
            if getattr(self, name) == 0:
                raise ConfigError(f"JointMap.{name} = 0: must be non-zero (the map must be invertible)")
        check_range(self, "shoulder_offset_rad", -math.pi, math.pi)
        check_range(self, "elbow_offset_rad", -math.pi, math.pi)
        _check_per_joint(self, "hold_pose_rad", -math.pi, math.pi)

    def to_wam(self, virtual) -> np.ndarray:
        """(..., 2) virtual-arm angles (rad) -> (..., 4) WAM joint angles (rad)."""
        virtual = np.asarray(virtual, dtype=float)
        out = np.broadcast_to(np.asarray(self.hold_pose_rad), virtual.shape[:-1] + (4,)).copy()
        out[..., self.shoulder_joint] = self.shoulder_scale * virtual[..., 0] + self.shoulder_offset_rad
        out[..., self.elbow_joint] = self.elbow_scale * virtual[..., 1] + self.elbow_offset_rad
        return out

    def to_virtual(self, wam) -> np.ndarray:
        """(..., 4) WAM joint angles (rad) -> (..., 2) virtual-arm angles (rad); inverse of :meth:`to_wam`."""
        wam = np.asarray(wam, dtype=float)
        return np.stack([(wam[..., self.shoulder_joint] - self.shoulder_offset_rad) / self.shoulder_scale,
                         (wam[..., self.elbow_joint] - self.elbow_offset_rad) / self.elbow_scale], axis=-1)


@dataclass(frozen=True)
class ControllerConfig:
    """The libbarrett-like 500 Hz chain.

    mode: ``"velocity"`` is the paper's chain (Network System -> PosToVel -> trackReferenceSignal(jv), i.e. the
        jv P loop, its torque low-pass and saturation, plus gravity compensation); ``"position"`` is
        trackReferenceSignal(jp): the jp PID with the wam4 gains (optional rate limiter on the reference).
    held_joints: how the joints the map does not drive (J2, J3) are held: ``"position"`` by the jp PID
        (wam.md §7.2), ``"chain"`` by the same chain as the driven joints (as trackReferenceSignal would).
    """

    mode: str = "velocity"
    held_joints: str = "position"
    control_period_s: float = _v("control_period_s")
    pos_to_vel_gain_per_s: float = _v("pos_to_vel_gain_per_s")
    pos_to_vel_limit_rad_s: float = _v("pos_to_vel_limit_rad_s")
    jp_kp: tuple = _v("jp_kp")
    jp_ki: tuple = _v("jp_ki")
    jp_kd: tuple = _v("jp_kd")
    jp_limit_nm: tuple = _v("jp_limit_nm")
    jv_kp: tuple = _v("jv_kp")
    jv_ki: tuple = _v("jv_ki")
    jv_kd: tuple = _v("jv_kd")
    jv_limit_nm: tuple = _v("jv_limit_nm")
    jv_torque_lowpass_rad_s: tuple = _v("jv_torque_lowpass_rad_s")
    velocity_filter_rad_s: tuple = _v("velocity_filter_rad_s")
    rate_limit_rad_s: float = _v("rate_limit_rad_s")

    def __post_init__(self):
        check_choice(self, "mode", ("velocity", "position"))
        check_choice(self, "held_joints", ("position", "chain"))
        check_range(self, "control_period_s", 1e-4, 0.1)
        check_range(self, "pos_to_vel_gain_per_s", 0.0, 1000.0, lo_open=True)
        check_range(self, "pos_to_vel_limit_rad_s", 0.0, 20.0, lo_open=True)
        for name in ("jp_kp", "jp_ki", "jp_kd", "jv_kp", "jv_ki", "jv_kd"):
            _check_per_joint(self, name, 0.0, 1e5)
        for name in ("jp_limit_nm", "jv_limit_nm"):
            _check_per_joint(self, name, 0.0, 500.0)
        for name in ("jv_torque_lowpass_rad_s", "velocity_filter_rad_s"):
            _check_per_joint(self, name, 1e-3, 1e5)
        check_range(self, "rate_limit_rad_s", 0.0, 100.0)


@dataclass(frozen=True)
class ReceiverConfig:
    """The Network System: what the robot does with incoming packets (the envelope is :class:`SafetyConfig`).

    timeout_s: no accepted packet for this long -> timeout (counted) and the link resets its sequence tracking.
    on_timeout: ``"hold_position"`` sets the target to where the robot is (ex11 / wam_node behaviour);
        ``"hold_target"`` keeps following the last received target.
    stale_after_s: a packet whose simulated time is older than the held target's by more than this is stale.
    max_reads_per_tick: datagrams read from the socket per 2 ms tick at most (the rest wait for the next tick).
    max_judged_per_tick: of the datagrams of one tick, only the newest this many are judged; the older ones are
        counted ``flood_dropped``. Bounds the work per tick under a flood; the newest valid packet still wins.
    """

    timeout_s: float = _v("receiver_timeout_s")
    on_timeout: str = "hold_position"
    stale_after_s: float = 0.0
    max_reads_per_tick: int = _v("max_reads_per_tick")
    max_judged_per_tick: int = _v("max_judged_per_tick")

    def __post_init__(self):
        check_range(self, "timeout_s", 0.004, 60.0)
        check_choice(self, "on_timeout", ("hold_position", "hold_target"))
        check_range(self, "stale_after_s", 0.0, 10.0)
        check_range(self, "max_reads_per_tick", 1, 100_000, integer=True)
        check_range(self, "max_judged_per_tick", 1, 10_000, integer=True)
        if self.max_judged_per_tick > self.max_reads_per_tick:
            raise ConfigError(f"ReceiverConfig.max_judged_per_tick = {self.max_judged_per_tick}: must be <= "
                              f"max_reads_per_tick ({self.max_reads_per_tick})")


@dataclass(frozen=True)
class SafetyConfig:
    """The safety envelope between the receiver and the controller (:mod:`jaxarm.robot.safety`).

    Every default and its source is in :data:`VALUES` (``jaxarm wam-sim --print-config``).

    accept_raw: accept headerless libbarrett-ex11 packets (unsafe: any 16- or 32-byte datagram parses).
    target_inset_rad: accepted targets lie inside each joint's range shrunk by this, rad.
    clamp_margin_rad: a target at most this far outside that allowed range is clamped (counted ``clamped``);
        farther, it is rejected (``out_of_range``), rad.
    velocity_limit_rad_s: per joint J1..J4, rad/s. A target whose distance from the last accepted one implies a
        faster joint speed is rejected (``jump``); the robot's own joint speed never exceeds it (velocity guard).
    velocity_warning_fraction: the velocity guard brakes a joint moving faster than this fraction of its limit.
    jump_clock_slack_s: the elapsed time of the jump check is the sender's clock difference, but at most the
        robot's own elapsed time plus this, s (so a forged timestamp cannot stretch it).
    max_consecutive_rejections: this many rejected datagrams in a row -> hold position (counted
        ``rejection_holds``).
    """

    accept_raw: bool = _v("accept_raw")
    target_inset_rad: float = _v("target_inset_rad")
    clamp_margin_rad: float = _v("clamp_margin_rad")
    velocity_limit_rad_s: tuple = _v("velocity_limit_rad_s")
    velocity_warning_fraction: float = _v("velocity_warning_fraction")
    jump_clock_slack_s: float = _v("jump_clock_slack_s")
    max_consecutive_rejections: int = _v("max_consecutive_rejections")

    def __post_init__(self):
        if not isinstance(self.accept_raw, bool):
            raise ConfigError(f"SafetyConfig.accept_raw = {self.accept_raw!r}: must be True or False")
        check_range(self, "target_inset_rad", 0.0, 0.5)
        check_range(self, "clamp_margin_rad", 0.0, 0.5)
        _check_per_joint(self, "velocity_limit_rad_s", 0.1, 100.0)
        check_range(self, "velocity_warning_fraction", 0.5, 1.0)
        check_range(self, "jump_clock_slack_s", 0.0, 1.0)
        check_range(self, "max_consecutive_rejections", 1, 1_000_000, integer=True)


@dataclass(frozen=True)
class PhysicsConfig:
    """MuJoCo side: which arm, substeps per 2 ms control tick, the (unpublished) joint friction and the joint
    torque limit (controller output + gravity compensation)."""

    variant: str = "wam4"
    substeps: int = 2
    damping: tuple = _v("joint_damping_nms")
    frictionloss: tuple = (0.0, 0.0, 0.0, 0.0)
    torque_limit_nm: tuple = _v("torque_limit_nm")

    def __post_init__(self):
        check_choice(self, "variant", ("wam4", "wam7_wrist_locked"))
        check_range(self, "substeps", 1, 50, integer=True)
        _check_per_joint(self, "damping", 0.0, 100.0)
        _check_per_joint(self, "frictionloss", 0.0, 100.0)
        _check_per_joint(self, "torque_limit_nm", 0.0, 500.0)


@dataclass(frozen=True)
class WamSimConfig:
    """Everything the simulated robot needs."""

    controller: ControllerConfig = field(default_factory=ControllerConfig)
    receiver: ReceiverConfig = field(default_factory=ReceiverConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    joint_map: JointMap = field(default_factory=JointMap)
    initial_virtual_rad: tuple = _v("initial_virtual_rad")

    def __post_init__(self):
        for name, kind in (("controller", ControllerConfig), ("receiver", ReceiverConfig),
                           ("safety", SafetyConfig), ("physics", PhysicsConfig), ("joint_map", JointMap)):
            if not isinstance(getattr(self, name), kind):
                raise ConfigError(f"WamSimConfig.{name} = {getattr(self, name)!r}: must be a {kind.__name__}")
        _check_per_joint(self, "initial_virtual_rad", -math.pi, math.pi, n=2)
        lo, hi = joint_limits(self)
        q0 = self.joint_map.to_wam(self.initial_virtual_rad)
        if np.any(q0 < lo) or np.any(q0 > hi):
            raise ConfigError(f"WamSimConfig.initial_virtual_rad = {self.initial_virtual_rad!r}: maps to WAM "
                              f"joints {q0.round(3).tolist()}, outside the allowed {lo.round(3).tolist()}.."
                              f"{hi.round(3).tolist()}")


def joint_limits(config: WamSimConfig) -> tuple[np.ndarray, np.ndarray]:
    """Allowed target range per WAM joint (joint range shrunk by ``SafetyConfig.target_inset_rad``), rad."""
    rng = np.asarray(_v("joint_range_rad"), dtype=float)
    m = config.safety.target_inset_rad
    return rng[:, 0] + m, rng[:, 1] - m


@dataclass(frozen=True)
class JitterConfig:
    """Packet inter-arrival model at the robot: Gamma fitted by moments to the paper's statistics.

    With mean m and standard deviation s, a Gamma(k, theta) has k = m^2/s^2 and theta = s^2/m:
    m = 15.09 ms, s = 5.65 ms give k = 7.133 and theta = 2.1155 ms (2.5-97.5 % range 6.1-28.1 ms; the paper
    reports 95 % within 6-26 ms and a 46 ms maximum).
    """

    mean_ms: float = _v("packet_interval_mean_ms")
    sd_ms: float = _v("packet_interval_sd_ms")

    def __post_init__(self):
        check_range(self, "mean_ms", 0.1, 10_000.0)
        check_range(self, "sd_ms", 0.0, 10_000.0, lo_open=True)

    @property
    def shape(self) -> float:
        return (self.mean_ms / self.sd_ms) ** 2

    @property
    def scale_ms(self) -> float:
        return self.sd_ms ** 2 / self.mean_ms


def values_markdown() -> str:
    """The table :data:`VALUES` as Markdown (for the README and ``jaxarm wam-sim --print-config``)."""
    rows = ["| name | value | unit | source |", "|---|---|---|---|"]
    for name, (value, unit, source) in VALUES.items():
        rows.append(f"| `{name}` | {value} | {unit} | {source} |")
    return "\n".join(rows)
