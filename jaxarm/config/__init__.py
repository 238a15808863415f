"""Static, hashable, validated configuration (sizes, time steps, which arm).

Traced metaparameters (what evolution may change) are pytrees of arrays and live next to the code that uses them.
"""
from jaxarm.config.validate import ConfigError, check_choice, check_interval, check_range
from jaxarm.config.arm import MusculoskeletalArmConfig, SimpleArmConfig
from jaxarm.config.gradient import GradientConfig
from jaxarm.config.spec import CellType, NetworkSpec, Pathway, Population, SynapsePhysics

__all__ = [
    "ConfigError", "check_choice", "check_interval", "check_range",
    "MusculoskeletalArmConfig", "SimpleArmConfig", "GradientConfig",
    "NetworkSpec", "Population", "Pathway", "CellType", "SynapsePhysics",
]
