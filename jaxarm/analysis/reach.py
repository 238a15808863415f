"""Reach metrics of one test trial, as the paper reports them (Dura-Bernal et al. 2015, §3.2). SI units: m, s.

Conventions (the paper does not define them; these are ours and are applied identically to every trajectory):

* ``xy[k]`` is the hand position at time k·dt from the start of the trial; include the start sample (k = 0), as the
  original's arm table does (``nqa`` row at t = 0), so a 1 s test at 10 ms gives T = 101 samples.
* inside the target area: hand-target distance <= radius (4 cm). First entry = first such sample.
* interval k (k = 1 … T-1) joins samples k-1 and k; its speed is |xy[k] - xy[k-1]| / dt.
* movement onset = start of the first interval whose speed exceeds ``onset_speed_m_s`` (default 0.02 m/s, i.e. the
  hand moved more than 0.2 mm in 10 ms).
* mean velocity before reaching = mean speed of the intervals from onset to first entry (= path length / time);
  mean velocity after reaching = mean speed of the intervals after first entry to the end of the trial.
* mean distance after reaching = mean hand-target distance over the samples from first entry to the end.
* time inside = number of samples inside × dt (all visits, not only the first).

Metrics that are undefined for a trial (it never reaches the target, never moves, or reaches it on the last sample)
are NaN, so averages over networks use ``nanmean`` over the successful ones, as the paper averaged "across
successful trajectories". All functions are pure and ``vmap``-able: masks, no data-dependent shapes.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

#: Success radius of the paper, m.
SUCCESS_RADIUS_M = 0.04
#: Default movement-onset speed threshold, m/s.
ONSET_SPEED_M_S = 0.02


class ReachMetrics(NamedTuple):
    """Per-trial reach metrics (scalars, or arrays with the batch shape under ``vmap``)."""

    success: jnp.ndarray                 # bool: the hand entered the target circle during the trial
    min_distance_m: jnp.ndarray          # smallest hand-target distance, m
    final_distance_m: jnp.ndarray        # hand-target distance at the last sample, m
    first_entry_s: jnp.ndarray           # time of the first sample inside, s (NaN if never)
    time_inside_s: jnp.ndarray           # total time inside the circle, s (0 if never)
    onset_s: jnp.ndarray                 # movement onset, s (NaN if the hand never moves)
    speed_before_m_s: jnp.ndarray        # mean speed from onset to first entry, m/s (NaN if undefined)
    speed_after_m_s: jnp.ndarray         # mean speed after first entry, m/s (NaN if undefined)
    distance_after_m: jnp.ndarray        # mean distance to the target centre from first entry on, m (NaN if never)


def interval_speeds(xy, dt):
    """(..., T-1) speeds of the intervals between consecutive samples, m/s. xy: (..., T, 2) m sampled every dt s."""
    seg = jnp.diff(jnp.asarray(xy), axis=-2)
    return jnp.sqrt(jnp.sum(seg * seg, axis=-1)) / dt


def _masked_mean(values, mask):
    n = jnp.sum(mask, axis=-1)
    total = jnp.sum(jnp.where(mask, values, 0.0), axis=-1)
    return jnp.where(n > 0, total / jnp.maximum(n, 1), jnp.nan)


class DistanceMetrics(NamedTuple):
    """The reach metrics that need only the hand–target distance (for references that store nothing else, such as
    the original NEURON model's runs); :func:`reach_metrics` computes the same fields the same way."""

    success: jnp.ndarray                 # bool: the distance fell to the radius or below
    first_entry_s: jnp.ndarray           # time of the first sample inside, s (NaN if never)
    time_inside_s: jnp.ndarray           # total time inside the circle, s (0 if never)
    distance_after_m: jnp.ndarray        # mean distance from first entry to the end, same unit as the input (NaN if never)


def _distance_metrics_and_entry(dist, dt, radius_m):
    """:class:`DistanceMetrics` and the first entry's sample index (T = never), which :func:`reach_metrics` also needs."""
    n = dist.shape[-1]
    inside = dist <= radius_m
    success = jnp.any(inside, axis=-1)
    entry = jnp.where(success, jnp.argmax(inside, axis=-1), n)          # n = "never"
    return DistanceMetrics(
        success=success,
        first_entry_s=jnp.where(success, entry * dt, jnp.nan),
        time_inside_s=jnp.sum(inside, axis=-1) * dt,
        distance_after_m=_masked_mean(dist, (jnp.arange(n) >= entry[..., None]) & success[..., None]),
    ), entry


@jax.jit
def distance_metrics(distance, dt, radius_m=SUCCESS_RADIUS_M) -> DistanceMetrics:
    """Entry, time inside and mean distance after entry of one trial from its hand–target distance alone.

    Args:
        distance (ArrayLike): (T,) hand–target distance, ``distance[k]`` at time k·dt, in the unit of ``radius_m``
            (m by default; pass ``radius_m=4.0`` for cm).
        dt (float): sample period in s.
        radius_m (float): success radius, same unit as ``distance`` (paper: 0.04 m).
    """
    dist = jnp.asarray(distance)
    if not jnp.issubdtype(dist.dtype, jnp.floating):
        dist = dist.astype(jnp.float32)
    return _distance_metrics_and_entry(dist, dt, radius_m)[0]


@jax.jit
def reach_metrics(xy, target_xy, dt, radius_m=SUCCESS_RADIUS_M, onset_speed_m_s=ONSET_SPEED_M_S) -> ReachMetrics:
    """Reach metrics of one trial.

    Args:
        xy (ArrayLike): (T, 2) hand positions in m, ``xy[k]`` at time k·dt (T >= 2).
        target_xy (ArrayLike): (2,) target centre in m.
        dt (float): sample period in s.
        radius_m (float): success radius in m (paper: 0.04).
        onset_speed_m_s (float): speed in m/s above which an interval counts as movement (movement onset).
    """
    xy = jnp.asarray(xy)
    if not jnp.issubdtype(xy.dtype, jnp.floating):
        xy = xy.astype(jnp.float32)
    n = xy.shape[-2]
    k = jnp.arange(n)
    dist = jnp.sqrt(jnp.sum((xy - jnp.asarray(target_xy, xy.dtype)) ** 2, axis=-1))
    by_distance, entry = _distance_metrics_and_entry(dist, dt, radius_m)
    success = by_distance.success

    speed = interval_speeds(xy, dt)                              # interval i joins samples i and i+1
    moving = speed > onset_speed_m_s
    moves = jnp.any(moving)
    onset = jnp.where(moves, jnp.argmax(moving), n)              # sample at which movement starts

    interval_end = k[1:]                                         # interval i ends at sample i+1
    before = (interval_end > onset) & (interval_end <= entry) & success
    after = (interval_end > entry) & success
    return ReachMetrics(
        success=success,
        min_distance_m=jnp.min(dist),
        final_distance_m=dist[-1],
        first_entry_s=by_distance.first_entry_s,
        time_inside_s=by_distance.time_inside_s,
        onset_s=jnp.where(moves, onset * dt, jnp.nan),
        speed_before_m_s=_masked_mean(speed, before),
        speed_after_m_s=_masked_mean(speed, after),
        distance_after_m=by_distance.distance_after_m,
    )
