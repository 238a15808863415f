"""The authors' simple kinematic arm (spec §8)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import make_arm
from jaxarm.config import ConfigError, SimpleArmConfig


def test_start_posture_lengths_and_hand_match_spec():
    arm = make_arm("simple")
    obs = arm.observe(arm.init())
    np.testing.assert_allclose(obs.proprio, [0.1059, 0.1541, 0.1552, 0.1048], atol=1e-4)  # spec §8
    np.testing.assert_allclose(obs.hand, [0.0976, 0.3809], atol=1e-4)                  # spec §6


@pytest.mark.parametrize("group, joint, sign", [(0, 0, -1), (1, 0, +1), (2, 1, -1), (3, 1, +1)])
def test_each_group_moves_its_joint(group, joint, sign):
    arm = make_arm("simple")
    s = arm.step(arm.init(), jnp.eye(4)[group])
    dq = np.asarray(arm.observe(s).q - arm.observe(arm.init()).q)
    assert dq[joint] == pytest.approx(sign * 0.04, abs=1e-6)
    assert dq[1 - joint] == 0.0


def _push(arm, u, n):
    step = jax.jit(arm.step)
    s = arm.init()
    for _ in range(n):
        s = step(s, u)
    return s


def test_windup_quirk_is_the_default_and_optional():
    push_up = jnp.array([0.0, 1.0, 0.0, 0.0])
    push_down = jnp.array([1.0, 0.0, 0.0, 0.0])
    faithful, clamped = make_arm("simple"), make_arm("simple", config=SimpleArmConfig(windup=False))
    for arm in (faithful, clamped):
        s = _push(arm, push_up, 60)  # 60 x 0.04 rad drives far past 110 deg
        assert float(arm.observe(s).q[0]) == pytest.approx(np.radians(110), abs=1e-5)
    # one step back: the clamped arm leaves the limit at once, the wound-up one does not
    s_f = faithful.step(_push(faithful, push_up, 60), push_down)
    s_c = clamped.step(_push(clamped, push_up, 60), push_down)
    assert float(faithful.observe(s_f).q[0]) == pytest.approx(np.radians(110), abs=1e-5)
    assert float(clamped.observe(s_c).q[0]) < np.radians(110) - 0.03


def test_vmap_equals_single_steps():
    arm = make_arm("simple")
    u = jax.random.uniform(jax.random.PRNGKey(0), (256, 4))
    states = jax.vmap(arm.init)(jnp.tile(jnp.array([0.62, 1.53]), (256, 1)))
    out = jax.jit(jax.vmap(arm.step))(states, u)
    assert out.q_acc.shape == (256, 2)
    for i in (0, 17, 255):   # determinism across processes and thread counts: tests/test_determinism.py
        one = arm.step(jax.tree.map(lambda a: a[i], states), u[i])
        np.testing.assert_array_equal(out.q_acc[i], one.q_acc)


@pytest.mark.parametrize("kwargs, field", [({"gain_rad": 0.0}, "gain_rad"), ({"windup": "yes"}, "windup"),
                                           ({"elbow_range_deg": (10, 5)}, "elbow_range_deg")])
def test_config_errors_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        SimpleArmConfig(**kwargs)


def test_make_arm_rejects_unknown_kind():
    with pytest.raises(ConfigError, match="kind"):
        make_arm("robotic")
