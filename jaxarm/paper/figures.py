"""The paper's figures and what draws each of them from our runs.

``jaxarm figures RUN`` (:mod:`jaxarm.viz.figures`) and ``jaxarm export --figures DIR`` (:mod:`jaxarm.robot.figures`)
name their figures for what they draw; :data:`FIGURES` says which of them stands for which figure of Dura-Bernal et
al. 2015 (Figs. 5-7: the virtual arm's network and reaches, §3.2; Figs. 9-10: the robot following it, §3.3).
"""
from __future__ import annotations

from typing import Callable, NamedTuple

from jaxarm.robot import figures as robot_figures
from jaxarm.viz import figures as run_figures


class PaperFigure(NamedTuple):
    """One figure of the paper as we draw it."""

    shows: str                  # what the paper's figure shows
    draw: Callable              # the function that draws ours
    name: str                   # its entry in ``jaxarm figures``' figures.json (its files' stem)


#: The paper's figure number -> our figure.
FIGURES: dict[int, PaperFigure] = {
    5: PaperFigure("spike raster of every population in a test, with the joint angles and the motor readout",
                   run_figures.raster_figure, "raster"),
    6: PaperFigure("hand paths and speeds of trained and naive networks", run_figures.reach_paths_figure,
                   "reach_paths"),
    7: PaperFigure("jerk of the hand: box plots of the jerk magnitude and each network's dimensionless jerk",
                   run_figures.jerk_box_figure, "jerk_box"),
    9: PaperFigure("hand X and Y over time, the virtual arm (as received) and the robot",
                   robot_figures.hand_xy_figure, "robot_hand_xy"),
    10: PaperFigure("jerk of the virtual arm's and the robot's hand trajectories", robot_figures.jerk_box_figure,
                    "robot_jerk"),
}
