"""Static configuration of the two arms (SI units: m, s, rad, N)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from jaxarm.config.validate import ConfigError, check_choice, check_interval, check_range

#: Start posture of every reach in the original (shoulder, elbow), rad ([model: task](../model.md#task-and-success)).
START_POSTURE_RAD = (0.62, 1.53)
#: Joint ranges used by the task code and the simple arm, degrees ([model: task](../model.md#task-and-success),
#: msarm.hoc L416-419).
SHOULDER_RANGE_DEG = (-10.0, 110.0)
ELBOW_RANGE_DEG = (0.0, 140.0)
#: Segment lengths of the authors' planar forward kinematics, m ([model: closed loop](../model.md#the-closed-loop),
#: msarm.hoc L406-411).
ARM_SEGMENTS_M = (0.4634 - 0.173, 0.7169 - 0.4634)
#: The kinks of the musculoskeletal arm that ``MusculoskeletalArmConfig.smooth`` can soften, by name: the muscle's
#: (``jaxarm.arm.muscle``) and the joint-limit penalty's.
SMOOTH_KINKS = ("tendon_slack", "force_clamps", "force_velocity", "activation", "implicit_step", "pennation_cap",
                "fiber_clip", "joint_limits")

#: Integrators of the muscles' fibre-length ODE (``MusculoskeletalArmConfig.muscle_integrator``).
MUSCLE_INTEGRATORS = ("linearly_implicit", "backward_euler")


class _JointRanges:
    """Joint ranges in rad from the ``shoulder_range_deg`` / ``elbow_range_deg`` fields (degrees)."""

    shoulder_range_deg: tuple[float, float]
    elbow_range_deg: tuple[float, float]

    @property
    def q_min_rad(self) -> tuple[float, float]:
        return (math.radians(self.shoulder_range_deg[0]), math.radians(self.elbow_range_deg[0]))

    @property
    def q_max_rad(self) -> tuple[float, float]:
        return (math.radians(self.shoulder_range_deg[1]), math.radians(self.elbow_range_deg[1]))


@dataclass(frozen=True)
class SimpleArmConfig(_JointRanges):
    """The authors' kinematic "dummy" arm ([model: the arms](../model.md#the-arms)). One step advances one 10 ms
    update.

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


