"""The two arms behind one interface: ``init(q0)``, ``step(state, u)``, ``observe(state)``.

``make_arm("simple")`` is the authors' kinematic arm (10 ms per step). ``make_arm("musculoskeletal",
backend="fast" | "mjx")`` is the authors' OpenSim arm translated to MJCF (1 ms per step). The names are
:data:`jaxarm.arm.registry.ARMS`.
"""
from __future__ import annotations

from jaxarm.arm.base import GROUPS, ArmObs, MuscleObs, hand_position
from jaxarm.arm.registry import ARMS, BACKENDS, choices_text, smooth_arms
from jaxarm.arm.simple import SimpleArm, SimpleArmState
from jaxarm.config.validate import ConfigError


def make_arm(kind: str = "musculoskeletal", backend: str = "fast", config=None, smooth: bool = False):
    """Build an arm. kind: a name of :data:`jaxarm.arm.registry.ARMS` ('simple' or 'musculoskeletal'); backend
    (musculoskeletal only): 'fast' or 'mjx'; config: the arm's ``SimpleArmConfig`` / ``MusculoskeletalArmConfig``
    (SI units; default: the paper's arm); smooth (musculoskeletal only): the C-infinity formulation to
    differentiate through (sets ``MusculoskeletalArmConfig.smooth``; ``docs/gradients.md``)."""
    if kind not in ARMS:
        raise ConfigError(f"kind = {kind!r}: must be one of {choices_text()}")
    arm = ARMS[kind]
    if smooth is not False and not arm.smooth:
        raise ConfigError(f"smooth = {smooth!r}: only the {' or '.join(smooth_arms())} arm has a smooth formulation, "
                          f"not {kind!r}")
    if arm.backends and backend not in BACKENDS:
        raise ConfigError(f"backend = {backend!r}: must be one of {', '.join(map(repr, BACKENDS))}")
    return arm.make(config, backend, smooth)


__all__ = ["GROUPS", "ArmObs", "MuscleObs", "hand_position", "SimpleArm", "SimpleArmState", "make_arm"]
