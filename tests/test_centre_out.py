"""Centre-out reaching to several targets from one network (jaxarm.task.centre_out): the eight targets, epochs
cycling over the targets, tests on every target, and the target code changing what the network does."""
import math

import jax
import numpy as np
import pytest

from jaxarm.config import ConfigError
from jaxarm.config.network import NetworkConfig
from jaxarm.config.spec import NetworkSpec
from jaxarm.learning.metaparams import MetaParams
from jaxarm.loop import LoopConfig
from jaxarm.run_centre_out import make_centre_out_train
from jaxarm.task.centre_out import CENTRE_OUT_8, CentreOut, ensure_target_code, with_target_code
from jaxarm.task.config import TARGET_ANGLES_RAD, forward_kinematics_m

TINY = dict(epochs_per_target=1, epoch_duration_s=0.2, test_duration_s=0.2)


def test_the_eight_targets_lie_15_cm_away_every_45_degrees():
    task = CentreOut()
    x0, y0 = task.task_config().start_xy_m
    for k, name in enumerate(CENTRE_OUT_8):
        x, y = forward_kinematics_m(TARGET_ANGLES_RAD[name])       # the original's joint angles, FK by hand below
        assert math.hypot(x - x0, y - y0) == pytest.approx(0.151, abs=0.001)
        assert (math.degrees(math.atan2(y - y0, x - x0)) - 45 * k + 180) % 360 - 180 == pytest.approx(0, abs=0.1)
    assert task.task_config().epochs == 24
    with pytest.raises(ConfigError, match="CentreOut.targets"):
        CentreOut(targets=("left", "nowhere"))
    paper = NetworkSpec.dura_bernal_2015()
    coded = with_target_code(paper, task)
    assert coded.without_population("T") == paper                     # removing the code gives the paper's back
    assert ensure_target_code(coded, task) is coded and ensure_target_code(paper, task) == coded
    with pytest.raises(ConfigError, match=r"target 0 \(left\) lies at 180.0 degrees"):
        with_target_code(NetworkSpec.dura_bernal_2015(), CentreOut(targets=("left", "right")))


@pytest.mark.slow   # compiles a training scan and an epoch: the default suite's 8-minute budget
def test_training_cycles_the_targets_epoch_by_epoch():
    """The scanned training equals epochs run by hand toward left, right, left, right (the target code's direction
    groups 0 = right at 0 degrees, 1 = left at 180)."""
    task = CentreOut(targets=("right", "left"), epochs_per_target=2, epoch_duration_s=0.2, test_duration_s=0.2)
    spec = with_target_code(NetworkSpec.dura_bernal_2015(), task, cells_per_target=4)
    fns = make_centre_out_train(LoopConfig(network=NetworkConfig(spec=spec, kernel="xla"), task=task.task_config()),
                                task)
    key, mp = jax.random.PRNGKey(5), MetaParams.original()
    trained, history = jax.jit(fns.train)(key, mp)
    carry = fns.fns.init(key)
    targets = task.stacked_targets()
    epoch = jax.jit(fns.fns.epoch)
    for e in range(4):
        carry, summary = epoch(carry, mp, jax.tree.map(lambda a, e=e: a[e % 2], targets))
        np.testing.assert_array_equal(np.asarray(summary.final_distance_m), np.asarray(history.final_distance_m)[e])
    np.testing.assert_array_equal(np.asarray(carry.trained.wgain), np.asarray(trained.wgain))


