"""The musculoskeletal arm: anatomy, rest, limits, backends against each other, vmap and gradients."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import make_arm
from jaxarm.arm.musculoskeletal import GROUP_MUSCLES


@pytest.fixture(scope="module")
def fast():
    return make_arm("musculoskeletal", backend="fast")


@pytest.fixture(scope="module")
def mjx_arm():
    return make_arm("musculoskeletal", backend="mjx")


def rollout(arm, us):
    """us: (T, 4) excitations held for one step each. Returns q (T, 2) and proprio (T, 4)."""
    def body(s, u):
        s = arm.step(s, u)
        obs = arm.observe(s)
        return s, (obs.q, obs.muscles.mtu_length_m)

    return jax.lax.scan(body, arm.init(), us)[1]


def random_excitations(key, seconds=1.0, hold_ms=10, dt_ms=1):
    """Piecewise-constant excitations in [0, 1], changing every ``hold_ms`` like the network's readout."""
    n = int(seconds * 1000 / hold_ms)
    u = jax.random.uniform(key, (n, 4))
    return jnp.repeat(u, hold_ms // dt_ms, axis=0)


def test_names_and_shapes(fast):
    assert len(fast.muscle_names) == 22
    q = jnp.array([0.62, 1.53])
    assert fast.mtu_lengths(q).shape == (22,)
    assert fast.moment_arms(q).shape == (22, 2)
    obs = fast.observe(fast.init())
    assert obs.proprio.shape == (4,) and obs.muscles.force_n.shape == (22,)
    np.testing.assert_allclose(obs.hand, [0.0976, 0.3809], atol=2e-4)


@pytest.mark.parametrize("group, joint, sign", [(0, 0, -1), (1, 0, +1), (2, 1, -1), (3, 1, +1)])
def test_each_group_moves_its_joint_the_right_way(fast, group, joint, sign):
    us = jnp.tile(0.5 * jnp.eye(4)[group], (200, 1))
    q, _ = jax.jit(lambda u: rollout(fast, u))(us)
    dq = np.asarray(q[-1] - q[0])
    assert sign * dq[joint] > np.radians(2), (group, np.degrees(dq))


def test_moment_arm_signs_match_anatomy(fast):
    idx = {n: i for i, n in enumerate(fast.muscle_names)}
    r = np.asarray(fast.moment_arms(jnp.array([0.62, 1.53])))
    for name in ("BIClong", "BICshort", "BRA"):
        assert r[idx[name], 1] > 0, name        # elbow flexors
    for name in ("TRIlong", "TRIlat", "TRImed"):
        assert r[idx[name], 1] < 0, name        # elbow extensors
    for name in ("PECM1", "DELT1", "Coracobrachialis"):
        assert r[idx[name], 0] > 0, name        # shoulder flexors
    for name in ("DELT3", "Infraspinatus", "Teres_minor"):
        assert r[idx[name], 0] < 0, name        # shoulder extensors
    for group in GROUP_MUSCLES:
        assert all(n in idx for n in group)


def test_unexcited_arm_holds_its_start_posture(fast):
    q, _ = jax.jit(lambda u: rollout(fast, u))(jnp.zeros((2000, 4)))
    assert np.degrees(np.abs(np.asarray(q - q[0])).max()) < 0.5


def test_joint_limits_hold_under_maximal_excitation(fast):
    lo, hi = np.radians([-10, 0]), np.radians([110, 140])
    for drive in (jnp.array([0.0, 1.0, 0.0, 1.0]), jnp.array([1.0, 0.0, 1.0, 0.0])):
        q, _ = jax.jit(lambda u: rollout(fast, u))(jnp.tile(drive, (1500, 1)))
        q = np.asarray(q)
        assert np.all(np.isfinite(q))
        assert np.all(q >= lo - np.radians(6)) and np.all(q <= hi + np.radians(6)), np.degrees([q.min(0), q.max(0)])


def test_same_inputs_same_trajectory(fast):
    us = random_excitations(jax.random.PRNGKey(3), 0.3)
    f = jax.jit(lambda u: rollout(fast, u))
    np.testing.assert_array_equal(f(us)[0], f(us)[0])


def test_fast_path_matches_mjx(fast, mjx_arm):
    """Issue 2: muscle lengths within 1 mm and joint trajectories within 1 degree over 1 s of random excitation."""
    for seed in (0, 1):
        us = random_excitations(jax.random.PRNGKey(seed), 1.0)
        q_f, l_f = jax.jit(lambda u: rollout(fast, u))(us)
        q_m, l_m = jax.jit(lambda u: rollout(mjx_arm, u))(us)
        assert np.degrees(np.abs(np.asarray(q_f - q_m)).max()) < 1.0
        assert np.abs(np.asarray(l_f - l_m)).max() < 1e-3


def test_vmap_over_256_arms(fast):
    keys = jax.random.split(jax.random.PRNGKey(0), 256)
    us = jax.vmap(lambda k: random_excitations(k, 0.05))(keys)
    q, _ = jax.jit(jax.vmap(lambda u: rollout(fast, u)))(us)
    assert q.shape == (256, 50, 2) and bool(jnp.isfinite(q).all())
    assert float(jnp.std(q[:, -1, 0])) > 0  # different inputs, different arms


@pytest.mark.parametrize("backend", ["fast", pytest.param("mjx", marks=pytest.mark.slow)])  # MJX: ~100 s compile
def test_gradient_through_100_steps_is_finite(backend, fast, mjx_arm):
    arm = fast if backend == "fast" else mjx_arm

    def loss(u_level):
        q, _ = rollout(arm, jnp.tile(u_level, (100, 1)))
        return jnp.sum(arm.observe(arm.init(q[-1])).hand ** 2) + jnp.sum(q[-1] ** 2)

    g = jax.jit(jax.grad(loss))(jnp.array([0.2, 0.6, 0.3, 0.5]))
    assert bool(jnp.isfinite(g).all()) and float(jnp.abs(g).sum()) > 0


def test_separable_fast_geometry_is_the_full_polynomial():
    """The fast path drops the mixed monomials of the length fit (rounding-level for these paths): same lengths and
    moment arms as the full 55-monomial polynomial to float32 rounding, over and beyond the joint ranges."""
    from jaxarm.arm.geometry import FastGeometry

    class FullPolynomial(FastGeometry):
        SEPARABLE_TOL_M = -1.0

    sep, full = FastGeometry(), FullPolynomial()
    assert sep.separable and not full.separable and sep.all_coef.shape[0] < full.all_coef.shape[0]
    q = jax.random.uniform(jax.random.PRNGKey(0), (2000, 2), minval=-0.35, maxval=2.6)
    a, b = (jax.vmap(lambda x, g=g: g(x, x))(q) for g in (sep, full))
    np.testing.assert_allclose(a.mtu_length_m, b.mtu_length_m, atol=1e-6)
    np.testing.assert_allclose(a.moment_arm_m, b.moment_arm_m, atol=1e-6)


def test_padding_lanes_are_inert(fast):
    """The muscle state is padded to whole SIMD registers; the padding lanes get no drive and pull on nothing, so the
    arm is the 22-muscle arm: torques and observations come from the real muscles only."""
    assert fast.n_muscles == 22 and fast.n_lanes % 8 == 0 and fast.n_lanes >= 22
    assert not np.asarray(fast.group_drive[fast.n_muscles:]).any()
    s = fast.init()
    assert s.muscle.activation.shape == (fast.n_lanes,)
    # Stretch only the padding lanes' fibres: the joint trajectory must not change at all.
    pad = jnp.arange(fast.n_lanes) >= fast.n_muscles
    poked = s._replace(muscle=s.muscle._replace(fiber_length_m=jnp.where(pad, s.muscle.fiber_length_m * 0.7,
                                                                         s.muscle.fiber_length_m)))
    us = random_excitations(jax.random.PRNGKey(5), 0.2)
    run = jax.jit(lambda s0: jax.lax.scan(lambda st, u: (fast.step(st, u), st.q), s0, us)[1])
    np.testing.assert_array_equal(run(s), run(poked))
    obs = fast.observe(s)
    assert obs.muscles.activation.shape == (22,) and obs.muscles.fiber_length_m.shape == (22,)
