"""Batch-aware conditional update: skip work that no network of a ``vmap``-ed batch needs.

Under ``vmap`` a ``lax.cond`` with a per-network predicate becomes a ``select``: both branches run for every
network at every call. The learning rule's updates are due only at the critic's and the scaling's moments (every
60 ms and 5 s of a 10 ms loop), so in training most of their work would be discarded. :func:`when_any` runs the
update for the whole batch only when at least one network needs it, and keeps the old values in the networks that
do not; results are exactly those of ``jnp.where(pred, f(x, aux), x)`` per network, at any depth of nested ``vmap``
(each level skips when none of its networks needs the update).
"""
from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp


def _select(pred, new, old):
    return jax.tree_util.tree_map(lambda n, o: jnp.where(jnp.reshape(pred, (-1,) + (1,) * (n.ndim - 1)), n, o),
                                  new, old)


def when_any(pred, f: Callable[[Any, Any], Any], x, aux=None):
    """``f(x, aux)`` where ``pred`` (a bool scalar per network), else ``x``.

    ``f`` maps the pytree ``x`` to a pytree of the same structure, shapes and dtypes; everything traced it needs is
    passed in ``aux`` (it must not close over traced values). Without ``vmap`` this is a ``lax.cond``.
    """
    aux = jax.tree_util.tree_map(jnp.asarray, aux)
    # Only the leaves of aux that f reads enter the custom_vmap call; the others become constants inside it. The call
    # is opaque to dead-code elimination, so a pytree passed in whole (the metaparameters) would otherwise count as
    # read, whether f reads it or not (tests/test_learning.py checks that the model reads every metaparameter).
    leaves, tree = jax.tree_util.tree_flatten(aux)
    read = _leaves_read(f, x, aux)
    shapes = [(jnp.shape(v), v.dtype) for v in leaves]

    def f_read(x, kept):
        it = iter(kept)
        full = [next(it) if r else jnp.zeros(shape, dtype) for r, (shape, dtype) in zip(read, shapes)]
        return f(x, jax.tree_util.tree_unflatten(tree, full))

    return _when_any(jnp.asarray(pred, bool), f_read, x, [v for v, r in zip(leaves, read) if r])


def _leaves_read(f, x, aux) -> list[bool]:
    """Per leaf of ``aux``: whether tracing ``f(x, aux)`` uses it at all."""
    jaxpr = jax.make_jaxpr(f)(x, aux).jaxpr
    n_x = len(jax.tree_util.tree_leaves(x))
    used = {id(v) for eqn in jaxpr.eqns for v in eqn.invars} | {id(v) for v in jaxpr.outvars}
    return [id(v) in used for v in jaxpr.invars[n_x:]]


def _when_any(pred, f: Callable[[Any, Any], Any], x, aux):
    """:func:`when_any` of a bool ``pred`` and an ``aux`` of arrays, every one of which ``f`` reads."""

    @jax.custom_batching.custom_vmap
    def update(p, x, aux):
        return jax.lax.cond(p, f, lambda x, aux: x, x, aux)

    @update.def_vmap
    def rule(axis_size, in_batched, p, x, aux):
        p_b, x_b, aux_b = in_batched

        def batch(v, flag):
            return v if flag else jnp.broadcast_to(v, (axis_size,) + jnp.shape(v))

        x = jax.tree_util.tree_map(batch, x, x_b)
        p = batch(p, p_b)
        aux_axes = jax.tree_util.tree_map(lambda flag: 0 if flag else None, aux_b)

        def run(x, aux_p):
            aux, p = aux_p
            return _select(p, jax.vmap(f, in_axes=(0, aux_axes))(x, aux), x)

        out = _when_any(jnp.any(p), run, x, (aux, p))
        return out, jax.tree_util.tree_map(lambda _: True, out)

    return update(pred, x, aux)
