"""Proprioceptive (P) population code and spike generators (spec §3; msarm.hoc assignDP/updateDP, nsloc.mod).

Tuning: P cell j codes muscle group j % 4 at position k = j // 4 (48 positions per group). With the length range
[lo, hi] = [0.03, 0.23] m and step w = (hi - lo) / 48 = 4.17 mm, cell k responds to lengths (inclusive bounds)

* ``p_tuning="code"``: [lo + (k - 1) w, lo + (k + 2) w], width 3w = 12.5 mm (what the code does);
* ``p_tuning="paper"``: [lo + (k - 0.5) w, lo + (k + 1.5) w], width 2w = 8.33 mm (the paper's text), same centres.

Generators (NSLOC with noise 0, ``PState``; times in clock steps since the start of the run):

* every P cell fires once at ``p_start_ms`` (1 ms), whatever its tuning;
* a cell in its window fires a regular train at ``p_rate_hz`` (100 Hz); outside, its interval is effectively infinite;
* :func:`set_lengths` (called by the closed loop every 10 ms) changes the intervals the way NSLOC reacts: a shorter
  interval restarts the train with the first spike one new interval after the change; a longer one takes effect
  after the spike already scheduled (so a cell leaving its window fires once more).
* Before the first :func:`set_lengths` every interval is infinite, so only the start spike happens (the original's
  first P update is at t = 10 ms).

Ambiguity resolved here: NSLOC polls interval changes every 1 ms; we apply a change at the step of the call.
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.network.populations import Populations

#: "Never" for a P interval or next spike, in steps (the original's 1e8 ms interval).
NEVER_STEPS = 2 ** 30


class PState(NamedTuple):
    next_step: jnp.ndarray      # (n_P,) int32 step of each cell's next spike
    interval_steps: jnp.ndarray  # (n_P,) int32 current interval, steps (NEVER_STEPS when silent)


def tuning_windows(config: NetworkConfig) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) float32 arrays (n_P,) of every P cell's length window, m (inclusive)."""
    pops = Populations(config)
    k = pops.p_tuning_index().astype(np.float64)
    lo_m, hi_m = config.p_length_range_m
    w = (hi_m - lo_m) / config.p_positions_per_group
    if config.p_tuning == "code":
        lo, hi = lo_m + (k - 1) * w, lo_m + (k + 2) * w
    else:
        lo, hi = lo_m + (k - 0.5) * w, lo_m + (k + 1.5) * w
    return lo.astype(np.float32), hi.astype(np.float32)


def active_cells(config: NetworkConfig, lengths_m):
    """(n_P,) bool: which P cells code the 4 muscle lengths ``lengths_m`` (m, GROUPS order)."""
    lo, hi = tuning_windows(config)
    groups = jnp.asarray(Populations(config).p_groups())
    length = jnp.asarray(lengths_m, jnp.float32)[groups]
    return (length >= lo) & (length <= hi)


def init_p(config: NetworkConfig) -> PState:
    n = config.n_p
    return PState(next_step=jnp.full((n,), config.steps(config.p_start_ms), jnp.int32),
                  interval_steps=jnp.full((n,), NEVER_STEPS, jnp.int32))


def set_lengths(config: NetworkConfig, p: PState, lengths_m, step) -> PState:
    """Update the P trains for new muscle lengths (m) at clock step ``step`` (NSLOC interval-change semantics)."""
    on = active_cells(config, lengths_m)
    interval = jnp.where(on, config.steps(1000.0 / config.p_rate_hz), NEVER_STEPS).astype(jnp.int32)
    shorter = interval < p.interval_steps
    next_step = jnp.where(shorter, jnp.asarray(step, jnp.int32) + interval, p.next_step)
    return PState(next_step=next_step.astype(jnp.int32), interval_steps=interval)


def p_step(p: PState, step):
    """Spikes of the P cells at clock step ``step`` (the step just completed). Returns (state, (n_P,) bool)."""
    spiked = p.next_step == step
    following = jnp.where(p.interval_steps >= NEVER_STEPS, NEVER_STEPS, p.next_step + p.interval_steps)
    nxt = jnp.where(spiked, following, p.next_step)
    return PState(next_step=nxt, interval_steps=p.interval_steps), spiked
