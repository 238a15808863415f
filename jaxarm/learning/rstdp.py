"""Reward-modulated STDP with motor babbling, the paper's learning rule ([model:
learning](../model.md#learning-reward-modulated-stdp), babbling included), behind the learning-rule interface
(:mod:`jaxarm.learning.rule`).

After every 10 ms training interval at time t (ms since the start of the epoch), in the original's order:

1. if t - last critic update > rl_dt_ms, the critic compares the last two stored errors (10 ms apart, both from
   before this interval's arm step) and rewards (>= 1 mm closer) or punishes (>= 1 mm farther) every plastic
   synapse with a live tag (:func:`jaxarm.learning.stdp.dopamine_update`; tagging runs inside the network kernels);
2. every syn_scaling_dt_ms, global synaptic scaling brings the network's weighted total back to its initial S0;
3. at the critic's moments motor babbling picks the EM noise rates (:mod:`jaxarm.learning.babbling`).

The babbling state is carried from epoch to epoch; the critic's and the scaling's clocks restart with every epoch.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.batching import when_any
from jaxarm.config.validate import ConfigError
from jaxarm.cpu_arithmetic import rows_dot
from jaxarm.learning import babbling as bab
from jaxarm.learning import critic as crit
from jaxarm.learning import stdp
from jaxarm.learning.rule import LearningRule, plastic_upper
from jaxarm.network import noise as noise_mod


@dataclass(frozen=True)
class RSTDPConfig:
    """Static form of R-STDP.

    Attributes:
        babbling: the babbling schedule (:class:`~jaxarm.learning.babbling.BabblingConfig`).
        eligibility: the form of the reward-modulated update (:class:`~jaxarm.learning.stdp.EligibilityConfig`).
        plasticity: False freezes the weights (babbling still runs): a control condition.
    """

    babbling: bab.BabblingConfig = field(default_factory=bab.BabblingConfig)
    eligibility: stdp.EligibilityConfig = field(default_factory=stdp.EligibilityConfig)
    plasticity: bool = True

    def __post_init__(self):
        for name, kind in (("babbling", bab.BabblingConfig), ("eligibility", stdp.EligibilityConfig)):
            if not isinstance(getattr(self, name), kind):
                raise ConfigError(f"RSTDPConfig.{name} = {getattr(self, name)!r}: must be a {kind.__name__}")
        if not isinstance(self.plasticity, bool):
            raise ConfigError(f"RSTDPConfig.plasticity = {self.plasticity!r}: must be True or False")


class RSTDPRun(NamedTuple):
    """R-STDP's state within an epoch."""

    babble: bab.BabblingState
    last_rl_ms: jnp.ndarray       # () time of the last critic update, ms
    last_scaling_ms: jnp.ndarray  # () time of the last synaptic scaling, ms


class RSTDP(LearningRule):
    """The paper's rule; its state across epochs is the :class:`~jaxarm.learning.babbling.BabblingState`."""

    Config = RSTDPConfig
    summary = "reward-modulated STDP with motor babbling, the paper's (default)"

    @cached_property
    def scaling_tables(self):
        """Per synapse: |AMPA| + |NMDA| or |GABA| base weight (mV), zero for the generator's (P->ES: scaling counts
        the 512 network cells only, as in the original), and the total S0 of those base weights."""
        layout = self.loop.net.layout
        generators = self.loop.net.config.spec.generators
        per_pathway = [0.0 if pw.pre in generators else abs(pw.weight_mv) + abs(layout.nmda_weight_mv(pw))
                       for pw in layout.pathways]
        base = np.array([per_pathway[i] for i in layout.pathway_of_synapse()], np.float32)
        return base, float(base.sum())  # numpy: a cached jax array would leak from the first trace that built it

    def init(self, key) -> bab.BabblingState:
        return bab.init_babbling(self.config.babbling)

    def begin_epoch(self, state: bab.BabblingState, wgain, mp):
        babble = bab.start_epoch(state)
        zero = jnp.zeros((), jnp.float32)
        return RSTDPRun(babble=babble, last_rl_ms=zero, last_scaling_ms=zero), babble.rates_hz

    def end_epoch(self, run: RSTDPRun, net, mp):
        return run.babble, net.wgain

    def reinforce(self, x, aux):
        """One critic signal applied to every plastic synapse with a live tag ([model:
        learning](../model.md#learning-reward-modulated-stdp)). x = (wgain, pdope_ms)."""
        (wgain, pdope), (mp, t_ms, signal) = x, aux
        n_plastic = self.loop.net.layout.n_plastic
        maxw = plastic_upper(self.loop.plastic_tables, mp)
        w_plastic, pdope = stdp.dopamine_update(wgain[:n_plastic], pdope, True, maxw, mp.learn_rate, t_ms, signal,
                                                mp.max_elig_tr_dur_ms, config=self.config.eligibility)
        return wgain.at[:n_plastic].set(w_plastic), pdope

    def scale(self, wgain, _):
        """Global synaptic scaling ([model: learning](../model.md#learning-reward-modulated-stdp)): if the weighted
        total S grew beyond the initial S0, every gain is multiplied by S0/S. Two dot products: the original's per-cell
        bookkeeping only excludes cells whose outgoing gains are all exactly 0, which soft-bounded multiplicative
        updates never reach."""
        base, s0 = self.scaling_tables
        factor = s0 / jnp.maximum(rows_dot(base, wgain), 1e-12)   # the same bits in any batch
        return jnp.where((base > 0) & (factor < 1.0), wgain * factor, wgain)  # P->ES inputs are not INTF6 synapses

    def _set_em_rates(self, noise, rates_hz):
        return noise_mod.set_em_rates(self.loop.config.network, noise, rates_hz)

    def update(self, run: RSTDPRun, net, key, moment, mp):
        t_ms = moment.t_ms
        due = crit.rl_update_due(t_ms, run.last_rl_ms, mp.rl_dt_ms)
        signal = jnp.where(due, crit.critic_signal(moment.err_hist_m[0], moment.err_hist_m[1]), 0.0)
        last_scaling = run.last_scaling_ms
        if self.config.plasticity:
            # The updates are due at the critic's and the scaling's moments only; when_any skips them in every
            # interval where no network of a batch needs them (same result as computing and masking).
            wgain, pdope = when_any(signal != 0, self.reinforce, (net.wgain, net.pdope_ms), (mp, t_ms, signal))
            scale_due = (t_ms - run.last_scaling_ms) >= mp.syn_scaling_dt_ms
            wgain = when_any(scale_due, self.scale, wgain)
            net = net._replace(wgain=wgain, pdope_ms=pdope)
            last_scaling = jnp.where(scale_due, t_ms, run.last_scaling_ms)
        new_babble, rates = bab.babble(key, run.babble, t_ms, mp, config=self.config.babbling)
        babble = jax.tree_util.tree_map(lambda a, b: jnp.where(due, a, b), new_babble, run.babble)
        net = net._replace(noise=when_any(due, self._set_em_rates, net.noise, rates))
        last_rl = jnp.where(due, t_ms, run.last_rl_ms)
        return RSTDPRun(babble=babble, last_rl_ms=last_rl, last_scaling_ms=last_scaling), net, signal
