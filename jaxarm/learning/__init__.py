"""The authors' learning rule as array primitives: critic, tagging + reward-modulated update, synaptic scaling,
motor babbling, and the tuned metaparameters (spec §4, §5, §7)."""
from jaxarm.learning.babbling import (EXPLORE_PATTERNS, BabblingConfig, BabblingState, babble,
                                      em_noise_rates_in_test, init_babbling, pattern_rates, start_epoch)
from jaxarm.learning.critic import MIN_ERROR_CHANGE_M, critic_signal, rl_update_due
from jaxarm.learning.metaparams import BOUNDS, NAMES, ORIGINAL, Bound, MetaParams, clip_to_bounds, from_unit, stack, to_unit
from jaxarm.learning.scaling import apply_synaptic_scaling, scaling_due, scaling_factor
from jaxarm.learning.stdp import (NEVER_SPIKED_MS, NO_TAG_MS, PLASTIC_PATHWAYS, EligibilityConfig, dopamine_update,
                                  eligible, is_plastic, pathway_inc, pathway_maxw, tag_on_spikes, tag_post_before_pre,
                                  tag_pre_before_post, tag_spiking_rows)

__all__ = [
    "EXPLORE_PATTERNS", "BabblingConfig", "BabblingState", "babble", "em_noise_rates_in_test", "init_babbling",
    "pattern_rates", "start_epoch",
    "MIN_ERROR_CHANGE_M", "critic_signal", "rl_update_due",
    "BOUNDS", "NAMES", "ORIGINAL", "Bound", "MetaParams", "clip_to_bounds", "from_unit", "stack", "to_unit",
    "apply_synaptic_scaling", "scaling_due", "scaling_factor",
    "NEVER_SPIKED_MS", "NO_TAG_MS", "PLASTIC_PATHWAYS", "EligibilityConfig", "dopamine_update", "eligible",
    "is_plastic", "pathway_inc", "pathway_maxw", "tag_on_spikes", "tag_post_before_pre", "tag_pre_before_post",
    "tag_spiking_rows",
]
