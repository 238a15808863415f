"""ROS 2 export without a ROS install: a rosbag2 (MCAP storage) written with the ``rosbags`` library.

What a bag holds (topic names are :data:`TRAJECTORY_TOPIC`, :data:`TARGET_TOPIC`, :data:`STATE_TOPIC`):

* ``/wam/joint_trajectory``: one ``trajectory_msgs/msg/JointTrajectory`` with the whole trajectory on the 10 ms
  update grid: the four WAM joints after the joint map (J2/J3 at their hold pose), positions (rad) and velocities
  (rad/s, central differences, so ``joint_trajectory_controller`` interpolates cubic splines rather than
  straight lines), ``time_from_start`` the sample's time from the first. Its header stamp is zero, which
  ``joint_trajectory_controller`` reads as "start now". Bag time: the first packet's.
* ``/wam/target_joint_states``: one ``sensor_msgs/msg/JointState`` per packet, stamped (header and bag time)
  with the packet's send time: the positions the robot would receive, at the packet rate and with the packet
  timing of the export (``live``: every 10 ms; ``jitter``: the paper's Gamma intervals).
* ``/wam/joint_states`` (offline simulation only): the simulated robot at 500 Hz, position (rad), velocity
  (rad/s) and effort (joint torque, N m), as a robot driver publishes ``joint_states`` (Barrett's ``wam_node``
  does, wam.md §2).

Times: stamps count from ``start_ns`` (default 0, i.e. 1970-01-01; ``ros2 bag play`` replays relative timing).
Joint names default to :data:`DEFAULT_JOINT_NAMES`, in J1..J4 order. Message types come from the rosbags ROS 2
Jazzy type store (identical definitions and hashes in Humble for these messages; a test checks it). The bag is
rosbag2 format version 9 (what ROS 2 Jazzy records; rosbags writes 8 or 9 only).
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np

#: Default joint names, J1..J4 (the ``wam/jN_joint`` convention of Barrett-WAM ROS descriptions).
DEFAULT_JOINT_NAMES = ("wam/j1_joint", "wam/j2_joint", "wam/j3_joint", "wam/j4_joint")
TRAJECTORY_TOPIC = "/wam/joint_trajectory"
TARGET_TOPIC = "/wam/target_joint_states"
STATE_TOPIC = "/wam/joint_states"
TRAJECTORY_TYPE = "trajectory_msgs/msg/JointTrajectory"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
ROSBAG2_VERSION = 9


def typestore():
    """The rosbags type store the bag's message types come from (ROS 2 Jazzy)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def check_joint_names(names: Sequence[str]) -> tuple[str, ...]:
    """Four distinct, non-empty joint names (ROS names: letters, digits, ``_`` and ``/``), or ValueError."""
    names = tuple(names)
    if len(names) != 4:
        raise ValueError(f"joint names: need 4 (J1..J4), got {len(names)}: {list(names)}")
    for name in names:
        if not name or not all(ch.isalnum() or ch in "_/" for ch in name) or name[0].isdigit():
            raise ValueError(f"joint name {name!r}: use letters, digits, '_' and '/', not starting with a digit")
    if len(set(names)) != 4:
        raise ValueError(f"joint names must differ: {list(names)}")
    return names


def _stamp(ts, ns: int):
    Time = ts.types["builtin_interfaces/msg/Time"]
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def _header(ts, ns: int, frame_id: str = ""):
    return ts.types["std_msgs/msg/Header"](stamp=_stamp(ts, ns), frame_id=frame_id)


def _joint_state(ts, ns: int, names, position, velocity=None, effort=None):
    empty = np.zeros(0)
    return ts.types[JOINT_STATE_TYPE](
        header=_header(ts, ns), name=list(names), position=np.asarray(position, dtype=np.float64),
        velocity=empty if velocity is None else np.asarray(velocity, dtype=np.float64),
        effort=empty if effort is None else np.asarray(effort, dtype=np.float64))


