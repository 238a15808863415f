"""Centre-out reaching: target positions, hand-target distance, success ([model: task](../model.md#task-and-success); SI
units: m, s).

Everything here is a pure function of arrays, so the closed loop can ``vmap`` over targets (pass target positions as
arrays, not names) and over networks.
"""
from __future__ import annotations

from typing import Sequence

import jax.numpy as jnp
import numpy as np

from jaxarm.config.arm import ARM_SEGMENTS_M, START_POSTURE_RAD
from jaxarm.task.config import TARGET_ANGLES_RAD, forward_kinematics_m
from jaxarm.config.validate import ConfigError


def target_position(name: str, segments_m=ARM_SEGMENTS_M) -> np.ndarray:
    """Hand position (2,) in m of the named target by the authors' forward kinematics."""
    if name not in TARGET_ANGLES_RAD:
        raise ConfigError(f"target = {name!r}: must be one of {', '.join(map(repr, TARGET_ANGLES_RAD))}")
    return np.asarray(forward_kinematics_m(TARGET_ANGLES_RAD[name], segments_m), dtype=np.float32)


def target_positions(names: Sequence[str], segments_m=ARM_SEGMENTS_M) -> np.ndarray:
    """(len(names), 2) hand positions in m; stack of :func:`target_position` (for ``vmap`` over targets)."""
    return np.stack([target_position(n, segments_m) for n in names])


def start_position(posture_rad=START_POSTURE_RAD, segments_m=ARM_SEGMENTS_M) -> np.ndarray:
    """Hand position (2,) in m at the start posture (original: (0.0976, 0.3809) m)."""
    return np.asarray(forward_kinematics_m(posture_rad, segments_m), dtype=np.float32)


def hand_target_distance(hand_xy, target_xy):
    """Euclidean hand-target distance in m (the original's ``errxy``). hand_xy: (..., 2) m; target_xy: (2,) m."""
    d = jnp.asarray(hand_xy) - jnp.asarray(target_xy)
    return jnp.sqrt(jnp.sum(d * d, axis=-1))


def inside_target(distance_m, radius_m=0.04):
    """True where the hand is inside the success circle (distance <= radius)."""
    return jnp.asarray(distance_m) <= radius_m


def reached(distance_m, radius_m=0.04, valid=None):
    """Success: the hand enters the circle at least once. distance_m: (T,) over the test trial.

    valid: optional (T,) bool mask of samples that count (for padded trajectories). Returns a bool scalar.
    """
    inside = inside_target(distance_m, radius_m)
    if valid is not None:
        inside = inside & jnp.asarray(valid)
    return jnp.any(inside, axis=-1)


def first_entry_index(distance_m, radius_m=0.04):
    """Index of the first sample inside the circle, or -1 if the hand never enters it. distance_m: (T,)."""
    inside = inside_target(distance_m, radius_m)
    return jnp.where(jnp.any(inside, axis=-1), jnp.argmax(inside, axis=-1), -1)
