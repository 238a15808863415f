"""The critic: reward or punishment from the change of the hand-target distance ([model:
learning](../model.md#learning-reward-modulated-stdp); msarm.hoc RLUpdate).

The original, at each RL update, compares the two most recent stored hand-target errors ``err1`` (older) and
``err2`` (newer), 10 ms apart and both from before the current arm step (RLMode = 3, COMBERR = 0, Cartesian error):
reward (+1) if err1 - err2 >= 1 mm, punishment (-1) if err2 - err1 >= 1 mm, otherwise nothing (0).
"""
from __future__ import annotations

import jax.numpy as jnp

#: minRLerrchangeLTP = minRLerrchangeLTD of the original, m.
MIN_ERROR_CHANGE_M = 0.001


def critic_signal(err_older_m, err_newer_m, threshold_m=MIN_ERROR_CHANGE_M):
    """+1 (reward) if the hand got >= threshold closer, -1 (punishment) if >= threshold farther, else 0.

    err_older_m, err_newer_m: hand-target distances in m (any matching shapes). Returns float32 of that shape.
    """
    older = jnp.asarray(err_older_m)
    newer = jnp.asarray(err_newer_m)
    reward = older - newer >= threshold_m
    punish = newer - older >= threshold_m
    return jnp.where(reward, 1.0, jnp.where(punish, -1.0, 0.0)).astype(jnp.float32)


def rl_update_due(t_ms, last_update_ms, rl_dt_ms):
    """Whether the critic runs at this loop step: t - last > rl_dt (strict; with 10 ms steps and rl_dt = 55.55 ms
    this is every 60 ms). ``last_update_ms`` is 0 at the start of each run."""
    return jnp.asarray(t_ms) - last_update_ms > rl_dt_ms
