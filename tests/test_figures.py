"""`jaxarm figures` and `jaxarm video` on tiny recorded runs: every named file is written, the data beside a figure
agrees with the spike record, the video decodes to the frames and size asked for, and bad options are one-line
errors."""
import csv
import json

import numpy as np
import pytest

from jaxarm.cli import main

#: Every file `jaxarm figures --grid --robot-log` writes for a simple-arm run recorded with --record-spikes.
SIMPLE_FILES = ("raster.png", "raster.npz", "rates.png", "rates.csv", "rates_epochs.csv",
                "raster_grid.png", "raster_grid.npz", "reach_paths.png", "reach_paths.npz",
                "reach_paths_grid.png", "reach_paths_grid.npz", "jerk_box.png", "jerk_box.csv", "jerk_box.npz",
                "robot_hand_xy.png", "robot_hand_xy.npz", "robot_jerk.png", "robot_jerk.json", "figures.json")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Two simple-arm networks, one 0.2 s epoch, a 1 s test, spikes recorded."""
    out = tmp_path_factory.mktemp("figures") / "run"
    assert main(["train", "--networks", "2", "--epochs", "1", "--epoch-s", "0.2", "--test-s", "1.0", "--out",
                 str(out), "--no-progress", "--record-spikes"]) == 0
    return out


def _robot_log(path):
    """A wam-sim style CSV: the robot follows a smooth target 0.1 s late, a packet every 14 ms."""
    t = np.arange(0.0, 3.0, 0.002)
    target = np.column_stack([0.6 + 0.3 * np.sin(t), 1.5 + 0.2 * np.sin(1.3 * t)])
    robot = np.column_stack([0.6 + 0.3 * np.sin(t - 0.1), 1.5 + 0.2 * np.sin(1.3 * (t - 0.1))])
    new = (np.arange(len(t)) % 7 == 0).astype(float)
    np.savetxt(path, np.column_stack([t, target, robot, new]), delimiter=",", comments="",
               header="t,target_shoulder,target_elbow,robot_shoulder,robot_elbow,new_target")
    return path


def test_figures_writes_every_named_file_and_its_data_matches_the_record(run, tmp_path, capsys):
    from jaxarm.recordfile import SpikeFile

    out = tmp_path / "fig"
    assert main(["figures", str(run), "--out", str(out), "--network", "1", "--grid", "--robot-log",
                 str(_robot_log(tmp_path / "robot.csv"))]) == 0
    for name in SIMPLE_FILES:
        assert (out / name).stat().st_size > 0, name
    manifest = json.loads((out / "figures.json").read_text())
    assert sorted(f for files in manifest["written"].values() for f in files) == sorted(SIMPLE_FILES[:-1])
    assert "simple arm has no muscles" in manifest["skipped"]["muscles"]
    # the rates are the record's spikes per population, per cell and second: back to counts they sum to the record
    f = SpikeFile(run / "spikes.npz")
    counts = f.get("test", "counts")[1]
    with open(out / "rates.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 100                                   # 1 s in 10 ms bins
    for pop in ("P", "ES", "EM", "IML"):
        n_cells = f.pop_stop[pop] - f.pop_start[pop]
        total = sum(float(r[f"{pop}_hz"]) * n_cells * (float(r["t_stop_ms"]) - float(r["t_start_ms"])) / 1000
                    for r in rows)
        assert total == pytest.approx(counts[f.pop_start[pop]:f.pop_stop[pop]].sum(), abs=1e-3)
    raster = np.load(out / "raster.npz")
    assert len(raster["t_ms"]) == counts.sum() and int(raster["seed"]) == int(f.seeds[1])
    # P at the top of the raster, IML at the bottom (the paper's order)
    assert raster["row"][raster["cell"] >= f.pop_start["P"]].max() < 192
    jerk = list(csv.DictReader(open(out / "jerk_box.csv")))
    assert [int(r["seed"]) for r in jerk] == f.seeds.tolist()
    assert "robot_hand_xy.png" in capsys.readouterr().out


def test_the_paper_figure_numbers_live_in_jaxarm_paper():
    """The figure code names its figures for what they draw; jaxarm.paper.figures maps the paper's numbers to them."""
    import re
    from pathlib import Path

    from jaxarm.paper.figures import FIGURES
    from jaxarm.robot import figures as robot_figures
    from jaxarm.viz import figures as run_figures

    assert sorted(FIGURES) == [5, 6, 7, 9, 10]
    viz = Path(run_figures.__file__).read_text()
    for number, figure in FIGURES.items():
        assert figure.draw.__module__ in (run_figures.__name__, robot_figures.__name__), number
        assert f'written["{figure.name}"]' in viz, figure.name       # its entry in figures.json
    for module in (run_figures, robot_figures):
        text = Path(module.__file__).read_text()
        assert not re.search(r"\bfig_?\d|\bFigs?\. ?\d", text), module.__name__


