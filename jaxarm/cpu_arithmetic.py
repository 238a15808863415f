"""Arithmetic whose bits do not depend on a network's place in its group, nor on the group's size.

Two things in XLA:CPU made them depend on it: fused multiply-add (below, :func:`pin`) and dot products
(:func:`ordered_dot`).

XLA:CPU lets LLVM fuse ``a * b + c`` into one FMA instruction (one rounding instead of two) wherever its code
generator sees fit, and the code it generates for a group of networks is not the same for every row: in the
closed loop's P-cell window test the first network's ``x = (q - q_min) / (q_max - q_min)`` was hoisted out of the
unrolled rows and rounded on its own, so its ``1 - x`` took two roundings where the other seven networks' took one
(``vfnmadd``). At a joint limit the muscle length then sits on a window edge, one P cell fired in some networks of
a group and not in others, and a network's training drifted with its place in the group (found with eight copies
of one network in one group: ``experiments/group_place.py --compare copies``). Without FMA every multiply and add
rounds on its own, whatever code LLVM generates, so the rows of a group compute the same numbers.

:func:`pin` caps XLA:CPU's instruction set at AVX (``--xla_cpu_max_isa=AVX``: no FMA, no AVX2 or AVX-512 in XLA's
code; the native network kernel is compiled apart and keeps them). It must run before JAX starts its CPU backend;
``import jaxarm`` calls it. Measured cost on the closed loop: none beyond noise (``docs/scaling.md``).

XLA:CPU computes a ``dot`` with kernels chosen and blocked by the operands' shapes, so the order in which a row's
products are summed changes with the batch a ``vmap`` adds: the musculoskeletal arm's muscle-path polynomial
(``FastGeometry``) gave other bits for a network alone, in a group of 4 and in a group of 64, and a network's
training parted with its group's size (``tests/test_batch_invariance.py``). :func:`ordered_dot` sums the products
one after the other, in the contraction's order, as elementwise operations that round the same in every row.

XLA:CPU also rewrites a division by a divisor that a ``vmap``'s rows share (a broadcast) into a product with the
divisor's reciprocal, rounded twice, and keeps the division where the divisor differs per row or there is no
batch: the critic update's soft bound gave a network other bits in a group of one than in a group of 8 with a
metaparameter set shared by the group. :func:`divide` computes what a group of 8 computed, in any group.

A long product (synaptic scaling's weighted total over 50,664 synapses) cannot be written out term by term.
XLA:CPU's matrix-vector product gives every row the same bits in batches of 8, 16, 32 and 64 rows, at any place,
but others in batches of 1, 2, 4 or 7 (``tests/test_batch_invariance.py``): :func:`rows_dot` pads a batch with zero
rows to a multiple of :data:`DOT_ROW_GROUP`, so a network computes its product as it does in the commands' default
groups of 8, whatever group it is in.
"""
from __future__ import annotations

import os
import warnings

import jax
import jax.numpy as jnp

#: The flag :func:`pin` adds to ``XLA_FLAGS``.
NO_FMA_FLAG = "--xla_cpu_max_isa=AVX"
#: Set this environment variable to 1 to keep XLA's FMA (a network's bits may then depend on its place).
KEEP_FMA_ENV = "JAXARM_XLA_FMA"


def pin() -> bool:
    """Add :data:`NO_FMA_FLAG` to ``XLA_FLAGS`` unless ``XLA_FLAGS`` already sets ``xla_cpu_max_isa`` or
    ``$JAXARM_XLA_FMA`` is 1. Returns whether XLA:CPU will run without FMA. Warns (once per process) when JAX's
    backend started before this call, too late for the flag."""
    flags = os.environ.get("XLA_FLAGS", "")
    if os.environ.get(KEEP_FMA_ENV) == "1":
        return False
    if "xla_cpu_max_isa" in flags:
        return NO_FMA_FLAG in flags.split()
    from jax._src import xla_bridge

    if xla_bridge.backends_are_initialized():
        warnings.warn("jaxarm: JAX computed before jaxarm was imported, so XLA:CPU keeps fused multiply-add and a "
                      "network's bits may depend on its place in its batch; import jaxarm first (or set "
                      f"XLA_FLAGS={NO_FMA_FLAG})", stacklevel=3)
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {NO_FMA_FLAG}".strip()
    return True


def ordered_dot(x, y):
    """``x @ y`` summed in a fixed order: ``x[..., 0] y[0] + x[..., 1] y[1] + ...``, left to right, each product
    and sum rounded on its own, so every row of a batch gets the same bits whatever the batch's size.

    ``x`` is (..., K), or a list of K arrays of shape (...) (its columns one by one: nothing stacks them), and ``y``
    (K,) (a matrix-vector or vector-vector product: the result is ``x.shape[:-1]``) or (K, M) (the result is
    ``x.shape[:-1] + (M,)``). For the small contractions of the arm (K at most a few tens), not for large matrix
    products.
    """
    columns = list(x) if isinstance(x, (list, tuple)) else None
    y = jnp.asarray(y)
    k_x = len(columns) if columns is not None else jnp.shape(x)[-1]
    if k_x != y.shape[0] or y.ndim not in (1, 2):
        shape = f"{k_x} columns" if columns is not None else str(jnp.shape(x))
        raise ValueError(f"ordered_dot: shapes {shape} and {y.shape} do not contract (x (..., K), y (K,) or (K, M))")
    if columns is None:
        x = jnp.asarray(x)
        columns = [x[..., k] for k in range(k_x)]

    def term(k):
        xk = jnp.asarray(columns[k])
        return xk[..., None] * y[k] if y.ndim == 2 else xk * y[k]

    total = term(0)
    for k in range(1, y.shape[0]):
        total = total + term(k)
    return total


