"""The simulator as its own process behind a real UDP socket on 127.0.0.1, fed by the exporter process or by
hand-made bad packets. Short runs (a few seconds), loopback only, every wait bounded."""
import json
import math
import os
import selectors
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from jaxarm.robot.cli import export_main
from jaxarm.robot.config import PhysicsConfig
from jaxarm.robot.exporter import Trajectory, save_trajectory_csv
from jaxarm.robot.metrics import load_log, xcorr_delay
from jaxarm.robot.protocol import encode, encode_raw
from jaxarm.robot.simulator import within_joint_range

STARTUP_TIMEOUT_S = 60.0


def _start_sim(tmp_path, duration_s, *extra):
    cmd = [sys.executable, "-m", "jaxarm.cli", "wam-sim", "--port", "0", "--duration", str(duration_s),
           "--log", str(tmp_path / "log.csv"), "--summary", str(tmp_path / "summary.json"), *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, JAX_PLATFORMS="cpu"))
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    if not sel.select(timeout=STARTUP_TIMEOUT_S):
        proc.kill()
        pytest.fail("wam-sim did not report its socket in time")
    line = proc.stdout.readline()
    assert line.startswith("wam-sim: listening on udp://127.0.0.1:"), (line, proc.stderr.read())
    return proc, int(line.rsplit(":", 1)[1])


def _finish(proc, tmp_path, timeout_s=60.0):
    out, err = proc.communicate(timeout=timeout_s)
    assert proc.returncode == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary == json.loads((tmp_path / "summary.json").read_text())
    return summary, load_log(tmp_path / "log.csv")


def test_exporter_streams_to_simulator_process_and_robot_follows(tmp_path, capsys):
    t = np.arange(201) * 0.010                                   # 2 s on the 10 ms grid -> 201 packets
    q = np.column_stack([0.62 + 0.3 * np.sin(np.pi * t), 1.53 - 0.3 * np.sin(np.pi * t)])
    save_trajectory_csv(tmp_path / "traj.csv", Trajectory(t, q))
    proc, port = _start_sim(tmp_path, 4.0)
    try:
        # The exporter command runs in this process (`jaxarm export` = export_main) so that no interpreter start-up
        # eats into the simulator's 4 s; the simulator is its own process, as a robot would be.
        capsys.readouterr()
        assert export_main(["--trajectory", str(tmp_path / "traj.csv"), "--to", f"udp://127.0.0.1:{port}",
                            "--live", "--start-delay", "0.2"]) == 0
        assert json.loads(capsys.readouterr().out)["sent"] == 201
    finally:
        summary, log = _finish(proc, tmp_path)
    # The log: 500 Hz, the required columns, every packet accepted, exactly one timeout after the stream ends.
    assert len(log["t"]) == 2000 and np.allclose(np.diff(log["t"]), 0.002)
    for col in ("t", "target_shoulder", "target_elbow", "robot_shoulder", "robot_elbow", "packets_ok",
                "packets_rejected", "hold", "packets_jump", "packets_raw_refused", "qd1"):
        assert col in log
    assert summary["packets"]["ok"] == 201 and summary["packets"]["rejected"] == 0
    assert log["packets_ok"][-1] == 201 and summary["packets"]["timeouts"] == 1
    # Targets logged are the trajectory's samples (joint map undone), in order.
    got = np.column_stack([log["target_shoulder"], log["target_elbow"]])[log["new_target"] > 0]
    k = np.searchsorted(t, log["target_time"][log["new_target"] > 0] - 1e-9)
    np.testing.assert_allclose(got, q[k], atol=1e-7)
    # The robot followed: small lag, small error while moving, at rest on the last sample at the end.
    moving = (log["t"] > 0.5) & (log["t"] < 2.0)
    for j, name in enumerate(("shoulder", "elbow")):
        target, robot = log[f"target_{name}"], log[f"robot_{name}"]
        assert 0.0 < xcorr_delay(target[moving], robot[moving], 0.002) < 0.15
        assert np.degrees(np.abs(target - robot)[moving]).mean() < 3.0
        assert abs(math.degrees(robot[-1] - q[-1, j])) < 0.5
    wam_q = np.column_stack([log[f"q{i}"] for i in range(1, 5)])
    assert within_joint_range(wam_q)


