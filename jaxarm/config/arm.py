"""Static configuration of the two arms (SI units: m, s, rad, N)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from jaxarm.config.validate import ConfigError, check_choice, check_interval, check_range

#: Start posture of every reach in the original (shoulder, elbow), rad (spec §6).
START_POSTURE_RAD = (0.62, 1.53)
#: Joint ranges used by the task code and the simple arm, degrees (spec §6, msarm.hoc L416-419).
SHOULDER_RANGE_DEG = (-10.0, 110.0)
ELBOW_RANGE_DEG = (0.0, 140.0)
#: Segment lengths of the authors' planar forward kinematics, m (spec §3, msarm.hoc L406-411).
ARM_SEGMENTS_M = (0.4634 - 0.173, 0.7169 - 0.4634)


@dataclass(frozen=True)
class SimpleArmConfig:
    """The authors' kinematic "dummy" arm (spec §8). One step advances one 10 ms update.

    Attributes:
        gain_rad: joint-angle change per update per unit of (flexor - extensor) excitation, rad.
        windup: True reproduces the original code (the internal angle accumulators are not clamped, only the
            reported angles are, so an arm pushed past a limit must be pushed back just as far before it moves).
            False clamps the accumulators (what the paper describes).
        shoulder_range_deg, elbow_range_deg: reported-angle limits, degrees.
        proprio_range_m: (min, max) muscle length of the linear angle -> length map, m.
    """

    gain_rad: float = 0.04
    windup: bool = True
    shoulder_range_deg: tuple[float, float] = SHOULDER_RANGE_DEG
    elbow_range_deg: tuple[float, float] = ELBOW_RANGE_DEG
    proprio_range_m: tuple[float, float] = (0.03, 0.23)
    segments_m: tuple[float, float] = ARM_SEGMENTS_M

    def __post_init__(self):
        check_range(self, "gain_rad", 0.0, 1.0, lo_open=True)
        if not isinstance(self.windup, bool):
            raise ConfigError(f"SimpleArmConfig.windup = {self.windup!r}: must be True or False")
        check_interval(self, "shoulder_range_deg", -180.0, 180.0)
        check_interval(self, "elbow_range_deg", -180.0, 180.0)
        check_interval(self, "proprio_range_m", 0.0, 1.0)
        if len(self.segments_m) != 2 or not all(isinstance(v, (int, float)) and 0 < v <= 2 for v in self.segments_m):
            raise ConfigError(f"SimpleArmConfig.segments_m = {self.segments_m!r}: a pair (upper arm, forearm), each in (0, 2] m")

    @property
    def q_min_rad(self) -> tuple[float, float]:
        return (math.radians(self.shoulder_range_deg[0]), math.radians(self.elbow_range_deg[0]))

    @property
    def q_max_rad(self) -> tuple[float, float]:
        return (math.radians(self.shoulder_range_deg[1]), math.radians(self.elbow_range_deg[1]))
