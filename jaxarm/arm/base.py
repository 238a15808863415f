"""What every arm shares: the observation record and the authors' planar forward kinematics.

Arm boundary units: SI (m, s, rad). Excitations are dimensionless in [0, 1], ordered like the original's motor
groups: (shoulder extensors, shoulder flexors, elbow extensors, elbow flexors).
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import jax.numpy as jnp

from jaxarm.config.arm import ARM_SEGMENTS_M

#: Muscle-group order of excitations and proprioceptive lengths (EM/P cell id % 4 in the network).
GROUPS = ("shoulder_extensors", "shoulder_flexors", "elbow_extensors", "elbow_flexors")


class MuscleObs(NamedTuple):
    """Per-muscle detail, each (n_muscles,) in the arm's muscle order."""

    activation: jnp.ndarray      # dimensionless [0, 1]
    active_force_n: jnp.ndarray  # N, along the tendon
    passive_force_n: jnp.ndarray # N, along the tendon
    force_n: jnp.ndarray         # N, total tendon force
    fiber_length_m: jnp.ndarray  # m
    mtu_length_m: jnp.ndarray    # m, muscle-tendon unit length


class ArmObs(NamedTuple):
    """What an arm reports after a step."""

    q: jnp.ndarray        # (2,) joint angles (shoulder, elbow), rad
    qd: jnp.ndarray       # (2,) joint velocities, rad/s
    hand: jnp.ndarray     # (2,) hand position in the shoulder frame by the authors' FK, m
    proprio: jnp.ndarray  # (4,) proprioceptive lengths in GROUPS order, m
    muscles: Optional[MuscleObs] = None  # None for the simple arm


def hand_position(q, segments_m=ARM_SEGMENTS_M):
    """Authors' planar forward kinematics ([model: closed loop](../model.md#the-closed-loop)): elbow = L1 (cos q1, sin
    q1); hand = elbow + L2 (cos(q1+q2), sin(q1+q2)).

    q: (..., 2) rad. Returns (..., 2) m.
    """
    q = jnp.asarray(q)
    l1, l2 = segments_m
    q1, q12 = q[..., 0], q[..., 0] + q[..., 1]
    return jnp.stack([l1 * jnp.cos(q1) + l2 * jnp.cos(q12), l1 * jnp.sin(q1) + l2 * jnp.sin(q12)], axis=-1)
