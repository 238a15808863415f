"""Motor readout: EM spikes per muscle group in a lagged window -> 4 muscle excitations ([model: closed
loop](../model.md#the-closed-loop), msarm.hoc L280-544).

Every interface period (10 ms) the loop pushes the EM spike counts of the period just ended, per muscle group
(EM global id % 4), into a history (``ReadoutState.bins``; row i holds the spikes in (t - 10(i+1), t - 10 i] where t
is the time of the last push). The excitation at time t is

    u_g = sum of rows with t - 10 i in [t - window - lag, t - lag)  /  v_em_max

with window = mcmdspkwd = 76.08 ms, lag = EMlag = 50 ms, v_em_max = 117.92 (original values): rows i = 6..12, i.e.
exactly the spikes in **(t - 130, t - 60]**. Before t >= window + lag (126.08 ms, so until t = 120 ms) u = 0.
``NetworkConfig.readout_clip`` clips u to [0, 1] (the paper's thresholded readout; the hoc code does not clip).
Window, lag and v_em_max are traced (evolution tunes the first and last).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.network.populations import N_GROUPS, Populations

V_EM_MAX = 117.92
WINDOW_MS = 76.08
LAG_MS = 50.0


class ReadoutState(NamedTuple):
    bins: jnp.ndarray    # (readout_bins, 4) float32 EM spike counts per period, newest first
    pushes: jnp.ndarray  # () int32 number of periods pushed (t = pushes * interface_ms)


def init_readout(config: NetworkConfig) -> ReadoutState:
    return ReadoutState(bins=jnp.zeros((config.readout_bins, N_GROUPS), jnp.float32),
                        pushes=jnp.zeros((), jnp.int32))


def em_group_counts(config: NetworkConfig, counts):
    """(4,) EM spikes per muscle group from per-cell counts (..., n_all) (or (..., n_cells))."""
    em = jnp.asarray(counts)[..., Populations(config).slice(config.spec.readout)]
    # a one-hot product rather than a scatter-add: XLA:CPU makes a float scatter-add deterministic by sorting its
    # indices (~5 % of a training step in a profile; integer counts are exact in float32 either way)
    one_hot = np.eye(N_GROUPS, dtype=np.float32)[Populations(config).em_groups()]
    return jnp.matmul(em.astype(jnp.float32), one_hot, precision=jax.lax.Precision.HIGHEST)


def push(state: ReadoutState, group_counts) -> ReadoutState:
    """Append the (4,) EM spike counts of the period that just ended."""
    bins = jnp.concatenate([jnp.asarray(group_counts, jnp.float32)[None], state.bins[:-1]], axis=0)
    return ReadoutState(bins=bins, pushes=state.pushes + 1)


def window_rows(config: NetworkConfig, window_ms=WINDOW_MS, lag_ms=LAG_MS):
    """(readout_bins,) bool: which history rows the readout sums (row i ends 10 i ms before the last push)."""
    age = jnp.arange(config.readout_bins, dtype=jnp.float32) * config.interface_ms
    return (age > lag_ms) & (age <= jnp.asarray(window_ms) + lag_ms)


def excitation(config: NetworkConfig, state: ReadoutState, v_em_max=V_EM_MAX, window_ms=WINDOW_MS, lag_ms=LAG_MS):
    """(4,) muscle excitations (dimensionless) at the time of the last push."""
    rows = window_rows(config, window_ms, lag_ms)
    t_ms = state.pushes.astype(jnp.float32) * config.interface_ms
    total = jnp.sum(jnp.where(rows[:, None], state.bins, 0.0), axis=0)
    if config.readout_em_reference:
        total = total * (config.readout_em_reference / config.size(config.spec.readout))
    u = jnp.where(t_ms >= jnp.asarray(window_ms) + lag_ms, total / v_em_max, 0.0)
    return jnp.clip(u, 0.0, 1.0) if config.readout_clip else u
