"""The simulated WAM: the MuJoCo C model of :mod:`jaxarm.robot.wam_model` under the 500 Hz chain of
:mod:`jaxarm.robot.controller`.

Tick ``n`` happens at robot time ``t_n = n * T`` (T = 2 ms): read the joint positions, let the Network System
(:mod:`jaxarm.robot.receiver`, with the safety envelope) judge the datagrams that arrived since tick ``n - 1``,
compute the controller torque, step the physics by T (``PhysicsConfig.substeps`` MuJoCo steps) and log one row.
Two drivers:

* :func:`run_offline`: packets come with their robot arrival times; runs as fast as possible; deterministic.
* :func:`run_live`: packets come from a UDP socket (bound to 127.0.0.1 unless told otherwise); each tick waits for
  its wall-clock deadline. If the process falls behind it catches up without sleeping, so the log always has one
  row per tick of simulated time; late ticks are counted. At most ``ReceiverConfig.max_reads_per_tick``
  datagrams are read per tick (a flood waits in the socket buffer; what the kernel drops when that buffer is
  full never reaches the robot and is not counted). SIGTERM or SIGINT end the run after the current tick.

Gravity compensation is ideal (MuJoCo ``gravcomp`` routed through the actuators), standing in for libbarrett's
calibrated gravity term; the total joint torque is clamped at the joint's limit.
"""
from __future__ import annotations

import json
import math
import os
import signal
import socket
import time
from dataclasses import asdict
from pathlib import Path
from typing import Callable, Iterable, NamedTuple, Optional

import numpy as np

from jaxarm.robot import safety
from jaxarm.robot.config import WamSimConfig
from jaxarm.robot.controller import control_init, control_params, control_step
from jaxarm.robot.protocol import MAX_PACKET_BYTES
from jaxarm.robot.receiver import FOLLOWING, HOLD_TIMEOUT, Counters, receive, receiver_init
from jaxarm.robot.wam_model import JOINT_RANGE_RAD, mjcf_for

#: Receiver counters logged per tick as ``packets_<name>`` (cumulative; ok is ``packets_ok`` above).
COUNTER_COLUMNS = tuple(f"packets_{k}" for k in Counters._fields if k not in ("ok", "timeouts", "rejection_holds"))
#: Columns of the 500 Hz log, in order. Angles in rad, time in s, torque in N m, speeds in rad/s.
#: target_* / robot_* are in the virtual arm's convention (joint map undone); q*, tau*, qd* are the WAM's J1..J4.
#: packets_ok / packets_rejected and the packets_<kind> columns are cumulative counts (jaxarm.robot.receiver);
#: hold is 0 (following), 1 (holding after a timeout) or 2 (holding after consecutive rejections).
LOG_COLUMNS = ("t", "target_shoulder", "target_elbow", "robot_shoulder", "robot_elbow", "packets_ok",
               "packets_rejected", "new_target", "target_seq", "target_time", "q1", "q2", "q3", "q4",
               "tau1", "tau2", "tau3", "tau4", "qd1", "qd2", "qd3", "qd4", "hold", "timeouts",
               "rejection_holds") + COUNTER_COLUMNS
_COUNTER_FIELDS = ("timeouts", "rejection_holds") + tuple(c[len("packets_"):] for c in COUNTER_COLUMNS)
_FIRST_COUNTER = LOG_COLUMNS.index("timeouts")