@dataclass(frozen=True)
class MusculoskeletalArmConfig(_JointRanges):
    """The authors' OpenSim arm (SI units). One step advances ``dt_s`` (default 1 ms, the paper's arm step).

    Attributes:
        dt_s: arm step, s. The original integrated at 0.1 ms inside 10 ms updates; 1 ms is the paper's figure and
            what both muscle integrators are tested at (``tests/test_muscle_integrator.py``).
        substeps: integration substeps per step (dt_s / substeps each), of skeleton and muscles alike.
        muscle_substeps: with ``muscle_integrator="linearly_implicit"`` only: steps of the muscles' fibre-length
            ODE per (sub)step of the skeleton, along the path lengths extrapolated linearly over the step (10: 0.1
            ms, the authors' integrator step; the default integrator before backward Euler). The
            fibre ODE is stiff (PECM1's tendon is 2.8 mm) and kinked (zero tendon force when slack): taken at
            1 ms it chatters (PECM1's tendon force jumped between 0 and 2850 N from one step to the next) and over
            1 s of smooth random excitation the arm's path was off by 13 deg (median of 20 inputs; 46 deg at most)
            from a converged 0.05 ms run, and 1e-4 rad at the start moved it by 7 deg. With 10 the path is within
            0.19 deg (median of 20 inputs; 0.44 at most) of a converged float64 run (0.05 ms skeleton, 0.01 ms
            muscle steps), and a 1e-4 rad start perturbation moves it by < 0.01 deg (``python
            experiments/arm_convergence.py``). ``"backward_euler"`` (the default) is closer still at 1 ms, in a
            third of the time.
        muscle_integrator: how the muscles' fibre lengths advance over each (sub)step of the skeleton.
            ``"backward_euler"`` (default): one
            fully implicit step over the whole (sub)step, solved by ``muscle_newton_iterations`` safeguarded Newton
            iterations from the fibre length that keeps each tendon's length
            (``jaxarm.arm.muscle.step_backward_euler``); the skeleton gets the tendon forces at the step's midpoint
            (the mean of the start and end fibre and path lengths). At 1 ms its joint paths are closer to a
            converged run (float64, 0.05 ms skeleton and 0.01 ms muscle steps) than ten 0.1 ms linearly-implicit
            sub-steps on every input set measured (1 s of step, ramp, smooth random, 10 ms-held random and maximal
            excitations), PECM1's tendon force does not chatter, and the arm runs about 3 times as many arm-steps
            per second (``python experiments/arm_convergence.py``, ``python benchmarks/arm.py``;
            ``docs/results/muscle_integrator.json``). ``"linearly_implicit"``: ``muscle_substeps`` diagonal
            linearly-implicit Euler steps (``jaxarm.arm.muscle.step``); the skeleton gets the mean of their end
            forces (the default before 2026-12-06; docs/changelog.md).
        muscle_newton_iterations: Newton iterations of the ``"backward_euler"`` muscle step (ignored otherwise).
            3 by default: 2 already beat ten sub-steps on the joint paths, but leave a one-step force error of 0.24
            of F_max on PECM1 taking up slack fast (ten sub-steps: 0.13).
        time_scale_s, activation1, activation2: defaults for the Schutte activation ODE where the .osim stores 0
            (all 22 muscles do; the authors' simulator used unpublished internal defaults). We use OpenSim's
            Schutte1993Muscle defaults (0.1 s, 7.667, 1.459854): the paper's tau = 100 ms scale, activation time
            constant ~11 ms at full excitation, deactivation ~68 ms.
        damping: fibre damping of Schutte's force-velocity relation; None keeps each muscle's stored value (1.0).
        joint_limit_stiffness_nm_per_rad, joint_limit_damping_nms_per_rad: Kelvin-Voigt penalty torque beyond the
            joint range, (shoulder, elbow). The settings file lists "2500 1000 500 1500" for its joint-limit force
            subsystem without units or meaning. We take the first two as stiffness, N m/rad. Read as damping, the
            other two would hold the arm against a limit for b/k = 0.2 and 1.5 s after the muscles let go, so the
            damping is instead near-critical for those stiffnesses and the joints' inertia (2 sqrt(k I) with
            I ~ 0.25 and 0.05 kg m^2): the arm stops at a limit without bouncing off it and leaves it freely.
            The damping acts only inside the limit zone and is integrated implicitly.
        shoulder_range_deg, elbow_range_deg: joint ranges where the limit torque starts, degrees.
        relax_at_start: reproduce the intent of the authors' ``ScaleMuscleToRelax``: any muscle whose fibre would be
            stretched beyond its optimal length at the start posture (with a taut tendon) gets a longer tendon slack
            length, just enough that the fibre sits at optimal length with a slack tendon there. The unexcited arm
            then carries no muscle force at the start posture and holds it. False keeps the stored parameters (the
            arm then drifts: TRIlong pulls with hundreds of newtons).
        start_posture_rad: posture used by the relaxation rule and the default ``init``, rad.
        smooth: False (the model as published, piecewise smooth) or True: every kink (slack tendons, the clamps at
            zero force, the force-velocity branch switch, the activation-rate switch, the implicit step's
            ``min(df, 0)``, the pennation cap, the fibre-length clip, the joint-limit penalty) replaced by a
            C-infinity version of a stated width (``jaxarm.arm.muscle.W_*``,
            ``jaxarm.arm.musculoskeletal.W_JOINT_LIMIT_RAD``), so that gradients through a whole reach match finite
            differences; the path stays within the default model's integration error (``docs/gradients.md``). A
            tuple of names from ``SMOOTH_KINKS`` softens only those (to find which kink
            matters).
    """

    dt_s: float = 0.001
    substeps: int = 1
    muscle_substeps: int = 10
    muscle_integrator: str = "backward_euler"
    muscle_newton_iterations: int = 3
    time_scale_s: float = 0.1
    activation1: float = 7.667
    activation2: float = 1.459854
    damping: float | None = None
    joint_limit_stiffness_nm_per_rad: tuple[float, float] = (2500.0, 1000.0)
    joint_limit_damping_nms_per_rad: tuple[float, float] = (50.0, 15.0)
    shoulder_range_deg: tuple[float, float] = SHOULDER_RANGE_DEG
    elbow_range_deg: tuple[float, float] = ELBOW_RANGE_DEG
    relax_at_start: bool = True
    start_posture_rad: tuple[float, float] = START_POSTURE_RAD
    segments_m: tuple[float, float] = ARM_SEGMENTS_M
    smooth: bool | tuple[str, ...] = False

    def __post_init__(self):
        check_range(self, "dt_s", 1e-5, 0.005)
        check_range(self, "substeps", 1, 100, integer=True)
        check_range(self, "muscle_substeps", 1, 100, integer=True)
        check_choice(self, "muscle_integrator", MUSCLE_INTEGRATORS)
        check_range(self, "muscle_newton_iterations", 1, 20, integer=True)
        check_range(self, "time_scale_s", 0.001, 1.0)
        check_range(self, "activation1", 0.0, 100.0)
        check_range(self, "activation2", 0.01, 100.0)
        if self.damping is not None:
            check_range(self, "damping", 0.01, 10.0)
        for name in ("joint_limit_stiffness_nm_per_rad", "joint_limit_damping_nms_per_rad"):
            value = getattr(self, name)
            if len(value) != 2 or not all(isinstance(v, (int, float)) and 0 <= v <= 1e5 for v in value):
                raise ConfigError(f"MusculoskeletalArmConfig.{name} = {value!r}: must be a pair (shoulder, elbow), "
                                  "each in [0, 100000]")
        check_interval(self, "shoulder_range_deg", -180.0, 180.0)
        check_interval(self, "elbow_range_deg", -180.0, 180.0)
        if not isinstance(self.relax_at_start, bool):
            raise ConfigError(f"MusculoskeletalArmConfig.relax_at_start = {self.relax_at_start!r}: must be True or False")
        if not (isinstance(self.smooth, bool) or (isinstance(self.smooth, tuple) and set(self.smooth) <= set(SMOOTH_KINKS))):
            raise ConfigError(f"MusculoskeletalArmConfig.smooth = {self.smooth!r}: must be True, False or a tuple of "
                              f"names from {', '.join(SMOOTH_KINKS)}")
        lo, hi = self.q_min_rad, self.q_max_rad
        q0 = self.start_posture_rad
        if len(q0) != 2 or not all(lo[i] <= q0[i] <= hi[i] for i in range(2)):
            raise ConfigError(f"MusculoskeletalArmConfig.start_posture_rad = {q0!r}: must lie within the joint ranges "
                              f"shoulder [{lo[0]:.4f}, {hi[0]:.4f}] rad, elbow [{lo[1]:.4f}, {hi[1]:.4f}] rad")
