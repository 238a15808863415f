"""ROS 2 export: `jaxarm export --to rosbag2:DIR` and `--to offline --rosbag2 DIR` write a rosbag2 (MCAP) that the
rosbags reader opens; its messages match the source trajectory, the packets and the simulated robot to float
precision."""
import json
import math

import numpy as np
import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from jaxarm.robot.cli import export_main
from jaxarm.robot.exporter import Trajectory, save_trajectory_csv, send_times
from jaxarm.robot.metrics import load_log

NAMES = ["wam/j1_joint", "wam/j2_joint", "wam/j3_joint", "wam/j4_joint"]


def _read(path):
    """{topic: (msgtype, [(bag time ns, message)])}, deserialised with the ROS 2 Jazzy type store."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    out = {}
    with Reader(path) as reader:
        assert reader.message_count == sum(c.msgcount for c in reader.connections)
        for conn, t_ns, raw in reader.messages():
            out.setdefault(conn.topic, (conn.msgtype, []))[1].append((t_ns, ts.deserialize_cdr(raw, conn.msgtype)))
    return out


def _source(tmp_path):
    # 1 s at 200 Hz: the exporter resamples it onto the 10 ms grid (101 samples) by linear interpolation.
    t = np.arange(201) * 0.005
    q = np.column_stack([0.62 + 0.3 * np.sin(2 * t), 1.53 - 0.2 * t ** 2])
    save_trajectory_csv(tmp_path / "traj.csv", Trajectory(t, q))
    grid_t = np.arange(101) * 0.010
    grid_q = np.column_stack([0.62 + 0.3 * np.sin(2 * grid_t), 1.53 - 0.2 * grid_t ** 2])   # closed form
    return grid_t, grid_q


def test_rosbag2_holds_the_trajectory_and_the_packet_stream(tmp_path, capsys):
    grid_t, grid_q = _source(tmp_path)
    bag = tmp_path / "bag"
    assert export_main(["--trajectory", str(tmp_path / "traj.csv"), "--to", f"rosbag2:{bag}", "--seed", "3"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["messages"] == {"/wam/joint_trajectory": 1, "/wam/target_joint_states": 101}
    topics = _read(bag)
    assert set(topics) == {"/wam/joint_trajectory", "/wam/target_joint_states"}
    # The whole trajectory: one JointTrajectory, WAM joints after the default joint map (J1 = shoulder,
    # J4 = elbow, J2 = J3 = pi/2), positions to the CSV's 9 significant digits.
    msgtype, [(t0_ns, traj)] = topics["/wam/joint_trajectory"]
    assert msgtype == "trajectory_msgs/msg/JointTrajectory" and t0_ns == 0
    assert traj.joint_names == NAMES and (traj.header.stamp.sec, traj.header.stamp.nanosec) == (0, 0)
    pos = np.array([p.positions for p in traj.points])
    np.testing.assert_allclose(pos[:, 0], grid_q[:, 0], atol=1e-8)
    np.testing.assert_allclose(pos[:, 3], grid_q[:, 1], atol=1e-8)
    np.testing.assert_array_equal(pos[:, 1:3], math.pi / 2)
    tfs = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in traj.points])
    np.testing.assert_allclose(tfs, grid_t, atol=1e-9)
    # Velocities: d/dt of the closed form, to the error of central differences on the h = 10 ms grid
    # (h^2/6 max|f'''| = 1e-4/6 x 2.4 = 4e-5 rad/s for the shoulder; exact for the elbow's parabola).
    vel = np.array([p.velocities for p in traj.points])
    np.testing.assert_allclose(vel[1:-1, 0], 0.6 * np.cos(2 * grid_t[1:-1]), atol=4.1e-5)
    np.testing.assert_allclose(vel[1:-1, 3], -0.4 * grid_t[1:-1], atol=1e-7)    # CSV rounding / 20 ms
    # What the robot would receive: one JointState per packet, stamped with the Gamma send time (seed 3).
    msgtype, states = topics["/wam/target_joint_states"]
    assert msgtype == "sensor_msgs/msg/JointState" and len(states) == 101
    expected_ns = np.round(send_times(101, "jitter", 3) * 1e9).astype(np.int64)
    np.testing.assert_array_equal([t for t, _ in states], expected_ns)
    np.testing.assert_array_equal([m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec for _, m in states],
                                  expected_ns)
    np.testing.assert_allclose(np.array([m.position for _, m in states]), pos, rtol=0, atol=0)
    assert all(m.name == NAMES and len(m.velocity) == 0 for _, m in states)


def test_offline_rosbag2_also_records_the_simulated_robot(tmp_path, capsys):
    _source(tmp_path)
    bag = tmp_path / "offline_bag"
    names = "a/shoulder_yaw,a/pitch,a/roll,a/elbow"
    assert export_main(["--trajectory", str(tmp_path / "traj.csv"), "--to", "offline", "--live", "--duration", "1.5",
                        "--log", str(tmp_path / "log.csv"), "--rosbag2", str(bag), "--joint-names", names]) == 0
    capsys.readouterr()
    topics = _read(bag)
    assert {k: (v[0], len(v[1])) for k, v in topics.items()} == {
        "/wam/joint_trajectory": ("trajectory_msgs/msg/JointTrajectory", 1),
        "/wam/target_joint_states": ("sensor_msgs/msg/JointState", 101),     # --live: every 10 ms
        "/wam/joint_states": ("sensor_msgs/msg/JointState", 750)}            # 1.5 s at 500 Hz
    log = load_log(tmp_path / "log.csv")                                      # the same run, as CSV
    _, robot = topics["/wam/joint_states"]
    assert robot[0][1].name == names.split(",")
    np.testing.assert_array_equal([t for t, _ in robot], np.round(log["t"] * 1e9).astype(np.int64))
    for field, col in (("position", "q"), ("velocity", "qd"), ("effort", "tau")):
        got = np.array([getattr(m, field) for _, m in robot])
        want = np.column_stack([log[f"{col}{i}"] for i in range(1, 5)])
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-12)         # CSV keeps 9 significant digits
    _, targets = topics["/wam/target_joint_states"]
    np.testing.assert_allclose([t for t, _ in targets], np.arange(101) * 10_000_000)


def test_message_definitions_are_the_same_in_humble_and_jazzy():
    # The bag uses the Jazzy type store; a Humble reader sees the same definitions (same RIHS01 hashes).
    humble, jazzy = get_typestore(Stores.ROS2_HUMBLE), get_typestore(Stores.ROS2_JAZZY)
    for msgtype in ("trajectory_msgs/msg/JointTrajectory", "sensor_msgs/msg/JointState"):
        assert humble.hash_rihs01(msgtype) == jazzy.hash_rihs01(msgtype)


def test_write_bag_refuses_an_existing_directory_and_bad_names(tmp_path):
    from jaxarm.robot.rosbag import check_joint_names, write_bag

    (tmp_path / "taken").mkdir()
    z = np.zeros((2, 4))
    with pytest.raises(FileExistsError):
        write_bag(tmp_path / "taken", np.array([0.0, 0.01]), z, np.array([0.0, 0.01]), z)
    for bad in (["a", "b", "c"], ["a", "a", "b", "c"], ["a", "b", "c", "1d"], ["a", "b", "c", "d e"]):
        with pytest.raises(ValueError):
            check_joint_names(bad)
