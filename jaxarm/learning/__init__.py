"""The authors' learning rule as array primitives: critic, the reward-modulated update, motor babbling, and the
tuned metaparameters ([model: learning](../model.md#learning-reward-modulated-stdp),
[metaparameters](../model.md#metaparameters)). Tagging runs inside the network kernels; the rules built from these
primitives, behind one interface, are in :mod:`jaxarm.learning.rule` (interface), :mod:`jaxarm.learning.rstdp`,
:mod:`jaxarm.learning.gradient`, :mod:`jaxarm.learning.perturbation` and :mod:`jaxarm.learning.registry`."""
from jaxarm.learning.babbling import (EXPLORE_PATTERNS, BabblingConfig, BabblingState, babble,
                                      em_noise_rates_in_test, init_babbling, pattern_rates, start_epoch)
from jaxarm.learning.critic import MIN_ERROR_CHANGE_M, critic_signal, rl_update_due
from jaxarm.learning.metaparams import (BOUNDS, NAMES, ORIGINAL, RETIRED, Bound, MetaParams, clip_to_bounds, from_unit,
                                        stack, to_unit, as_current)
from jaxarm.learning.stdp import NEVER_SPIKED_MS, NO_TAG_MS, EligibilityConfig, dopamine_update, eligible

__all__ = [
    "EXPLORE_PATTERNS", "BabblingConfig", "BabblingState", "babble", "em_noise_rates_in_test", "init_babbling",
    "pattern_rates", "start_epoch",
    "MIN_ERROR_CHANGE_M", "critic_signal", "rl_update_due",
    "BOUNDS", "NAMES", "ORIGINAL", "RETIRED", "Bound", "MetaParams", "clip_to_bounds", "from_unit", "stack", "to_unit",
    "as_current",
    "NEVER_SPIKED_MS", "NO_TAG_MS", "EligibilityConfig", "dopamine_update", "eligible",
]