class SimLog(NamedTuple):
    """A finished run: one row per tick (``rows``, columns :data:`LOG_COLUMNS`) and the final counters."""

    rows: np.ndarray
    counters: Counters
    late_ticks: int = 0
    wall_s: float = 0.0
    events: tuple = ()          # (robot time s, message) of every hold
    stopped_by: Optional[str] = None   # signal name when a signal ended the run early

    def column(self, name: str) -> np.ndarray:
        return self.rows[:, LOG_COLUMNS.index(name)]

    def columns(self) -> dict[str, np.ndarray]:
        """``{column name: array}``, the form :mod:`jaxarm.robot.metrics` reads."""
        return {name: self.rows[:, i] for i, name in enumerate(LOG_COLUMNS)}

    def summary(self) -> dict:
        q = self.rows[:, 10:14]
        tau = self.rows[:, 14:18]
        qd = self.rows[:, 18:22]
        duration = len(self.rows) * _period(self.rows)
        return {
            "ticks": int(len(self.rows)),
            "duration_s": duration,
            "wall_s": self.wall_s,
            "real_time_factor": duration / self.wall_s if self.wall_s > 0 else None,
            "late_ticks": int(self.late_ticks),
            "stopped_by": self.stopped_by,
            "packets": dict(self.counters._asdict(), rejected=self.counters.rejected),
            "holds": [{"t_s": t, "message": m} for t, m in self.events],
            "q_min_rad": q.min(axis=0).tolist() if len(q) else None,
            "q_max_rad": q.max(axis=0).tolist() if len(q) else None,
            "abs_qd_max_rad_s": np.abs(qd).max(axis=0).tolist() if len(qd) else None,
            "abs_tau_max_nm": np.abs(tau).max(axis=0).tolist() if len(tau) else None,
        }

    def to_csv(self, path) -> Path:
        """Write the log as CSV (header row of :data:`LOG_COLUMNS`). Written to a temporary file beside ``path``
        and renamed, so ``path`` is never a partial log."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fmt = (["%.4f"] + ["%.9g"] * 4 + ["%d"] * 4 + ["%.6f"] + ["%.9g"] * 12
               + ["%d"] * (len(LOG_COLUMNS) - 22))
        tmp = path.with_name(path.name + ".partial")
        np.savetxt(tmp, self.rows, delimiter=",", header=",".join(LOG_COLUMNS), comments="", fmt=fmt)
        os.replace(tmp, path)
        return path


def _period(rows: np.ndarray) -> float:
    return float(rows[1, 0] - rows[0, 0]) if len(rows) > 1 else 0.0


class WamSimulator:
    """The robot: MuJoCo model + controller + receiver. One :meth:`tick` per 2 ms of simulated time."""

    def __init__(self, config: WamSimConfig | None = None):
        import mujoco

        self._mj = mujoco
        self.config = config or WamSimConfig()
        ph = self.config.physics
        self.period_s = self.config.controller.control_period_s
        self.model = mujoco.MjModel.from_xml_string(mjcf_for(ph, self.period_s))
        self.data = mujoco.MjData(self.model)
        self.params = control_params(self.config, *joint_inertia_range(self.model, self.config))
        self.envelope = safety.envelope(self.config)
        jm = self.config.joint_map
        # The joint map's inverse as index/offset/scale pairs, so the per-tick log avoids array allocation.
        self._undo = ((jm.shoulder_joint, jm.shoulder_offset_rad, jm.shoulder_scale),
                      (jm.elbow_joint, jm.elbow_offset_rad, jm.elbow_scale))
        self.reset()

    def reset(self) -> None:
        q0 = self.config.joint_map.to_wam(self.config.initial_virtual_rad)
        self._mj.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q0
        self._mj.mj_forward(self.model, self.data)
        self.control = control_init(q0)
        self.receiver = receiver_init(q0)
        self._counted, self._counts = None, np.zeros(len(LOG_COLUMNS) - _FIRST_COUNTER)
        self._ok_rejected = (0, 0)
        self.events: list[tuple[float, str]] = []
        self.n = 0

    @property
    def t(self) -> float:
        """Robot time of the next tick, s."""
        return self.n * self.period_s

    def tick(self, datagrams: Iterable[bytes] = ()) -> np.ndarray:
        """Run one tick with the datagrams that arrived since the previous one; return its log row."""
        t = self.t
        q = self.data.qpos.copy()
        qd = self.data.qvel.copy()
        hold_before = self.receiver.hold
        self.receiver, accepted = receive(self.config, self.envelope, self.receiver, datagrams, t, q)
        if self.receiver.hold != hold_before and self.receiver.hold != FOLLOWING:
            self.events.append((t, self._hold_message()))
        self.control, tau = control_step(self.params, self.control, q, self.receiver.target, qd)
        self.data.ctrl[:] = tau
        self._mj.mj_step(self.model, self.data, nstep=self.config.physics.substeps)
        r = self.receiver
        row = np.empty(len(LOG_COLUMNS))
        row[0] = t
        (js, os_, ss), (je, oe, se) = self._undo
        row[1] = (r.target[js] - os_) / ss
        row[2] = (r.target[je] - oe) / se
        row[3] = (q[js] - os_) / ss
        row[4] = (q[je] - oe) / se
        c = r.counters
        if c is not self._counted:   # counters change only when packets arrive
            self._counted = c
            self._ok_rejected = (c.ok, c.rejected)
            self._counts = np.array([getattr(c, k) for k in _COUNTER_FIELDS], dtype=float)
        row[5], row[6] = self._ok_rejected
        row[7] = accepted > 0
        row[8] = -1 if r.seq is None else r.seq
        row[9] = math.nan if r.t is None else r.t
        row[10:14] = q
        row[14:18] = self.data.qfrc_actuator
        row[18:22] = qd
        row[22] = r.hold
        row[_FIRST_COUNTER:] = self._counts
        self.n += 1
        return row

    def _hold_message(self) -> str:
        r = self.receiver
        if r.hold == HOLD_TIMEOUT:
            what = ("holding position" if self.config.receiver.on_timeout == "hold_position"
                    else "holding the last target")
            return f"{what}: no accepted packet for {self.config.receiver.timeout_s:g} s (timeout)"
        return (f"holding position: {r.rejections_in_row} datagrams rejected in a row "
                f"(last: {r.last_rejection})")


def joint_inertia_range(model, config: WamSimConfig) -> tuple[np.ndarray, np.ndarray]:
    """Largest and smallest diagonal of the joint-space mass matrix (incl. armature), kg m^2, over J4 across its
    range and the held J2/J3 pose (J1 does not change the mass matrix); used by the joint-limit and velocity
    guards."""
    import mujoco

    data = mujoco.MjData(model)
    hold = config.joint_map.to_wam(config.initial_virtual_rad)
    largest, smallest = np.zeros(model.nv), np.full(model.nv, np.inf)
    full = np.zeros((model.nv, model.nv))
    for q4 in np.linspace(*JOINT_RANGE_RAD[3], 9):
        data.qpos[:] = hold
        data.qpos[3] = q4
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        largest, smallest = np.maximum(largest, np.diag(full)), np.minimum(smallest, np.diag(full))
    return largest, smallest


def run_offline(config: WamSimConfig | None, arrivals_s: np.ndarray, datagrams: list[bytes],
                duration_s: float) -> SimLog:
    """Simulate ``duration_s`` of robot time as fast as possible; datagram ``k`` arrives at ``arrivals_s[k]`` (s,
    robot clock; sorted) and is handed to the first tick at or after its arrival."""
    sim = WamSimulator(config)
    n_ticks = int(round(duration_s / sim.period_s))
    arrivals_s = np.asarray(arrivals_s, dtype=float)
    if len(arrivals_s) != len(datagrams):
        raise ValueError("arrivals_s and datagrams differ in length")
    if np.any(np.diff(arrivals_s) < 0):
        raise ValueError("arrivals_s must be sorted")
    # Tick n takes the packets with arrival in (t_{n-1}, t_n]; index boundaries computed once.
    tick_times = np.arange(n_ticks) * sim.period_s
    ends = np.searchsorted(arrivals_s, tick_times + 1e-12, side="right")
    rows = np.empty((n_ticks, len(LOG_COLUMNS)))
    start = 0
    wall0 = time.perf_counter()
    for n in range(n_ticks):
        end = ends[n]
        rows[n] = sim.tick(datagrams[start:end])
        start = end
    wall = time.perf_counter() - wall0
    return SimLog(rows, sim.receiver.counters, 0, wall, tuple(sim.events))


def open_receiver_socket(host: str = "127.0.0.1", port: int = 0) -> socket.socket:
    """A non-blocking UDP socket bound to (host, port); port 0 picks a free port."""
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    sock.bind((host, port))
    sock.setblocking(False)
    return sock


class SocketReader:
    """Reads at most ``max_reads`` datagrams per call from a non-blocking socket, into one preallocated buffer.

    A datagram longer than :data:`~jaxarm.robot.protocol.MAX_PACKET_BYTES` is kept as its first
    ``MAX_PACKET_BYTES + 1`` bytes: enough for the receiver to call it oversize, without holding up to 64 KiB per
    datagram of a flood in memory.
    """

    def __init__(self, sock: socket.socket, max_reads: int):
        self.sock = sock
        self.max_reads = max_reads
        self._buf = bytearray(65536)     # the largest UDP payload fits: nothing is silently truncated
        self._view = memoryview(self._buf)

    def read(self) -> list[bytes]:
        out = []
        recv_into, view, cap = self.sock.recv_into, self._view, MAX_PACKET_BYTES + 1
        for _ in range(self.max_reads):
            try:
                n = recv_into(view)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:   # e.g. an ICMP error queued on the socket: not a datagram, keep reading
                continue
            out.append(bytes(view[:min(n, cap)]))
        return out


class StopSignals:
    """While active, SIGTERM and SIGINT set :attr:`stopped_by` (the signal's name) instead of killing the
    process, so that a run they end still writes a complete log. Use as a context manager (main thread only)."""

    def __init__(self):
        self.stopped_by: Optional[str] = None

    def _handler(self, signum, frame):
        self.stopped_by = signal.Signals(signum).name

    def __enter__(self):
        self._old = {s: signal.signal(s, self._handler) for s in (signal.SIGTERM, signal.SIGINT)}
        return self

    def __exit__(self, *exc):
        for s, h in self._old.items():
            signal.signal(s, h)


def run_live(config: WamSimConfig | None, sock: socket.socket, duration_s: float,
             on_tick: Optional[Callable[[np.ndarray], None]] = None,
             on_event: Optional[Callable[[float, str], None]] = None,
             stop: Optional[StopSignals] = None) -> SimLog:
    """Run ``duration_s`` of robot time paced to the wall clock, reading datagrams from ``sock``.

    ``on_event(t, message)`` is called when the robot starts holding (timeout or consecutive rejections).
    SIGTERM/SIGINT end the run after the current tick; the log then holds the ticks done so far and
    ``stopped_by`` names the signal. Pass ``stop`` to keep handling them after the run (e.g. while writing the
    log); without it they are handled only during the run.
    """
    sim = WamSimulator(config)
    reader = SocketReader(sock, sim.config.receiver.max_reads_per_tick)
    n_ticks = int(round(duration_s / sim.period_s))
    chunk = min(n_ticks, 50_000)
    blocks, rows = [], np.empty((chunk, len(LOG_COLUMNS)))   # grows by chunks: memory follows the ticks done
    late = filled = 0
    own = stop is None
    stop = stop or StopSignals()
    if own:
        stop.__enter__()
    try:
        wall0 = time.perf_counter()
        for n in range(n_ticks):
            if stop.stopped_by:
                break
            deadline = wall0 + n * sim.period_s
            wait = deadline - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            elif wait < -sim.period_s:
                late += 1
            n_events = len(sim.events)
            if filled == len(rows):
                blocks.append(rows)
                rows, filled = np.empty((chunk, len(LOG_COLUMNS))), 0
            rows[filled] = sim.tick(reader.read())
            filled += 1
            if on_tick is not None:
                on_tick(rows[filled - 1])
            if on_event is not None:
                for t, message in sim.events[n_events:]:
                    on_event(t, message)
        wall = time.perf_counter() - wall0
    finally:
        if own:
            stop.__exit__()
    blocks.append(rows[:filled])
    all_rows = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
    return SimLog(all_rows, sim.receiver.counters, late, wall, tuple(sim.events), stop.stopped_by)


def config_dict(config: WamSimConfig) -> dict:
    """The configuration as plain JSON-able data (for summaries)."""
    return json.loads(json.dumps(asdict(config), default=list))


def within_joint_range(q: np.ndarray) -> bool:
    """True when every row of ``q`` (..., 4) lies inside the WAM's joint ranges."""
    rng = np.asarray(JOINT_RANGE_RAD)
    return bool(np.all(q >= rng[:, 0]) and np.all(q <= rng[:, 1]))