@pytest.mark.slow
def test_the_target_code_changes_the_reach_and_the_control_does_not():
    task = CentreOut(**TINY)
    mp = MetaParams.original()
    key = jax.random.PRNGKey(1)
    hands = {}
    for name, spec in (("control", NetworkSpec.dura_bernal_2015()),
                       ("code", with_target_code(NetworkSpec.dura_bernal_2015(), task))):
        fns = make_centre_out_train(LoopConfig(network=NetworkConfig(spec=spec), task=task.task_config()), task)
        trained = fns.fns.init(key).trained
        res = jax.jit(fns.test)(key, trained, mp)
        hand = np.asarray(res.hand_m)                                        # (8 targets, samples, 2)
        xy = np.asarray(task.stacked_targets().xy_m)
        np.testing.assert_allclose(np.asarray(res.distance_m), np.linalg.norm(hand - xy[:, None], axis=-1),
                                   rtol=1e-6)
        hands[name] = hand
    # without a target code the test does not depend on the target (no learning in the test)
    assert all(np.array_equal(hands["control"][0], h) for h in hands["control"][1:])
    # with it, the eight tests differ (a different group of target cells drives the motor cells each time)
    assert sum(not np.array_equal(hands["code"][0], h) for h in hands["code"][1:]) >= 6


@pytest.mark.slow
def test_the_command_line_trains_and_tests_the_eight_targets(tmp_path):
    import json

    from jaxarm.cli import main

    out = tmp_path / "co"
    assert main(["train", "--task", "centre-out-8", "--networks", "2", "--epochs", "1", "--epoch-s", "0.2",
                 "--test-s", "0.2", "--test-each-epoch", "--out", str(out)]) == 0
    r = json.loads((out / "results.json").read_text())
    curve = r["learning_curve"]            # every network tested on every target after every epoch
    assert curve["epochs"] == list(range(1, 9)) and len(curve["success_count"]) == 8
    assert np.shape(curve["criterion_s"]) == (2, 8) and np.shape(curve["fresh_noise_criterion_s"]) == (2, 8)
    assert r["targets"] == list(CENTRE_OUT_8) and len(r["trained"]["success"]) == 2
    assert sum(r["trained"]["targets_reached_per_network"]) == 2
    spec = r["config"]["loop"]["network"]["spec"]
    assert [p["name"] for p in spec["populations"]][-2:] == ["P", "T"]       # the target code was added
    hand = np.load(out / "trajectories.npz")["hand"]
    assert hand.shape == (2, 8, 21, 2)
    assert (out / "checkpoints" / "8").is_dir()            # the runner's checkpoint after every epoch
    # `jaxarm test --from` rebuilds the task from the checkpoint's description: the same test, the same results
    assert main(["test", "--from", str(out), "--test-s", "0.2"]) == 0
    again = json.loads((out / "test" / "results.json").read_text())
    assert again["trained"] == r["trained"] and again["naive"] == r["naive"]
    # recorded: one window per target and test; the recording changes no result, and window test_T holds the test
    # on target T (its joint angles, through the planar kinematics by hand, give that target's hand path)
    assert main(["test", "--from", str(out), "--test-s", "0.2", "--record-spikes", "--out", str(out / "rec")]) == 0
    rec = json.loads((out / "rec" / "results.json").read_text())
    assert rec["trained"] == r["trained"] and rec["naive"] == r["naive"]
    assert rec["record"]["windows"] == [f"{w}_{t}" for w in ("test", "naive_test") for t in CENTRE_OUT_8]
    spikes, traj = np.load(out / "rec" / "spikes.npz"), np.load(out / "rec" / "trajectories.npz")
    for window, key in (("test", "hand"), ("naive_test", "naive_hand")):
        for k, target in enumerate(CENTRE_OUT_8):
            q = spikes[f"{window}_{target}.q_rad"]                  # (networks, samples, 2) after each 10 ms
            hand = np.array([[forward_kinematics_m(x) for x in net] for net in q])
            np.testing.assert_allclose(hand, traj[key][:, k, 1:], atol=1e-6)
            assert spikes[f"{window}_{target}.counts"].sum() > 0
    # `jaxarm figures` draws the raster and rates of a target's test (default: the first target's) and says why it
    # skips the reaching figures
    assert main(["figures", str(out / "rec"), "--out", str(tmp_path / "fig")]) == 0
    manifest = json.loads((tmp_path / "fig" / "figures.json").read_text())
    assert manifest["window"] == f"test_{CENTRE_OUT_8[0]}" and set(manifest["written"]) == {"raster", "rates"}
    assert "centre-out" in manifest["skipped"]["reach_paths"]
    drawn = np.load(tmp_path / "fig" / "raster.npz")
    assert len(drawn["t_ms"]) == spikes[f"test_{CENTRE_OUT_8[0]}.counts"][0].sum()
    # the target code's cells are drawn by direction group (cell k in group k % 8, as the network assigns them), so
    # the group that fires in a target's test is one block of rows, and only that group fires
    from jaxarm.recordfile import SpikeFile
    from jaxarm.viz.figures import cell_layout

    f = SpikeFile(out / "rec" / "spikes.npz")
    lo, hi = f.pop_start["T"], f.pop_stop["T"]
    assert f.target_group[lo:hi].tolist() == [k % 8 for k in range(hi - lo)]
    row = cell_layout(f)[0]
    for k, target in enumerate(CENTRE_OUT_8):
        rows = np.sort(row[lo:hi][f.target_group[lo:hi] == k])
        assert np.all(np.diff(rows) == 1)
        fired = f.get(f"test_{target}", "counts")[0][lo:hi] > 0
        assert set(f.target_group[lo:hi][fired].tolist()) == {k}


