"""Reward-modulated STDP as the original ran it: spike tagging and the dopamine-like update ([model:
learning](../model.md#learning-reward-modulated-stdp)).

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

Variants the paper describes, off by default (:class:`EligibilityConfig`): exponential decay of a tag's effect,
``exp(-(t - pdope)/tau)`` with tau = 20 ms; consuming tags after use; hard bounds (``w += inc`` clipped to
[0, maxw]). The paper's backward (post-before-pre) tags are not offered: the network kernels tag pre-before-post
pairs only, as the original ran (BACKELIGTR = 0).

Tagging itself happens inside the network kernels (:func:`jaxarm.network.synapses.deliver_block` and the native
kernel), on every postsynaptic spike; this module holds the update applied at the critic's moments.

Which synapses are plastic: ``Pathway.plastic`` in the spec (``NetworkSpec.pathways``); their soft bounds: plast_ee_maxw
onto E cells, plast_ei_maxw onto I cells (:attr:`jaxarm.loop.ClosedLoop.plastic_tables`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp

from jaxarm.config.validate import ConfigError, check_range
from jaxarm.cpu_arithmetic import divide

#: ``pdope`` of an untagged synapse (the original's -1e9; exactly representable in float32).
NO_TAG_MS = -1e9
#: Last-spike time of a cell that has not spiked in this run (any negative value means "never").
NEVER_SPIKED_MS = -1e9

@dataclass(frozen=True)
class EligibilityConfig:
    """Which form of the learning rule to run. Defaults = the code as it ran ([model:
    learning](../model.md#learning-reward-modulated-stdp)).

    Attributes:
        exponential: scale each update by exp(-(t - tag time)/exp_tau_ms) (EXPELIGTR).
        exp_tau_ms: time constant of the exponential variant, ms (the code's pplasttau = 20 ms).
        reset_after_use: clear a tag once it has been rewarded or punished (reseteligtr).
        soft_bounds: soft-bounded steps (SOFTSTDP); False: fixed steps clipped to [0, maxw].
    """

    exponential: bool = False
    exp_tau_ms: float = 20.0
    reset_after_use: bool = False
    soft_bounds: bool = True

    def __post_init__(self):
        for name in ("exponential", "reset_after_use", "soft_bounds"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"EligibilityConfig.{name} = {getattr(self, name)!r}: must be True or False")
        check_range(self, "exp_tau_ms", 0.0, 1e4, lo_open=True)


def eligible(pdope, plastic, t_ms, max_elig_tr_dur_ms):
    """Synapses whose tag is alive at t: tagged (pdope > NO_TAG_MS), plastic and t - pdope <= max_elig_tr_dur_ms."""
    return (pdope > NO_TAG_MS) & plastic & (t_ms - pdope <= max_elig_tr_dur_ms)


@partial(jax.jit, static_argnames=("config",))
def dopamine_update(wgain, pdope, plastic, maxw, inc, t_ms, signal, max_elig_tr_dur_ms,
                    config: EligibilityConfig = EligibilityConfig()):
    """Apply one critic signal to every synapse with a live tag (the original's ``dopelearn``).

    Args:
        wgain (jax.Array): (...) weight gains (dimensionless, multiplying the base weight).
        pdope (jax.Array): (...) tag times, ms.
        plastic (jax.Array): bool mask (broadcastable).
        maxw (ArrayLike): soft bound, per synapse or scalar (dimensionless, in units of the base weight).
        inc (ArrayLike): step of one update, per synapse or scalar (dimensionless).
        t_ms (float): current time, ms.
        signal (ArrayLike): +1 reward, -1 punishment, 0 nothing (a traced scalar is fine).
        max_elig_tr_dur_ms (float): tag lifetime, ms.

    Returns:
        (wgain, pdope): updated gains (>= 0) and tags (cleared after use only with ``config.reset_after_use``).
    """
    wgain = jnp.asarray(wgain)
    signal = jnp.asarray(signal)
    live = eligible(pdope, plastic, t_ms, max_elig_tr_dur_ms) & (signal != 0)
    potentiate = signal > 0
    if config.soft_bounds:
        # as a group of 8 computes it, in any group (cpu_arithmetic.divide): XLA:CPU turns a division by a bound
        # the group shares into a product with its reciprocal (other bits in 5 % of the updated gains)
        fraction = divide(wgain, maxw)
        step = jnp.where(potentiate, inc * (1.0 - fraction), -inc * fraction)
    else:
        step = jnp.where(potentiate, inc, -inc) * jnp.ones_like(wgain)
    if config.exponential:
        step = step * jnp.exp(-(t_ms - pdope) / config.exp_tau_ms)
    new = jnp.maximum(wgain + step, 0.0)
    if not config.soft_bounds:
        new = jnp.minimum(new, maxw)
    wgain = jnp.where(live, new, wgain)
    if config.reset_after_use:
        pdope = jnp.where(live, jnp.asarray(NO_TAG_MS, pdope.dtype), pdope)
    return wgain, pdope
