"""Layout-independent results: one device, two devices, two processes on 127.0.0.1 give the same bits, and a batch
padded to the device count never reports its padding."""
import contextlib
import json
import os
import socket
import subprocess
import sys
import tempfile

import jax
import numpy as np
import pytest
from jax.sharding import AxisType, Mesh

from jaxarm.learning.metaparams import MetaParams
from jaxarm.loop import LoopConfig
from jaxarm.task.config import TaskConfig

TINY = LoopConfig(arm="simple", task=TaskConfig(epochs=2, epoch_duration_s=0.3, test_duration_s=0.2))


@contextlib.contextmanager
def parallel_groups(at_once: int):
    """The process's --networks-at-once set to ``at_once`` for the block (jaxarm.parallel.networks_at_once)."""
    from jaxarm import parallel

    before, parallel._networks_at_once = parallel._networks_at_once, at_once
    try:
        yield
    finally:
        parallel._networks_at_once = before


def _docs_text(page: str) -> str:
    from pathlib import Path

    return (Path(__file__).resolve().parents[1] / "docs" / page).read_text()


def one_device_mesh():
    return Mesh(np.asarray(jax.devices()[:1]), ("batch",), axis_types=(AxisType.Auto,))


def test_the_suite_runs_on_two_devices():
    assert jax.device_count() == 2


