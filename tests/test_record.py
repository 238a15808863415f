"""Spike recording in the closed loop (jaxarm.record): the record equals what the network counts, recording changes
nothing it observes, and its bounds fail with errors naming the option."""
import json

import jax
import numpy as np
import pytest

from jaxarm import record as rec_mod
from jaxarm import recordfile
from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import MetaParams
from jaxarm.loop import LoopConfig
from jaxarm.network import NetworkConfig, native
from jaxarm.network.populations import Populations
from jaxarm.task.config import TaskConfig
from jaxarm.train import make_train

TASK = TaskConfig(epochs=1, epoch_duration_s=0.3, test_duration_s=0.2)
#: The XLA kernel compiles four programs for minutes on a loaded 2-core machine: in the slow suite.
KERNELS = (pytest.param("xla", marks=pytest.mark.slow),
           pytest.param("native", marks=pytest.mark.skipif(not native.available(),
                                                      reason="native kernel unavailable")))


def _histogram(buf, r, n_all, start_step, stop_step, steps_per_interval):
    """Spikes per cell of network r's decoded buffer, after checking every spike lies in (start_step, stop_step],
    in order."""
    step, cell = rec_mod.decode(buf.word[r], buf.bits[r], buf.used[r], n_all, start_step, steps_per_interval)
    assert len(step) == int(buf.count[r]) and int(buf.used[r]) <= len(step)
    assert np.all((step > start_step) & (step <= stop_step))
    order = step.astype(np.int64) * n_all + cell
    assert np.all(np.diff(order) > 0)          # by step, then cell; each (step, cell) at most once
    return np.bincount(cell, minlength=n_all)


def test_packed_buffer_decodes_to_numpys_nonzero_and_counts_what_it_drops():
    """Random spike blocks (5 intervals of 40 steps x 45 cells: words straddle steps and intervals end mid-word)
    pushed one interval at a time decode to exactly np.nonzero of the blocks, in (step, cell) order; a buffer too
    small keeps the first slots and counts the rest."""
    steps, n_all, intervals, start = 40, 45, 5, 1000
    rng = np.random.default_rng(0)
    blocks = rng.random((intervals, steps, n_all)) < 0.02
    blocks[2] = False                                     # a silent interval
    blocks[3, -1, -1] = True                              # the last bit of an interval's padded last word

    def record(capacity):
        buf = rec_mod.empty(capacity)
        for i in range(intervals):
            buf = jax.jit(rec_mod.push)(buf, blocks[i], np.int32(i))
        return buf

    buf = record(4000)
    step, cell = rec_mod.decode(buf.word, buf.bits, buf.used, n_all, start, steps)
    ref_step, ref_cell = np.nonzero(blocks.reshape(intervals * steps, n_all))
    np.testing.assert_array_equal(step, start + 1 + ref_step)
    np.testing.assert_array_equal(cell, ref_cell)
    assert int(buf.count) == blocks.sum() and int(buf.used) <= blocks.sum()
    small = record(10)
    assert int(small.used) == int(buf.used) and int(small.count) == int(buf.count)
    with pytest.raises(RuntimeError, match=r"seed 7 \(\d+ spikes in \d+ slots\).* capacity of 10 slots"):
        rec_mod.check_overflow(jax.tree.map(lambda x: x[None], small), 10, [7], "test", 50.0)
    s_small, c_small = rec_mod.decode(small.word, small.bits, small.used, n_all, start, steps)
    k = len(s_small)
    np.testing.assert_array_equal(s_small, step[:k])
    np.testing.assert_array_equal(c_small, cell[:k])


@pytest.mark.parametrize("kernel", KERNELS)
def test_record_equals_the_networks_own_counts_and_changes_nothing(kernel):
    """Two networks, one 0.3 s epoch (its last 0.1 s recorded) and a 0.2 s test, on each kernel: the decoded record
    of every window equals, cell by cell, the spike counter the network keeps itself; per population it equals the
    test's reported rates x duration x size; epoch and test results are bit-identical with and without recording."""
    cfg = LoopConfig(arm="simple", network=NetworkConfig(kernel=kernel), task=TASK)
    record = rec_mod.RecordConfig(train_last_s=0.1)
    plain, recd = make_train(cfg), make_train(cfg, record)
    mp = MetaParams.original()
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    carry = jax.jit(jax.vmap(plain.init))(keys)
    c0, s0 = jax.jit(jax.vmap(plain.epoch, in_axes=(0, None)))(carry, mp)
    c1, s1, win = jax.jit(jax.vmap(recd.epoch_recorded, in_axes=(0, None)))(carry, mp)
    for a, b in zip(jax.tree.leaves((c0, s0)), jax.tree.leaves((c1, s1))):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    t0 = jax.jit(jax.vmap(plain.test, in_axes=(0, 0, None)))(keys, c0.trained, mp)
    t1 = jax.jit(jax.vmap(recd.test, in_axes=(0, 0, None)))(keys, c0.trained, mp)
    assert t0.record is None
    for a, b in zip(jax.tree.leaves(t0), jax.tree.leaves(t1._replace(record=None))):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))

    n_all, spi = cfg.network.n_all, plain.loop.steps_per_interval
    pops = Populations(cfg.network)
    epoch_steps, test_steps = TASK.epoch_steps * spi, TASK.test_steps * spi
    for r in range(2):
        hist = _histogram(win.spikes, r, n_all, epoch_steps - 10 * spi, epoch_steps, spi)
        np.testing.assert_array_equal(hist, np.asarray(win.counts[r]))
        hist = _histogram(t1.record.spikes, r, n_all, 0, test_steps, spi)
        np.testing.assert_array_equal(hist, np.asarray(t1.record.counts[r]))
        for j, p in enumerate(cfg.network.spec.network_populations):
            n_spikes = hist[pops.slice(p)].sum()
            assert n_spikes == pytest.approx(float(t0.rates_hz[r, j]) * TASK.test_duration_s * cfg.network.size(p),
                                             rel=1e-5)
        assert hist.sum() > 100                           # the network fired: the comparison has content
    # the recorded arm is the test's own (rows 1.. of the trajectory: the state after each interval)
    np.testing.assert_array_equal(np.asarray(t1.record.hand_m), np.asarray(t0.hand_m)[:, 1:])
    np.testing.assert_array_equal(np.asarray(win.u).shape, (2, 10, 4))


