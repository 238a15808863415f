"""Spike delivery through an index ring buffer, from fixed-capacity spike lists (``lax.top_k``).

Ring buffer: a flat float32 array of ``n_slots * 4 * n_cells + n_cells`` entries; slot s (step m lands in slot
m % n_slots) holds, channel-major, the summed weights arriving at each cell in that step: rows AMPA-distal,
NMDA-distal, GABA-proximal, GABA-distal (mV). ``n_slots = max delay + 1``. The trailing n_cells entries are a pad
that only ever receives zeros (the NMDA write of a GABA synapse, see below), so every index is in bounds.

Delivery of the network spikes of step m (cost proportional to the spike-list length, never to the number of
synapses):

1. the spike list: ``lax.top_k`` of the spike vector returns at most ``spike_capacity`` spiking cell ids; unused
   entries point to a dummy cell (id n_cells) whose delivery row is all dummy synapses of weight 0;
2. their delivery rows ``out_syn[ids]`` give synapse ids; each synapse adds ``weight * wgain`` to its target channel
   and ``nmda`` to the NMDA channel of its cell, in slot (m + delay) % n_slots (two flat scatter-adds). A GABA
   synapse has nmda = 0 and its NMDA write lands, harmlessly, one channel further (or in the pad);
3. with plasticity bookkeeping, the same list tags the plastic inputs of every listed cell (``pdope = t`` where the
   presynaptic cell fired within the pairing window before t; spec §4), by a scatter-max (tags only move forward);
4. if more cells spiked than the list holds, further passes take the next ones in the same step (exact; each extra
   pass is counted). After ``max_passes`` passes anything left is lost and counted — a test fails on that.

P -> ES input (:func:`deliver_p_window`): P trains change only when the loop sets new muscle lengths, so at the start
of every chunk of steps the P spikes of the whole chunk are known; their synapses (4224, each P->ES synapse once per
chunk) are written into the ring at once, at the arrival step of each spike. No capacity is involved, so the
all-P volley at 1 ms is delivered exactly. The ring therefore spans a chunk plus the P delay.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.network.wiring import DELAY_BITS, N_CHANNELS, Wiring

#: ``pdope`` of an untagged synapse and last spike time of a cell that has not fired in this run, ms
#: (the original's -1e9; same convention as :mod:`jaxarm.learning.stdp`).
NO_TAG_MS = -1e9
NEVER_SPIKED_MS = -1e9


class Counters(NamedTuple):
    """Capacity statistics since the start of the run (int32 scalars)."""

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


def spike_list(remaining, capacity: int, dummy: int):
    """Up to ``capacity`` ids of cells with ``remaining > 0`` (lowest ids first); empty entries = ``dummy``."""
    vals, ids = jax.lax.top_k(remaining, capacity)
    return jnp.where(vals > 0, ids, dummy)


def deliver(ring, ids, step, wiring: Wiring, wgain, n_slots: int, n_cells: int):
    """Scatter the synapses of the listed cells into the ring buffer (see module docstring)."""
    syn = wiring.out_syn[ids]                                # (K, out_capacity)
    p = wiring.packed[syn]
    delay = p & ((1 << DELAY_BITS) - 1)
    target = p >> DELAY_BITS
    w = wiring.weight[syn] * jnp.take(wgain, syn, mode="clip")
    slot = jax.lax.rem(step + delay, n_slots)
    index = (slot * (N_CHANNELS * n_cells) + target).reshape(-1)
    ring = ring.at[index].add(w.reshape(-1), mode="promise_in_bounds")
    ring = ring.at[index + n_cells].add(wiring.nmda[syn].reshape(-1), mode="promise_in_bounds")
    return ring


def tag(pdope_ms, ids, t_ms, last_spike_ms, wiring: Wiring, window_ms):
    """Pre-before-post tags for the listed postsynaptic cells: ``pdope = t`` on each plastic input whose
    presynaptic cell last fired at most ``window_ms`` before t (and at all in this run)."""
    syn = wiring.in_plastic[ids]                             # (K, width); padding = n_plastic (dropped)
    last = jnp.take(last_spike_ms, wiring.in_plastic_pre[ids], mode="fill", fill_value=NEVER_SPIKED_MS)
    hit = (last >= 0.0) & (t_ms - last <= window_ms)
    value = jnp.where(hit, t_ms, NO_TAG_MS).astype(pdope_ms.dtype)
    return pdope_ms.at[syn.reshape(-1)].max(value.reshape(-1), mode="drop")


def deliver_spikes(ring, pdope_ms, counters: Counters, spiked, step, t_ms, last_spike_ms, wiring: Wiring, wgain,
                   window_ms, *, capacity: int, max_passes: int, n_slots: int, n_cells: int, bookkeeping: bool):
    """All delivery (and tagging) for the network spikes ``spiked`` (n_cells,) bool of clock step ``step``;
    ``last_spike_ms`` (n_all,) already includes this step's spikes."""

    def one_pass(ring, pdope_ms, remaining):
        ids = spike_list(remaining, capacity, n_cells)
        ring = deliver(ring, ids, step, wiring, wgain, n_slots, n_cells)
        if bookkeeping:
            pdope_ms = tag(pdope_ms, ids, t_ms, last_spike_ms, wiring, window_ms)
        remaining = remaining.at[ids].set(0.0, mode="drop")
        return ring, pdope_ms, remaining

    remaining = spiked.astype(jnp.float32)
    ring, pdope_ms, remaining = one_pass(ring, pdope_ms, remaining)

    def more(carry):
        _, _, remaining, passes = carry
        return (passes < max_passes) & jnp.any(remaining > 0)

    def again(carry):
        ring, pdope_ms, remaining, passes = carry
        ring, pdope_ms, remaining = one_pass(ring, pdope_ms, remaining)
        return ring, pdope_ms, remaining, passes + 1

    if max_passes > 1:
        ring, pdope_ms, remaining, passes = jax.lax.while_loop(
            more, again, (ring, pdope_ms, remaining, jnp.ones((), jnp.int32)))
    else:
        passes = jnp.ones((), jnp.int32)
    counters = Counters(extra_passes=counters.extra_passes + passes - 1,
                        lost_spikes=counters.lost_spikes + jnp.sum(remaining > 0).astype(jnp.int32))
    return ring, pdope_ms, counters


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
