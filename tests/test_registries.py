"""Arms and tasks are registered once by name (jaxarm.arm.registry, jaxarm.task.registry): make_arm, every
configuration check and every command's choices read the registries."""
import pytest

from jaxarm.arm import make_arm
from jaxarm.arm.registry import ARMS, BACKENDS
from jaxarm.config.validate import ConfigError
from jaxarm.task.registry import DEFAULT, TASKS

COMMANDS = ("train", "test", "reproduce", "evolve", "rerank", "demo")


def _choices(command: str) -> dict:
    from jaxarm.cli import parser

    return {a.dest: a for a in parser(command)._actions if a.dest in ("arm", "task", "backend")}


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_takes_its_arm_task_and_backend_choices_from_the_registries(command):
    for dest, registered in (("arm", ARMS), ("task", TASKS), ("backend", BACKENDS)):
        action = _choices(command).get(dest)
        if action is not None and action.choices is not None:
            assert tuple(action.choices) == tuple(registered), (command, dest)
    if "task" in _choices(command):
        assert _choices(command)["task"].default == DEFAULT


def test_make_arm_builds_every_registered_arm_and_names_the_choices_in_one_line():
    for name, arm in ARMS.items():
        built = make_arm(name, config=arm.Config())
        assert built.dt_s > 0
    with pytest.raises(ConfigError, match=r"^kind = 'elbow': must be one of 'simple', 'musculoskeletal'$"):
        make_arm("elbow")
    with pytest.raises(ConfigError, match=r"^smooth = True: only the musculoskeletal arm has a smooth formulation, "
                                          r"not 'simple'$"):
        make_arm("simple", smooth=True)
    with pytest.raises(ConfigError, match=r"^backend = 'gpu': must be one of 'fast', 'mjx'$"):
        make_arm("musculoskeletal", backend="gpu")


def test_every_configuration_check_reads_the_arm_registry():
    from jaxarm.evolve.fitness import FitnessOptions
    from jaxarm.loop import LoopConfig
    from jaxarm.paper.presets import Preset

    with pytest.raises(ConfigError, match=r"^LoopConfig.arm = 'elbow': must be one of 'simple', 'musculoskeletal'$"):
        LoopConfig(arm="elbow")
    with pytest.raises(ConfigError, match=r"^FitnessOptions.arm = 'elbow': must be one of 'simple', "
                                          r"'musculoskeletal'$"):
        FitnessOptions(arm="elbow")
    with pytest.raises(ConfigError, match=r"arms = \['elbow'\]: must be a non-empty list of 'simple', "
                                          r"'musculoskeletal'$"):
        Preset(name="x", description="", arms=("elbow",), best={})


def test_every_task_is_a_configuration_with_its_targets_and_a_registered_fitness():
    from jaxarm.evolve import fitness
    from jaxarm.task.config import TARGET_ANGLES_RAD

    assert list(TASKS) == ["reaching", "centre-out-8"] and DEFAULT == "reaching"
    registered = fitness.available()
    for name, task in TASKS.items():
        task.Config()                                        # the task by this name, valid
        assert task.targets and all(t in TARGET_ANGLES_RAD for t in task.targets), name
        assert task.fitness in registered, name
