"""Exporter inputs (CSV, NPZ, `jaxarm test` folder, synthetic), resampling and the packet variants."""
import numpy as np
import pytest

from jaxarm.robot.config import SafetyConfig, WamSimConfig
from jaxarm.robot.exporter import (Trajectory, load_trajectory, packets, resample, save_trajectory_csv, simulate)
from jaxarm.robot.protocol import decode
from jaxarm.robot.synthetic import PAPER_DISPLACEMENT_DEG, peak_speed_deg_s, reach_trajectory


def _traj():
    t = np.arange(0, 0.5, 0.005)
    return Trajectory(t, np.column_stack([0.6 + 0.2 * t, 1.5 - 0.4 * t]))


def test_csv_npz_and_result_folder_give_the_same_trajectory(tmp_path):
    tr = _traj()
    save_trajectory_csv(tmp_path / "a.csv", tr)
    np.savez(tmp_path / "b.npz", t=tr.t, q=tr.q)
    folder = tmp_path / "result"
    folder.mkdir()
    other = tr.q + 0.1
    np.savez(folder / "trajectories.npz", t=tr.t, q=np.stack([tr.q, other]))   # (networks, T, 2)
    for src in (tmp_path / "a.csv", tmp_path / "b.npz", folder):
        got = load_trajectory(src)
        np.testing.assert_allclose(got.t, tr.t, atol=1e-9)
        np.testing.assert_allclose(got.q, tr.q, atol=1e-8)
    np.testing.assert_allclose(load_trajectory(folder, network=1).q, other)
    with pytest.raises(ValueError, match="network"):
        load_trajectory(folder, network=2)
    (tmp_path / "bad.csv").write_text("time,a,b\n0,1,2\n")
    with pytest.raises(ValueError, match="header"):
        load_trajectory(tmp_path / "bad.csv")
    with pytest.raises(FileNotFoundError):
        load_trajectory(tmp_path)                                             # a folder without trajectories.npz


def test_resample_to_the_10ms_update_grid():
    g = resample(_traj())
    np.testing.assert_allclose(np.diff(g.t), 0.01)
    assert len(g.t) == 50                                                     # 0 .. 0.49 s
    np.testing.assert_allclose(g.q[:, 0], 0.6 + 0.2 * g.t)


def test_packet_variants_carry_the_same_targets():
    g = resample(_traj())
    ext, raw, wam = packets(g), packets(g, "raw"), packets(g, wam_joints=True)
    assert decode(ext[3]).seq == 3 and decode(ext[3]).t == pytest.approx(0.03)
    assert decode(raw[3]).seq is None and len(decode(wam[3]).angles) == 4
    accept_raw = WamSimConfig(safety=SafetyConfig(accept_raw=True))     # the robot refuses raw packets by default
    logs = [simulate(_traj(), accept_raw, timing="live", duration_s=1.0, fmt=f, wam_joints=w)
            for f, w in (("extended", False), ("raw", False), ("extended", True))]
    for log in logs[1:]:
        np.testing.assert_allclose(log.rows[:, 1:5], logs[0].rows[:, 1:5], atol=1e-12)


def test_synthetic_stand_in_matches_paper_displacement_and_ranges():
    t, q = reach_trajectory(seed=4)
    disp = np.degrees(np.abs(np.diff(q, axis=0)).sum(axis=0))
    np.testing.assert_allclose(disp, PAPER_DISPLACEMENT_DEG, rtol=0.02)
    assert np.degrees(q[:, 0]).min() >= -10 and np.degrees(q[:, 0]).max() <= 110
    assert np.degrees(q[:, 1]).min() >= 0 and np.degrees(q[:, 1]).max() <= 140
    np.testing.assert_allclose(q[0], [0.62, 1.53])
    assert np.all(peak_speed_deg_s(t, q) > 60)                                # "velocities above 60 deg/s"
    np.testing.assert_array_equal(reach_trajectory(seed=4)[1], q)             # seeded


@pytest.mark.parametrize("text, needle", [
    ("", "header must name t, shoulder and elbow"),
    ("t,shoulder,elbow\n", "at least two samples"),
    ("t,shoulder,elbow\n0,1\n0.1,1,1\n", "line 2"),
    ("t,shoulder,elbow\n0,1,1\n0.1,nope,1\n", "line 3"),
    ("t,shoulder,elbow\n0,1,1\n0.1,nan,1\n", "non-finite"),
    ("t,shoulder,elbow\n0.1,1,1\n0,1,1\n", "strictly increasing"),
])
def test_bad_csv_files_say_what_and_where(tmp_path, text, needle):
    (tmp_path / "bad.csv").write_text(text)
    with pytest.raises(ValueError, match=needle) as err:
        load_trajectory(tmp_path / "bad.csv")
    assert "bad.csv" in str(err.value)
