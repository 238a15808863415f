"""The network as pure functions: ``init``, ``step``, ``run`` over a :class:`State` pytree (one network; ``vmap`` for many).

Usage::

    net = Network(NetworkConfig())
    wiring = net.make_wiring(jax.random.key(0))          # or vmap over keys: one wiring per network
    state = net.init(jax.random.key(1))
    state = net.set_lengths(state, lengths_m)            # every 10 ms, from the arm (m)
    state, spikes = net.run(wiring, state, params, net.config.steps_per_interface)   # spikes (n_steps, n_all) bool

Units: ms and mV inside; muscle lengths in m at :meth:`Network.set_lengths`.

How a run is organised (all inside one ``lax.scan``; results are exactly those of delivering after every step):
chunks of one interface period (10 ms), each starting by writing the P input of the whole chunk into the ring
buffer; inside a chunk, blocks of :attr:`Network.block_steps` cell steps, each followed by the delivery of the
block's spikes (:mod:`jaxarm.network.synapses`).

State layout (every field may carry leading batch axes under ``vmap``):

* ``step``: () int32 clock steps since the start of the run; the time is ``step * dt_ms``.
* ``cells``: :class:`~jaxarm.network.cell.CellState`, (n_cells,) arrays for the 512 INTF6 cells (ids 0..511).
* ``p``: :class:`~jaxarm.network.proprio.PState` of the generator cells (the paper's: the 192 P cells, ids 512..703).
* ``noise``: :class:`~jaxarm.network.noise.NoiseState` (seeds, the Poisson tables of the current rates, per-lane event
  budgets).
* ``ring``: the synaptic input ring buffer (:mod:`jaxarm.network.synapses`).
* ``wgain``: (n_syn,) float32 gain of every synapse on its AMPA/GABA base weight (1 at start). Per-post-cell layout:
  ``WiringLayout.view(state.wgain, "ES->EM")`` is the (n_post, in_degree) block of a pathway, matching
  ``wiring.pre`` viewed the same way. Persists across runs (epochs); the learning rule and synaptic scaling
  update it with array ops.
* ``pdope_ms``: (n_plastic,) float32 tag time of every plastic synapse (synapse k < n_plastic; -1e9 = untagged),
  ms since the start of the run. Written on postsynaptic spikes when ``plasticity_bookkeeping`` is on.
* ``last_spike_ms``, ``prev_spike_ms``: (n_all,) float32 last and second-to-last spike time of every cell in this
  run, ms (-1e9 = none).
* ``spike_count``: (n_all,) int32 spikes of every cell since the start of the run.
* ``counters``: :class:`~jaxarm.network.synapses.Counters` (extra spike-list passes, lost spikes).

``step`` returns the spikes of every cell in that step ((n_all,) bool, global id order) so a 10 ms interface can
count EM spikes per group (:func:`jaxarm.network.readout.em_group_counts`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.network import cell as cell_mod
from jaxarm.network import noise as noise_mod
from jaxarm.network import proprio as proprio_mod
from jaxarm.network import synapses as syn_mod
from jaxarm.network.populations import Populations
from jaxarm.network.wiring import Wiring, WiringLayout, make_wiring

#: Pre-before-post pairing window of tagging, ms (maxplastt, main.hoc L46).
MAX_PLAST_T_MS = 69.57


class NetworkParams(NamedTuple):
    """Traced values the network step uses (scalars, or batched under ``vmap``)."""

    max_plast_t_ms: jnp.ndarray  # tagging window, ms

    @classmethod
    def original(cls) -> "NetworkParams":
        return cls(max_plast_t_ms=jnp.asarray(MAX_PLAST_T_MS, jnp.float32))


class State(NamedTuple):
    step: jnp.ndarray
    cells: cell_mod.CellState
    p: proprio_mod.PState
    noise: noise_mod.NoiseState
    ring: jnp.ndarray
    wgain: jnp.ndarray
    pdope_ms: jnp.ndarray
    last_spike_ms: jnp.ndarray
    prev_spike_ms: jnp.ndarray
    spike_count: jnp.ndarray
    counters: syn_mod.Counters


@dataclass(frozen=True)
class Network:
    """Pure functions of one network configuration (hashable: safe as a static argument)."""

    config: NetworkConfig = field(default_factory=NetworkConfig)

    @cached_property
    def layout(self) -> WiringLayout:
        return WiringLayout(self.config)

    @cached_property
    def pops(self) -> Populations:
        return Populations(self.config)

    @cached_property
    def cell_constants(self) -> cell_mod.CellConstants:
        return cell_mod.cell_constants(self.config)

    @cached_property
    def noise_weights(self) -> np.ndarray:
        return noise_mod.noise_weights(self.config)

    @cached_property
    def chunk_steps(self) -> int:
        """Steps per chunk of :meth:`run` (one interface period): P input is written once per chunk."""
        return self.config.steps_per_interface

    @cached_property
    def p_delay_steps(self) -> int:
        """Longest delay of the generator's (P's) pathways, in steps."""
        return max(self.config.steps(pw.delay_ms[1]) for pw in self.layout.generator_pathways)

    @cached_property
    def n_slots(self) -> int:
        """Ring-buffer slots: enough for the longest delay of any pathway (at least 5 ms) and for a chunk of P input
        plus its delay. A spike's input lands in slot (step + delay) % n_slots, so a delay of n_slots steps or more
        would arrive early."""
        longest = max(self.config.steps(pw.delay_ms[1]) for pw in self.layout.pathways)
        return max(max(self.config.steps(5.0), longest) + 1, self.chunk_steps + self.p_delay_steps)

    @cached_property
    def max_passes(self) -> int:
        """Spike-list passes allowed per block and group: the configured limit, or (0) enough for every cell of
        every network to fire, at any batch size (a list holds at least min(capacity, batch share) per network)."""
        if self.config.max_passes:
            return self.config.max_passes
        sizes = [sum(self.config.size(p) for p in g) for g in self.layout.spike_groups]
        shares = [min(k, s) for k, s in zip(*self.config.group_capacities())]
        return max(math.ceil(n / s) for n, s in zip(sizes, shares))

    @cached_property
    def delivery_shape(self) -> syn_mod.DeliveryShape:
        lay, c = self.layout, self.config
        slices = tuple(tuple((self.pops.start[p], self.pops.stop[p]) for p in g) for g in lay.spike_groups)
        capacity, share = c.group_capacities()
        return syn_mod.DeliveryShape(group_slices=slices, excitatory=lay.group_is_excitatory, capacity=capacity,
                                     batch_share=tuple(float(x) for x in share), max_passes=self.max_passes,
                                     n_slots=self.n_slots, n_cells=c.n_cells, n_plastic=lay.n_plastic,
                                     bookkeeping=c.plasticity_bookkeeping,
                                     sequential=c.event_summation == "sequential", physics=c.spec.physics)

    @cached_property
    def p_synapses(self) -> "slice | np.ndarray":
        """The synapses from generator populations (the paper's P), delivered once per chunk."""
        return self.layout.generator_synapses

    @cached_property
    def p_synapse_ids(self) -> np.ndarray:
        """:attr:`p_synapses` as an (n,) int32 id table (what the native kernel takes)."""
        return np.arange(self.layout.n_syn, dtype=np.int32)[self.p_synapses]

    @cached_property
    def native_cell_floats(self) -> np.ndarray:
        """(12, n_cells) float32 cell constants in the native kernel's order."""
        c = self.cell_constants
        return np.stack([c.rmp, c.vth, c.vblock, c.ahpwt, c.post_spike_excess, c.decay_ampa, c.decay_nmda,
                         c.decay_gaba_prox, c.decay_gaba_dist, c.decay_ahp, c.decay_rr, c.decay_rr_first]
                        ).astype(np.float32)

    @cached_property
    def native_cell_group(self) -> np.ndarray:
        """(n_cells,) int32 spike group of every network cell."""
        out = np.zeros(self.config.n_cells, np.int32)
        for g, ranges in enumerate(self.delivery_shape.group_slices):
            for a, b in ranges:
                out[a:b] = g
        return out

    @cached_property
    def native_cell_row(self) -> np.ndarray:
        """(n_cells,) int32 row of every network cell in its group's delivery tables."""
        out = np.zeros(self.config.n_cells, np.int32)
        for ranges in self.delivery_shape.group_slices:
            row = 0
            for a, b in ranges:
                out[a:b] = np.arange(row, row + b - a)
                row += b - a
        return out

    @property
    def uses_native_kernel(self) -> bool:
        """Whether chunks run in the native kernel (``config.kernel``; "auto" decides when first traced)."""
        if self.config.kernel == "xla" or self.differentiable:
            return False
        from jaxarm.network import native
        if self.config.kernel == "native":
            if not native.available():
                raise RuntimeError(f"NetworkConfig.kernel = 'native' but the native kernel is unavailable: "
                                   f"{native.status()} (use kernel='auto' or 'xla')")
            return True
        return native.available()

    @property
    def differentiable(self) -> bool:
        """Whether spikes carry a surrogate derivative (``config.spike_gradient``): XLA kernel, dense delivery,
        float32 spikes out of :meth:`run`, and each chunk rematerialised on the backward pass."""
        return self.config.spike_gradient != "none"

    def make_wiring(self, key) -> Wiring:
        return make_wiring(self.config, key)

    def init(self, key, wgain=None, em_rates_hz=None) -> State:
        """Fresh run: cells at rest, no spikes, no tags, step 0. ``key`` seeds the background noise; ``wgain``
        (n_syn,) carries learned gains over from a previous run (default all 1); ``em_rates_hz`` (4,) the EM AMPA
        noise per group (default 200 Hz)."""
        c, lay = self.config, self.layout
        return State(
            step=jnp.zeros((), jnp.int32),
            cells=cell_mod.init_cells(c.n_cells),
            p=proprio_mod.init_p(c),
            noise=noise_mod.init_noise(c, key, em_rates_hz),
            ring=jnp.zeros((syn_mod.ring_size(self.n_slots, c.n_cells),), jnp.float32),
            wgain=jnp.ones((lay.n_syn,), jnp.float32) if wgain is None else jnp.asarray(wgain, jnp.float32),
            pdope_ms=jnp.full((lay.n_plastic if c.plasticity_bookkeeping else 0,), syn_mod.NO_TAG_MS, jnp.float32),
            last_spike_ms=jnp.full((c.n_all,), syn_mod.NEVER_SPIKED_MS, jnp.float32),
            prev_spike_ms=jnp.full((c.n_all,), syn_mod.NEVER_SPIKED_MS, jnp.float32),
            spike_count=jnp.zeros((c.n_all,), jnp.int32),
            counters=syn_mod.Counters(jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32)),
        )

    def set_lengths(self, state: State, lengths_m) -> State:
        """New muscle lengths (4,) in m (GROUPS order) for the P code, from now on."""
        return state._replace(p=proprio_mod.set_lengths(self.config, state.p, lengths_m, state.step))

    def set_target(self, state: State, direction_rad, rate_scale=1.0) -> State:
        """Point every target code (generator populations with ``code="target"``) at the direction
        ``direction_rad`` (rad, counterclockwise from +x), firing at its ``rate_hz`` times ``rate_scale``, from now
        on; a no-op in the paper's network."""
        return state._replace(p=proprio_mod.set_target(self.config, state.p, direction_rad, state.step, rate_scale))

    def target_code_wiring(self, wiring: Wiring, weight_scale, density_scale) -> Wiring:
        """``wiring`` with the target codes' pathways at ``weight_scale`` times their weight and ``density_scale``
        times their density (:func:`jaxarm.network.proprio.target_code_wiring`); ``wiring`` itself without a code."""
        if not self.config.spec.target_codes:
            return wiring
        return proprio_mod.target_code_wiring(self.config, wiring, weight_scale, density_scale)

    def set_em_rates(self, state: State, em_rates_hz) -> State:
        """EM AMPA background rate per muscle group (4,), Hz, from now on."""
        return state._replace(noise=noise_mod.set_em_rates(self.config, state.noise, em_rates_hz))

    def time_ms(self, state: State):
        return state.step.astype(jnp.float32) * self.config.dt_ms

    def _cell_step(self, state: State, spike_step):
        """One clock step of every cell, reading its input from the ring (no delivery). ``spike_step``: (n_cells,)
        step of each cell's spike in the current block (-1 none). Returns (state, spike_step, spikes (n_all,)):
        bool, or float32 with a surrogate derivative when :attr:`differentiable`."""
        c = self.config
        n = c.n_cells
        m = state.step + 1
        t_ms = m.astype(jnp.float32) * c.dt_ms
        syn_in, ring = syn_mod.read_slot(state.ring, m, self.n_slots, n)
        counts, noise = noise_mod.draw_events(state.noise, m)
        drive = counts * self.noise_weights  # (3, n): AMPA, GABA-prox, GABA-dist
        order = noise_mod.excitation_first(state.noise, m) if c.same_step_inhibition == "random_order" else None
        cells, net_spiked = cell_mod.cell_step(
            state.cells, syn_in[0] + drive[0], syn_in[1], syn_in[2] + drive[1], syn_in[3] + drive[2],
            self.cell_constants, sequential=c.event_summation == "sequential",
            on_event=c.threshold_test == "on_event", per_event_crossing=c.crossing == "per_event",
            excitation_first=order,
            surrogate_width_mv=c.surrogate_width_mv if self.differentiable else 0.0, surrogate_scale=c.surrogate_scale,
            physics=c.spec.physics)
        p, p_spiked = proprio_mod.p_step(state.p, m)
        values = None
        if self.differentiable:
            values = jnp.concatenate([net_spiked, p_spiked.astype(jnp.float32)])
            net_spiked = net_spiked > 0.5
        spiked = jnp.concatenate([net_spiked, p_spiked])
        state = state._replace(
            step=m, cells=cells, p=p, ring=ring, noise=noise,
            prev_spike_ms=jnp.where(spiked, state.last_spike_ms, state.prev_spike_ms),
            last_spike_ms=jnp.where(spiked, t_ms, state.last_spike_ms),
            spike_count=state.spike_count + spiked.astype(jnp.int32))
        return state, jnp.where(net_spiked, m, spike_step), (spiked if values is None else values)

    @cached_property
    def block_steps(self) -> int:
        """Steps per delivery block: the largest divisor of :attr:`chunk_steps` that is no longer than the shortest
        network delay (so a block's spikes all arrive after it) nor the shortest refractory period (so a cell fires
        at most once per block)."""
        generators = self.config.spec.generators
        d_min = min(self.config.steps(pw.delay_ms[0]) for pw in self.layout.pathways if pw.pre not in generators)
        limit = max(1, min(d_min, int(self.cell_constants.n_refractory.min())))
        if self.config.block_steps:
            limit = min(limit, self.config.block_steps)
        return max(k for k in range(1, self.chunk_steps + 1) if self.chunk_steps % k == 0 and k <= limit)

    def _block(self, wiring: Wiring, state: State, params: NetworkParams, n_steps: int, collect: bool):
        """``n_steps`` (<= block_steps) cell steps, then delivery of their spikes."""
        n = self.config.n_cells
        if self.differentiable:
            return self._block_dense(wiring, state, params, n_steps, collect)

        def body(carry, _):
            s, spike_step = carry
            s, spike_step, spiked = self._cell_step(s, spike_step)
            return (s, spike_step), (spiked if collect else None)

        (state, spike_step), spikes = jax.lax.scan(body, (state, jnp.full((n,), -1, jnp.int32)), None,
                                                   length=n_steps)
        ring, pdope_ms, counters = syn_mod.deliver_block(
            state.ring, state.pdope_ms, state.counters, spike_step, state.last_spike_ms, state.prev_spike_ms, wiring,
            state.wgain, params.max_plast_t_ms, self.delivery_shape, self.config.dt_ms)
        return state._replace(ring=ring, pdope_ms=pdope_ms, counters=counters), spikes

    def _block_dense(self, wiring: Wiring, state: State, params: NetworkParams, n_steps: int, collect: bool):
        """:meth:`_block` with surrogate spikes and dense delivery (:attr:`differentiable`); the same state.

        Delivery is once per block, so each cell's surrogate derivatives of the block's steps leave at one step: its
        spike step if it fired, else the step at which its margin was closest to threshold (the largest surrogate
        density). A step's derivative therefore arrives at most ``block_steps - 1`` steps from where per-step
        delivery would put it, and exactly there with ``NetworkConfig.block_steps = 1`` (measured against it in
        ``experiments/surrogate_gradient.py``)."""
        n = self.config.n_cells
        c = self.cell_constants

        def body(carry, _):
            s, spike_step, value, near_step, nearest = carry
            s, spike_step, spiked = self._cell_step(s, spike_step)
            # the surrogate density is largest where |Vm - VTHC| is smallest (cells outside refractoriness); it
            # only chooses a step, so no derivative is carried for it
            margin = jnp.abs(cell_mod.membrane_potential(jax.lax.stop_gradient(s.cells), c, self.config.spec.physics)
                             - (c.vth + jax.lax.stop_gradient(s.cells.vthc_excess)))
            margin = jnp.where(s.cells.steps_since_spike >= c.n_refractory, margin, jnp.inf)
            closer = margin < nearest
            near_step = jnp.where(closer, s.step, near_step)
            # a cell fires at most once per block: the sum is its spike, and the sum of its surrogates backward
            return (s, spike_step, value + spiked[:n], near_step, jnp.minimum(margin, nearest)), (
                spiked if collect else None)

        first = jnp.full((n,), state.step + 1, jnp.int32)
        (state, spike_step, value, near_step, _), spikes = jax.lax.scan(
            body, (state, jnp.full((n,), -1, jnp.int32), jnp.zeros((n,), jnp.float32), first,
                   jnp.full((n,), jnp.inf, jnp.float32)), None, length=n_steps)
        ring, pdope_ms = syn_mod.deliver_block_dense(
            state.ring, state.pdope_ms, jnp.where(spike_step >= 0, spike_step, near_step), value,
            state.last_spike_ms, state.prev_spike_ms, wiring, state.wgain, params.max_plast_t_ms,
            self.delivery_shape, self.config.dt_ms)
        return state._replace(ring=ring, pdope_ms=pdope_ms), spikes

    def _chunk(self, wiring: Wiring, state: State, params: NetworkParams, n_steps: int, collect: bool):
        """Write the P input of the next ``n_steps`` (<= chunk_steps) steps, then run them block by block."""
        if self.uses_native_kernel:
            from jaxarm.network import native
            state, spikes = native.chunk(self, wiring, state, params, n_steps)
            return state, (spikes if collect else None)
        min_interval = proprio_mod.min_interval_steps(self.config)
        ring = syn_mod.deliver_p_window(
            state.ring, state.p.next_step, state.p.interval_steps, state.step, n_steps, wiring, state.wgain,
            self.p_synapses, self.config.n_cells, proprio_mod.NEVER_STEPS,
            max_spikes=n_steps // min_interval + 1, n_slots=self.n_slots, n_cells=self.config.n_cells,
            sequential=self.config.event_summation == "sequential", physics=self.config.spec.physics)
        state = state._replace(ring=ring)
        full, rest = divmod(n_steps, self.block_steps)
        outs = []
        if full:
            def block(s, _):
                return self._block(wiring, s, params, self.block_steps, collect)

            state, spikes = jax.lax.scan(block, state, None, length=full)
            if collect:
                outs.append(spikes.reshape((-1,) + spikes.shape[2:]))
        if rest:
            state, spikes = self._block(wiring, state, params, rest, collect)
            if collect:
                outs.append(spikes)
        if not collect:
            return state, None
        return state, outs[0] if len(outs) == 1 else jnp.concatenate(outs)

    def step(self, wiring: Wiring, state: State, params: NetworkParams):
        """Advance one clock step. Returns (state, spikes (n_all,) bool of this step). :meth:`run` is faster for
        many steps (it writes P input once per chunk instead of once per step)."""
        state, spiked = self._chunk(wiring, state, params, 1, True)
        return state, spiked[0]

    def run(self, wiring: Wiring, state: State, params: NetworkParams, n_steps: int, collect: bool = True):
        """``n_steps`` steps (static) by ``lax.scan`` in chunks of :attr:`chunk_steps`.

        Returns (state, spikes (n_steps, n_all) bool), or (state, None) with ``collect=False``. Muscle lengths
        (:meth:`set_lengths`) and noise rates stay fixed for the whole call. When :attr:`differentiable` the
        spikes are float32 (the same values, with a surrogate derivative) and each chunk is rematerialised on the
        backward pass (``jax.checkpoint``), so backpropagation stores one state per chunk, not per step.
        """
        full, rest = divmod(n_steps, self.chunk_steps)
        outs = []
        if full:
            def chunk(s, _):
                return self._chunk(wiring, s, params, self.chunk_steps, collect)

            if self.differentiable:
                chunk = jax.checkpoint(chunk)

            state, spikes = jax.lax.scan(chunk, state, None, length=full)
            if collect:
                outs.append(spikes.reshape((-1,) + spikes.shape[2:]))
        if rest:
            state, spikes = self._chunk(wiring, state, params, rest, collect)
            if collect:
                outs.append(spikes)
        if not collect:
            return state, None
        return state, outs[0] if len(outs) == 1 else jnp.concatenate(outs)