@pytest.mark.slow   # compiles a centre-out training and test for two batch sizes
def test_networks_train_to_the_same_bits_in_a_batch_of_three_and_of_ten():
    """The batch runs through jaxarm.parallel.sharded_map (one network at a time on every device, padded): keys 0-2
    trained as a batch of 3 and as the first 3 of 10 give the same test paths and successes (a plain vmap over 3
    and over 10 networks compiles different code, which may round differently in the last bit)."""
    from jaxarm.run_centre_out import train_and_test

    task = CentreOut(targets=("right", "left"), epochs_per_target=1, epoch_duration_s=1.0, test_duration_s=0.2)
    spec = with_target_code(NetworkSpec.dura_bernal_2015(), task, cells_per_target=4)
    config = LoopConfig(arm="simple", network=NetworkConfig(spec=spec), task=task.task_config())
    few = train_and_test(config, task, [0, 1, 2], MetaParams.original())
    many = train_and_test(config, task, list(range(10)), MetaParams.original())
    for name in ("trained", "naive"):
        np.testing.assert_array_equal(few[name]["hand_m"], many[name]["hand_m"][:3])
        assert few[name]["success"] == many[name]["success"][:3]
    assert np.asarray(many["trained"]["hand_m"]).shape == (10, 2, 21, 2)


@pytest.mark.slow   # two conditions compiled
def test_reproduce_runs_the_task_with_its_control_and_resumes(tmp_path, capsys):
    """``jaxarm reproduce --task centre-out-8``: both conditions, the control without the target code; the table's
    counts are the per-network successes summed; a rerun finds both conditions done and trains nothing."""
    import json

    from jaxarm.cli import main

    out = tmp_path / "co"
    argv = ["reproduce", "--task", "centre-out-8", "--arm", "simple", "--networks", "2", "--epochs", "1",
            "--epoch-s", "0.2", "--test-s", "0.2", "--out", str(out)]
    assert main(argv) == 0
    r = json.loads((out / "centre_out.json").read_text())
    assert set(r["conditions"]) == {"target-code", "control"}
    co, ctl = r["conditions"]["target-code"], r["conditions"]["control"]
    assert co["populations"][-2:] == ["P", "T"] and ctl["populations"][-1] == "P" and "T" not in ctl["populations"]
    table = (out / "centre_out.md").read_text()
    for k, t in enumerate(CENTRE_OUT_8):
        n = sum(row[k] for row in co["trained"]["success"])
        assert f"| {t} ({co['directions_deg'][k]:g} deg) | {n}/2 " in table
    capsys.readouterr()
    assert main(argv) == 0
    said = capsys.readouterr().out
    assert "target-code: already in" in said and "control: already in" in said
    assert main(["reproduce", "--task", "centre-out-8", "--arm", "simple", "--targets", "left", "--out",
                 str(out)]) == 2