def test_figures_without_a_spike_record_draws_the_rest_and_says_how_to_record(run, tmp_path, capsys):
    import shutil

    bare = tmp_path / "bare"
    shutil.copytree(run, bare, ignore=shutil.ignore_patterns("spikes.npz", "checkpoints"))
    assert main(["figures", str(bare), "--out", str(tmp_path / "f")]) == 0
    err = capsys.readouterr().err
    assert "skipped raster: no spikes.npz" in err and "--record-spikes" in err
    assert (tmp_path / "f" / "reach_paths.png").is_file() and not (tmp_path / "f" / "raster.png").exists()
    for argv, msg in (([str(run), "--network", "2"], "--network 2: the run has 2 networks (0..1)"),
                      ([str(tmp_path / "nowhere")], "no results.json and trajectories.npz"),
                      ([str(run), "--window", "epoch_9"], "no window 'epoch_9'")):
        with pytest.raises(SystemExit):
            main(["figures", "--out", str(tmp_path / "g")] + argv)
        assert msg in capsys.readouterr().err


def test_video_of_a_1s_test_decodes_to_the_frames_and_size_asked(run, tmp_path, capsys):
    import imageio.v2 as imageio

    out = tmp_path / "reach.mp4"
    assert main(["video", str(run), "--network", "1", "--out", str(out), "--fps", "12", "--size", "320x240",
                 "--no-progress"]) == 0
    reader = imageio.get_reader(out)
    frames = [frame for frame in reader]
    reader.close()
    assert len(frames) == 12 and frames[0].shape == (240, 320, 3)
    assert np.std(frames[-1]) > 0                              # something was drawn
    assert main(["video", str(run), "--out", str(tmp_path / "part.mp4"), "--fps", "10", "--start-s", "0.25",
                 "--stop-s", "0.75", "--size", "160x120", "--no-progress"]) == 0
    assert sum(1 for _ in imageio.get_reader(tmp_path / "part.mp4")) == 5
    # The simulated WAM drawn as a second arm (tab:purple) from a robot log; without the log, no purple anywhere.
    log = _robot_log(tmp_path / "wam.csv")
    assert main(["video", str(run), "--out", str(tmp_path / "wam.mp4"), "--fps", "10", "--stop-s", "0.3",
                 "--robot-log", str(log), "--size", "320x240", "--no-progress"]) == 0
    purple = [int(np.sum(np.all(np.abs(f[:, :130].astype(int) - (148, 103, 189)) < 30, axis=-1)))   # arm panel
              for f in (imageio.get_reader(tmp_path / n).get_data(0) for n in ("wam.mp4", "reach.mp4"))]
    assert purple[0] > 30 and purple[1] == 0, purple
    for argv, msg in ((["--size", "321x240"], "both even"), (["--stop-s", "2"], "stop <= 1 s"),
                      (["--fps", "0"], "--fps 0: must be in [1, 120]"),
                      (["--renderer", "mujoco"], "--renderer mujoco: the simple arm has no MJCF model"),
                      (["--robot-log", str(tmp_path / "none.csv")], "none.csv: no such file")):
        with pytest.raises(SystemExit):
            main(["video", str(run), "--out", str(tmp_path / "x.mp4")] + argv)
        assert msg in capsys.readouterr().err