def test_no_module_starts_jax_at_import():
    """Importing any jaxarm module (a notebook's first cell) leaves JAX's devices unchosen, so `jaxarm.parallel.start`
    and the commands can still give every core its device (evosax computes at import: jaxarm.evolve defers it)."""
    code = """
import importlib, pkgutil
from jax._src import xla_bridge
import jaxarm
for m in pkgutil.walk_packages(jaxarm.__path__, "jaxarm."):
    importlib.import_module(m.name)
    assert not xla_bridge.backends_are_initialized(), m.name
from jaxarm import parallel
parallel.start(devices=3)
import jax
assert jax.device_count() == 3, jax.devices()
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_an_odd_batch_padded_over_two_devices_equals_one_device(tmp_path):
    from jaxarm.experiment import write_outputs
    from jaxarm.run import Run

    mp = MetaParams.original()
    results = {}
    for name, mesh in (("two", None), ("one", one_device_mesh())):
        run = Run(TINY, 3, 5, tmp_path / name, mp, mesh=mesh)
        assert run.n_padded == (4 if name == "two" else 3)     # one network at a time: padded to the devices
        carry, history, *_ = run.train(progress=False)
        trained, naive = run.test(carry.trained), run.test(run.naive())
        assert trained.hand_m.shape[0] == 3 and history.rewards.shape == (2, 3)
        results[name] = write_outputs(run, trained, naive, history, 1.0, 2)
    a, b = results["two"], results["one"]
    assert a["n_networks"] == 3 and [n["seed"] for n in a["networks"]] == [5, 6, 7]
    for key in ("networks", "naive", "history", "success_count", "test_rates_hz"):
        assert a[key] == b[key], key
    ta, tb = (np.load(tmp_path / n / "trajectories.npz") for n in ("two", "one"))
    for k in ta.files:
        np.testing.assert_array_equal(ta[k], tb[k], err_msg=k)


def test_networks_at_once_groups_and_pads_a_devices_share():
    """`map_networks` in groups equals one `vmap` on a function whose arithmetic cannot depend on the batch; the
    padding rounds a batch up to whole groups on every device; a negative group is refused naming the option."""
    from jaxarm import parallel
    from jaxarm.config.validate import ConfigError

    x = np.arange(21, dtype=np.int32)
    for k in (0, 1, 4, 8, 21, 40):
        np.testing.assert_array_equal(parallel.map_networks(lambda v: v * v + 1, k)(x), x * x + 1)
    two = parallel.mesh()
    assert [parallel.padded_size(n, two, 8) for n in (1, 16, 17, 30)] == [16, 16, 32, 32]
    assert [parallel.padded_size(n, one_device_mesh(), 8) for n in (1, 8, 9, 30)] == [8, 8, 16, 32]
    assert parallel.padded_size(3, two) == 4 and parallel.networks_at_once() == parallel.CPU_NETWORKS_AT_ONCE
    with pytest.raises(ConfigError, match="--networks-at-once = -1"):
        parallel.start(networks_at_once=-1)


def test_sharded_map_gives_every_row_whatever_the_mesh_and_batch():
    """`sharded_map` pads a batch to whole groups on every device and drops the padding: every row, of a pytree,
    for batches of 1, 5 and 17 rows, without a mesh, on one device and on two, as one jit."""
    from jaxarm import parallel

    fn = lambda a, b: {"sum": a + b["y"], "twice": 2 * a}              # noqa: E731
    for n in (1, 5, 17):
        a, y = np.arange(n, dtype=np.float32), np.arange(n, dtype=np.float32)[:, None] * np.ones(3, np.float32)
        for m in (None, one_device_mesh(), parallel.mesh()):
            out = jax.jit(parallel.sharded_map(fn, m, 8))(a, {"y": y})
            np.testing.assert_array_equal(np.asarray(out["sum"]), a[:, None] + y)
            np.testing.assert_array_equal(np.asarray(out["twice"]), 2 * a)


def test_networks_is_not_read_as_networks_at_once(monkeypatch):
    """The command line sets up the devices from its scale-out options before the command parses the rest; `--networks
    30` must not reach that parser as an abbreviation of `--networks-at-once` (it did: every `jaxarm train --networks N`
    ran its networks N at a time and padded the batch to N per device)."""
    from jaxarm import cli, parallel

    seen = {}
    monkeypatch.setattr(parallel, "start", lambda *a: seen.update(args=a))
    assert cli._start_devices("train", ["--networks", "30", "--devices", "1", "--out", "x"]) == 0
    assert seen["args"] == (1, None, None, None, None, None)     # the last: --coordinator-timeout
    assert cli._start_devices("train", ["--networks-at-once", "4"]) == 0 and seen["args"][4] == 4


@pytest.mark.slow
def test_a_batch_of_30_trains_to_the_same_bits_on_one_and_two_devices():
    """30 networks, 15 s of training (critic updates, the scaling at 5 and 10 s): on one device (30 at once before
    the fix) and on two (15 each) network 14 drifted apart (XLA's CPU code for a batch that is not a multiple of 8
    rounded the learning rule's updates differently in the last bit, jaxarm.cpu_arithmetic); one network at a time
    (the default since 2026-12-07) on one device and on two, every state array is the same."""
    from jaxarm.run import Run

    config = LoopConfig(arm="simple", task=TaskConfig(epochs=1, epoch_duration_s=15.0, test_duration_s=0.2))
    carries = []
    for mesh in (None, one_device_mesh()):
        with tempfile.TemporaryDirectory() as d:
            carry = Run(config, 30, 0, d, MetaParams.original(), mesh=mesh).train(progress=False)[0]
            carries.append([np.asarray(x)[:30] for x in jax.tree.leaves(carry)])
    for x, y in zip(*carries):
        np.testing.assert_array_equal(x, y)


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_a_run_checkpointed_on_two_devices_resumes_on_one(tmp_path):
    from jaxarm.run import Run

    mp = MetaParams.original()
    full = Run(TINY, 3, 0, tmp_path / "full", mp, mesh=one_device_mesh()).train(progress=False)
    Run(TINY, 3, 0, tmp_path / "moved", mp).train(progress=False, stop_after=1)          # 2 devices, padded to 4
    resumed = Run(TINY, 3, 0, tmp_path / "moved", mp, mesh=one_device_mesh()).train(progress=False)
    assert resumed[3] == 1
    for x, y in zip(jax.tree.leaves(full[1]), jax.tree.leaves(resumed[1])):
        np.testing.assert_array_equal(x, y)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def two_processes(args: list[str], out, tmp_path) -> None:
    """The same command in two processes joined through a coordinator on 127.0.0.1 (one CPU device each)."""
    port = free_port()
    env = dict(os.environ, JAX_COMPILATION_CACHE_DIR=str(tmp_path / "xla-cache"),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0", JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0")
    procs = [subprocess.Popen([sys.executable, "-m", "jaxarm.cli", *args, "--out", str(out), "--devices", "1",
                               "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2", "--process-id", str(i)],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
             for i in range(2)]
    logs = [p.communicate(timeout=600)[0] for p in procs]
    for p, log in zip(procs, logs):
        assert p.returncode == 0, log[-3000:]


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_two_processes_train_and_search_like_one(tmp_path):
    """`jaxarm train` and a 2-generation CMA-ES `jaxarm evolve` (5 candidates x 2 seeds, padded to the devices) in two
    processes on 127.0.0.1 against this process (two devices): identical results.json networks, trajectories,
    search history and top-k. (The reaching fitness over processes: the slow suite's test below.)"""
    from jaxarm.cli import main

    train = ["train", "--arm", "simple", "--target", "left", "--networks", "3", "--epochs", "2", "--epoch-s", "0.3",
             "--test-s", "0.2", "--seed", "0", "--no-progress"]
    evolve = ["evolve", "--fitness", "quadratic", "--population", "5", "--generations", "2", "--chunk", "1",
              "--seeds-per-candidate", "2", "--top-k", "3"]
    for args, name in ((train, "train"), (evolve, "evolve")):
        assert main([*args, "--out", str(tmp_path / f"{name}-one")]) == 0
        two_processes(args, tmp_path / f"{name}-two", tmp_path)
    a, b = (json.loads((tmp_path / f"train-{n}" / "results.json").read_text()) for n in ("one", "two"))
    assert a["networks"] == b["networks"] and a["naive"] == b["naive"] and a["history"] == b["history"]
    assert b["timing"]["layout"]["processes"] == 2
    ta, tb = (np.load(tmp_path / f"train-{n}" / "trajectories.npz") for n in ("one", "two"))
    for k in ta.files:
        np.testing.assert_array_equal(ta[k], tb[k], err_msg=k)
    for f in ("history.json", "top_k.json"):
        ha, hb = (json.loads((tmp_path / f"evolve-{n}" / f).read_text()) for n in ("one", "two"))
        if f == "history.json":
            ha, hb = ha["history"], hb["history"]
        assert ha == hb, f


@pytest.mark.slow
def test_two_processes_train_the_centre_out_task_like_one(tmp_path):
    """`jaxarm train --task centre-out-8` (eight targets, one epoch each) in two processes on 127.0.0.1 against this
    process (two devices): the same runner, so the same results and trajectories."""
    from jaxarm.cli import main

    train = ["train", "--task", "centre-out-8", "--arm", "simple", "--networks", "3", "--epochs", "1", "--epoch-s",
             "0.2", "--test-s", "0.2", "--seed", "0", "--no-progress"]
    assert main([*train, "--out", str(tmp_path / "one")]) == 0
    two_processes(train, tmp_path / "two", tmp_path)
    a, b = (json.loads((tmp_path / n / "results.json").read_text()) for n in ("one", "two"))
    for key in ("trained", "naive", "history_mean_over_networks_by_epoch", "test_rates_hz", "seeds"):
        assert a[key] == b[key], key
    assert b["timing"]["layout"]["processes"] == 2
    ta, tb = (np.load(tmp_path / n / "trajectories.npz") for n in ("one", "two"))
    for k in ta.files:
        np.testing.assert_array_equal(ta[k], tb[k], err_msg=k)


@pytest.mark.slow
def test_two_processes_reproduce_the_centre_out_comparison_like_one(tmp_path):
    """`jaxarm reproduce --task centre-out-8` (the target-code network and its control, through the runner) in two
    processes: the same centre_out.json conditions and table as one process."""
    from jaxarm.cli import main

    args = ["reproduce", "--task", "centre-out-8", "--arm", "simple", "--networks", "2", "--epochs", "1",
            "--epoch-s", "0.2", "--test-s", "0.2", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "one")]) == 0
    two_processes(args, tmp_path / "two", tmp_path)
    a, b = (json.loads((tmp_path / n / "centre_out.json").read_text())["conditions"] for n in ("one", "two"))
    assert set(a) == set(b) == {"target-code", "control"}
    for name in a:
        for key in ("trained", "naive", "history_mean_over_networks_by_epoch", "test_rates_hz"):
            assert a[name][key] == b[name][key], (name, key)
    assert (tmp_path / "one" / "centre_out.md").read_text() == (tmp_path / "two" / "centre_out.md").read_text()