def test_the_centre_out_search_protocol_and_the_command_line_task():
    """``jaxarm evolve --task centre-out-8``: the eight targets and the centre-out fitness unless given; a reaching
    fitness with the task is refused; the protocol splits ``--train-s`` into epochs per target (by hand)."""
    import argparse

    from jaxarm.evolve.cli import _apply_task
    from jaxarm.evolve.reaching import _centre_out_task

    a = argparse.Namespace(task="centre-out-8", targets=None, fitness=None)
    _apply_task(a)
    assert (a.targets.split(","), a.fitness) == (list(CENTRE_OUT_8), "centre-out")
    a = argparse.Namespace(task="reaching", targets=None, fitness=None)
    _apply_task(a)
    assert (a.targets, a.fitness) == ("left,bottom", "reaching")
    with pytest.raises(ConfigError, match="--fitness reaching does not score --task centre-out-8"):
        _apply_task(argparse.Namespace(task="centre-out-8", targets=None, fitness="reaching"))
    t = _centre_out_task(CENTRE_OUT_8, 720.0)                  # 720 s / 8 targets = 3 epochs of 30 s each
    assert (t.epochs_per_target, t.epoch_duration_s) == (3, 30.0)
    t = _centre_out_task(CENTRE_OUT_8, 120.0)                  # under 30 s per target: one shorter epoch each
    assert (t.epochs_per_target, t.epoch_duration_s) == (1, 15.0)


@pytest.mark.slow   # compiles a centre-out training and test
def test_the_centre_out_fitness_is_the_mean_shortfall_of_one_trained_network():
    """The fitness equals the 2 cm shortfall, computed here with numpy from the test's distance traces of the same
    network trained with the task's functions, averaged over the targets; its success rate is the fraction entered."""
    from jaxarm.evolve import fitness
    from jaxarm.evolve.reaching import _centre_out_task

    targets = ("right", "top", "left", "bottom")
    f = fitness.build("centre-out", fitness.FitnessOptions(arm="simple", targets=targets, train_s=0.8))
    assert f.epochs == 1   # per target, as `jaxarm train --task centre-out-8 --epochs` counts them
    mp = MetaParams.original()
    key = jax.random.PRNGKey(5)
    value, metrics = jax.jit(f.fn)(key, mp)
    task = _centre_out_task(targets, 0.8)
    spec = with_target_code(NetworkSpec.dura_bernal_2015(), task)
    fns = make_centre_out_train(LoopConfig(arm="simple", network=NetworkConfig(spec=spec), task=task.task_config()),
                                task)
    k_train, k_test = jax.random.split(key)
    res = jax.jit(lambda: fns.test(k_test, fns.train(k_train, mp)[0], mp))()
    closest = np.asarray(res.distance_m).min(axis=1)
    assert closest.shape == (4,)
    assert float(value) == pytest.approx(np.maximum(closest - 0.02, 0.0).mean(), abs=1e-6)
    assert float(metrics["success_rate"]) == pytest.approx((closest <= 0.04).mean())
    assert f.network_seconds_per_eval == pytest.approx(0.8 + 4 * 1.0)


# ------------------------------------------------------------------ the target code's metaparameters (traced)
def _code_spec(task, weight_mv=2.0, pmat=0.2, rate_hz=100.0):
    return with_target_code(NetworkSpec.dura_bernal_2015(), task, weight_mv=weight_mv, pmat=pmat, rate_hz=rate_hz)


