"""Clock-driven port of the INTF6 cell (``mod/intf6.mod``, [model: cell](../model.md#cell-intf6-clock-driven)). Membrane
quantities in mV, time in ms.

State of each network cell (:class:`CellState`, arrays of shape (n_cells,), deviations from rest in mV):
``ampa`` (VAM2, distal AMPA), ``nmda`` (VNM2, distal NMDA), ``gaba_prox`` (VGA, from FS cells, tau 10 ms),
``gaba_dist`` (VGA2, from LTS cells, tau 20 ms), ``ahp`` (after-hyperpolarisation), ``vthc_excess`` (dynamic
threshold VTHC minus its resting value VTH) and ``steps_since_spike`` (int; saturates).

One step of dt, in the original's per-event order:

1. decay every component by exp(-dt/tau) (exact for a linear decay, so no integration error); once the absolute
   refractory period is over, the threshold excess decays by exp(-dt/tauRR) (the first step by exactly the time
   elapsed since the refractory period ended, so VTHC(t) = VTH + (VTHR - VTH) exp(-(t - trrs)/tauRR) on the grid);
2. V = sum of components clamped to [RMP, -RMP], the deviation used for every driving force of this step;
3. jumps from the synaptic and noise input of this step (summed weights, mV):
   AMPA ``+= w (1 - V/65)`` floored at 0; NMDA (only while below 90) ``+= w B(RMP + V) (1 - V/90)`` with the Mg block
   ``B(v) = 1 / (1 + exp(-0.062 v) 1.6/3.57)``; GABA (only while above -15) ``-= w (1 + V/15)`` capped at 0;
4. Vm = RMP + sum, clamped to [-90, 0]; if not refractory and Vm > VTHC: a spike if Vm <= Vblock, else nothing
   (depolarisation block). A spike lowers AHP by ahpwt, sets VTHC = VTH + RRWght (Vblock - VTH) and starts the
   absolute refractory period.

Differences from the event-driven original (the "LIF approximation" of the design):

* by default the threshold is tested at every step rather than only when an event arrives (the original misses
  crossings caused by decaying inhibition or a decaying dynamic threshold until the next event; with ~400
  background events per second per cell it tests every ~2.5 ms on average); ``NetworkConfig.threshold_test =
  "on_event"`` tests only in steps with input, as the original;
* events arriving in the same step share one V (the original recomputes V between events); for k equal AMPA events
  the original gives (65 - V)(1 - (1 - w/65)^k) instead of k w (1 - V/65) — the difference is second order in w/65
  and matters only for volleys of many simultaneous inputs;
* spikes, delays and the refractory period live on the dt grid (a spike is tested, and happens, at the end of a step);
  so by default a step whose excitation lifts a cell above threshold and whose inhibition brings it back below gives
  no spike, where the original fires if the excitatory event came first; ``NetworkConfig.same_step_inhibition =
  "random_order"`` draws that order per cell and step;
* the original zeroes components below hoc_epsilon and takes exp from a 5000-point table; we use exact exp;
* the proximal AMPA/NMDA components VAM/VNM receive no input in this model (every excitatory synapse and all
  excitatory noise is distal), so they are identically 0 and omitted.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.config.spec import SynapsePhysics
from jaxarm.network import surrogate
from jaxarm.network.populations import Populations

# The physics every cell shares (reversal potentials, Mg block, clamp, synaptic time constants) and the cell types'
# INTF6 parameters come from the spec (``NetworkSpec.physics``, ``NetworkSpec.cell_types``); where a function below
# is called without them, it takes the spec's defaults (``SynapsePhysics()``).
_SINCE_MAX = 2 ** 30


class CellState(NamedTuple):
    ampa: jnp.ndarray
    nmda: jnp.ndarray
    gaba_prox: jnp.ndarray
    gaba_dist: jnp.ndarray
    ahp: jnp.ndarray
    vthc_excess: jnp.ndarray
    steps_since_spike: jnp.ndarray


class CellConstants(NamedTuple):
    """Per-cell constants for one dt (numpy float32 / int32 arrays of shape (n_cells,))."""

    rmp: np.ndarray
    vth: np.ndarray
    vblock: np.ndarray
    ahpwt: np.ndarray
    post_spike_excess: np.ndarray  # RRWght (Vblock - VTH)
    n_refractory: np.ndarray       # steps a spike blocks the threshold test: ceil(refrac / dt)
    decay_ampa: np.ndarray
    decay_nmda: np.ndarray
    decay_gaba_prox: np.ndarray
    decay_gaba_dist: np.ndarray
    decay_ahp: np.ndarray
    decay_rr: np.ndarray           # exp(-dt / tauRR)
    decay_rr_first: np.ndarray     # exp(-(n_refractory dt - refrac) / tauRR), the first free step


def cell_constants(config: NetworkConfig) -> CellConstants:
    spec = config.spec
    types = [spec.cell_type(t) for t in Populations(config).cell_type_of_network_cells()]
    dt = config.dt_ms
    ph = spec.physics

    def per_cell(f):
        return np.array([f(t) for t in types], dtype=np.float32)

    n_ref = np.array([math.ceil(t.refrac_ms / dt - 1e-9) for t in types], dtype=np.int32)
    first = np.array([math.exp(-(math.ceil(t.refrac_ms / dt - 1e-9) * dt - t.refrac_ms) / t.taurr_ms)
                      for t in types], dtype=np.float32)
    uniform = lambda tau: np.full(len(types), math.exp(-dt / tau), np.float32)  # noqa: E731
    return CellConstants(
        rmp=per_cell(lambda t: t.rmp_mv), vth=per_cell(lambda t: t.vth_mv), vblock=per_cell(lambda t: t.vblock_mv),
        ahpwt=per_cell(lambda t: t.ahpwt_mv),
        post_spike_excess=per_cell(lambda t: t.rrwght * (t.vblock_mv - t.vth_mv)),
        n_refractory=n_ref,
        decay_ampa=uniform(ph.tau_ampa_ms), decay_nmda=uniform(ph.tau_nmda_ms),
        decay_gaba_prox=uniform(ph.tau_gaba_prox_ms), decay_gaba_dist=uniform(ph.tau_gaba_dist_ms),
        decay_ahp=per_cell(lambda t: math.exp(-dt / t.tauahp_ms)),
        decay_rr=per_cell(lambda t: math.exp(-dt / t.taurr_ms)),
        decay_rr_first=first,
    )


def init_cells(n: int) -> CellState:
    """Every cell at rest: components 0, VTHC = VTH, not refractory (intf6 reset())."""
    z = jnp.zeros((n,), jnp.float32)
    return CellState(ampa=z, nmda=z, gaba_prox=z, gaba_dist=z, ahp=z, vthc_excess=z,
                     steps_since_spike=jnp.full((n,), _SINCE_MAX, jnp.int32))


def event_load(w, e_rev: float, max_jump_fraction: float = SynapsePhysics.max_jump_fraction):
    """Load of synaptic weight(s) ``w`` (mV) on a channel with reversal distance ``e_rev`` (65 for AMPA, 15 for
    GABA), for the sequential summation of events arriving in one step: ``-e_rev * log(1 - w/e_rev)``. Loads add;
    a step's summed load L gives the jump ``(e_rev -+ V) (1 - exp(-L / e_rev))``, which for one event is exactly
    ``w (1 -+ V/e_rev)`` and for several is what the original's one-event-at-a-time jumps give (each event moves V
    toward the reversal by the fraction w/e_rev of the remaining distance; ``max_jump_fraction`` caps w/e_rev, so
    a weight at or beyond the reversal distance saturates). Works on numpy and jax arrays."""
    xp = jnp if isinstance(w, jnp.ndarray) else np
    return -e_rev * xp.log1p(-xp.minimum(xp.asarray(w, xp.float32) / e_rev, max_jump_fraction))


def mg_block(v_abs, physics: SynapsePhysics = SynapsePhysics()):
    """NMDA Mg-block factor of the absolute membrane potential (mV)."""
    return 1.0 / (1.0 + jnp.exp(-physics.mg_slope_per_mv * v_abs) * (physics.mg_mm / physics.mg0_mm))


def cell_step(s: CellState, ampa_in, nmda_in, gaba_prox_in, gaba_dist_in, c: CellConstants,
              sequential: bool = False, on_event: bool = False, per_event_crossing: bool = False,
              excitation_first=None, surrogate_width_mv: float = 0.0, surrogate_scale: float = 1.0,
              physics: SynapsePhysics = SynapsePhysics()):
    """Advance every cell by one step and apply this step's input (summed weights, mV, each (n_cells,)).

    ``sequential``: the AMPA and GABA inputs are summed loads (:func:`event_load`) rather than summed weights, and
    several events of one channel in a step saturate toward the reversal as the original's one-by-one jumps do.
    With one event per step both forms are the same. ``on_event``: test the threshold only in cells that received
    input in this step (``NetworkConfig.threshold_test = "on_event"``). ``per_event_crossing``
    (``NetworkConfig.crossing = "per_event"``): a cell below threshold before this step's input and above Vblock after
    it spikes, as the original, which tests after every event, would have at the event that crossed the threshold.
    ``excitation_first`` ((n_cells,) bool, ``NetworkConfig.same_step_inhibition = "random_order"``): whether this
    step's excitatory events come before its inhibitory ones; where they do and V after the excitatory jumps alone
    passes the threshold test, the cell spikes even if the inhibitory jumps bring it back below, as the original
    would have at the excitatory event (None: the end-of-step test alone, as if inhibition came first).
    ``physics``: reversal potentials, Mg block and clamp (the spec's). Returns (new state, spiked (n_cells,) bool).
    """
    E_AMPA, E_NMDA, E_GABA = physics.e_ampa_mv, physics.e_nmda_mv, physics.e_gaba_mv  # noqa: N806
    ampa = s.ampa * c.decay_ampa
    nmda = s.nmda * c.decay_nmda
    gaba_prox = s.gaba_prox * c.decay_gaba_prox
    gaba_dist = s.gaba_dist * c.decay_gaba_dist
    ahp = s.ahp * c.decay_ahp
    since = jnp.minimum(s.steps_since_spike, _SINCE_MAX - 1) + 1
    rr = jnp.where(since > c.n_refractory, c.decay_rr, jnp.where(since == c.n_refractory, c.decay_rr_first, 1.0))
    excess = s.vthc_excess * rr

    v = jnp.clip(ampa + nmda + gaba_prox + gaba_dist + ahp, c.rmp, -c.rmp)
    # driving-force factors 1 - V/E, written with reciprocals (a float division costs several multiplications)
    if sequential:
        # (E - V)(1 - exp(-L/E)) = the sum of one-by-one jumps; written as a jump per unit load times the load
        ampa_jump = (E_AMPA - v) * -jnp.expm1(ampa_in * (-1.0 / E_AMPA))
        gaba_prox_jump = (v - E_GABA) * -jnp.expm1(gaba_prox_in * (1.0 / E_GABA))
        gaba_dist_jump = (v - E_GABA) * -jnp.expm1(gaba_dist_in * (1.0 / E_GABA))
    else:
        ampa_jump = ampa_in * (1.0 - v * (1.0 / E_AMPA))
        gaba_factor = 1.0 - v * (1.0 / E_GABA)
        gaba_prox_jump, gaba_dist_jump = gaba_prox_in * gaba_factor, gaba_dist_in * gaba_factor
    ampa = jnp.maximum(ampa + ampa_jump, 0.0)
    nmda = jnp.where(nmda < E_NMDA, nmda + nmda_in * mg_block(c.rmp + v, physics) * (1.0 - v * (1.0 / E_NMDA)), nmda)
    if excitation_first is not None:
        # V after the excitatory jumps alone (summed in the end-of-step test's order), tested as that test does; the
        # flag needs both kinds of input in this step (without inhibition the end-of-step test is the same test)
        vm_exc = jnp.clip(c.rmp + ampa + nmda + gaba_prox + gaba_dist + ahp, physics.vm_min_mv, physics.vm_max_mv)
        exc_below_block = vm_exc <= c.vblock
        if per_event_crossing:
            exc_below_block = exc_below_block | (c.rmp + v <= c.vth + excess)
        fires_first = (excitation_first & (since >= c.n_refractory) & ((ampa_in != 0.0) | (nmda_in != 0.0))
                       & ((gaba_prox_in != 0.0) | (gaba_dist_in != 0.0)) & (vm_exc > c.vth + excess)
                       & exc_below_block)
    gaba_prox = jnp.where(gaba_prox > E_GABA, jnp.minimum(gaba_prox - gaba_prox_jump, 0.0), gaba_prox)
    gaba_dist = jnp.where(gaba_dist > E_GABA, jnp.minimum(gaba_dist - gaba_dist_jump, 0.0), gaba_dist)

    vm = jnp.clip(c.rmp + ampa + nmda + gaba_prox + gaba_dist + ahp, physics.vm_min_mv, physics.vm_max_mv)
    crossed = (since >= c.n_refractory) & (vm > c.vth + excess)
    if on_event:
        crossed = crossed & ((ampa_in != 0.0) | (nmda_in != 0.0) | (gaba_prox_in != 0.0) | (gaba_dist_in != 0.0))
    below_block = vm <= c.vblock
    if per_event_crossing:
        # the deviation v before this step's jumps (clamped as the driving force sees it) was below threshold: the
        # input crossed the window (VTHC, Vblock] on the way up, where one of its events would have fired the cell
        below_block = below_block | (c.rmp + v <= c.vth + excess)
    spiked = crossed & below_block
    if excitation_first is not None:
        spiked = spiked | fires_first
    out = spiked
    if surrogate_width_mv:
        out = surrogate.spike_value(spiked, vm - (c.vth + excess), since >= c.n_refractory, surrogate_width_mv,
                                    surrogate_scale)
    ahp = jnp.where(spiked, ahp - c.ahpwt, ahp)
    excess = jnp.where(spiked, c.post_spike_excess, excess)
    since = jnp.where(spiked, 0, since)
    return CellState(ampa, nmda, gaba_prox, gaba_dist, ahp, excess, since), out


def membrane_potential(s: CellState, c: CellConstants, physics: SynapsePhysics = SynapsePhysics()):
    """Vm in mV (RMP + components, clamped to [vm_min_mv, vm_max_mv], the paper's [-90, 0]), as the spike test
    sees it."""
    return jnp.clip(c.rmp + s.ampa + s.nmda + s.gaba_prox + s.gaba_dist + s.ahp, physics.vm_min_mv,
                    physics.vm_max_mv)