@pytest.fixture(scope="module")
def ms_run(tmp_path_factory):
    """Two musculoskeletal-arm networks, one 0.1 s epoch, a 0.5 s test, spikes (and muscles) recorded."""
    run = tmp_path_factory.mktemp("ms") / "run"
    assert main(["train", "--arm", "musculoskeletal", "--networks", "2", "--epochs", "1", "--epoch-s", "0.1",
                 "--test-s", "0.5", "--out", str(run), "--no-progress", "--record-spikes"]) == 0
    return run


@pytest.mark.slow
def test_musculoskeletal_run_draws_its_muscles(ms_run, tmp_path):
    """The musculoskeletal arm's run writes muscles.npz; figures draws it and the video draws its 22 paths."""
    import imageio.v2 as imageio

    run = ms_run
    assert main(["figures", str(run), "--out", str(tmp_path / "f"), "--network", "1"]) == 0
    data = np.load(tmp_path / "f" / "muscles.npz")
    assert data["activation"].shape == (50, 22) and len(data["muscle_names"]) == 22
    rec = np.load(run / "muscles.npz")
    np.testing.assert_array_equal(data["force_n"], rec["test.force_n"][1])
    assert main(["video", str(run), "--out", str(tmp_path / "m.mp4"), "--fps", "10", "--size", "320x180",
                 "--no-progress"]) == 0
    assert sum(1 for _ in imageio.get_reader(tmp_path / "m.mp4")) == 5


def _mujoco_video(run, out, gl):
    """`jaxarm video --renderer mujoco` in a child process (MuJoCo reads MUJOCO_GL when it is imported)."""
    import os
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "jaxarm.cli", "video", str(run), "--renderer", "mujoco", "--out",
                           str(out), "--fps", "10", "--size", "480x270", "--no-progress"],
                          capture_output=True, text=True, timeout=300, env=dict(os.environ, MUJOCO_GL=gl))


@pytest.mark.slow
def test_mujoco_renders_the_musculoskeletal_arm_where_it_can(ms_run, tmp_path):
    """--renderer mujoco: frames of the MJCF arm (egl or osmesa); where neither renders offscreen, the command says so
    in one line and exits 2, and the test is skipped with that line."""
    import imageio.v2 as imageio

    run = ms_run
    for gl in ("egl", "osmesa"):
        proc = _mujoco_video(run, tmp_path / "mj.mp4", gl)
        if proc.returncode == 0:
            break
        assert proc.returncode == 2 and ("cannot render offscreen" in proc.stderr
                                         or "cannot be imported with MUJOCO_GL" in proc.stderr), proc.stderr[-2000:]
        assert len(proc.stderr.strip().splitlines()[-1]) < 400
    else:
        pytest.skip(f"MuJoCo cannot render offscreen here: {proc.stderr.strip().splitlines()[-1]}")
    frames = [f for f in imageio.get_reader(tmp_path / "mj.mp4")]
    assert len(frames) == 5 and frames[0].shape == (270, 480, 3)
    panel = [f[:, :200].astype(float) for f in frames]                 # the arm panel (left)
    assert panel[0].std() > 5.0                                         # something was rendered
    assert np.abs(panel[-1] - panel[0]).mean() > 0.1                    # the arm moved
    red = (panel[0][..., 0] > 120) & (panel[0][..., 1] < 110) & (panel[0][..., 2] < 110)
    assert red.sum() > 20                                               # the target disc


def test_a_bad_mujoco_gl_is_a_one_line_error_in_any_command(tmp_path):
    """MuJoCo reads MUJOCO_GL at import; a command that needs MuJoCo (here training with the musculoskeletal arm)
    says so in one line and exits 2 instead of a traceback."""
    import os
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "jaxarm.cli", "train", "--arm", "musculoskeletal", "--networks", "1",
                           "--epochs", "1", "--epoch-s", "0.1", "--test-s", "0.1", "--out", str(tmp_path / "r"),
                           "--no-progress"], capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, MUJOCO_GL="no-such-gl"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    line = proc.stderr.strip().splitlines()[-1]
    assert "MUJOCO_GL=no-such-gl" in line and len(line) < 400