def test_code_weight_and_density_scales_give_the_spec_at_that_weight_and_density():
    """The reference is the spec itself: a code at 2 mV scaled by 2 has exactly the synapses of a code at 4 mV, and
    a density scale of 1/2 keeps, in every EM cell, exactly the partners the wiring of a code at half the density
    draws from the same key (14 of 64 at pmat 0.2 -> 7 at 0.1); the rest deliver nothing. At both scales 1 the wiring
    is unchanged."""
    from jaxarm.network.network import Network
    from jaxarm.network.wiring import WiringLayout

    task = CentreOut()
    key = jax.random.PRNGKey(3)
    net = Network(NetworkConfig(spec=_code_spec(task)))
    wiring = net.make_wiring(key)
    block = WiringLayout(net.config).synapses("T->EM")

    same = net.target_code_wiring(wiring, 1.0, 1.0)
    for a, b in zip(jax.tree.leaves(same), jax.tree.leaves(wiring)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))

    heavy = Network(NetworkConfig(spec=_code_spec(task, weight_mv=4.0))).make_wiring(key)
    doubled = net.target_code_wiring(wiring, 2.0, 1.0)
    np.testing.assert_array_equal(np.asarray(doubled.weight), np.asarray(heavy.weight))
    np.testing.assert_array_equal(np.asarray(doubled.nmda), np.asarray(heavy.nmda))
    assert np.asarray(doubled.weight[block]).min() == 4.0

    sparse_net = Network(NetworkConfig(spec=_code_spec(task, pmat=0.1)))
    sparse = sparse_net.make_wiring(key)
    k, k_half = WiringLayout(net.config).in_degree["T->EM"], WiringLayout(sparse_net.config).in_degree["T->EM"]
    assert (k, k_half) == (14, 7)                           # pmat x pmat_scale x 64 T cells, rounded
    halved = net.target_code_wiring(wiring, 1.0, 0.5)
    n_em = net.config.size("EM")
    pre = np.asarray(wiring.pre[block]).reshape(n_em, k)
    w = np.asarray(halved.weight[block]).reshape(n_em, k)
    sparse_block = WiringLayout(sparse_net.config).synapses("T->EM")
    np.testing.assert_array_equal(pre[:, :k_half], np.asarray(sparse.pre[sparse_block]).reshape(n_em, k_half))
    assert (w[:, :k_half] == 2.0).all() and (w[:, k_half:] == 0.0).all()
    assert (np.asarray(halved.nmda[block]).reshape(n_em, k)[:, k_half:] == 0.0).all()
    other = np.ones(wiring.weight.shape[0], bool)
    other[block] = False                                  # nothing outside the code's pathway changes
    np.testing.assert_array_equal(np.asarray(halved.weight)[other], np.asarray(wiring.weight)[other])


def test_code_rate_scale_gives_the_spec_at_that_rate():
    """A code at 100 Hz scaled by 0.5 fires the intervals of a code at 50 Hz (80 steps of 0.25 ms); scale 1, traced,
    the spec's own; the silent groups stay silent."""
    from jaxarm.network import proprio

    task = CentreOut()
    fast, slow = NetworkConfig(spec=_code_spec(task)), NetworkConfig(spec=_code_spec(task, rate_hz=50.0))
    direction = jax.numpy.float32(math.pi)                   # left: direction group 4
    for scale, reference in ((0.5, slow), (1.0, fast)):
        got = jax.jit(lambda s: proprio.set_target(fast, proprio.init_p(fast), direction, 40, s))(
            jax.numpy.float32(scale))
        want = proprio.set_target(reference, proprio.init_p(reference), direction, 40)
        np.testing.assert_array_equal(np.asarray(got.interval_steps), np.asarray(want.interval_steps))
        np.testing.assert_array_equal(np.asarray(got.next_step), np.asarray(want.next_step))
    intervals = np.asarray(proprio.set_target(fast, proprio.init_p(fast), direction, 40, 0.5).interval_steps)
    assert sorted(set(intervals[-64:].tolist())) == [80, proprio.NEVER_STEPS]
    assert (intervals[-64:] == 80).sum() == 8                # the 8 cells of the left group
    clipped = [np.asarray(proprio.set_target(fast, proprio.init_p(fast), direction, 40, s).interval_steps)
               for s in (3.0, proprio.MAX_CODE_RATE_SCALE)]  # above the bound the P window would drop spikes
    np.testing.assert_array_equal(clipped[0], clipped[1])
    assert sorted(set(clipped[0][-64:].tolist())) == [20, proprio.NEVER_STEPS]     # 200 Hz: 5 ms


