"""The centre-out reaching task: targets, start posture, success criterion, protocol lengths ([model:
task](../model.md#task-and-success))."""
from jaxarm.task.centre_out import CENTRE_OUT_8, CentreOut, ensure_target_code, with_target_code
from jaxarm.task.config import REACHING_TARGETS, TARGET_ANGLES_RAD, TaskConfig, forward_kinematics_m
from jaxarm.task.reaching import (first_entry_index, hand_target_distance, inside_target, reached, start_position,
                                  target_position, target_positions)

__all__ = [
    "REACHING_TARGETS", "TARGET_ANGLES_RAD", "TaskConfig", "forward_kinematics_m",
    "first_entry_index", "hand_target_distance", "inside_target", "reached", "start_position",
    "target_position", "target_positions", "CENTRE_OUT_8", "CentreOut", "with_target_code",
    "ensure_target_code",
]
