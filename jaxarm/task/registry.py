"""Tasks by name: ``jaxarm train --task``, ``jaxarm reproduce --task`` and ``jaxarm evolve --task`` take their choices
from :data:`TASKS`. A new task is its configuration class (the task as data) and one entry here."""
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


#: name -> task; the first is the default.
TASKS = {
    "reaching": Task(TaskConfig, "one target per network, the paper's task", REACHING_TARGETS, "reaching"),
    "centre-out-8": Task(CentreOut, "the original's eight centre-out targets from one network, cycled epoch by epoch, "
                                    "with a target code; every network tested on every target", CENTRE_OUT_8,
                         "centre-out"),
}
DEFAULT = "reaching"
