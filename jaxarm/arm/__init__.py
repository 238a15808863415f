"""The two arms behind one interface: ``init(q0)``, ``step(state, u)``, ``observe(state)``.

``make_arm("simple")`` is the authors' kinematic arm (10 ms per step). ``make_arm("musculoskeletal",
backend="mjx" | "fast")`` is the authors' OpenSim arm translated to MJCF (1 ms per step).
"""
from __future__ import annotations

from jaxarm.arm.base import GROUPS, ArmObs, MuscleObs, hand_position
from jaxarm.arm.simple import SimpleArm, SimpleArmState
from jaxarm.config.validate import ConfigError

ARM_KINDS = ("simple", "musculoskeletal")
BACKENDS = ("mjx", "fast")


def make_arm(kind: str = "musculoskeletal", backend: str = "fast", config=None, smooth: bool = False):
    """Build an arm. kind: 'simple' or 'musculoskeletal'; backend (musculoskeletal only): 'mjx' or 'fast';
    config: the arm's ``SimpleArmConfig`` / ``MusculoskeletalArmConfig`` (SI units; default: the paper's arm);
    smooth (musculoskeletal only): the C-infinity formulation to differentiate through (sets
    ``MusculoskeletalArmConfig.smooth``; ``docs/gradients.md``)."""
    if smooth is not False and kind != "musculoskeletal":
        raise ConfigError(f"smooth = {smooth!r}: only the musculoskeletal arm has a smooth formulation, not {kind!r}")
    if kind == "simple":
        from jaxarm.config.arm import SimpleArmConfig
        return SimpleArm(config or SimpleArmConfig())
    if kind == "musculoskeletal":
        if backend not in BACKENDS:
            raise ConfigError(f"backend = {backend!r}: must be one of {', '.join(map(repr, BACKENDS))}")
        from jaxarm.arm.musculoskeletal import make_musculoskeletal_arm
        if smooth:
            import dataclasses

            from jaxarm.config.arm import MusculoskeletalArmConfig
            config = dataclasses.replace(config or MusculoskeletalArmConfig(), smooth=True)
        return make_musculoskeletal_arm(backend, config)
    raise ConfigError(f"kind = {kind!r}: must be one of {', '.join(map(repr, ARM_KINDS))}")


__all__ = ["GROUPS", "ArmObs", "MuscleObs", "hand_position", "SimpleArm", "SimpleArmState", "make_arm"]
