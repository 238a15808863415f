"""A real SIGKILL of `jaxarm train` and `jaxarm reproduce` processes mid-run; the same command resumes and ends with
the results of an uninterrupted run, bit for bit (small sizes: a few networks, epochs of 0.4 s).

The uninterrupted reference runs in this process (the CLI's own entry point); the killed and resumed runs are child
processes sharing a persistent XLA compilation cache, so the second one loads what the first compiled.
"""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

TRAIN = ["train", "--arm", "simple", "--target", "left", "--networks", "2", "--epochs", "6", "--epoch-s", "0.4",
         "--test-s", "0.2", "--seed", "3", "--no-progress"]


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    cache = tmp_path_factory.mktemp("xla-cache")
    return dict(os.environ, JAX_COMPILATION_CACHE_DIR=str(cache), JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
                JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0")


def cli(args, out: Path):
    return [sys.executable, "-m", "jaxarm.cli", *args, "--out", str(out)]


def in_process(args, out):
    from jaxarm.cli import main

    assert main([*args, "--out", str(out)]) == 0


def run_to_end(args, out, env):
    proc = subprocess.run(cli(args, out), capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def kill_after(args, out: Path, checkpoint: Path, env):
    """Start the command, SIGKILL its whole process group once ``checkpoint`` exists (a completed epoch)."""
    proc = subprocess.Popen(cli(args, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True, env=env)
    deadline = time.time() + 300
    while not checkpoint.exists():
        assert proc.poll() is None and time.time() < deadline, "the run ended before it could be killed"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def same_results(a: Path, b: Path):
    ra, rb = (json.loads((f / "results.json").read_text()) for f in (a, b))
    assert ra["networks"] == rb["networks"] and ra["naive"] == rb["naive"] and ra["history"] == rb["history"]
    ta, tb = np.load(a / "trajectories.npz"), np.load(b / "trajectories.npz")
    for k in ta.files:
        np.testing.assert_array_equal(ta[k], tb[k], err_msg=k)


def test_killed_train_resumes_bit_for_bit(tmp_path, env):
    in_process(TRAIN, tmp_path / "full")
    killed = tmp_path / "killed"
    kill_after(TRAIN, killed, killed / "checkpoints" / "2", env)
    done = sorted(int(p.name) for p in (killed / "checkpoints").iterdir() if p.name.isdigit())
    assert 2 <= done[-1] < 6 and not (killed / "results.json").exists()
    run_to_end(TRAIN, killed, env)
    same_results(tmp_path / "full", killed)


@pytest.mark.slow   # 35 s: the default suite's budget; killed train and damaged-checkpoint resumes stay in it
def test_killed_reproduce_resumes_bit_for_bit(tmp_path, env):
    args = ["reproduce", "--arm", "simple", "--preset", "simple-cmaes-left-local", "--targets", "left",
            "--networks", "2", "--top", "2", "--epochs", "4", "--epoch-s", "0.4", "--test-s", "0.2", "--no-progress"]
    in_process(args, tmp_path / "full")
    killed = tmp_path / "killed"
    kill_after(args, killed, killed / "checkpoints" / "2", env)
    assert not (killed / "success_table.json").exists()
    run_to_end(args, killed, env)
    for mode in ("seeds", "top30"):
        same_results(tmp_path / "full" / "left" / mode, killed / "left" / mode)
    ta, tb = (json.loads((d / "success_table.json").read_text()) for d in (tmp_path / "full", killed))
    assert ta["targets"] == tb["targets"]


CENTRE_OUT = ["train", "--task", "centre-out-8", "--arm", "simple", "--networks", "2", "--epochs", "1", "--epoch-s",
              "0.4", "--test-s", "0.2", "--seed", "3", "--no-progress"]


def same_centre_out_results(a: Path, b: Path):
    ra, rb = (json.loads((f / "results.json").read_text()) for f in (a, b))
    for key in ("trained", "naive", "history_mean_over_networks_by_epoch", "test_rates_hz", "naive_test_rates_hz",
                "seeds", "targets"):
        assert ra[key] == rb[key], key
    ta, tb = np.load(a / "trajectories.npz"), np.load(b / "trajectories.npz")
    for k in ta.files:
        np.testing.assert_array_equal(ta[k], tb[k], err_msg=k)


@pytest.mark.slow   # three centre-out trainings (one compiles in this process, two in children)
def test_killed_centre_out_train_resumes_bit_for_bit(tmp_path, env):
    """`jaxarm train --task centre-out-8` runs through the same runner as reaching: killed after its second epoch
    (of eight, one per target), the same command resumes and ends with the uninterrupted run's results."""
    in_process(CENTRE_OUT, tmp_path / "full")
    killed = tmp_path / "killed"
    kill_after(CENTRE_OUT, killed, killed / "checkpoints" / "2", env)
    done = sorted(int(p.name) for p in (killed / "checkpoints").iterdir() if p.name.isdigit())
    assert 2 <= done[-1] < 8 and not (killed / "results.json").exists()
    said = run_to_end(CENTRE_OUT, killed, env)
    assert "centre-out targets, 2 networks" in said.stdout
    same_centre_out_results(tmp_path / "full", killed)
