"""Spike delivery through an index ring buffer, from fixed-capacity spike lists (``lax.top_k``).

Ring buffer: a flat float32 array of ``n_slots * 4 * n_cells + n_cells`` entries; slot s (step m lands in slot
m % n_slots) holds, channel-major, the summed weights arriving at each cell in that step: rows AMPA-distal,
NMDA-distal, GABA-proximal, GABA-distal (mV). The trailing n_cells entries are a pad, so the NMDA write of any
synapse (target + n_cells) stays in bounds.

Spikes are delivered once per *block* of L steps (L <= the shortest network delay and <= the shortest refractory
period, so every spike of a block still arrives after the block, and a cell fires at most once per block): the
cells advance L steps reading the ring, remembering the step of each cell's spike; then the block's spikes are
delivered, each at its own spike step + delay — exactly what per-step delivery would do, with L times fewer spike
lists, and lists sized for a block rather than for a step. Work is proportional to the spike-list lengths, never to
the number of synapses. For each spike group (ES; EM; inhibitory cells, :data:`jaxarm.network.wiring.SPIKE_GROUPS`):

1. the spike list: ``lax.top_k`` of the group's "fired in this block" vector gives at most ``spike_capacity[g]``
   cells; unused entries point to the group's "no spike" row, whose synapses have weight 0;
2. their rows of the group tables give, per synapse, target channel, delay, base weight and NMDA weight; the gain
   ``wgain`` of each synapse multiplies the AMPA/GABA weight; two flat scatter-adds (one for inhibitory groups,
   which have no NMDA) write them into slot (spike step + delay) % n_slots;
3. with plasticity bookkeeping, the same list tags the plastic inputs of every listed cell: ``pdope = t`` (its spike
   time) where the presynaptic cell's last spike at or before t was at most ``max_plast_t_ms`` earlier (spec §4),
   by a scatter-max (tags only move forward in time, so max = overwrite). A presynaptic cell that fired later in the
   same block is looked up by its previous spike (cells keep their last two spike times);
4. if a group had more spikes than its list holds, further passes take the next ones in the same block (exact;
   every extra pass is counted in :class:`Counters`). After ``max_passes`` passes anything left is lost and
   counted — a test fails on that.

Speed notes (measured on the 2-core CPU, 60 networks; see benchmarks/network.py):

* the slot is cleared with zeros made data-dependent on the slot just read, else XLA copies the ring every step;
* under ``vmap`` a ``while_loop`` with a per-network predicate selects its whole carry (ring, tags) every pass;
  :func:`deliver_spikes` is therefore a ``custom_vmap`` whose batched rule runs the extra passes for all networks
  at once while any network needs one (networks with nothing left deliver "no spike" rows of zeros) and writes
  with one scatter over the flattened batch. Under nested ``vmap`` it stays exact but loses that advantage.

P -> ES input (:func:`deliver_p_window`): P trains change only when the loop sets new muscle lengths, so at the start
of every chunk of steps the P spikes of the whole chunk are known; their synapses (4224, each P->ES synapse once per
chunk) are written into the ring at once, at the arrival step of each spike. No capacity is involved, so the
all-P volley at 1 ms is delivered exactly. The ring therefore spans a chunk plus the P delay.
"""
from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.network.wiring import DELAY_BITS, N_CHANNELS, GroupTables, Wiring

#: ``pdope`` of an untagged synapse and last spike time of a cell that has not fired in this run, ms
#: (the original's -1e9; same convention as :mod:`jaxarm.learning.stdp`).
NO_TAG_MS = -1e9
NEVER_SPIKED_MS = -1e9


class Counters(NamedTuple):
    """Capacity statistics since the start of the run (int32 scalars per network)."""

    extra_passes: jnp.ndarray  # spike-list passes beyond the first (spikes delivered exactly, at extra cost)
    lost_spikes: jnp.ndarray   # spikes never delivered because max_passes was reached (must stay 0)


def ring_size(n_slots: int, n_cells: int) -> int:
    return n_slots * N_CHANNELS * n_cells + n_cells


def read_slot(ring, step, n_slots: int, n_cells: int):
    """(4, n_cells) inputs arriving in clock step ``step``, and the ring with that slot cleared."""
    width = N_CHANNELS * n_cells
    start = jax.lax.rem(step, n_slots) * width
    row = jax.lax.dynamic_slice(ring, (start,), (width,))
    # The zeros are made to depend on the row just read (min(|x|, 0) is 0 for any finite x) so that XLA orders the
    # read before the in-place clear; without this data dependency XLA:CPU copies the whole ring every step
    # (measured: ~10x slower for 60 networks).
    after_read = jnp.minimum(jnp.abs(row[0]), 0.0)
    ring = jax.lax.dynamic_update_slice(ring, jnp.zeros((width,), ring.dtype) * after_read, (start,))
    return row.reshape(N_CHANNELS, n_cells), ring


