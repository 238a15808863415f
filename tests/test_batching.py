"""jaxarm.batching.when_any: per-network results of a masked update, with the work skipped when nobody needs it."""
import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.batching import when_any


def f(x, aux):
    a, b = x
    scale, shift = aux
    return a * scale + shift, b - jnp.sum(a)


def reference(pred, x, aux):
    new = f(x, aux)
    return jax.tree_util.tree_map(lambda n, o: jnp.where(pred, n, o), new, x)


def data(n):
    k1, k2, k3 = jax.random.split(jax.random.key(0), 3)
    x = (jax.random.normal(k1, (n, 5)), jax.random.normal(k2, (n,)))
    aux = (jax.random.uniform(k3, (n,)) + 0.5, jnp.float32(2.0))
    return x, aux


def test_unbatched_is_a_cond():
    x, aux = data(1)
    x = jax.tree_util.tree_map(lambda a: a[0], x)
    aux = (aux[0][0], aux[1])
    for pred in (True, False):
        out = jax.jit(lambda p, x, aux: when_any(p, f, x, aux))(jnp.bool_(pred), x, aux)
        for o, r in zip(out, reference(pred, x, aux)):
            np.testing.assert_allclose(np.asarray(o), np.asarray(r), rtol=1e-6)


def test_vmapped_equals_masked_update_and_keeps_a_cond():
    x, aux = data(6)
    pred = jnp.array([True, False, True, False, False, True])
    run = jax.vmap(lambda p, x, s: when_any(p, f, x, (s, aux[1])))
    out = jax.jit(run)(pred, x, aux[0])
    ref = jax.vmap(lambda p, x, s: reference(p, x, (s, aux[1])))(pred, x, aux[0])
    for o, r in zip(out, ref):
        np.testing.assert_allclose(np.asarray(o), np.asarray(r), rtol=1e-6)
    none = jax.jit(run)(jnp.zeros(6, bool), x, aux[0])
    for o, r in zip(none, x):
        np.testing.assert_allclose(np.asarray(o), np.asarray(r), rtol=1e-6)
    assert "cond" in str(jax.make_jaxpr(run)(pred, x, aux[0])), "the batch-wide skip should survive vmap"


def test_nested_vmap_and_unbatched_operand():
    x, aux = data(6)
    pred = jnp.array([True, False, False, False, True, False]).reshape(2, 3)
    xs = jax.tree_util.tree_map(lambda a: a.reshape((2, 3) + a.shape[1:]), x)
    out = jax.jit(jax.vmap(jax.vmap(lambda p, x: when_any(p, f, x, aux=(jnp.float32(3.0), jnp.float32(1.0))))))(
        pred, xs)
    ref = jax.vmap(jax.vmap(lambda p, x: reference(p, x, (3.0, 1.0))))(pred, xs)
    for o, r in zip(out, ref):
        np.testing.assert_allclose(np.asarray(o), np.asarray(r), rtol=1e-6)
    # operand shared by the batch (unbatched), predicate per network
    x0 = jax.tree_util.tree_map(lambda a: a[0], x)
    out = jax.jit(jax.vmap(lambda p: when_any(p, f, x0, (jnp.float32(3.0), jnp.float32(1.0)))))(pred[0])
    ref = jax.vmap(lambda p: reference(p, x0, (3.0, 1.0)))(pred[0])
    for o, r in zip(out, ref):
        np.testing.assert_allclose(np.asarray(o), np.asarray(r), rtol=1e-6)
