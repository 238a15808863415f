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
from jaxarm.task.centre_out import CENTRE_OUT_8, CentreOut, make_centre_out_train, with_target_code
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
                 "--test-s", "0.2", "--out", str(out)]) == 0
    r = json.loads((out / "results.json").read_text())
    assert r["targets"] == list(CENTRE_OUT_8) and len(r["trained"]["success"]) == 2
    assert sum(r["trained"]["targets_reached_per_network"]) == 2
    spec = r["config"]["loop"]["network"]["spec"]
    assert [p["name"] for p in spec["populations"]][-2:] == ["P", "T"]       # the target code was added
    hand = np.load(out / "trajectories.npz")["hand"]
    assert hand.shape == (2, 8, 21, 2)
    with pytest.raises(SystemExit):
        main(["train", "--task", "centre-out-8", "--learning", "gradient", "--out", str(tmp_path / "g")])
