"""The robot following the virtual arm, drawn (matplotlib, Agg backend, written to files); the paper's figures they
match are :data:`jaxarm.paper.figures.FIGURES`.

* :func:`hand_xy_figure`: hand X and Y over time, the virtual arm's trajectory as received at the robot (red) and
  the robot's (blue), both on the robot's clock.
* :func:`jerk_box_figure`: (A) box plots of the jerk magnitude of the virtual and robot hand trajectories (log scale;
  points/outliers in the labels, as the paper's caption gives them); (B) the dimensionless jerk of each.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from jaxarm.robot.metrics import dimensionless_jerk, hand_xy, jerk, signals


def _plt():
    import matplotlib
    if "matplotlib.pyplot" not in sys.modules:   # a notebook's own backend stays (a switch closes its figures)
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def hand_xy_figure(log: dict, path: str | Path, title: str = "virtual (received) vs robot") -> Path:
    """Write the hand X and Y over time of ``log`` (a log dict), virtual arm and robot, to ``path``; return the
    path."""
    plt = _plt()
    s = signals(log)
    hv, hr = hand_xy(s["target"]), hand_xy(s["robot"])
    fig, axes = plt.subplots(2, 1, figsize=(9, 4.8), sharex=True)
    for k, (ax, name) in enumerate(zip(axes, ("X", "Y"))):
        ax.plot(s["t"], hv[:, k] * 100, color="tab:red", lw=0.9, label="virtual arm (received at robot)")
        ax.plot(s["t"], hr[:, k] * 100, color="tab:blue", lw=0.9, label="robot arm")
        ax.set_ylabel(f"hand {name} (cm)")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title(title)
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def jerk_box_figure(log: dict, path: str | Path) -> Path:
    """Write the jerk of ``log``'s virtual arm and robot (box plots of the jerk magnitude, dimensionless jerk) to
    ``path``; return the path."""
    plt = _plt()
    s = signals(log)
    t, new = s["t"], s["new"]
    hv, hr = hand_xy(s["target"][new]), hand_xy(s["robot"])
    jv = np.linalg.norm(jerk(t[new], hv)[1], axis=-1)
    jr = np.linalg.norm(jerk(t, hr)[1], axis=-1)
    dlj = [dimensionless_jerk(t[new], hv), dimensionless_jerk(t, hr)]
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(9, 3.8))
    box = ax_a.boxplot([jv[jv > 0], jr[jr > 0]], whis=1.5, sym=".")
    n_out = [len(f.get_ydata()) for f in box["fliers"]]
    ax_a.set_xticks([1, 2], [f"virtual\n{len(jv)}/{n_out[0]}", f"robot\n{len(jr)}/{n_out[1]}"])
    ax_a.set_yscale("log")
    ax_a.set_ylabel("jerk (m/s$^3$)")
    ax_a.set_title("A  jerk (points/outliers)")
    ax_b.bar([0, 1], dlj, color=["tab:red", "tab:blue"])
    ax_b.set_xticks([0, 1], ["virtual", "robot"])
    ax_b.set_yscale("log")
    ax_b.set_ylabel("dimensionless jerk")
    ax_b.set_title("B  dimensionless jerk")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
