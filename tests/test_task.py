"""Reaching task: targets from the authors' FK, start posture, success criterion, config validation."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.arm.base import hand_position
from jaxarm.config.validate import ConfigError
from jaxarm.task import (REACHING_TARGETS, TARGET_ANGLES_RAD, TaskConfig, first_entry_index, hand_target_distance,
                         reached, start_position, target_position, target_positions)


def test_paper_targets_match_spec_positions_and_distance():
    # spec §6: left (-0.0536, 0.3809) m, bottom (0.0976, 0.2296) m, start (0.0976, 0.3809) m, both 15.1 cm away.
    np.testing.assert_allclose(target_position("left"), [-0.0536, 0.3809], atol=1e-4)
    np.testing.assert_allclose(target_position("bottom"), [0.0976, 0.2296], atol=1e-4)
    np.testing.assert_allclose(start_position(), [0.0976, 0.3809], atol=1e-4)
    for name in REACHING_TARGETS:
        assert np.linalg.norm(target_position(name) - start_position()) == pytest.approx(0.1512, abs=5e-4)


def test_targets_agree_with_traced_forward_kinematics():
    for name, q in TARGET_ANGLES_RAD.items():
        np.testing.assert_allclose(target_position(name), np.asarray(hand_position(jnp.asarray(q))), atol=1e-6)
    assert target_positions(REACHING_TARGETS).shape == (2, 2)
    with pytest.raises(ConfigError, match="target"):
        target_position("middle")


def test_task_config_defaults_and_derived_values():
    cfg = TaskConfig()
    assert cfg.target == "left" and cfg.start_posture_rad == (0.62, 1.53)
    assert cfg.success_radius_m == 0.04 and cfg.test_duration_s == 1.0
    assert cfg.epochs == 12 and cfg.epoch_duration_s == 30.0 and cfg.training_s == 360.0
    assert cfg.test_steps == 100 and cfg.epoch_steps == 3000
    np.testing.assert_allclose(cfg.target_xy_m, target_position("left"), atol=1e-6)
    np.testing.assert_allclose(TaskConfig(target="bottom").target_xy_m, target_position("bottom"), atol=1e-6)
    hash(cfg)  # static config must be hashable


@pytest.mark.parametrize("kwargs, field", [
    ({"target": "middle"}, "target"),
    ({"success_radius_m": 0.0}, "success_radius_m"),
    ({"success_radius_m": 1.0}, "success_radius_m"),
    ({"test_duration_s": -1.0}, "test_duration_s"),
    ({"test_duration_s": 1.005}, "test_duration_s"),
    ({"epochs": 12.5}, "epochs"),
    ({"epochs": -1}, "epochs"),
    ({"epoch_duration_s": 0.0}, "epoch_duration_s"),
    ({"start_posture_rad": (0.62, 3.0)}, "start_posture_rad"),
    ({"start_posture_rad": (0.62,)}, "start_posture_rad"),
    ({"segments_m": (0.29, -0.25)}, "segments_m"),
])
def test_task_config_validation_names_field_and_range(kwargs, field):
    with pytest.raises(ConfigError) as err:
        TaskConfig(**kwargs)
    msg = str(err.value)
    assert f"TaskConfig.{field}" in msg
    assert any(word in msg for word in ("[", "(", "one of", "whole number"))  # states the allowed range/choices


def test_success_is_entering_the_circle():
    target = jnp.asarray([0.0, 0.0])
    # hand passes at 3.9 cm from the target (success) vs 4.1 cm (failure); T = 101 samples
    t = jnp.linspace(-1.0, 1.0, 101)
    for offset, expected in ((0.039, True), (0.041, False)):
        path = jnp.stack([t * 0.2, jnp.full_like(t, offset)], axis=-1)
        d = hand_target_distance(path, target)
        assert bool(reached(d, 0.04)) is expected
        # inside once |x| <= sqrt(0.04² - 0.039²) = 8.9 mm; x steps 4 mm, so first at x = -8 mm, sample 48
        assert int(first_entry_index(d, 0.04)) == (48 if expected else -1)
    # a valid mask can exclude samples (padded trajectories)
    path = jnp.stack([t * 0.2, jnp.full_like(t, 0.039)], axis=-1)
    d = hand_target_distance(path, target)
    assert not bool(reached(d, 0.04, valid=jnp.arange(101) < 48))
    assert bool(reached(d, 0.04, valid=jnp.arange(101) < 49))


def test_success_vmaps_over_targets_and_trajectories():
    targets = jnp.asarray(target_positions(REACHING_TARGETS))
    paths = jnp.stack([jnp.linspace(start_position(), targets[0], 11), jnp.full((11, 2), start_position())])
    d = jax.vmap(lambda p: jax.vmap(lambda tg: hand_target_distance(p, tg))(targets))(paths)  # (path, target, T)
    ok = jax.jit(reached)(d)
    np.testing.assert_array_equal(np.asarray(ok), [[True, False], [False, False]])
