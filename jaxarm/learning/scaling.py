"""Global synaptic scaling (spec §4; msarm.hoc synScaling), run every synScalingDT (5 s) of training.

The original sums, over every presynaptic cell of the network whose outgoing gains do not all vanish
(Σ wgain > 0), the base weights S0 = Σ(|w1| + |w2|) and the current weights S = Σ(|w1| + |w2|)·wgain
(w1, w2 = AMPA & NMDA base weights, or the GABA weight). If S0/S < 1 (total weight grew), **every** wgain in the
network, plastic or not, excitatory or inhibitory, is multiplied by S0/S; otherwise nothing changes.
Only synapses between network cells count (the P -> ES inputs come from NSLOC generators and are neither summed
nor scaled).

Synapses can be passed as any pytree of blocks (e.g. a dict of pathways), each leaf an array of per-synapse
values of any shape, with matching ``presyn`` global ids.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp


@partial(jax.jit, static_argnames=("n_cells",))
def scaling_factor(wgain, base_abs_weight, presyn, n_cells: int, valid=None):
    """The factor min(1, S0/S) that synaptic scaling would apply now (scalar).

    Args:
        wgain: pytree of per-synapse gains. base_abs_weight: same structure, |w1| + |w2| per synapse.
        presyn: same structure, int global id of each synapse's presynaptic cell (< n_cells).
        n_cells: number of network cells (static).
        valid: optional same-structure bool masks of real synapses (padding excluded from every sum).
    """
    gains, bases, pres = (jax.tree_util.tree_leaves(x) for x in (wgain, base_abs_weight, presyn))
    valids = jax.tree_util.tree_leaves(valid) if valid is not None else [None] * len(gains)
    if not (len(gains) == len(bases) == len(pres) == len(valids)):
        raise ValueError("wgain, base_abs_weight, presyn (and valid) must have the same tree structure")
    per_cell = jnp.zeros((3, n_cells), jnp.float32)   # rows: S0_c, S_c, Σ wgain_c
    for g, b, p, v in zip(gains, bases, pres, valids):
        g = jnp.asarray(g, jnp.float32)
        b = jnp.asarray(b, jnp.float32) * jnp.ones_like(g)
        if v is not None:
            g, b = jnp.where(v, g, 0.0), jnp.where(v, b, 0.0)
        ids = jnp.broadcast_to(jnp.asarray(p), g.shape).reshape(-1)
        rows = jnp.stack([b.reshape(-1), (b * g).reshape(-1), g.reshape(-1)])
        per_cell = per_cell + jax.vmap(lambda r: jax.ops.segment_sum(r, ids, num_segments=n_cells))(rows)
    counted = per_cell[2] > 0
    s0 = jnp.sum(jnp.where(counted, per_cell[0], 0.0))
    s = jnp.sum(jnp.where(counted, per_cell[1], 0.0))
    ratio = s0 / jnp.where(s > 0, s, 1.0)
    return jnp.where((s > 0) & (ratio < 1.0), ratio, 1.0)


@partial(jax.jit, static_argnames=("n_cells",))
def apply_synaptic_scaling(wgain, base_abs_weight, presyn, n_cells: int, valid=None):
    """Scale every gain by :func:`scaling_factor`. Returns (scaled wgain pytree, factor)."""
    factor = scaling_factor(wgain, base_abs_weight, presyn, n_cells, valid)
    return jax.tree_util.tree_map(lambda g: g * factor.astype(jnp.asarray(g).dtype), wgain), factor


def scaling_due(t_ms, last_scaling_ms, period_ms):
    """Whether scaling runs at this loop step: t - last >= period (``last`` is 0 at the start of each run, so with
    5 s periods it runs at t = 5, 10, 15, ... s of every epoch)."""
    return jnp.asarray(t_ms) - last_scaling_ms >= period_ms
