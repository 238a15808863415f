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
    """Every combination of the 4 groups at full excitation for 1 s (15 of them): the penalty limits (the authors'
    2500 / 1000 N m/rad) stop the joints at most 3.4 deg (shoulder) and 1.9 deg (elbow) past their ranges, as the
    docs say; some combination reaches each limit (so the bound is exercised)."""
    import itertools

    lo, hi = np.radians([-10, 0]), np.radians([110, 140])
    roll = jax.jit(lambda u: rollout(fast, jnp.tile(u, (1000, 1)))[0])
    worst = np.full(2, -np.inf)
    for r in range(1, 5):
        for groups in itertools.combinations(range(4), r):
            q = np.asarray(roll(jnp.zeros(4).at[jnp.array(groups)].set(1.0)))
            assert np.all(np.isfinite(q))
            worst = np.maximum(worst, np.maximum(lo - q.min(0), q.max(0) - hi))
    assert np.all(worst > np.radians(1.0)), np.degrees(worst)
    assert worst[0] < np.radians(3.6) and worst[1] < np.radians(2.1), np.degrees(worst)


@pytest.mark.slow  # MJX compiles for ~40 s: the default suite's 8-minute budget on CI
def test_backends_agree_and_are_well_conditioned_on_smooth_inputs(fast, mjx_arm):
    """20 seeds of smooth random excitation (1 s): fast and MJX within 1 deg of each other, and
    moving the start shoulder angle by 1e-4 rad moves either path by < 1 deg (with one 1 ms muscle step per arm step
    the backends differed by 6 deg and a 1e-4 rad start moved a path by 7 deg: experiments/arm_convergence.py)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent.parent / "experiments"))
    from arm_convergence import paths
    from jaxarm.arm.inputs import smooth_random_excitations

    us = np.stack([smooth_random_excitations(seed) for seed in range(7, 27)])
    q0 = np.array([0.62, 1.53])
    runs = {name: (paths(arm, q0, us), paths(arm, q0 + [1e-4, 0.0], us)) for name, arm in
            (("fast", fast), ("mjx", mjx_arm))}
    for name, (q, moved) in runs.items():
        assert np.degrees(np.abs(q - moved)).max() < 1.0, name
        assert np.degrees(np.ptp(q, axis=1)).max() > 20.0          # the inputs do swing the joints
    assert np.degrees(np.abs(runs["fast"][0] - runs["mjx"][0])).max() < 1.0


def test_vmap_over_256_arms(fast):
    keys = jax.random.split(jax.random.PRNGKey(0), 256)
    us = jax.vmap(lambda k: random_excitations(k, 0.05))(keys)
    q, _ = jax.jit(jax.vmap(lambda u: rollout(fast, u)))(us)
    assert q.shape == (256, 50, 2) and bool(jnp.isfinite(q).all())
    assert float(jnp.std(q[:, -1, 0])) > 0  # different inputs, different arms


@pytest.mark.slow   # compile-heavy (~10 s fast, ~100 s MJX)
@pytest.mark.parametrize("backend", ["fast", "mjx"])  # MJX: ~100 s compile
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