def trajectory_message(ts, t_s: np.ndarray, q_wam: np.ndarray, names):
    """The whole trajectory as one JointTrajectory: ``t_s`` (T,) s, ``q_wam`` (T, 4) rad."""
    Point = ts.types["trajectory_msgs/msg/JointTrajectoryPoint"]
    Duration = ts.types["builtin_interfaces/msg/Duration"]
    rel_ns = np.round((np.asarray(t_s) - t_s[0]) * 1e9).astype(np.int64)
    qd = np.gradient(q_wam, t_s, axis=0) if len(t_s) > 1 else np.zeros_like(q_wam)
    empty = np.zeros(0)
    points = [Point(positions=np.ascontiguousarray(q_wam[k], dtype=np.float64),
                    velocities=np.ascontiguousarray(qd[k], dtype=np.float64), accelerations=empty, effort=empty,
                    time_from_start=Duration(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)))
              for k, ns in enumerate(rel_ns)]
    return ts.types[TRAJECTORY_TYPE](header=_header(ts, 0), joint_names=list(names), points=points)


def write_bag(path: str | Path, grid_t_s: np.ndarray, grid_q_wam: np.ndarray, send_times_s: np.ndarray,
              packet_q_wam: np.ndarray, joint_names: Sequence[str] = DEFAULT_JOINT_NAMES,
              robot_log: Optional[dict] = None, start_ns: int = 0) -> dict:
    """Write a rosbag2 (MCAP) directory at ``path`` (must not exist).

    ``grid_t_s`` (T,) s and ``grid_q_wam`` (T, 4) rad: the trajectory on the update grid (the JointTrajectory).
    ``send_times_s`` (P,) s from the first packet and ``packet_q_wam`` (P, 4) rad: what each packet carries.
    ``robot_log``: the simulator's log columns (``t``, ``q1..q4``, ``qd1..qd4``, ``tau1..tau4``) to record as
    the robot's joint states. Returns ``{topic: message count}``.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    names = check_joint_names(joint_names)
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path}: exists already; a rosbag2 is written to a new directory")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"{path.parent}: no such directory")
    ts = typestore()
    counts = {}
    send_ns = start_ns + np.round(np.asarray(send_times_s, dtype=float) * 1e9).astype(np.int64)
    with Writer(path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(TRAJECTORY_TOPIC, TRAJECTORY_TYPE, typestore=ts)
        msg = trajectory_message(ts, np.asarray(grid_t_s, float), np.asarray(grid_q_wam, float), names)
        writer.write(conn, int(send_ns[0]) if len(send_ns) else start_ns, ts.serialize_cdr(msg, TRAJECTORY_TYPE))
        counts[TRAJECTORY_TOPIC] = 1
        conn = writer.add_connection(TARGET_TOPIC, JOINT_STATE_TYPE, typestore=ts)
        for ns, q in zip(send_ns, np.asarray(packet_q_wam, float)):
            writer.write(conn, int(ns), ts.serialize_cdr(_joint_state(ts, int(ns), names, q), JOINT_STATE_TYPE))
        counts[TARGET_TOPIC] = len(send_ns)
        if robot_log is not None:
            conn = writer.add_connection(STATE_TOPIC, JOINT_STATE_TYPE, typestore=ts)
            t = np.asarray(robot_log["t"], dtype=float)
            cols = {k: np.column_stack([robot_log[f"{k}{i}"] for i in range(1, 5)]) for k in ("q", "qd", "tau")}
            tick_ns = start_ns + np.round(t * 1e9).astype(np.int64)
            for n, ns in enumerate(tick_ns):
                msg = _joint_state(ts, int(ns), names, cols["q"][n], cols["qd"][n], cols["tau"][n])
                writer.write(conn, int(ns), ts.serialize_cdr(msg, JOINT_STATE_TYPE))
            counts[STATE_TOPIC] = len(tick_ns)
    return counts
