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
the number of synapses. For each spike group (``NetworkSpec.spike_groups``; the paper's ES; EM; inhibitory cells):

1. the spike list: ``lax.top_k`` of the group's "fired in this block" vector gives at most K cells; unused entries
   point to the group's "no spike" row, whose synapses have weight 0. Under ``vmap`` the list is one for the whole
   batch (top_k over the batch's flattened vector, K = ``max(spike_capacity, ceil(B * batch_spike_capacity))``), so
   its length follows the batch's mean number of spikes, which is steady, rather than the busiest network's;
2. their rows of the group tables give, per synapse, target channel, delay, base weight and NMDA weight; the gain
   ``wgain`` of each synapse multiplies the AMPA/GABA weight; one flat scatter-add over the flattened batch of rings
   writes them into slot (spike step + delay) % n_slots;
3. with plasticity bookkeeping, the same list tags the plastic inputs of every listed cell: ``pdope = t`` (its spike
   time) where the presynaptic cell's last spike at or before t was at most ``max_plast_t_ms`` earlier ([model:
   learning](../model.md#learning-reward-modulated-stdp)), by a scatter-max (tags only move forward in time, so max =
   overwrite). A presynaptic cell that fired later in the same block is looked up by its previous spike (cells keep
   their last two spike times);
4. if the list could not hold all spikes, further passes take the next ones in the same block (exact; every network
   with spikes left counts the pass in :class:`Counters`). After ``max_passes`` passes anything left is lost and
   counted — a test fails on that.

Speed notes (measured on the 2-core CPU, 60 networks; see benchmarks/network.py):

* the slot is cleared with zeros made data-dependent on the slot just read, else XLA copies the ring every step;
* the scatter-add is the cost of delivery and it is proportional to the list length times the row width, so
  per-network lists sized for a network's bursts (16 ES entries where ~1 is used) wasted most of it: one list per
  batch halved the whole network step at 60 networks (7.5 -> 15.7 network-s/s, same machine and session);
* :func:`deliver_block` is a ``custom_vmap`` whose batched rule is that batch-wide delivery (a plain ``vmap`` of a
  ``while_loop`` with a per-network predicate would select the whole ring every pass). Under nested ``vmap`` it
  stays exact but only the innermost axis shares a list: flatten networks into one batch axis where possible.

P -> ES input (:func:`deliver_p_window`): P trains change only when the loop sets new muscle lengths, so at the start
of every chunk of steps the P spikes of the whole chunk are known; their synapses (4224, each P->ES synapse once per
chunk) are written into the ring at once, at the arrival step of each spike. No capacity is involved, so the
all-P volley at 1 ms is delivered exactly. The ring therefore spans a chunk plus the P delay.
"""
from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.config.validate import ConfigError
from jaxarm.config.spec import SynapsePhysics
from jaxarm.network.cell import event_load
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
    capacity: tuple              # per group: spike-list length of one network (the floor of a batch's list)
    batch_share: tuple           # per group: spike-list entries per network of a batch (float)
    max_passes: int
    n_slots: int
    n_cells: int
    n_plastic: int
    bookkeeping: bool
    sequential: bool = False     # AMPA/GABA weights enter the ring as loads (jaxarm.network.cell.event_load)
    physics: SynapsePhysics = SynapsePhysics()   # reversal potentials and the jump cap of those loads


def list_length(shape: DeliveryShape, g: int, n_networks: int) -> int:
    """Spike-list length of group ``g`` for a batch of ``n_networks``: ``max(capacity, ceil(n * batch_share))``."""
    return max(shape.capacity[g], math.ceil(n_networks * shape.batch_share[g] - 1e-9))


def _group_values(per_cell, shape: DeliveryShape):
    """Per group, the (..., n_group) slice of a per-network-cell array."""
    out = []
    for ranges in shape.group_slices:
        parts = [per_cell[..., a:b] for a, b in ranges]
        out.append(parts[0] if len(parts) == 1 else jnp.concatenate(parts, axis=-1))
    return out


def _row(table, net, cell, batched: bool):
    """Rows ``cell`` (K,) of a group table, of network ``net`` (K,) when the tables are batched."""
    return table[net, cell] if batched else table[cell]


def _group_pass(ring, pdope_ms, remaining, steps, last_spike_ms, prev_spike_ms, wgain, window_ms, tables: GroupTables,
                tables_batched: bool, g: int, k: int, shape: DeliveryShape, dt_ms: float):
    """One pass of group ``g`` over the whole batch: the first ``k`` of the remaining spikes of all networks
    (flattened network-major), delivered by one scatter-add into the flattened ring and tagged by one scatter-max.

    ``remaining``/``steps``: (B * n_g,) "not yet delivered" (1.0/0.0) and spike step of every cell of the group.
    Returns (ring, pdope_ms, remaining)."""
    n_g = remaining.shape[0] // ring.shape[0]
    vals, flat = jax.lax.top_k(remaining, k)
    valid = vals > 0
    net = jnp.where(valid, flat // n_g, 0)
    cell = jnp.where(valid, flat % n_g, n_g)                   # n_g = the "no spike" row (weights 0)
    s = jnp.where(valid, steps[flat], 0)                        # (K,) spike step of each listed cell
    ring, pdope_ms = _deliver_rows(ring, pdope_ms, net, cell, s, None, last_spike_ms, prev_spike_ms, wgain, window_ms,
                                   tables, tables_batched, g, shape, dt_ms)
    remaining = remaining.at[flat].set(0.0, mode="promise_in_bounds")
    return ring, pdope_ms, remaining


def _deliver_rows(ring, pdope_ms, net, cell, s, value, last_spike_ms, prev_spike_ms, wgain, window_ms,
                  tables: GroupTables, tables_batched: bool, g: int, shape: DeliveryShape, dt_ms: float):
    """Deliver and tag the rows ``cell`` (K,) of group ``g``'s tables, of networks ``net`` (K,), each spiking at
    step ``s`` (K,): one scatter-add into the (B, ring) rings and one scatter-max into the (B, n_plastic) tags.
    ``value`` (K,) float32 scales each row's weights (the spike itself, 1.0 or 0.0, carrying a surrogate
    derivative) or is None (every listed row spiked). Returns (ring, pdope_ms)."""
    n = shape.n_cells
    b, r = ring.shape
    packed = _row(tables.out_packed, net, cell, tables_batched)  # (K, C) row gathers
    syn = _row(tables.out_syn, net, cell, tables_batched)
    w = _row(tables.out_weight, net, cell, tables_batched) * wgain.at[net[:, None], syn].get(mode="clip")
    if shape.sequential:
        ph = shape.physics
        w = event_load(w, ph.e_ampa_mv if shape.excitatory[g] else -ph.e_gaba_mv, ph.max_jump_fraction)
    if value is not None:
        w = w * value[:, None]
    delay = packed & ((1 << DELAY_BITS) - 1)
    index = (net * r)[:, None] + jax.lax.rem(s[:, None] + delay, shape.n_slots) * (N_CHANNELS * n) + (
        packed >> DELAY_BITS)
    if shape.excitatory[g]:
        index = jnp.concatenate([index, index + n], axis=1)    # AMPA row then NMDA row of each spike
        w_nmda = _row(tables.out_nmda, net, cell, tables_batched)
        w = jnp.concatenate([w, w_nmda if value is None else w_nmda * value[:, None]], axis=1)
    ring = ring.reshape(-1).at[index.reshape(-1)].add(w.reshape(-1), mode="promise_in_bounds").reshape(b, r)
    if shape.bookkeeping:
        p = pdope_ms.shape[-1]
        t_post = (s.astype(jnp.float32) * dt_ms)[:, None]
        pre = _row(tables.in_plastic_pre, net, cell, tables_batched)
        last = last_spike_ms.at[net[:, None], pre].get(mode="fill", fill_value=NEVER_SPIKED_MS)
        prev = prev_spike_ms.at[net[:, None], pre].get(mode="fill", fill_value=NEVER_SPIKED_MS)
        last = jnp.where(last <= t_post, last, prev)          # the presynaptic spike at or before t_post
        hit = (last >= 0.0) & (t_post - last <= window_ms[net][:, None])
        if value is not None:                                  # dense rows: only those that spiked tag
            hit = hit & (value > 0.5)[:, None]
        tag = (net * p)[:, None] + jnp.minimum(_row(tables.in_plastic, net, cell, tables_batched), p - 1)
        pdope_ms = pdope_ms.reshape(-1).at[tag.reshape(-1)].max(
            jnp.where(hit, t_post, NO_TAG_MS).astype(jnp.float32).reshape(-1), mode="promise_in_bounds"
        ).reshape(b, p)
    return ring, pdope_ms


def deliver_block_dense(ring, pdope_ms, delivery_step, spike_value, last_spike_ms, prev_spike_ms, wiring: Wiring,
                        wgain, window_ms, shape: DeliveryShape, dt_ms: float):
    """:func:`deliver_block` for differentiation (``NetworkConfig.spike_gradient``), of one network (plain
    ``vmap`` for many): every cell's row is written, its weights times its spike ``spike_value`` (n_cells,)
    float32 (1.0 or 0.0 forward, a surrogate derivative backward), so a cell that did not fire passes on the
    derivative of its threshold. ``delivery_step`` (n_cells,) int32: the step each cell's row leaves at, its spike
    step if it fired, else the step its derivative belongs to (a step of this block, never a fixed one: the
    derivative arrives at that step + the synapse's delay). Rows that did not fire add exact zeros and the fired
    rows are added in the order of the spike lists (ascending cell), so the ring, and every spike after it, is bit
    for bit the same as with spike lists. Work: every synapse of the network per block, not only those of the
    spikes. Returns (ring, pdope_ms)."""
    ring, pdope_ms = ring[None], pdope_ms[None]
    for g, (tables, steps, values) in enumerate(zip(wiring.groups, _group_values(delivery_step, shape),
                                                    _group_values(spike_value, shape))):
        cell = jnp.arange(steps.shape[-1])
        ring, pdope_ms = _deliver_rows(ring, pdope_ms, jnp.zeros_like(cell), cell, steps, values,
                                       last_spike_ms[None], prev_spike_ms[None], wgain[None],
                                       jnp.asarray(window_ms, jnp.float32)[None], tables, False, g, shape, dt_ms)
    return ring[0], pdope_ms[0]


def _deliver_batched(ring, pdope_ms, counters: Counters, spike_step, last_spike_ms, prev_spike_ms, wgain, window_ms,
                     groups, groups_batched: bool, shape: DeliveryShape, dt_ms: float):
    """Delivery for a batch: every argument but ``groups`` has a leading batch axis B. ``spike_step``: (B, n_cells)
    int32 step of each cell's spike in this block, -1 if none.

    Per spike group, one spike list serves the whole batch (its length :func:`list_length` grows with B), so the
    work follows the batch's total number of spikes rather than the busiest network's: a burst in one network costs
    extra passes of one list, not of every network's list."""
    b = ring.shape[0]
    # flat indices into the batch's rings and tags are int32
    if b * max(ring.shape[1], pdope_ms.shape[-1]) >= 2 ** 31:
        raise ConfigError(f"a batch of {b} networks with {ring.shape[1]} ring entries each overflows the XLA "
                          f"kernel's int32 indices: at most {(2 ** 31 - 1) // max(ring.shape[1], pdope_ms.shape[-1])} "
                          "networks per device (shard the batch over more devices, or use the native kernel)")
    extra = jnp.zeros((b,), jnp.int32)
    lost = jnp.zeros((b,), jnp.int32)
    for g, (tables, steps) in enumerate(zip(groups, _group_values(spike_step, shape))):
        n_g = steps.shape[-1]
        k = min(list_length(shape, g, b), b * n_g)
        steps = steps.reshape(-1)
        one = functools.partial(_group_pass, steps=steps, last_spike_ms=last_spike_ms, prev_spike_ms=prev_spike_ms,
                                wgain=wgain, window_ms=window_ms, tables=tables, tables_batched=groups_batched, g=g,
                                k=k, shape=shape, dt_ms=dt_ms)

        def left_per_network(remaining, n_g=n_g):
            return jnp.sum(remaining.reshape(b, n_g) > 0, axis=-1, dtype=jnp.int32)

        ring, pdope_ms, remaining = one(ring, pdope_ms, (steps >= 0).astype(jnp.float32))
        if shape.max_passes > 1 and k < b * n_g:
            def more(carry):
                return (carry[3] < shape.max_passes) & jnp.any(carry[2] > 0)

            def again(carry):
                ring, pdope_ms, remaining, passes, extra = carry
                extra = extra + (left_per_network(remaining) > 0).astype(jnp.int32)
                ring, pdope_ms, remaining = one(ring, pdope_ms, remaining)
                return ring, pdope_ms, remaining, passes + 1, extra

            ring, pdope_ms, remaining, _, extra = jax.lax.while_loop(
                more, again, (ring, pdope_ms, remaining, jnp.ones((), jnp.int32), extra))
        lost = lost + left_per_network(remaining)
    counters = Counters(extra_passes=counters.extra_passes + extra, lost_spikes=counters.lost_spikes + lost)
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
                     p_start_id: int, never: int, *, max_spikes: int, n_slots: int, n_cells: int,
                     sequential: bool = False, physics: SynapsePhysics = SynapsePhysics()):
    """Write the P -> ES input of every P spike in steps (first_step, first_step + n_steps] into the ring.

    ``next_step``/``interval_steps``: (n_P,) P train state at ``first_step`` (intervals do not change inside the
    window). ``p_synapses``: the static slice of the synapses from P (the generator population; the paper's
    P -> ES). ``sequential``: write AMPA loads (:func:`jaxarm.network.cell.event_load`, with ``physics``) instead
    of weights. ``max_spikes``: most spikes one train can
    have in the window (n_steps // shortest interval + 1). Needs n_slots >= n_steps + the P delay.
    """
    pre = wiring.pre[p_synapses] - p_start_id
    nxt, interval = next_step[pre], interval_steps[pre]
    delay, target = wiring.delay_steps[p_synapses], wiring.target[p_synapses]
    w = wiring.weight[p_synapses] * wgain[p_synapses]
    if sequential:
        w = event_load(w, physics.e_ampa_mv, physics.max_jump_fraction)
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