def test_bad_packets_are_counted_by_reason_and_robot_keeps_running(tmp_path):
    proc, port = _start_sim(tmp_path, 2.5)
    sends = [
        encode([0.62, 1.53], 0, 0.00),              # ok
        encode([0.62, 1.55], 1, 0.01),              # ok
        b"not a packet",                            # malformed
        b"WAMJ" + b"\x09\x00\x02\x00" + bytes(28),  # malformed (version 9)
        encode([0.5, 1.1], 2, 0.02)[:-5],           # truncated
        bytes(4000),                                # oversize
        encode([float("nan"), 1.0], 2, 0.02),       # nonfinite
        encode_raw([0.62, 1.55]),                   # raw_refused (no --accept-raw)
        b"GET / HTTP/1.1\r\n",                      # raw_refused: 16 bytes, ~1e98 rad if taken as raw
        encode([0.62, 1.55], 1, 0.01),              # duplicate
        encode([0.64, 1.57], 5, 0.05),              # ok
        encode([0.63, 1.56], 4, 0.04),              # out of order
        encode([0.65, 1.58], 6, 0.00),              # stale: newer seq, older time
        encode([9.0, -7.0], 7, 0.07),               # out of range: rejected
        encode([0.0, 9.0, -9.0, 1.0], 8, 0.08),     # out of range in WAM joints (J2, J3)
        encode([2.0, 1.57], 9, 0.09),               # jump: 1.4 rad in 40 ms
        encode([0.65, 1.58], 10, 0.10),             # ok
    ]
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for data in sends:
                sock.sendto(data, ("127.0.0.1", port))
                time.sleep(0.01)
    finally:
        summary, log = _finish(proc, tmp_path)
    p = summary["packets"]
    got = {k: p[k] for k in ("ok", "malformed", "truncated", "oversize", "nonfinite", "raw_refused", "duplicate",
                             "out_of_order", "stale", "out_of_range", "jump")}
    assert got == dict(ok=4, malformed=2, truncated=1, oversize=1, nonfinite=1, raw_refused=2, duplicate=1,
                       out_of_order=1, stale=1, out_of_range=2, jump=1)
    assert p["rejected"] == 13 and p["received"] == len(sends) and log["packets_rejected"][-1] == 13
    for kind, n in got.items():                                     # one log column per counter
        assert log["packets_" + kind][-1] == n
    assert p["timeouts"] == 1 and log["hold"][-1] == 1 and summary["holds"][0]["message"].endswith("(timeout)")
    # It never stopped (every tick logged), never left its joint range or torque limits, never produced NaN,
    # and never followed a rejected target.
    assert summary["ticks"] == 1250 and len(log["t"]) == 1250
    wam_q = np.column_stack([log[f"q{i}"] for i in range(1, 5)])
    tau = np.column_stack([log[f"tau{i}"] for i in range(1, 5)])
    assert within_joint_range(wam_q) and np.all(np.isfinite(wam_q))
    assert np.all(np.abs(tau) <= np.array(PhysicsConfig().torque_limit_nm) + 1e-9)
    # The good targets span shoulder 0.62..0.65 and elbow 1.53..1.58 rad (the timeout hold lands near the last).
    assert 0.62 - 1e-3 <= log["target_shoulder"].min() and log["target_shoulder"].max() <= 0.65 + 1e-3
    assert 1.53 - 1e-3 <= log["target_elbow"].min() and log["target_elbow"].max() <= 1.58 + 1e-3


def test_simulator_refuses_bad_options():
    out = subprocess.run([sys.executable, "-m", "jaxarm.cli", "wam-sim", "--port", "0"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 2 and "--duration" in out.stderr
