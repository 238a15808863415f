"""The simulated WAM: the MuJoCo C model of :mod:`jaxarm.robot.wam_model` under the 500 Hz chain of
:mod:`jaxarm.robot.controller`.

Tick ``n`` happens at robot time ``t_n = n * T`` (T = 2 ms): read the joint positions, let the Network System judge
the datagrams that arrived since tick ``n - 1``, compute the controller torque, step the physics by T
(``PhysicsConfig.substeps`` MuJoCo steps) and log one row. Two drivers:

* :func:`run_offline`: packets come with their robot arrival times; runs as fast as possible; deterministic.
* :func:`run_live`: packets come from a UDP socket (bound to 127.0.0.1 unless told otherwise); each tick waits for
  its wall-clock deadline. If the process falls behind it catches up without sleeping, so the log always has one
  row per tick of simulated time; late ticks are counted.

Gravity compensation is ideal (MuJoCo ``gravcomp`` routed through the actuators), standing in for libbarrett's
calibrated gravity term; the total joint torque is clamped at the joint's limit.
"""
from __future__ import annotations

import json
import math
import signal
import socket
import time
from dataclasses import asdict
from pathlib import Path
from typing import Callable, Iterable, NamedTuple, Optional

import numpy as np

from jaxarm.robot.config import WamSimConfig
from jaxarm.robot.controller import (Counters, control_init, control_params, control_step, receive,
                                     receiver_init)
from jaxarm.robot.wam_model import JOINT_RANGE_RAD, mjcf_for

#: Columns of the 500 Hz log, in order. Angles in rad, time in s, torque in N m.
#: target_* / robot_* are in the virtual arm's convention (joint map undone); q* and tau* are the WAM's J1..J4.
LOG_COLUMNS = ("t", "target_shoulder", "target_elbow", "robot_shoulder", "robot_elbow", "packets_ok",
               "packets_bad", "new_target", "target_seq", "target_time", "q1", "q2", "q3", "q4",
               "tau1", "tau2", "tau3", "tau4")