#: Rows of the batch :func:`rows_dot` computes its product in: a multiple of this many.
DOT_ROW_GROUP = 8


def rows_dot(v, x):
    """``v . x`` for a long vector ``v`` (N,) that is the same in every network (a constant table) and a network's
    ``x`` (N,), with the same bits alone and at any place in a batch of any size: under ``vmap`` the batch's rows
    are padded with zero rows to a multiple of :data:`DOT_ROW_GROUP` and multiplied in one matrix-vector product
    (nested ``vmap`` levels as one batch of all their rows); unbatched, as one row padded the same way."""
    v, x = jnp.asarray(v), jnp.asarray(x)
    if v.ndim != 1 or x.shape != v.shape:
        raise ValueError(f"rows_dot: v and x must be vectors of one length, got {v.shape} and {x.shape}")
    return _rows_dot(v, x)


@jax.custom_jvp
def _rows_dot(v, x):
    return _rows_product(v, x[None])[0]


@_rows_dot.defjvp
def _rows_dot_jvp(primals, tangents):
    # the product is bilinear; its derivative by XLA's own dot (only the value is held to the same bits)
    (v, x), (dv, dx) = primals, tangents
    return _rows_dot(v, x), jnp.dot(dv, x) + jnp.dot(v, dx)


def _materialised(x, batched, axis_size):
    """``x`` with the batch axis a ``vmap`` rule gets it without (``batched`` False: the same in every row)."""
    return x if batched else jnp.broadcast_to(x, (axis_size,) + x.shape)


def _padded(rows):
    pad = -rows.shape[0] % DOT_ROW_GROUP
    return jnp.concatenate([rows, jnp.zeros((pad,) + rows.shape[1:], rows.dtype)]) if pad else rows


@jax.custom_batching.custom_vmap
def _rows_product(v, rows):
    """(B,) products of ``v`` with each of ``rows`` (B, N), in one product over the rows padded to a multiple of
    DOT_ROW_GROUP."""
    n = rows.shape[0]
    return jax.vmap(lambda r: jnp.dot(v, r))(_padded(rows))[:n]


@_rows_product.def_vmap
def _rows_product_vmap(axis_size, in_batched, v, rows):
    v_batched, rows_batched = in_batched
    if v_batched:
        raise ValueError("rows_dot: v must be the same in every network of a batch (vmap over x only)")
    rows = _materialised(rows, rows_batched, axis_size)
    a, b, n = rows.shape
    # this level's rows and the rows below as one batch (an outer vmap level flattens it again)
    return _rows_product(v, rows.reshape(a * b, n)).reshape(a, b), True


def divide(a, b):
    """``a / b`` elementwise (broadcast together) as XLA:CPU computes it for a group of networks, in every batch: a
    division (one rounding) where the divisor is each network's own (batched under ``vmap``), a product with the
    divisor's reciprocal (two roundings) where the group's networks share it (unbatched under ``vmap``) or there is
    no batch.

    XLA:CPU rewrites a division by a broadcast divisor into that product, so a group of 8 with a shared
    metaparameter set computed the reciprocal's product and a group of one the division; this keeps what groups
    of 8 computed, for any group (a division written as such, under a batch of per-network divisors, is
    materialised behind an optimisation barrier so that no rewrite applies)."""
    a, b = jnp.broadcast_arrays(jnp.asarray(a), jnp.asarray(b))
    return _divide(a, b)


@jax.custom_jvp
def _divide(a, b):
    return _divide_as_in_groups(a, b)


@_divide.defjvp
def _divide_jvp(primals, tangents):
    (a, b), (da, db) = primals, tangents
    q = _divide(a, b)
    return q, (da - q * db) / b


@jax.custom_batching.custom_vmap
def _divide_as_in_groups(a, b):
    return a * (1.0 / b)      # no batch: as a group whose networks share the divisor


@_divide_as_in_groups.def_vmap
def _divide_as_in_groups_vmap(axis_size, in_batched, a, b):
    a_batched, b_batched = in_batched
    if not b_batched:        # shared by the rows: the reciprocal's product, as XLA computed it
        return _materialised(a, a_batched, axis_size) * (1.0 / b), True
    return _true_divide(_materialised(a, a_batched, axis_size), b), True


@jax.custom_batching.custom_vmap
def _true_divide(a, b):
    return a / b


@_true_divide.def_vmap
def _true_divide_vmap(axis_size, in_batched, a, b):
    a, b = jax.lax.optimization_barrier(tuple(_materialised(x, f, axis_size) for x, f in zip((a, b), in_batched)))
    return _true_divide(a, b), True
