"""What a runner needs of a task: the interface :class:`jaxarm.task.config.TaskConfig` (reaching, one target) and
:class:`jaxarm.task.centre_out.CentreOut` (several targets, cycled) both provide, so one runner
(:class:`jaxarm.run.Runner`: devices, groups, padding, checkpoints, resume, progress) trains and tests either.

* :meth:`~TaskInterface.task_config`: the per-run settings every epoch and test read (epochs, epoch and test lengths,
  the start posture every epoch and test begin from, the success radius of the test).
* :meth:`~TaskInterface.network_target`: one network's target data (a :class:`~jaxarm.task.config.Target`, traced):
  reaching's one target (arrays (2,)), centre-out's schedule of targets (arrays (n_targets, 2)). A batch stacks one
  row per network, so networks of one batch may reach different targets (``jaxarm reproduce``'s groups).
* :meth:`~TaskInterface.epoch`: what an epoch trains toward. Given one network's ``epoch(carry, mp, target)``
  (:func:`jaxarm.train.make_train`), the epoch of the task: ``epoch(carry, mp, network_target)``.
* :meth:`~TaskInterface.test`: the test over the task's targets. Given ``test(key, trained, mp, target)``, the
  task's ``test(key, trained, mp, network_target)`` (centre-out's has a leading target axis).
* :attr:`~TaskInterface.test_key_fold`: what a network's key is folded with for its test (None: the key itself).
* :meth:`~TaskInterface.identity`: the JSON description of the task that a checkpoint must match to be resumed.

For the command line (:data:`jaxarm.task.registry.TASKS`), a registered task's class also has ``from_options``
(its runs from ``jaxarm train``'s options), ``prepare_spec(spec)`` (what it adds to the network: centre-out's target
code) and ``from_identity`` (``jaxarm test --from``: the task again from the identity a run recorded).

Reaching's ``epoch`` and ``test`` return the functions they are given, so its compiled programs are those of a run
that knows no task interface.
"""
from __future__ import annotations

from typing import Callable, Protocol, runtime_checkable


@runtime_checkable
class TaskInterface(Protocol):
    """A task a runner can train and test (module docstring)."""

    test_key_fold: int | None

    def task_config(self):
        """The :class:`~jaxarm.task.config.TaskConfig` of the run's epochs and tests."""

    def network_target(self):
        """One network's target data (:class:`~jaxarm.task.config.Target`, numpy float32)."""

    def epoch(self, epoch_fn: Callable) -> Callable:
        """``epoch_fn(carry, mp, target)`` -> the task's ``epoch(carry, mp, network_target)``."""

    def test(self, test_fn: Callable) -> Callable:
        """``test_fn(key, trained, mp, target)`` -> the task's ``test(key, trained, mp, network_target)``."""

    def identity(self) -> dict:
        """The task as JSON, for a run's description."""


__all__ = ["TaskInterface"]