@pytest.mark.slow
def test_two_processes_search_the_reaching_task_like_one(tmp_path):
    from jaxarm.cli import main

    evolve = ["evolve", "--fitness", "reaching-shortfall", "--arm", "simple", "--targets", "left", "--train-s", "0.3",
              "--population", "5", "--generations", "2", "--chunk", "1", "--seeds-per-candidate", "1", "--top-k", "3"]
    assert main([*evolve, "--out", str(tmp_path / "one")]) == 0
    two_processes(evolve, tmp_path / "two", tmp_path)
    for f in ("history.json", "top_k.json"):
        ha, hb = (json.loads((tmp_path / n / f).read_text()) for n in ("one", "two"))
        if f == "history.json":
            ha, hb = ha["history"], hb["history"]
        assert ha == hb, f


def test_a_device_may_wait_longer_than_xlas_40_s_at_a_gather(monkeypatch):
    """XLA:CPU aborts a process whose device waits 40 s at a collective for the others; `parallel.start` passes it
    longer limits (unless XLA_FLAGS sets them). Shown with a 1 s warning limit passed the same way: device 0 arrives
    2 s late at a psum and XLA warns, so XLA reads what start() sets."""
    from jaxarm import parallel

    code = """
import time
import jax, jax.numpy as jnp
from jax import lax
from jax.sharding import PartitionSpec as P
from jaxarm import parallel
parallel.COLLECTIVE_WAIT_S["xla_cpu_collective_call_warn_stuck_timeout_seconds"] = 1
parallel.start(devices=2)
late = lambda x: (time.sleep(2.0), x)[1]
share = lambda x: lax.psum(lax.cond(lax.axis_index(parallel.AXIS) == 0, lambda x: jax.pure_callback(late, x, x),
                                    lambda x: x, x), parallel.AXIS)
print(jax.jit(jax.shard_map(share, mesh=parallel.mesh(), in_specs=P(parallel.AXIS), out_specs=P(),
                    check_vma=False))(jnp.ones(2)))
"""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "may be stuck" in proc.stderr and "[2.]" in proc.stdout
    # the defaults: minutes, not XLA's seconds; a limit the user set in XLA_FLAGS is kept
    assert parallel.COLLECTIVE_WAIT_S["xla_cpu_collective_call_terminate_timeout_seconds"] >= 3600
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_collective_call_warn_stuck_timeout_seconds=5")
    parallel._relax_collective_waits()
    assert os.environ["XLA_FLAGS"].split() == ["--xla_cpu_collective_call_warn_stuck_timeout_seconds=5",
                                               "--xla_cpu_collective_call_terminate_timeout_seconds=21600"]


