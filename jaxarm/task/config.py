"""Static configuration of the centre-out reaching task ([model: task](../model.md#task-and-success); SI units: m, s,
rad).

The targets are the authors' joint-angle targets (``msarm.hoc`` setTargByID, ``centerOutTask=1``: 15.1 cm from the start
hand position); their hand positions follow from the authors' forward kinematics
(:func:`jaxarm.arm.base.hand_position`). The original trained and tested on ``left`` only; the paper also reports
``bottom``. The other six targets of the same ring are included because the code defines them; their names are
the code's comments, and the four diagonal ones do not match where the targets lie in our frame (e.g. "left-bottom"
is to the right of and below the start position), so prefer the paper's two.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, NamedTuple

import numpy as np

from jaxarm.config.arm import ARM_SEGMENTS_M, ELBOW_RANGE_DEG, SHOULDER_RANGE_DEG, START_POSTURE_RAD
from jaxarm.config.validate import ConfigError, check_choice, check_range

#: Joint-angle targets (shoulder, elbow) in rad of the original's ``centerOutTask == 1`` (``setTargByID``),
#: by the names the code gives them. "left" is target id 1, "bottom" id 3.
TARGET_ANGLES_RAD: dict[str, tuple[float, float]] = {
    "right": (0.45519364, 1.16293505),
    "left": (0.9911765, 1.57515715),
    "top": (1.29295714, 0.20699215),
    "bottom": (0.20234833, 2.19736336),
    "right-top": (0.95196038, 0.47728848),
    "left-top": (1.16275143, 0.92036049),
    "left-bottom": (0.12116826, 1.78758638),
    "right-bottom": (0.67440973, 2.09186399),
}
#: The reaching task's targets unless told otherwise (``jaxarm.task.registry.TASKS["reaching"]``): the two the
#: paper reports.
REACHING_TARGETS = ("left", "bottom")
#: Choices of TaskConfig.test_em_noise_events.
TEST_EM_NOISE_EVENTS = ("unlimited", "netstim")
#: Fold of a network's key that seeds its reaching test (``TaskConfig.test_key_fold``).
TEST_KEY_FOLD = 7


def forward_kinematics_m(q_rad, segments_m=ARM_SEGMENTS_M) -> tuple[float, float]:
    """Authors' planar FK in plain Python floats (for static configuration; the traced version is
    :func:`jaxarm.arm.base.hand_position`)."""
    l1, l2 = segments_m
    q1, q12 = q_rad[0], q_rad[0] + q_rad[1]
    return (l1 * math.cos(q1) + l2 * math.cos(q12), l1 * math.sin(q1) + l2 * math.sin(q12))


class Target(NamedTuple):
    """Where a network reaches, as traced data (one per network under ``vmap``), so networks reaching different
    targets share one compiled loop: the hand position (m) and the joint angles (rad) of the target."""

    xy_m: Any       # (2,) float32
    q_rad: Any      # (2,) float32 (shoulder, elbow)

    @classmethod
    def named(cls, name: str) -> "Target":
        """The target of :data:`TARGET_ANGLES_RAD` called ``name`` (authors' forward kinematics)."""
        if name not in TARGET_ANGLES_RAD:
            raise ConfigError(f"target = {name!r}: must be one of {', '.join(TARGET_ANGLES_RAD)}")
        q = TARGET_ANGLES_RAD[name]
        return cls(np.asarray(forward_kinematics_m(q), np.float32), np.asarray(q, np.float32))

    @classmethod
    def stack(cls, names) -> "Target":
        """One row per name: (n, 2) arrays."""
        rows = [cls.named(n) for n in names]
        return cls(np.stack([r.xy_m for r in rows]), np.stack([r.q_rad for r in rows]))


@dataclass(frozen=True)
class TaskConfig:
    """One centre-out reaching task: training protocol, test trial and success criterion.

    Attributes:
        target: target name, one of :data:`TARGET_ANGLES_RAD` (the paper's are "left" and "bottom").
        start_posture_rad: (shoulder, elbow) at the start of every epoch and of the test, rad.
        success_radius_m: the hand must enter this circle around the target during the test, m (paper: 4 cm).
        test_duration_s: length of the test trial, s (original: 1 s, no learning).
        epochs: training epochs (original: 12). Each epoch restarts the arm at the start posture and resets the
            network's state, tags and noise streams; weights carry over.
        epoch_duration_s: simulated length of one training epoch, s (original: 30 s).
        update_interval_s: the closed loop's period (arm update, readout, error sample), s (original aDT = 10 ms).
        segments_m: (upper arm, forearm) lengths of the forward kinematics that define the target positions, m.
        test_em_noise_events: "unlimited" (default: every EM cell's test noise runs for the whole test) or
            "netstim": as the original's NetStims with ``number = tstop * rate / 1000`` ([model:
            babbling](../model.md#learning-reward-modulated-stdp)), each EM cell's AMPA test noise stops once it has
            emitted ceil(test duration in ms x em_noise_rate_test_hz / 1000) events (100 for 1 s at 99.01 Hz; a NetStim
            stops when its count reaches ``number``), which for about half the cells happens before the 1 s test ends.
            Training noise is never limited.
    """

    #: the task interface (:mod:`jaxarm.task.interface`): a network's test key is its key folded with this
    test_key_fold: ClassVar[int | None] = TEST_KEY_FOLD

    target: str = "left"
    start_posture_rad: tuple[float, float] = START_POSTURE_RAD
    success_radius_m: float = 0.04
    test_duration_s: float = 1.0
    epochs: int = 12
    epoch_duration_s: float = 30.0
    update_interval_s: float = 0.010
    segments_m: tuple[float, float] = ARM_SEGMENTS_M
    test_em_noise_events: str = "unlimited"

    def __post_init__(self):
        check_choice(self, "target", TARGET_ANGLES_RAD)
        check_choice(self, "test_em_noise_events", TEST_EM_NOISE_EVENTS)
        _check_posture(self)
        check_range(self, "success_radius_m", 0.0, 0.5, lo_open=True)
        check_range(self, "update_interval_s", 0.0, 0.1, lo_open=True)
        check_range(self, "test_duration_s", 0.0, 60.0, lo_open=True)
        check_range(self, "epochs", 0, 1000, integer=True)
        check_range(self, "epoch_duration_s", 0.0, 3600.0, lo_open=True)
        for name in ("test_duration_s", "epoch_duration_s"):
            _check_whole_intervals(self, name)
        if (len(self.segments_m) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v <= 2 for v in self.segments_m)):
            raise ConfigError(f"TaskConfig.segments_m = {self.segments_m!r}: a pair (upper arm, forearm), each in (0, 2] m")

    # -- the task interface (jaxarm.task.interface): one target, every epoch and the test -----------------------
    def task_config(self) -> "TaskConfig":
        """Itself: a reaching task is its own per-run settings."""
        return self

    def network_target(self) -> Target:
        """The one target, arrays (2,)."""
        return self.target_params

    def epoch(self, epoch_fn: Callable) -> Callable:
        """``epoch_fn`` itself: every epoch trains toward the network's target."""
        return epoch_fn

    def test(self, test_fn: Callable) -> Callable:
        """``test_fn`` itself: the test on the network's target."""
        return test_fn

    def identity(self) -> dict:
        """The reaching task as a run records it (``jaxarm train``'s description: target, epochs, epoch_s)."""
        return {"target": self.target, "epochs": self.epochs, "epoch_s": self.epoch_duration_s}

    # -- built from a command's options, or again from a run's description ------------------------------------------
    @classmethod
    def from_options(cls, *, targets, epochs: int, epoch_duration_s: float, test_duration_s: float,
                     test_em_noise_events: str) -> list[tuple[str, "TaskConfig"]]:
        """``jaxarm train``'s runs of this task: (name, task), one per target."""
        return [(t, cls(target=t, epochs=epochs, epoch_duration_s=epoch_duration_s, test_duration_s=test_duration_s,
                        test_em_noise_events=test_em_noise_events)) for t in targets]

    @classmethod
    def from_identity(cls, identity: dict, test_duration_s: float,
                      test_em_noise_events: str = "unlimited") -> "TaskConfig":
        """The task a run recorded (:meth:`identity`), tested for ``test_duration_s`` with that test noise."""
        return cls(target=identity["target"], epochs=identity["epochs"], epoch_duration_s=identity["epoch_s"],
                   test_duration_s=test_duration_s, test_em_noise_events=test_em_noise_events)

    def prepare_spec(self, spec):
        """The network spec this task trains (reaching needs nothing added)."""
        return spec

    @property
    def target_q_rad(self) -> tuple[float, float]:
        """Target joint angles (shoulder, elbow), rad."""
        return TARGET_ANGLES_RAD[self.target]

    @property
    def target_params(self) -> Target:
        """:attr:`target` as traced data (the default of the loop's ``target`` arguments)."""
        return Target.named(self.target)

    @property
    def target_xy_m(self) -> tuple[float, float]:
        """Target hand position by the authors' FK, m."""
        return forward_kinematics_m(self.target_q_rad, self.segments_m)

    @property
    def start_xy_m(self) -> tuple[float, float]:
        """Hand position at the start posture, m."""
        return forward_kinematics_m(self.start_posture_rad, self.segments_m)

    @property
    def test_steps(self) -> int:
        """Closed-loop updates in the test trial (100 for 1 s at 10 ms)."""
        return round(self.test_duration_s / self.update_interval_s)

    @property
    def epoch_steps(self) -> int:
        """Closed-loop updates per training epoch (3000 for 30 s at 10 ms)."""
        return round(self.epoch_duration_s / self.update_interval_s)

    @property
    def training_s(self) -> float:
        """Total simulated training time, s (360 s in the original)."""
        return self.epochs * self.epoch_duration_s


def _check_posture(cfg: TaskConfig) -> None:
    value = cfg.start_posture_rad
    lo_sh, hi_sh = (math.radians(v) for v in SHOULDER_RANGE_DEG)
    lo_el, hi_el = (math.radians(v) for v in ELBOW_RANGE_DEG)
    ok = (isinstance(value, (tuple, list)) and len(value) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))
    if not ok or not (lo_sh <= value[0] <= hi_sh and lo_el <= value[1] <= hi_el):
        raise ConfigError(
            f"TaskConfig.start_posture_rad = {value!r}: must be (shoulder, elbow) with shoulder in "
            f"[{lo_sh:.4f}, {hi_sh:.4f}] rad and elbow in [{lo_el:.4f}, {hi_el:.4f}] rad")


def _check_whole_intervals(cfg: TaskConfig, name: str) -> None:
    n = getattr(cfg, name) / cfg.update_interval_s
    if abs(n - round(n)) > 1e-6 * max(1.0, n):
        raise ConfigError(f"TaskConfig.{name} = {getattr(cfg, name)!r}: must be a whole number of update intervals "
                          f"(update_interval_s = {cfg.update_interval_s!r})")
