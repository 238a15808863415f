"""Tasks by name: ``jaxarm train --task``, ``jaxarm reproduce --task`` and ``jaxarm evolve --task`` take their choices
from :data:`TASKS`. A new task is its configuration class (the task as data, with the task interface of
:mod:`jaxarm.task.interface` and the class methods ``from_options`` and, for ``jaxarm test --from``,
``from_identity``), a module that writes its results, and one entry here."""
from __future__ import annotations

from typing import NamedTuple

from jaxarm.task.centre_out import CENTRE_OUT_8, CentreOut
from jaxarm.task.config import REACHING_TARGETS, TaskConfig


class Task(NamedTuple):
    """One registered task."""

    Config: type                # its configuration class; ``Config()`` is the task by this name
    summary: str                # one line for ``--help`` and the docs
    targets: tuple[str, ...]    # the targets it reaches unless told otherwise (names of TARGET_ANGLES_RAD)
    fitness: str                # the registered fitness that scores it in a search (jaxarm.evolve.fitness)
    outputs: str                # the module whose write_outputs(run, ...) and said(run, results) (and, for jaxarm
                                # test, said_test where it has one) the commands call
    identity: str | None = None  # the name its runs record in their description (None: reaching's description)


#: name -> task; the first is the default.
TASKS = {
    "reaching": Task(TaskConfig, "one target per network, the paper's task", REACHING_TARGETS, "reaching",
                     "jaxarm.experiment"),
    "centre-out-8": Task(CentreOut, "the original's eight centre-out targets from one network, cycled epoch by epoch, "
                                    "with a target code; every network tested on every target", CENTRE_OUT_8,
                         "centre-out", "jaxarm.run_centre_out", "centre-out"),
}
DEFAULT = "reaching"


def by_identity(name: str | None) -> tuple[str, Task] | None:
    """The registered task whose runs record ``name`` in their description's ``task`` (None: reaching)."""
    return next(((k, t) for k, t in TASKS.items() if t.identity == name), None)