def test_overflow_and_memory_bounds_fail_naming_the_option(tmp_path):
    """A buffer too small for the spikes fails after the run with the capacity and the option to raise; buffers
    above the memory limit are refused before anything runs; bad values name their field and range."""
    from jaxarm.run import Run

    cfg = LoopConfig(arm="simple", task=TaskConfig(epochs=1, epoch_duration_s=0.1, test_duration_s=0.1))
    mp = MetaParams.original()
    with pytest.raises(ConfigError, match=r"above --record-max-mb 0\.01"):
        Run(cfg, 2, 0, tmp_path, mp, record=rec_mod.RecordConfig(max_mb=0.01))
    with pytest.raises(ConfigError, match=r"--record-networks 2: the run has 2 networks"):
        Run(cfg, 2, 0, tmp_path, mp, record=rec_mod.RecordConfig(networks=(2,)))
    with pytest.raises(ConfigError, match=r"max_rate_hz = 0: must be in \(0, 10000\] Hz"):
        rec_mod.RecordConfig(max_rate_hz=0.0)
    with pytest.raises(ConfigError, match=r"--record-train-s 0.015: must be a multiple of 10 ms"):
        make_train(cfg, rec_mod.RecordConfig(train_last_s=0.015))
    # 0.5 Hz over 704 cells for 0.1 s: 36 spikes, far fewer than the network fires
    run = Run(cfg, 2, 0, tmp_path, mp, record=rec_mod.RecordConfig(max_rate_hz=0.5))
    assert run.record_capacity["test"] == 36
    assert run.record_memory["device_bytes"] == run.n_padded * 36 * rec_mod.BYTES_PER_SLOT
    with pytest.raises(RuntimeError, match=r"capacity of 36 slots .* raise --record-max-rate-hz"):
        run.test(run.naive())


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_train_and_test_commands_write_the_spike_file(tmp_path, capsys):
    """`jaxarm train --record-spikes` writes spikes.npz whose per-network spike lists equal the counts it saves,
    with the bound in results.json; `jaxarm test --record-networks 1` writes network 1 only."""
    from jaxarm.cli import main

    out = tmp_path / "run"
    assert main(["train", "--networks", "2", "--epochs", "2", "--epoch-s", "0.2", "--test-s", "0.2", "--out",
                 str(out), "--no-progress", "--record-spikes", "--record-train-s", "0.05", "--record-epochs",
                 "1"]) == 0
    res = json.loads((out / "results.json").read_text())["record"]
    assert res["windows"] == ["test", "naive_test", "epoch_1"] and res["files"] == ["spikes.npz"]
    assert res["capacity_spikes"]["test"] == 50 * 704 * 0.2
    f = recordfile.SpikeFile(out / "spikes.npz")
    assert f.windows == res["windows"] and len(f) == 2
    for w in f.windows:
        lo, hi = f.span_ms(w)
        for r in range(2):
            t_ms, cell = f.spikes(w, r)
            assert len(t_ms) == res["spikes"][w][r] == f.get(w, "counts")[r].sum()
            assert np.all((t_ms > lo) & (t_ms <= hi + 1e-9))
            np.testing.assert_array_equal(np.bincount(cell, minlength=f.n_all), f.get(w, "counts")[r])
    assert f.span_ms("epoch_1") == pytest.approx((150.0, 200.0))
    traj = np.load(out / "trajectories.npz")
    np.testing.assert_array_equal(f.get("test", "hand_m"), traj["hand"][:, 1:])
    # the same command again: the run is finished, nothing trains, the tests are re-recorded, and the training
    # window recorded by the first invocation stays in spikes.npz (it was dropped)
    assert main(["train", "--networks", "2", "--epochs", "2", "--epoch-s", "0.2", "--test-s", "0.2", "--out",
                 str(out), "--no-progress", "--record-spikes", "--record-train-s", "0.05", "--record-epochs",
                 "1"]) == 0
    assert "epoch(s) 1 finished before this invocation" in capsys.readouterr().err
    again = recordfile.SpikeFile(out / "spikes.npz")
    assert again.windows == f.windows
    assert json.loads((out / "results.json").read_text())["record"]["spikes"] == res["spikes"]
    for key in f.data:
        np.testing.assert_array_equal(again.data[key], f.data[key], err_msg=key)
    assert main(["test", "--from", str(out), "--test-s", "0.2", "--out", str(tmp_path / "t1"), "--record-spikes",
                 "--record-networks", "1"]) == 0
    g = recordfile.SpikeFile(tmp_path / "t1" / "spikes.npz")
    assert g.data["networks"].tolist() == [1] and g.seeds.tolist() == [f.seeds[1]]
    np.testing.assert_array_equal(g.spikes("test", 0)[1], f.spikes("test", 1)[1])   # the same networks, re-tested
    with pytest.raises(SystemExit):
        main(["test", "--from", str(out), "--record-networks", "1"])
    assert "--record-networks/--record-epochs need --record-spikes" in capsys.readouterr().err
