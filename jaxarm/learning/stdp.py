"""Reward-modulated STDP as the original ran it: spike tagging and the dopamine-like update (spec §4).

Pure functions over plain per-synapse arrays. The network stores synapses per postsynaptic cell with fixed in-degree,
so per-synapse arrays have shape (n_post, in_degree) and ``presyn`` (same shape) holds the global id of each synapse's
presynaptic cell; but every function here is elementwise over synapses and accepts any shape.

Units: times in ms since the start of the current run (epoch), as in NEURON; ``wgain`` is the dimensionless gain
on the synapse's base (AMPA/GABA) weight, initially 1.

Original semantics (``mod/intf6.mod`` applyEDOPE / dopelearn; flags as loaded: FORWELIGTR=1, BACKELIGTR=0,
EXPELIGTR=0, SOFTSTDP=1, reseteligtr=0, EPOTW=EDEPW=1):

* Tagging: when a postsynaptic cell spikes at t, every plastic synapse onto it whose presynaptic cell's *last* spike
  satisfies 0 <= t - last_pre <= maxplastt gets ``pdope = t``. Cells that never spiked (last spike < 0) are skipped.
  Only the plastic mask decides which synapses can be tagged (the original also tags I->X synapses, whose
  increment is 0, so they never change).
* Update (critic signal s = +1 reward / -1 punishment, at most every rlDT): every plastic synapse with
  ``pdope > -1e9`` and ``t - |pdope| <= maxeligtrdur`` changes by
  reward: ``w += inc (1 - w/maxw)``; punishment: ``w -= inc w/maxw``; then ``w = max(w, 0)``.
  Tags are not consumed, so one tag can serve two critic updates 60 ms apart (< 62.28 ms).
* Soft-bound invariant: if 0 <= w <= maxw and 0 <= inc <= maxw, the update keeps 0 <= w <= maxw.

Variants the paper describes, off by default (:class:`EligibilityConfig`): backward (post-before-pre) tags stored as
``pdope = -t`` with the opposite sign of learning; exponential decay of a tag's effect, ``exp(-(t - |pdope|)/tau)``
with tau = 20 ms; consuming tags after use; hard bounds (``w += inc`` clipped to [0, maxw]).

Per-step tagging: :func:`tag_pre_before_post` touches every synapse of a block; :func:`tag_spiking_rows` touches
only the rows of cells that spiked (fixed capacity), which is what a clock-driven network should call every step.

Which synapses are plastic and their maxima: :data:`PLASTIC_PATHWAYS`, :func:`pathway_maxw`, :func:`pathway_inc`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp

from jaxarm.config.validate import ConfigError, check_range

#: ``pdope`` of an untagged synapse (the original's -1e9; exactly representable in float32).
NO_TAG_MS = -1e9
#: Last-spike time of a cell that has not spiked in this run (any negative value means "never").
NEVER_SPIKED_MS = -1e9

#: Plastic (pre, post) population pairs (main.hoc setPlastParams / basestdp.hoc setplast, spec §4).
PLASTIC_PATHWAYS: tuple[tuple[str, str], ...] = (
    ("ES", "ES"), ("ES", "IS"), ("ES", "ISL"), ("ES", "EM"),
    ("EM", "EM"), ("EM", "IM"), ("EM", "IML"), ("EM", "ES"),
)
EXCITATORY_POPULATIONS = ("ES", "EM")
INHIBITORY_POPULATIONS = ("IS", "ISL", "IM", "IML")


@dataclass(frozen=True)
class EligibilityConfig:
    """Which form of the learning rule to run. Defaults = the code as it ran (spec §4).

    Attributes:
        backward: also tag post-before-pre pairs (BACKELIGTR); such tags potentiate on punishment and depress on
            reward.
        exponential: scale each update by exp(-(t - tag time)/exp_tau_ms) (EXPELIGTR).
        exp_tau_ms: time constant of the exponential variant, ms (the code's pplasttau = 20 ms).
        reset_after_use: clear a tag once it has been rewarded or punished (reseteligtr).
        soft_bounds: soft-bounded steps (SOFTSTDP); False: fixed steps clipped to [0, maxw].
    """

    backward: bool = False
    exponential: bool = False
    exp_tau_ms: float = 20.0
    reset_after_use: bool = False
    soft_bounds: bool = True

    def __post_init__(self):
        for name in ("backward", "exponential", "reset_after_use", "soft_bounds"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"EligibilityConfig.{name} = {getattr(self, name)!r}: must be True or False")
        check_range(self, "exp_tau_ms", 0.0, 1e4, lo_open=True)


def is_plastic(pre: str, post: str) -> bool:
    """Whether synapses from population ``pre`` to ``post`` are plastic in the original."""
    return (pre, post) in PLASTIC_PATHWAYS


def pathway_maxw(pre: str, post: str, mp):
    """maxw of synapses pre -> post: plast_ee_maxw onto E cells, plast_ei_maxw onto I cells from E cells, and
    3 x max_w_scaling from I cells (unused there: inc = 0). ``mp``: :class:`~jaxarm.learning.metaparams.MetaParams`."""
    if pre in INHIBITORY_POPULATIONS:
        return mp.maxw_ix
    return mp.plast_ee_maxw if post in EXCITATORY_POPULATIONS else mp.plast_ei_maxw


def pathway_inc(pre: str, post: str, mp):
    """Learning increment of synapses pre -> post: learn_rate if plastic, else 0."""
    return mp.learn_rate if is_plastic(pre, post) else jnp.zeros_like(mp.learn_rate)


@jax.jit
def tag_pre_before_post(pdope, presyn, last_spike_ms, post_spiked, t_ms, max_plast_t_ms, plastic):
    """Forward tags: set ``pdope = t`` on plastic synapses onto cells spiking at t whose presynaptic cell last
    spiked within [0, max_plast_t_ms] ms before.

    Args:
        pdope: (n_post, K) tag times, ms (NO_TAG_MS = untagged).
        presyn: (n_post, K) int global ids of the presynaptic cells.
        last_spike_ms: (n_cells,) last spike time of every cell, ms (negative = never). Whether it already holds
            spikes of the current step decides if simultaneous pre spikes count (d = 0 does in the original).
        post_spiked: (n_post,) bool, the postsynaptic cells that spike at t.
        t_ms: current time, ms. max_plast_t_ms: pairing window, ms.
        plastic: (n_post, K) bool (or broadcastable) mask of plastic synapses.
    """
    last_pre = jnp.asarray(last_spike_ms)[presyn]
    d = t_ms - last_pre
    hit = jnp.asarray(post_spiked)[:, None] & plastic & (last_pre >= 0) & (d >= 0) & (d <= max_plast_t_ms)
    return jnp.where(hit, jnp.asarray(t_ms, pdope.dtype), pdope)


@jax.jit
def tag_spiking_rows(pdope, presyn, last_spike_ms, rows, row_valid, t_ms, max_plast_t_ms, plastic):
    """Forward tags touching only the rows of cells that spiked: the sparse form of :func:`tag_pre_before_post`.

    The dense form costs O(all synapses) per call; this one O(capacity x in-degree), for a per-step call with a
    fixed capacity of spiking cells (the network must count spikes beyond its capacity as an overflow).

    Args:
        pdope, presyn, plastic: (n_post, K) as in :func:`tag_pre_before_post` (``plastic`` must be full-shape).
        last_spike_ms: (n_cells,) ms (negative = never).
        rows: (cap,) int row indices (postsynaptic cells of this block) that spiked; row_valid: (cap,) bool, False
            for unused slots. A row must appear at most once among the valid slots.
        t_ms: spike time(s), ms: a scalar or (cap,) per-row times.
    """
    n_post = pdope.shape[0]
    rows = jnp.asarray(rows)
    safe = jnp.where(row_valid, rows, 0)
    last_pre = jnp.asarray(last_spike_ms)[presyn[safe]]                       # (cap, K)
    t_row = jnp.broadcast_to(jnp.asarray(t_ms, pdope.dtype), rows.shape)[:, None]
    d = t_row - last_pre
    hit = plastic[safe] & (last_pre >= 0) & (d >= 0) & (d <= max_plast_t_ms)
    new_rows = jnp.where(hit, t_row, pdope[safe])
    # unused slots scatter out of bounds and are dropped, so they can never overwrite a real row
    return pdope.at[jnp.where(row_valid, rows, n_post)].set(new_rows, mode="drop")


@jax.jit
def tag_post_before_pre(pdope, presyn, pre_spiked, last_spike_post_ms, t_ms, max_plast_t_ms, plastic):
    """Backward tags (variant, BACKELIGTR): when a presynaptic cell spikes at t, set ``pdope = -t`` on its plastic
    synapses onto cells that last spiked within [0, max_plast_t_ms] ms before.

    Args:
        pre_spiked: (n_cells,) bool, the cells spiking at t (global ids, indexed by ``presyn``).
        last_spike_post_ms: (n_post,) last spike times of the postsynaptic cells, ms (negative = never).
        Others as in :func:`tag_pre_before_post`.
    """
    last_post = jnp.asarray(last_spike_post_ms)[:, None]
    d = t_ms - last_post
    hit = jnp.asarray(pre_spiked)[presyn] & plastic & (last_post >= 0) & (d >= 0) & (d <= max_plast_t_ms)
    return jnp.where(hit, -jnp.asarray(t_ms, pdope.dtype), pdope)


@partial(jax.jit, static_argnames=("config",))
def tag_on_spikes(pdope, presyn, post_ids, spiked, last_spike_ms, t_ms, max_plast_t_ms, plastic,
                  config: EligibilityConfig = EligibilityConfig()):
    """All tagging for one time step in global-id form: forward tags for spiking postsynaptic cells and, with
    ``config.backward``, backward tags for spiking presynaptic cells (applied second, as the original processes
    the spiking cell's inputs before its outputs).

    post_ids: (n_post,) int global ids of the postsynaptic cells of this block; spiked: (n_cells,) bool;
    last_spike_ms: (n_cells,) ms. Other arguments as in :func:`tag_pre_before_post`.
    """
    spiked = jnp.asarray(spiked)
    last_spike_ms = jnp.asarray(last_spike_ms)
    pdope = tag_pre_before_post(pdope, presyn, last_spike_ms, spiked[post_ids], t_ms, max_plast_t_ms, plastic)
    if config.backward:
        pdope = tag_post_before_pre(pdope, presyn, spiked, last_spike_ms[post_ids], t_ms, max_plast_t_ms, plastic)
    return pdope


def eligible(pdope, plastic, t_ms, max_elig_tr_dur_ms):
    """Synapses whose tag is alive at t: tagged (pdope > NO_TAG_MS), plastic and t - |pdope| <= max_elig_tr_dur_ms."""
    return (pdope > NO_TAG_MS) & plastic & (t_ms - jnp.abs(pdope) <= max_elig_tr_dur_ms)


@partial(jax.jit, static_argnames=("config",))
def dopamine_update(wgain, pdope, plastic, maxw, inc, t_ms, signal, max_elig_tr_dur_ms,
                    config: EligibilityConfig = EligibilityConfig()):
    """Apply one critic signal to every synapse with a live tag (the original's ``dopelearn``).

    Args:
        wgain: (...) weight gains (dimensionless). pdope: (...) tag times, ms.
        plastic: bool mask (broadcastable). maxw, inc: per-synapse or scalar soft bound and step.
        t_ms: current time, ms. signal: +1 reward, -1 punishment, 0 nothing (a traced scalar is fine).
        max_elig_tr_dur_ms: tag lifetime, ms.

    Returns:
        (wgain, pdope): updated gains (>= 0) and tags (cleared after use only with ``config.reset_after_use``).
    """
    wgain = jnp.asarray(wgain)
    signal = jnp.asarray(signal)
    live = eligible(pdope, plastic, t_ms, max_elig_tr_dur_ms) & (signal != 0)
    forward = pdope >= 0
    potentiate = (signal > 0) == forward          # reward x forward or punishment x backward -> LTP
    if config.soft_bounds:
        step = jnp.where(potentiate, inc * (1.0 - wgain / maxw), -inc * (wgain / maxw))
    else:
        step = jnp.where(potentiate, inc, -inc) * jnp.ones_like(wgain)
    if config.exponential:
        step = step * jnp.exp(-(t_ms - jnp.abs(pdope)) / config.exp_tau_ms)
    new = jnp.maximum(wgain + step, 0.0)
    if not config.soft_bounds:
        new = jnp.minimum(new, maxw)
    wgain = jnp.where(live, new, wgain)
    if config.reset_after_use:
        pdope = jnp.where(live, jnp.asarray(NO_TAG_MS, pdope.dtype), pdope)
    return wgain, pdope