def test_summary_and_table_count_the_held_out_tests_and_the_median_network():
    """summary() on hand-made test results (3 networks, 8 targets): counts per target, targets reached per network
    and their median, for the trained, naive and held-out tests; the table shows the held-out column first."""
    from types import SimpleNamespace

    from jaxarm.run_centre_out import summary, table_markdown

    task, spec = CentreOut(), with_target_code(NetworkSpec.dura_bernal_2015(), CentreOut())
    n_pop = len(spec.network_populations)
    history = SimpleNamespace(rates_last10s_hz=np.zeros((2, 3, n_pop)), mean_wgain=np.ones((2, 3, len(spec.pathways))),
                              rewards=np.zeros((2, 3)), punishments=np.zeros((2, 3)),
                              min_distance_m=np.full((2, 3), 0.1), lost_spikes=np.zeros((2, 3), int))

    start = np.asarray(task.task_config().start_xy_m)
    goal = np.asarray(task.stacked_targets().xy_m) - start                       # (8, 2), 15.1 cm each

    def result(success, turn_deg=0.0):
        """Every hand moves from the start half-way to its target, its path turned by ``turn_deg``."""
        success = np.asarray(success, bool)
        c, s_ = np.cos(np.radians(turn_deg)), np.sin(np.radians(turn_deg))
        step = 0.5 * goal @ np.array([[c, s_], [-s_, c]])
        hand = np.broadcast_to(np.stack([start + 0 * step, start + step], axis=1), (3, 8, 2, 2))
        return SimpleNamespace(success=success, rates_hz=np.zeros((3, 8, n_pop)), lost_spikes=np.zeros((3, 8), int),
                               min_distance_m=np.where(success, 0.03, 0.1), hand_m=hand,
                               distance_m=np.linalg.norm(hand - (start + goal)[:, None], axis=-1))

    trained = [[1] * 8, [1] * 6 + [0] * 2, [1, 0, 0, 0, 0, 0, 0, 0]]           # 8, 6 and 1 targets
    held_out = [[1] * 7 + [0], [0] * 8, [1, 1, 0, 0, 0, 0, 0, 0]]              # 7, 0 and 2 targets
    r = summary(task, spec, [0, 1, 2], history, result(trained), result(np.zeros((3, 8))), result(held_out, 45.0))
    assert r["trained"]["median_travel_cm"]["top"] == pytest.approx(7.55, abs=0.01)     # half of 15.1 cm
    assert r["trained"]["median_direction_error_deg"]["top"] == 0.0
    assert r["held_out"]["median_direction_error_deg"]["left"] == pytest.approx(45.0)
    assert r["trained"]["median_targets_reached"] == 6 and r["held_out"]["median_targets_reached"] == 2
    assert r["naive"]["median_targets_reached"] == 0
    assert r["held_out"]["per_target"]["right"] == 2 and r["held_out"]["per_target"]["left-bottom"] == 0
    assert r["trained"]["targets_reached_per_network"] == [0, 1, 0, 0, 0, 0, 1, 0, 1]
    for k in ("trained", "naive", "held_out"):
        r[k].pop("hand_m")
    table = table_markdown({"conditions": {"target-code": {"condition": "target-code", **r}}})
    assert table.splitlines()[0] == ("| target (direction) | target-code: held-out noise | target-code: trained (naive) "
                                     "| target-code: median closest approach, cm, trained (naive) | target-code: median "
                                     "travel, cm, and direction error, deg, at the closest approach, trained |")
    assert table.splitlines()[2] == "| right (0 deg) | 2/3 | 3/3 (0/3) | 3.0 (10.0) | 7.6, 0 |"
    assert "target-code, held-out: networks by number of targets reached (0..8): [1, 0, 1, 0, 0, 0, 0, 1, 0]; " \
           "median 2 of 8 per network" in table
