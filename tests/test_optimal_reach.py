"""Optimal-control reference reaches: the optimiser reaches the target, and its excitations do so on the arm as
published too (an independent rollout, not the optimiser's own)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import make_arm
from jaxarm.config.validate import ConfigError
from jaxarm.control.optimal_reach import OptimalReachConfig, optimal_reach
from jaxarm.task.config import Target


def test_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="OptimalReachConfig.cost"):
        OptimalReachConfig(cost="fastest")
    with pytest.raises(ConfigError, match="OptimalReachConfig.hold_s"):
        OptimalReachConfig(duration_s=0.5, hold_s=0.6)
    with pytest.raises(ConfigError, match="OptimalReachConfig.initial_excitation"):
        OptimalReachConfig(initial_excitation=1.0)


@pytest.mark.slow
def test_min_effort_reach_ends_at_rest_on_the_target_on_both_arm_formulations():
    xy = Target.named("left").xy_m
    r = optimal_reach(xy, OptimalReachConfig(duration_s=0.6, hold_s=0.2, iterations=80))
    assert r.loss[-1] < r.loss[0] / 100
    start = np.linalg.norm(r.hand_m[0] - xy)
    assert start > 0.14                                   # a 15 cm reach
    assert np.linalg.norm(r.hand_m[-1] - xy) < 0.01
    # The same excitations through the default (piecewise) arm, stepped here: the smooth arm's reach is the
    # published arm's reach to within the smooth formulation's width.
    arm = make_arm("musculoskeletal")

    def body(s, u):
        s = arm.step(s, u)
        return s, arm.observe(s).hand
    hand = np.asarray(jax.lax.scan(body, arm.init(), jnp.asarray(r.excitations))[1])
    assert np.linalg.norm(hand[-1] - xy) < 0.015
    assert np.abs(hand - r.hand_m).max() < 0.01
    # Coming to rest: over the hold the speed falls to a small fraction of its peak (80 iterations do not
    # converge fully; experiments/optimal_reach.py runs 300).
    speed = np.linalg.norm(np.diff(hand, axis=0), axis=-1) / r.dt_s
    assert speed[-20:].mean() < 0.05 * speed.max()
