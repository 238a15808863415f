"""Centre-out reaching to several targets with one network: the targets alternate epoch by epoch during training,
a target code (a generator population, :mod:`jaxarm.network.proprio`) tells the network which one is current, and
every network is tested on every target.

The eight targets are the original's own centre-out set (``centerOutTask``, :data:`jaxarm.task.config.
TARGET_ANGLES_RAD`): 15.1 cm from the start hand position every 45 degrees, all inside the simple arm's joint
ranges. :data:`CENTRE_OUT_8` lists them by direction (0, 45, ..., 315 degrees counterclockwise from +x), so target
k is direction group k of an 8-group target code.

    task = CentreOut()                                    # the eight targets, 3 epochs each, cycled
    net = NetworkConfig(spec=with_target_code(NetworkSpec.dura_bernal_2015()))

This module is the task as data, with the task interface (:mod:`jaxarm.task.interface`) that lets the runner
(:class:`jaxarm.run.Runner`) train and test it as it does reaching: each network's targets are the schedule (arrays
(n_targets, 2)), epoch e trains toward row e % n_targets, the test runs on every row. :mod:`jaxarm.run_centre_out`
runs it (``make_centre_out_train``, ``train_and_test``, ``run_with_control``) and writes its results.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable, ClassVar

import jax

from jaxarm.config.spec import GENERATOR, NetworkSpec, Pathway, Population
from jaxarm.config.validate import ConfigError, check_range
from jaxarm.task.config import TARGET_ANGLES_RAD, Target, TaskConfig

#: The original's eight centre-out targets by direction from the start hand position: 0, 45, ..., 315 degrees.
#: (The original's names: "left-bottom" lies at -45 degrees and "right-bottom" at -135 degrees.)
CENTRE_OUT_8 = ("right", "right-top", "top", "left-top", "left", "right-bottom", "bottom", "left-bottom")


@dataclass(frozen=True)
class CentreOut:
    """The task as data: ``targets`` (names of :data:`~jaxarm.task.config.TARGET_ANGLES_RAD`, in target-code group
    order), ``epochs_per_target`` training epochs of ``epoch_duration_s`` toward each, cycled (epoch e trains toward
    target e % n), and the usual test (``test_duration_s``, ``success_radius_m``) on every target."""

    #: the task interface: a network is tested with its own key (as this task always was), not a fold of it
    test_key_fold: ClassVar[int | None] = None

    targets: tuple[str, ...] = CENTRE_OUT_8
    epochs_per_target: int = 3
    epoch_duration_s: float = 30.0
    test_duration_s: float = 1.0
    success_radius_m: float = 0.04

    def __post_init__(self):
        if not self.targets or any(t not in TARGET_ANGLES_RAD for t in self.targets) \
                or len(set(self.targets)) != len(self.targets):
            raise ConfigError(f"CentreOut.targets = {self.targets!r}: distinct names among "
                              f"{', '.join(TARGET_ANGLES_RAD)}")
        check_range(self, "epochs_per_target", 1, 1000, integer=True)

    def task_config(self) -> TaskConfig:
        """The per-run settings (the named target is only the default; every run gets its target explicitly)."""
        return TaskConfig(target=self.targets[0], epochs=self.epochs_per_target * len(self.targets),
                          epoch_duration_s=self.epoch_duration_s, test_duration_s=self.test_duration_s,
                          success_radius_m=self.success_radius_m)

    def stacked_targets(self) -> Target:
        """(n_targets, 2) Target arrays, in ``targets`` order."""
        return Target.stack(self.targets)

    # -- the task interface (jaxarm.task.interface) ------------------------------------------------------------------
    def network_target(self) -> Target:
        """A network's target data: every target, (n_targets, 2) arrays in ``targets`` order (the schedule)."""
        return self.stacked_targets()

    def epoch(self, epoch_fn: Callable) -> Callable:
        """The epoch toward target ``carry.epoch % n_targets`` of the network's targets."""
        n = len(self.targets)

        def epoch(carry, mp, targets):
            return epoch_fn(carry, mp, jax.tree.map(lambda a: a[carry.epoch % n], targets))

        return epoch

    def test(self, test_fn: Callable) -> Callable:
        """The test on every target (one key, one trained network): a TestResult with a leading target axis."""
        return jax.vmap(test_fn, in_axes=(None, None, None, 0))

    def identity(self) -> dict:
        """The task as a run records it (the test's length apart: a finished run may be re-tested longer)."""
        return {"name": "centre-out"} | {k: list(v) if isinstance(v, tuple) else v
                                         for k, v in dataclasses.asdict(self).items() if k != "test_duration_s"}

    # -- built from a command's options, or again from a run's description ------------------------------------------
    @classmethod
    def from_options(cls, *, targets, epochs: int, epoch_duration_s: float, test_duration_s: float,
                     test_em_noise_events: str) -> list[tuple[str, "CentreOut"]]:
        """``jaxarm train --task centre-out-8``'s one run: the eight targets, ``epochs`` per target (``targets``,
        reaching's option, and the test noise option do not apply)."""
        return [("centre-out-8", cls(epochs_per_target=epochs, epoch_duration_s=epoch_duration_s,
                                     test_duration_s=test_duration_s))]

    @classmethod
    def from_identity(cls, identity: dict, test_duration_s: float,
                      test_em_noise_events: str = "unlimited") -> "CentreOut":
        """The task a run recorded (:meth:`identity`), tested for ``test_duration_s`` (the test noise option, as in
        :meth:`from_options`, does not apply)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in identity.items() if k != "name"},
                   test_duration_s=test_duration_s)

    def prepare_spec(self, spec: NetworkSpec) -> NetworkSpec:
        """The network spec with this task's target code (added unless the spec has one)."""
        return ensure_target_code(spec, self)

    def directions_deg(self) -> tuple[float, ...]:
        """Direction of each target from the start hand position, degrees counterclockwise from +x."""
        x0, y0 = self.task_config().start_xy_m
        return tuple(math.degrees(math.atan2(float(t[1]) - y0, float(t[0]) - x0))
                     for t in self.stacked_targets().xy_m)