class SimLog(NamedTuple):
    """A finished run: one row per tick (``rows``, columns :data:`LOG_COLUMNS`) and the final counters."""

    rows: np.ndarray
    counters: Counters
    late_ticks: int = 0
    wall_s: float = 0.0

    def column(self, name: str) -> np.ndarray:
        return self.rows[:, LOG_COLUMNS.index(name)]

    def columns(self) -> dict[str, np.ndarray]:
        """``{column name: array}``, the form :mod:`jaxarm.robot.metrics` reads."""
        return {name: self.rows[:, i] for i, name in enumerate(LOG_COLUMNS)}

    def summary(self) -> dict:
        q = self.rows[:, 10:14]
        tau = self.rows[:, 14:18]
        duration = len(self.rows) * _period(self.rows)
        return {
            "ticks": int(len(self.rows)),
            "duration_s": duration,
            "wall_s": self.wall_s,
            "real_time_factor": duration / self.wall_s if self.wall_s > 0 else None,
            "late_ticks": int(self.late_ticks),
            "packets": dict(self.counters._asdict(), bad=self.counters.bad),
            "q_min_rad": q.min(axis=0).tolist() if len(q) else None,
            "q_max_rad": q.max(axis=0).tolist() if len(q) else None,
            "abs_tau_max_nm": np.abs(tau).max(axis=0).tolist() if len(tau) else None,
        }

    def to_csv(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fmt = ["%.4f"] + ["%.9g"] * 4 + ["%d"] * 4 + ["%.6f"] + ["%.9g"] * 8
        np.savetxt(path, self.rows, delimiter=",", header=",".join(LOG_COLUMNS), comments="", fmt=fmt)
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
        self.params = control_params(self.config, max_joint_inertia(self.model, self.config))
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
        self._counted, self._ok_bad = None, (0, 0)
        self.n = 0

    @property
    def t(self) -> float:
        """Robot time of the next tick, s."""
        return self.n * self.period_s

    def tick(self, datagrams: Iterable[bytes] = ()) -> np.ndarray:
        """Run one tick with the datagrams that arrived since the previous one; return its log row."""
        t = self.t
        q = self.data.qpos.copy()
        self.receiver, accepted = receive(self.config, self.receiver, datagrams, t, q)
        self.control, tau = control_step(self.params, self.control, q, self.receiver.target)
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
        if r.counters is not self._counted:   # counters change only when packets arrive
            self._counted, self._ok_bad = r.counters, (r.counters.ok, r.counters.bad)
        row[5], row[6] = self._ok_bad
        row[7] = accepted > 0
        row[8] = -1 if r.seq is None else r.seq
        row[9] = math.nan if r.t is None else r.t
        row[10:14] = q
        row[14:18] = self.data.qfrc_actuator
        self.n += 1
        return row


def max_joint_inertia(model, config: WamSimConfig) -> np.ndarray:
    """Largest diagonal of the joint-space mass matrix (incl. armature), kg m^2, over J4 across its range and the
    held J2/J3 pose (J1 does not change the mass matrix); used by the joint-limit guard."""
    import mujoco

    data = mujoco.MjData(model)
    hold = config.joint_map.to_wam(config.initial_virtual_rad)
    best = np.zeros(model.nv)
    full = np.zeros((model.nv, model.nv))
    for q4 in np.linspace(*JOINT_RANGE_RAD[3], 9):
        data.qpos[:] = hold
        data.qpos[3] = q4
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        best = np.maximum(best, np.diag(full))
    return best


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
    return SimLog(rows, sim.receiver.counters, 0, wall)


def open_receiver_socket(host: str = "127.0.0.1", port: int = 0) -> socket.socket:
    """A non-blocking UDP socket bound to (host, port); port 0 picks a free port."""
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    sock.bind((host, port))
    sock.setblocking(False)
    return sock


def _drain(sock: socket.socket, max_packets: int = 10_000) -> list[bytes]:
    out = []
    for _ in range(max_packets):  # bounded: a flood cannot stall the control loop forever
        try:
            out.append(sock.recv(65536))
        except (BlockingIOError, InterruptedError):
            break
    return out


def run_live(config: WamSimConfig | None, sock: socket.socket, duration_s: float,
             on_tick: Optional[Callable[[np.ndarray], None]] = None) -> SimLog:
    """Run ``duration_s`` of robot time paced to the wall clock, reading datagrams from ``sock``.

    SIGTERM/SIGINT end the run early; the log then holds the ticks done so far.
    """
    sim = WamSimulator(config)
    n_ticks = int(round(duration_s / sim.period_s))
    rows = np.empty((n_ticks, len(LOG_COLUMNS)))
    stop = {"flag": False}

    def _stop(signum, frame):
        stop["flag"] = True

    old = {s: signal.signal(s, _stop) for s in (signal.SIGTERM, signal.SIGINT)}
    late = 0
    done = 0
    try:
        wall0 = time.perf_counter()
        for n in range(n_ticks):
            if stop["flag"]:
                break
            deadline = wall0 + n * sim.period_s
            wait = deadline - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            elif wait < -sim.period_s:
                late += 1
            rows[n] = sim.tick(_drain(sock))
            done = n + 1
            if on_tick is not None:
                on_tick(rows[n])
        wall = time.perf_counter() - wall0
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    return SimLog(rows[:done], sim.receiver.counters, late, wall)


def config_dict(config: WamSimConfig) -> dict:
    """The configuration as plain JSON-able data (for summaries)."""
    return json.loads(json.dumps(asdict(config), default=list))


def within_joint_range(q: np.ndarray) -> bool:
    """True when every row of ``q`` (..., 4) lies inside the WAM's joint ranges."""
    rng = np.asarray(JOINT_RANGE_RAD)
    return bool(np.all(q >= rng[:, 0]) and np.all(q <= rng[:, 1]))
