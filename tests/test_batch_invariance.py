"""A network's bits do not depend on the size of the batch it is computed in (jaxarm.cpu_arithmetic.ordered_dot).

XLA:CPU blocks a ``dot``'s sums by the operands' shapes, and for a batch of one its simplifier folded the muscle-path
polynomial's scale into each power's constant: the musculoskeletal arm's joint angles came out with other bits for
a network alone, in a batch of 4 and in one of 64, and its training parted with the batch's size. The arm now sums
its small products in a fixed order and keeps the scaled angle whole. Checked here on the arm alone (batches of 1,
3, 5, 8 and 64 against each other) and in closed-loop training (slow: alone, a group of 7, groups of 2), with the
arm's old products (XLA's ``dot``) as the positive control; the MJX backend's arm too (slow: batches of 1 and 3
against 8).

The closed loop runs through ``lax.map`` here, as a CPU device runs its share. A bare top-level ``vmap`` (``jaxarm
--networks-at-once 0``) gives the same network state, but its epoch summary's hand distances differ from the mapped
ones by about 1e-6 m (the hand's sines and cosines compiled into other code).
"""
import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.arm import make_arm
from jaxarm.cpu_arithmetic import ordered_dot

BATCHES = (1, 3, 5, 8)
N = 64


def test_ordered_dot_sums_left_to_right_in_float32():
    """Against a float32 loop in numpy, term by term (bit-equal), and float64 ``@`` (within rounding)."""
    rng = np.random.default_rng(3)
    x = rng.normal(size=(6, 19)).astype(np.float32)
    y = rng.normal(size=(19, 5)).astype(np.float32)
    v = rng.normal(size=19).astype(np.float32)
    expect = x[:, 0, None] * y[0]
    for k in range(1, 19):
        expect = (expect + x[:, k, None] * y[k]).astype(np.float32)
    np.testing.assert_array_equal(np.asarray(jax.jit(ordered_dot)(x, y)), expect)
    np.testing.assert_allclose(np.asarray(ordered_dot(x, v)), x.astype(float) @ v.astype(float), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(np.asarray(ordered_dot(v, y)), v.astype(float) @ y.astype(float), rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="do not contract"):
        ordered_dot(x, v[:3])


@pytest.fixture(scope="module")
def inputs():
    rng = np.random.default_rng(0)
    u = jnp.asarray(rng.uniform(0.0, 1.0, (N, 200, 4)).astype(np.float32))   # 200 ms of random group excitations
    q0 = jnp.asarray(rng.uniform(0.2, 1.2, (N, 2)).astype(np.float32))       # start postures, rad
    return u, q0


@functools.lru_cache(maxsize=None)
def musculoskeletal_arm(backend: str):
    """One arm per backend for every batch below (building one loads and relaxes the MuJoCo model)."""
    return make_arm("musculoskeletal", backend=backend)


def arm_paths(u, q0, backend="fast"):
    """Joint angles (batch, T, 2) rad of the musculoskeletal arm from q0 under excitations u, one vmap."""
    arm = musculoskeletal_arm(backend)

    def one(u, q0):
        def body(s, ut):
            s = arm.step(s, ut)
            return s, s.q
        return jax.lax.scan(body, arm.init()._replace(q=q0), u)[1]

    return np.asarray(jax.jit(jax.vmap(one))(u, q0))


def test_the_musculoskeletal_arm_gives_the_same_bits_in_every_batch_size(inputs):
    u, q0 = inputs
    everyone = arm_paths(u, q0)
    assert np.degrees(np.ptp(everyone, axis=1)).max() > 10.0   # the arms do move
    for b in BATCHES:
        np.testing.assert_array_equal(arm_paths(u[:b], q0[:b]), everyone[:b], err_msg=f"batch of {b} vs {N}")
    np.testing.assert_array_equal(arm_paths(u[N - 5:], q0[N - 5:]), everyone[N - 5:], err_msg="the last 5 alone")


@pytest.mark.slow   # three MJX compilations, about 30 s in all
def test_the_mjx_arm_gives_the_same_bits_in_every_batch_size(inputs):
    """The reference backend too: its own sums (MuJoCo's kinematics and mass matrix) are shape-independent here."""
    u, q0 = inputs
    u = u[:8, :40]
    everyone = arm_paths(u, q0[:8], "mjx")
    assert np.degrees(np.ptp(everyone, axis=1)).max() > 10.0
    for b in (1, 3):
        np.testing.assert_array_equal(arm_paths(u[:b], q0[:b], "mjx"), everyone[:b], err_msg=f"batch of {b} vs 8")


def test_positive_control_xla_dot_of_the_muscle_paths_depends_on_the_batch(inputs):
    """The products the arm used before: the monomials times the fit's coefficients through ``@``. Their bits for
    a network change with the batch; the ordered sum's do not."""
    _, q0 = inputs
    geometry = musculoskeletal_arm("fast").geometry
    coef = geometry.all_coef

    def monomials(q):   # as the arm built them before: a table of powers, its columns concatenated
        x = jax.lax.optimization_barrier((q - geometry.q_center) / geometry.q_halfwidth)
        rows = [jnp.ones_like(x)]
        for _ in range(geometry.degree):
            rows.append(rows[-1] * x)
        powers = jnp.stack(rows)
        return jnp.concatenate([powers[:, 0], powers[1:, 1]])

    def paths(f, q):
        return np.asarray(jax.jit(jax.vmap(lambda q: f(monomials(q), coef)))(q))

    plain = paths(jnp.matmul, q0)
    assert any(np.any(paths(jnp.matmul, q0[:b]) != plain[:b]) for b in (1, 4, 32))
    ordered = paths(ordered_dot, q0)
    for b in (1, 4, 32):
        np.testing.assert_array_equal(paths(ordered_dot, q0[:b]), ordered[:b])


@pytest.mark.slow
def test_closed_loop_training_gives_the_same_bits_alone_in_a_batch_and_in_groups():
    """Musculoskeletal arm, authors' metaparameters, 5.5 s of training with babbling and R-STDP (critic updates and
    the synaptic scaling at 5 s included), through ``lax.map`` as a CPU device runs its share
    (``jaxarm.parallel.map_networks``): networks 0-6 in one group of 7, network 5 alone, and the 7 in groups of 2 (a
    last group of 1). Before ``rows_dot`` and the soft bound's reciprocal (2026-12-07) a network alone parted from
    the group at the first critic update that its division rounded otherwise, and at the scaling."""
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    fns = make_train(LoopConfig(arm="musculoskeletal", task=TaskConfig(epochs=1, epoch_duration_s=5.5)))
    mp = MetaParams.original()
    carry = jax.jit(jax.vmap(fns.init))(jax.random.split(jax.random.PRNGKey(0), 7))

    def train(c, at_once):
        return jax.tree.leaves(jax.jit(lambda c: jax.lax.map(lambda one: fns.epoch(one, mp), c,
                                                             batch_size=at_once))(c))

    together = train(carry, 7)
    alone = train(jax.tree.map(lambda x: x[5:6], carry), 1)
    in_twos = train(carry, 2)
    assert np.asarray(together[0]).shape[0] == 7
    for whole, one, grouped in zip(together, alone, in_twos):
        np.testing.assert_array_equal(np.asarray(one), np.asarray(whole)[5:6])
        np.testing.assert_array_equal(np.asarray(grouped), np.asarray(whole))


def test_rows_dot_gives_the_same_bits_in_every_batch():
    """jaxarm.cpu_arithmetic.rows_dot (synaptic scaling's weighted total over every synapse): each row's product in
    batches of 1, 2, 7 and 9, nested vmaps, lax.map's groups of 1 and 3 and unbatched equals the row's in one batch of
    8; XLA's own product of a batch of one as the positive control (it differs in some rows on this machine)."""
    from jaxarm.cpu_arithmetic import rows_dot

    rng = np.random.default_rng(0)
    n = 50_664
    v = rng.uniform(0.0, 3.0, n).astype(np.float32)
    x = jnp.asarray(rng.uniform(0.5, 2.0, (8, n)).astype(np.float32))
    in_eight = np.asarray(jax.jit(jax.vmap(lambda r: jnp.dot(v, r)))(x))
    ours = jax.jit(jax.vmap(lambda r: rows_dot(v, r)))
    np.testing.assert_array_equal(np.asarray(ours(x)), in_eight)
    for b in (1, 2, 7):
        got = np.concatenate([np.asarray(ours(x[i:i + b])) for i in range(0, 8, b)])[:8]
        np.testing.assert_array_equal(got, in_eight)
    np.testing.assert_array_equal(np.asarray(ours(jnp.concatenate([x, x[:1]]))), np.append(in_eight, in_eight[0]))
    nested = jax.jit(jax.vmap(jax.vmap(lambda r: rows_dot(v, r))))(x.reshape(4, 2, n))
    np.testing.assert_array_equal(np.asarray(nested).reshape(-1), in_eight)
    for k in (1, 3):
        mapped = jax.jit(lambda x, k=k: jax.lax.map(lambda r: rows_dot(v, r), x, batch_size=k))(x)
        np.testing.assert_array_equal(np.asarray(mapped), in_eight)
    assert np.asarray(jax.jit(lambda r: rows_dot(v, r))(x[3])) == in_eight[3]
    alone = np.array([np.asarray(jax.jit(lambda r: jnp.dot(v, r))(x[i])) for i in range(8)])
    assert (alone != in_eight).any(), "positive control: XLA's product of one row rounds as in a batch of 8 here"


def test_the_critic_update_gives_the_same_bits_alone_and_in_a_batch():
    """One R-STDP critic update (jaxarm.learning.stdp.dopamine_update through batching.when_any, as the rule runs it):
    with bounds shared by the batch, a network alone, in a batch of one and in a batch of 8 give the same bits, those
    of the soft bound's fraction as the bound's reciprocal times the gain (what XLA computed for a group of 8); with
    each network's own bounds, batches of one and of 8 give those of the division (numpy float32 references)."""
    from jaxarm.batching import when_any
    from jaxarm.learning import stdp

    rng = np.random.default_rng(1)
    n = 29_672
    is_ee = rng.uniform(size=n) < 0.6
    w = rng.uniform(0.2, 3.0, (8, n)).astype(np.float32)
    tags = np.where(rng.uniform(size=(8, n)) < 0.3, 4995.0, -1e9).astype(np.float32)
    live = tags == np.float32(4995.0)      # tagged 5 ms before the update, within the 10 ms lifetime
    ee, ei, rate = np.float32(3.2167358), np.float32(9.108501), np.float32(0.08971194)

    def update(w, tags, signal, ee, ei):
        def reinforce(x, aux):
            (w, tags), (ee, ei, signal) = x, aux
            return stdp.dopamine_update(w, tags, True, jnp.where(is_ee, ee, ei), rate, 5000.0, signal, 10.0)

        return when_any(signal != 0, reinforce, (w, tags), (ee, ei, signal))[0]

    maxw = np.where(is_ee, ee, ei).astype(np.float32)
    one = np.float32(1.0)
    for signal in (1.0, -1.0):
        def reference(fraction):
            step = rate * (one - fraction) if signal > 0 else -rate * fraction
            return np.where(live, np.maximum(w + step, np.float32(0.0)), w)

        shared = reference(w * (one / maxw))
        own = reference(w / maxw)
        assert (shared != own).any()      # the two roundings differ somewhere: the test can tell them apart
        s = jnp.full(8, signal, jnp.float32)
        in_eight = jax.jit(jax.vmap(update, in_axes=(0, 0, 0, None, None)))(w, tags, s, ee, ei)
        np.testing.assert_array_equal(np.asarray(in_eight), shared)
        for i in (0, 5):
            alone = jax.jit(update)(w[i], tags[i], jnp.float32(signal), ee, ei)
            np.testing.assert_array_equal(np.asarray(alone), shared[i])
            in_one = jax.jit(jax.vmap(update, in_axes=(0, 0, 0, None, None)))(w[i:i + 1], tags[i:i + 1], s[:1], ee, ei)
            np.testing.assert_array_equal(np.asarray(in_one), shared[i:i + 1])
        per = jax.jit(jax.vmap(update))
        np.testing.assert_array_equal(np.asarray(per(w, tags, s, jnp.full(8, ee), jnp.full(8, ei))), own)
        np.testing.assert_array_equal(np.asarray(per(w[2:3], tags[2:3], s[:1], jnp.full(1, ee), jnp.full(1, ei))),
                                      own[2:3])
