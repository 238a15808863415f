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

        out = when_any(jnp.any(p), run, x, (aux, p))
        return out, jax.tree_util.tree_map(lambda _: True, out)

    return update(jnp.asarray(pred, bool), x, jax.tree_util.tree_map(jnp.asarray, aux))