def test_a_padded_batch_says_how_much_is_padding_and_what_fills_it():
    """A search's generation and a reproduction's batch that do not fill whole groups on their mesh say so in one
    line: the padded size, the fraction that is padding, and the --population / --networks that fills the groups;
    one that fills them says so too. The docs' SLURM recipe (8 nodes x 32 cores, 256 devices one network at a time):
    100 candidates x 2 seeds padded 21.9 % (the line the docs print), 1024 x 2 whole; in groups of 8, 256 x 2
    padded 75 %."""
    from types import SimpleNamespace

    from jaxarm import parallel
    from jaxarm.evolve.cli import generation_layout
    from jaxarm.evolve.search import EvolveConfig
    from jaxarm.paper.reproduce import batch_layout
    from jaxarm.run import SetsRun

    def search(population, seeds, mesh):
        return generation_layout(EvolveConfig(population_size=population, seeds_per_candidate=seeds), mesh)

    two, one = parallel.mesh(), one_device_mesh()
    assert search(5, 1, two) == ("a generation's 5 evaluations (5 candidates x 1 seed(s)): on 2 devices one network "
                                 "at a time, padded to 6: 16.7 % of what runs is padding (computed and dropped); "
                                 "--population 6 fills the groups (6 evaluations)")
    assert search(5, 2, two).endswith("on 2 devices one network at a time, no padding")
    assert search(3, 3, one).endswith("on 1 device one network at a time, no padding")
    with parallel_groups(8):
        assert search(5, 2, two) == ("a generation's 10 evaluations (5 candidates x 2 seed(s)): on 2 devices in "
                                     "groups of 8, padded to 16: 37.5 % of what runs is padding (computed and "
                                     "dropped); --population 8 fills the groups (16 evaluations)")
        assert search(8, 2, two).endswith("on 2 devices in groups of 8, whole groups (no padding)")
        assert search(3, 3, one).endswith("padded to 16: 43.8 % of what runs is padding (computed and dropped); "
                                          "--population 8 fills the groups (24 evaluations)")
    recipe = parallel.padding_note(512, "g", 256, 8, 8, ("--population", lambda p: 2 * p, 256))
    assert recipe == ("g: on 256 devices of 8 processes in groups of 8, padded to 2048: 75 % of what runs is padding "
                      "(computed and dropped); --population 1024 fills the groups (2048 networks)")
    assert parallel.padding_note(2048, "g", 256, 8, 8).endswith("whole groups (no padding)")
    # the recipe as the docs print it (one network at a time), with --population 100
    what = "jaxarm evolve: a generation's 200 evaluations (100 candidates x 2 seed(s))"
    printed = parallel.padding_note(200, what, 256, 1, 8, ("--population", lambda p: 2 * p, 100), unit="evaluations")
    assert printed in _docs_text("scaling.md")
    assert parallel.padding_note(2048, "g", 256, 1, 8).endswith("one network at a time, no padding")
    assert parallel.padding_note(10, "g", 4, 0) == "g: on 4 devices, padded to 12: 16.7 % of what runs is padding " \
                                                  "(computed and dropped); a batch of 12 networks (a multiple of 4) " \
                                                  "fills the groups"

    class Sets(SetsRun):     # a (b) group of a reproduction: one network per set, whatever --networks says
        def __init__(self, n):
            self.n = n

    default = [SimpleNamespace(n=30), Sets(30), SimpleNamespace(n=30), Sets(30)]   # 2 targets x ((a) 30 + (b) 30)
    assert batch_layout(default, two.size, 8) == (
        "the batch's 120 networks: on 2 devices in groups of 8, padded to 128: 6.25 % of what runs is padding "
        "(computed and dropped); --networks 34 fills the groups (128 networks)")
    assert batch_layout(default, 1, 4).endswith("whole groups (no padding)")
    assert batch_layout([Sets(30)], 2, 8).endswith("; a batch of 32 networks (a multiple of 16) fills the groups")
