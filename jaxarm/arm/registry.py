"""Arms by name: :func:`jaxarm.arm.make_arm`, ``LoopConfig.arm``, ``FitnessOptions.arm``, a preset's ``arms`` and
every command's ``--arm`` take their choices from :data:`ARMS`. A new arm is its module (``init(q0)``,
``step(state, u)``, ``observe(state)``, ``dt_s``), its configuration class and one entry here."""
from __future__ import annotations

import dataclasses
from typing import Callable, NamedTuple

from jaxarm.arm.simple import SimpleArm
from jaxarm.config.arm import MusculoskeletalArmConfig, SimpleArmConfig


class Arm(NamedTuple):
    """One registered arm."""

    Config: type          # its configuration dataclass (SI units); ``Config()`` is the default arm of that kind
    make: Callable        # (config, backend, smooth) -> the arm; config: a ``Config`` or None for the default
    summary: str          # one line for ``--help`` and the docs
    #: it has a C-infinity formulation to differentiate through (``make_arm(..., smooth=True)``)
    smooth: bool = False
    #: it takes a geometry backend (``make_arm(..., backend=...)``, one of :data:`BACKENDS`)
    backends: bool = False


#: The musculoskeletal arm's geometry backends, the default first.
BACKENDS = ("fast", "mjx")


def _simple(config, backend, smooth):
    return SimpleArm(config or SimpleArmConfig())


def _musculoskeletal(config, backend, smooth):
    from jaxarm.arm.musculoskeletal import make_musculoskeletal_arm   # MJCF tables: built when first asked for

    if smooth:
        config = dataclasses.replace(config or MusculoskeletalArmConfig(), smooth=True)
    return make_musculoskeletal_arm(backend, config)


#: name -> arm.
ARMS = {
    "simple": Arm(SimpleArmConfig, _simple, "the authors' kinematic arm, 10 ms per step"),
    "musculoskeletal": Arm(MusculoskeletalArmConfig, _musculoskeletal,
                           "the authors' OpenSim arm translated to MJCF, 1 ms per step", smooth=True, backends=True),
}


def choices_text(names=None) -> str:
    """The registered names (or ``names``) as an error message lists them: ``'simple', 'musculoskeletal'``."""
    return ", ".join(map(repr, ARMS if names is None else names))


def smooth_arms() -> tuple[str, ...]:
    """The arms with a smooth formulation."""
    return tuple(name for name, arm in ARMS.items() if arm.smooth)