def with_target_code(spec: NetworkSpec, task: CentreOut = CentreOut(), name: str = "T", cells_per_target: int = 8,
                     rate_hz: float = 100.0, posts: tuple[str, ...] = ("EM",), pmat: float = 0.2,
                     weight_mv: float = 2.0, plastic: bool = True) -> NetworkSpec:
    """``spec`` with a target code: ``cells_per_target`` x n_targets generator cells in n_targets direction groups
    (firing at ``rate_hz`` while their target is current), projecting to each of ``posts`` with density ``pmat``,
    AMPA weight ``weight_mv`` (mV), 3-5 ms delays, plastic by default (so reward-modulated STDP can tie each
    target's cells to the motor commands that reach it)."""
    n = len(task.targets)
    for k, d in enumerate(task.directions_deg()):
        if abs((d - 360.0 * k / n + 180.0) % 360.0 - 180.0) > 1.0:
            raise ConfigError(f"CentreOut.targets: target {k} ({task.targets[k]}) lies at {d:.1f} degrees; a target "
                              f"code needs target k at k x {360.0 / n:g} degrees (direction group k)")
    spec = spec.with_population(Population(name, cells_per_target * n, GENERATOR, code="target", groups=n,
                                           rate_hz=rate_hz))
    for post in posts:
        spec = spec.with_pathway(Pathway(name, post, pmat, weight_mv, (3.0, 5.0), plastic=plastic))
    return spec


def ensure_target_code(spec: NetworkSpec, task: CentreOut = CentreOut(), **code) -> NetworkSpec:
    """``spec`` itself when it already has a target code, else ``with_target_code(spec, task, **code)``."""
    return spec if spec.target_codes else with_target_code(spec, task, **code)