class DeliveryShape(NamedTuple):
    """Static parameters of delivery (hashable)."""

    group_slices: tuple          # per group: tuple of (start, stop) global-id ranges, concatenated
    excitatory: tuple            # per group: has NMDA
    capacity: tuple              # per group: spike-list length
    max_passes: int
    n_slots: int
    n_cells: int
    n_plastic: int
    bookkeeping: bool


def _group_values(per_cell, shape: DeliveryShape):
    """Per group, the (..., n_group) slice of a per-network-cell array."""
    out = []
    for ranges in shape.group_slices:
        parts = [per_cell[..., a:b] for a, b in ranges]
        out.append(parts[0] if len(parts) == 1 else jnp.concatenate(parts, axis=-1))
    return out


def _one_pass(remaining, spike_step, last_spike_ms, prev_spike_ms, wgain, window_ms, groups, shape: DeliveryShape,
              dt_ms: float):
    """One network, one pass: take up to capacity[g] of the remaining spikes per group. Returns (ring index, ring
    value, tag index, tag value, remaining); the tag arrays are empty without bookkeeping."""
    n = shape.n_cells
    ring_i, ring_v, tag_i, tag_v, left = [], [], [], [], []
    for g, (tables, rem, steps) in enumerate(zip(groups, remaining, spike_step)):
        tables: GroupTables
        n_g = rem.shape[-1]
        vals, ids = jax.lax.top_k(rem, shape.capacity[g])
        ids = jnp.where(vals > 0, ids, n_g)                     # n_g = the "no spike" row
        s = jnp.take(steps, ids, mode="fill", fill_value=0)     # (K,) spike step of each listed cell
        packed = tables.out_packed[ids]                         # (K, C) row gathers
        syn = tables.out_syn[ids]
        w = tables.out_weight[ids] * jnp.take(wgain, syn, mode="clip")
        delay = packed & ((1 << DELAY_BITS) - 1)
        index = jax.lax.rem(s[:, None] + delay, shape.n_slots) * (N_CHANNELS * n) + (packed >> DELAY_BITS)
        ring_i.append(index.reshape(-1))
        ring_v.append(w.reshape(-1))
        if shape.excitatory[g]:
            ring_i.append(index.reshape(-1) + n)
            ring_v.append(tables.out_nmda[ids].reshape(-1))
        if shape.bookkeeping:
            t_post = (s.astype(jnp.float32) * dt_ms)[:, None]
            pre = tables.in_plastic_pre[ids]
            last = jnp.take(last_spike_ms, pre, mode="fill", fill_value=NEVER_SPIKED_MS)
            prev = jnp.take(prev_spike_ms, pre, mode="fill", fill_value=NEVER_SPIKED_MS)
            last = jnp.where(last <= t_post, last, prev)      # the presynaptic spike at or before t_post
            hit = (last >= 0.0) & (t_post - last <= window_ms)
            tag_i.append(jnp.minimum(tables.in_plastic[ids], shape.n_plastic - 1).reshape(-1))
            tag_v.append(jnp.where(hit, t_post, NO_TAG_MS).astype(jnp.float32).reshape(-1))
        left.append(rem.at[ids].set(0.0, mode="drop"))
    cat = lambda xs, dt: jnp.concatenate(xs) if xs else jnp.zeros((0,), dt)  # noqa: E731
    return cat(ring_i, jnp.int32), cat(ring_v, jnp.float32), cat(tag_i, jnp.int32), cat(tag_v, jnp.float32), left


def _deliver_batched(ring, pdope_ms, counters: Counters, spike_step, last_spike_ms, prev_spike_ms, wgain, window_ms,
                     groups, groups_batched: bool, shape: DeliveryShape, dt_ms: float):
    """Delivery for a batch: every argument but ``groups`` has a leading batch axis B. ``spike_step``: (B, n_cells)
    int32 step of each cell's spike in this block, -1 if none."""
    b, r = ring.shape
    one_pass = jax.vmap(functools.partial(_one_pass, shape=shape, dt_ms=dt_ms),
                        in_axes=(0, 0, 0, 0, 0, 0, 0 if groups_batched else None))
    ring_offset = (jnp.arange(b, dtype=jnp.int32) * r)[:, None]
    p = pdope_ms.shape[-1]
    tag_offset = (jnp.arange(b, dtype=jnp.int32) * p)[:, None]
    steps = _group_values(spike_step, shape)

    def apply(ring, pdope_ms, remaining):
        ri, rv, ti, tv, remaining = one_pass(remaining, steps, last_spike_ms, prev_spike_ms, wgain, window_ms, groups)
        # one scatter over the flattened batch (about 2x faster than a batched scatter on XLA:CPU)
        ring = ring.reshape(-1).at[(ri + ring_offset).reshape(-1)].add(
            rv.reshape(-1), mode="promise_in_bounds").reshape(b, r)
        if shape.bookkeeping:
            pdope_ms = pdope_ms.reshape(-1).at[(ti + tag_offset).reshape(-1)].max(
                tv.reshape(-1), mode="promise_in_bounds").reshape(b, p)
        return ring, pdope_ms, remaining

    def left_per_network(remaining):
        return sum(jnp.sum(x > 0, axis=-1, dtype=jnp.int32) for x in remaining)

    remaining = [(x >= 0).astype(jnp.float32) for x in steps]
    ring, pdope_ms, remaining = apply(ring, pdope_ms, remaining)

    def more(carry):
        _, _, remaining, passes, _ = carry
        return (passes < shape.max_passes) & jnp.any(left_per_network(remaining) > 0)

    def again(carry):
        ring, pdope_ms, remaining, passes, extra = carry
        extra = extra + (left_per_network(remaining) > 0).astype(jnp.int32)
        ring, pdope_ms, remaining = apply(ring, pdope_ms, remaining)
        return ring, pdope_ms, remaining, passes + 1, extra

    extra = jnp.zeros((b,), jnp.int32)
    if shape.max_passes > 1:
        ring, pdope_ms, remaining, _, extra = jax.lax.while_loop(
            more, again, (ring, pdope_ms, remaining, jnp.ones((), jnp.int32), extra))
    counters = Counters(extra_passes=counters.extra_passes + extra,
                        lost_spikes=counters.lost_spikes + left_per_network(remaining))
    return ring, pdope_ms, counters


