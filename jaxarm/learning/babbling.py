"""Motor babbling: which EM muscle groups get extra background noise, and for how long ([model:
babbling](../model.md#learning-reward-modulated-stdp)).

As the code did it (msarm.hoc updateArm / SetEMNoiseRate, main.hoc train/test):

* The babbling state is checked only at RL updates (every 60 ms). When t - last_change >= change_dt, a new
  duration change_dt ~ U(100, randomMuscleDTmax) ms and a new pattern p = int(U(0, exploreTot/2)) are drawn
  (``EMNoiseMuscleGroup = 2p`` in the code). With randomMuscleDTmax <= 0 the pattern instead steps p -> p+1,
  wrapping to 0 when 2(p+1) >= exploreTot, and change_dt stays as it is.
* A pattern is one muscle group or a pair (``expSeq``, :data:`EXPLORE_PATTERNS`); with exploreTot = 16 the eight
  patterns are the four single groups and the pairs (sh-ext + el-ext), (sh-flex + el-flex), (sh-ext + el-flex),
  (sh-flex + el-ext).
* At every RL update the EM AMPA noise rate is set: EMNoiseRate (152.76 Hz) for cells of the pattern's group(s),
  EMNoiseRateMin (50 Hz) for the others. Before the first RL update of the first epoch every EM cell gets the
  default 200 Hz; later epochs start with the previous epoch's last setting.
* Initial pattern 0 (sh-ext) with change_dt = 1000 ms; at the start of every epoch last_change = 0 while pattern,
  change_dt and the rates carry over (initArmCB resets only lastMuscleNoiseChange).
* Test: every EM cell gets EMNoiseRate(test) = 99.01 Hz (:func:`em_noise_rates_in_test`).

The original seeds its draws with Random.ACG(inputseed + iepoch + t); we use an explicit JAX key per call (e.g.
``jax.random.fold_in(epoch_key, step)``), so the sequence differs from NEURON's but is deterministic for a key.

The paper's description ("one muscle group at a time ... max 1.5 s") is ``BabblingConfig(variant="paper")``:
single groups only, durations ~ U(min_dt_ms, max_dt_ms) = U(100, 1500) ms (the paper gives no minimum; we keep
the code's 100 ms).

Muscle groups (rates order): 0 shoulder extensors, 1 shoulder flexors, 2 elbow extensors, 3 elbow flexors
(EM cell id % 4).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.config.validate import check_choice, check_range

N_GROUPS = 4

#: expSeq of msarm.hoc initarm: pattern p activates groups expSeq[2p], expSeq[2p+1] (-1 = none). 16 patterns.
_EXP_SEQ = ((0, -1), (1, -1), (2, -1), (3, -1), (0, 2), (1, 3), (0, 3), (1, 2),
            (3, -1), (1, -1), (2, -1), (0, -1), (1, 2), (1, 3), (0, 2), (0, 3))
#: (16, 4) bool: which muscle groups each babbling pattern drives.
EXPLORE_PATTERNS = np.array([[g in pair for g in range(N_GROUPS)] for pair in _EXP_SEQ], dtype=bool)


@dataclass(frozen=True)
class BabblingConfig:
    """Static form of the babbling schedule.

    Attributes:
        variant: "code" (singles and pairs, U(min_dt_ms, randomMuscleDTmax)) or "paper" (single groups,
            U(min_dt_ms, max_dt_ms)).
        min_dt_ms: lower end of the duration distribution, ms (code: 100).
        max_dt_ms: upper end of the durations in the "paper" variant, ms (paper: 1.5 s); the "code" variant takes
            it from the metaparameters (``random_muscle_dt_max_ms``).
        initial_dt_ms: change_dt before the first draw, ms (code: 1000).
        initial_rate_hz: EM AMPA noise before the first RL update of the first epoch, Hz (code: 200).
        off_rate_hz: EM AMPA noise of groups not being babbled, Hz (EMNoiseRateMin = 50).
    """

    variant: str = "code"
    min_dt_ms: float = 100.0
    max_dt_ms: float = 1500.0
    initial_dt_ms: float = 1000.0
    initial_rate_hz: float = 200.0
    off_rate_hz: float = 50.0

    #: Former field names -> current ones: a run folder's record that uses them still reads
    #: (:func:`jaxarm.learning.rule.config_from_dict`).
    RENAMED_FIELDS = {"paper_max_dt_ms": "max_dt_ms"}

    def __post_init__(self):
        check_choice(self, "variant", ("code", "paper"))
        check_range(self, "min_dt_ms", 0.0, 1e5)
        check_range(self, "max_dt_ms", self.min_dt_ms, 1e5, lo_open=True)
        check_range(self, "initial_dt_ms", 0.0, 1e5)
        check_range(self, "initial_rate_hz", 0.0, 1e4)
        check_range(self, "off_rate_hz", 0.0, 1e4)


class BabblingState(NamedTuple):
    """Babbling state carried through training (scalars, or batched under ``vmap``)."""

    pattern: jnp.ndarray         # int32 index into EXPLORE_PATTERNS (the code's EMNoiseMuscleGroup / 2)
    last_change_ms: jnp.ndarray  # float32 time of the last pattern change in this run, ms
    change_dt_ms: jnp.ndarray    # float32 current duration, ms
    rates_hz: jnp.ndarray        # (4,) float32 EM AMPA noise rate per muscle group, Hz


def init_babbling(config: BabblingConfig = BabblingConfig()) -> BabblingState:
    """State at the start of training: pattern 0 (shoulder extensors), change_dt 1000 ms, 200 Hz everywhere."""
    return BabblingState(pattern=jnp.asarray(0, jnp.int32), last_change_ms=jnp.asarray(0.0, jnp.float32),
                         change_dt_ms=jnp.asarray(config.initial_dt_ms, jnp.float32),
                         rates_hz=jnp.full((N_GROUPS,), config.initial_rate_hz, jnp.float32))


def start_epoch(state: BabblingState) -> BabblingState:
    """New epoch (a fresh NEURON run): the change clock restarts at 0; pattern, duration and rates carry over."""
    return state._replace(last_change_ms=jnp.zeros_like(state.last_change_ms))


def pattern_rates(pattern, on_rate_hz, off_rate_hz):
    """(4,) noise rates, Hz: ``on_rate_hz`` for the groups of ``pattern``, ``off_rate_hz`` for the others."""
    on = jnp.asarray(EXPLORE_PATTERNS)[pattern]
    return jnp.where(on, jnp.asarray(on_rate_hz, jnp.float32), jnp.asarray(off_rate_hz, jnp.float32))


@partial(jax.jit, static_argnames=("config",))
def babble(key, state: BabblingState, t_ms, mp, config: BabblingConfig = BabblingConfig()):
    """One babbling step, to be called at every RL update (t in ms since the start of the run).

    Args:
        key (jax.Array): JAX PRNG key for this call.
        state (BabblingState): the babbling state.
        t_ms (float): current time, ms.
        mp (MetaParams): the metaparameters (uses random_muscle_dt_max_ms, explore_tot,
            em_noise_rate_train_hz).
    Returns:
        (new state, (4,) EM AMPA noise rates in Hz to apply from now on).
    """
    k_dt, k_pattern = jax.random.split(key)
    t = jnp.asarray(t_ms, jnp.float32)
    change = t - state.last_change_ms >= state.change_dt_ms
    u_dt = jax.random.uniform(k_dt, dtype=jnp.float32)
    u_pattern = jax.random.uniform(k_pattern, dtype=jnp.float32)
    n_patterns = EXPLORE_PATTERNS.shape[0]
    if config.variant == "paper":
        new_dt = config.min_dt_ms + u_dt * (config.max_dt_ms - config.min_dt_ms)
        new_pattern = jnp.minimum(jnp.floor(u_pattern * N_GROUPS), N_GROUPS - 1).astype(jnp.int32)
    else:
        dt_max = jnp.asarray(mp.random_muscle_dt_max_ms, jnp.float32)
        half = jnp.asarray(mp.explore_tot, jnp.float32) / 2.0
        random_dt = config.min_dt_ms + u_dt * (dt_max - config.min_dt_ms)
        random_pattern = jnp.clip(jnp.floor(u_pattern * half), 0, n_patterns - 1).astype(jnp.int32)
        # randomMuscleDTmax <= 0: the code's fixed cycle through the sequence with the current duration.
        step = state.pattern + 1
        cycled = jnp.where(2.0 * step >= 2.0 * half, 0, jnp.minimum(step, n_patterns - 1)).astype(jnp.int32)
        is_random = dt_max > 0
        new_dt = jnp.where(is_random, random_dt, state.change_dt_ms)
        new_pattern = jnp.where(is_random, random_pattern, cycled)
    pattern = jnp.where(change, new_pattern, state.pattern).astype(jnp.int32)
    rates = pattern_rates(pattern, mp.em_noise_rate_train_hz, config.off_rate_hz)
    new_state = BabblingState(
        pattern=pattern,
        last_change_ms=jnp.where(change, t, state.last_change_ms),
        change_dt_ms=jnp.where(change, new_dt, state.change_dt_ms).astype(jnp.float32),
        rates_hz=rates,
    )
    return new_state, rates


def em_noise_rates_in_test(mp):
    """(4,) EM AMPA noise rates of the test trial, Hz: EMNoiseRate(test) to every group (no babbling)."""
    return jnp.full((N_GROUPS,), 1.0, jnp.float32) * jnp.asarray(mp.em_noise_rate_test_hz, jnp.float32)