@functools.lru_cache(maxsize=None)
def _make_deliver(shape: DeliveryShape, dt_ms: float):
    n_state = 7  # per-network arguments before window_ms and groups

    @jax.custom_batching.custom_vmap
    def deliver(ring, pdope_ms, counters, spike_step, last_spike_ms, prev_spike_ms, wgain, window_ms, groups):
        args = jax.tree_util.tree_map(lambda x: jnp.asarray(x)[None], (
            ring, pdope_ms, counters, spike_step, last_spike_ms, prev_spike_ms, wgain, window_ms))
        out = _deliver_batched(*args, groups, False, shape, dt_ms)
        return jax.tree_util.tree_map(lambda x: x[0], out)

    @deliver.def_vmap
    def rule(axis_size, in_batched, *args):
        per_network, groups = args[:n_state + 1], args[n_state + 1]

        def batch(x, flag):
            return x if flag else jnp.broadcast_to(x, (axis_size,) + jnp.shape(x))

        per_network = jax.tree_util.tree_map(batch, tuple(per_network), tuple(in_batched[:n_state + 1]))
        groups_batched = any(jax.tree_util.tree_leaves(in_batched[n_state + 1]))
        if groups_batched:
            groups = jax.tree_util.tree_map(batch, groups, in_batched[n_state + 1])
        out = _deliver_batched(*per_network, groups, groups_batched, shape, dt_ms)
        return out, jax.tree_util.tree_map(lambda _: True, out)

    return deliver


def deliver_block(ring, pdope_ms, counters: Counters, spike_step, last_spike_ms, prev_spike_ms, wiring: Wiring,
                  wgain, window_ms, shape: DeliveryShape, dt_ms: float):
    """Deliver (and tag) the spikes of one block. ``spike_step``: (n_cells,) int32 step of each cell's spike in the
    block (-1: none); ``last_spike_ms``/``prev_spike_ms``: (n_all,) the last two spike times of every cell, ms,
    including the block. Returns (ring, pdope_ms, counters)."""
    return _make_deliver(shape, float(dt_ms))(ring, pdope_ms, counters, spike_step, last_spike_ms, prev_spike_ms,
                                              wgain, jnp.asarray(window_ms, jnp.float32), tuple(wiring.groups))


def deliver_p_window(ring, next_step, interval_steps, first_step, n_steps: int, wiring: Wiring, wgain, p_synapses: slice,
                     p_start_id: int, never: int, *, max_spikes: int, n_slots: int, n_cells: int):
    """Write the P -> ES input of every P spike in steps (first_step, first_step + n_steps] into the ring.

    ``next_step``/``interval_steps``: (n_P,) P train state at ``first_step`` (intervals do not change inside the
    window). ``p_synapses``: the static slice of the P -> ES synapses. ``max_spikes``: most spikes one train can
    have in the window (n_steps // shortest interval + 1). Needs n_slots >= n_steps + the P delay.
    """
    pre = wiring.pre[p_synapses] - p_start_id
    nxt, interval = next_step[pre], interval_steps[pre]
    delay, target = wiring.delay_steps[p_synapses], wiring.target[p_synapses]
    w = wiring.weight[p_synapses] * wgain[p_synapses]
    w_nmda = wiring.nmda[p_synapses]
    last = first_step + n_steps
    spike = nxt
    for _ in range(max_spikes):
        fire = (spike > first_step) & (spike <= last)
        index = jax.lax.rem(jnp.where(fire, spike + delay, 0), n_slots) * (N_CHANNELS * n_cells) + target
        ring = ring.at[index].add(jnp.where(fire, w, 0.0), mode="promise_in_bounds")
        ring = ring.at[index + n_cells].add(jnp.where(fire, w_nmda, 0.0), mode="promise_in_bounds")
        spike = jnp.where(interval >= never, never, spike + interval)
    return ring
