"""``jaxarm figures RUN --out DIR``: the figures of a run folder, each a PNG beside its data.

Files (named for what they draw; ``figures.json`` in DIR lists what was written and what was skipped, and why; which
of them are the paper's figures is :data:`jaxarm.paper.figures.FIGURES`):

* ``raster.png`` / ``.npz``: one network's spikes in a recorded window (``--window``, default the test) in bands,
  top to bottom P, ES, IS, ISL, EM, IM, IML (the paper's layout); P and EM cells sorted and coloured by muscle group;
  below, the joint angles and the EM readout (the four excitations sent to the arm). Needs ``spikes.npz``
  (``--record-spikes``).
* ``rates.png`` / ``rates.csv`` (+ ``rates_epochs.csv``): population rates over the window in ``--bin-ms`` bins
  (spikes per cell per second; the network's and the mean over recorded networks), and the per-epoch rates of the
  last 10 s of every training epoch (``history.npz``).
* ``reach_paths.png`` / ``.npz``: hand paths and speeds in the test, trained vs naive, every network.
* ``jerk_box.png`` / ``.csv`` / ``.npz``: jerk magnitude of every test sample (box plots, trained vs naive) and
  each network's dimensionless jerk (:mod:`jaxarm.analysis.jerk`).
* ``muscles.png`` / ``.npz``: the musculoskeletal arm's 22 activations, tendon forces and fibre lengths in the
  test, coloured by the group that drives them (needs ``muscles.npz``).
* ``robot_hand_xy.png`` / ``.npz`` and ``robot_jerk.png`` / ``.json``, with ``--robot-log`` (a ``jaxarm wam-sim``
  CSV log): hand X/Y of the virtual arm and the robot, and their jerk (:mod:`jaxarm.robot.figures`).
* ``--grid``: ``raster_grid`` and ``reach_paths_grid`` (PNG + NPZ), one panel per network.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

from jaxarm.arm.base import GROUPS
from jaxarm.recordfile import MUSCLES_FILE, SPIKES_FILE, SpikeFile
from jaxarm.runfolder import DamagedFile, lookup, read_json, read_npz

#: Muscle groups (jaxarm.arm.GROUPS order: shoulder extensors, shoulder flexors, elbow extensors, elbow flexors).
GROUP_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")
#: The paper's populations without a muscle group: excitatory dark, inhibitory purple; others of a changed network
#: take OTHER_COLORS in order.
POP_COLORS = {"ES": "0.2", "IS": "tab:purple", "ISL": "tab:pink", "IM": "tab:purple", "IML": "tab:pink"}
OTHER_COLORS = ("tab:brown", "tab:olive", "tab:cyan", "tab:gray", "darkgoldenrod", "teal")
PASSIVE_COLOR = "0.6"
#: What a run folder's trajectories.npz must hold for the figures and the video.
TRAJECTORY_KEYS = ("t", "q", "hand", "naive_q", "naive_hand", "seeds")


def band_order(f: SpikeFile) -> tuple[str, ...]:
    """Raster bands, top to bottom, in the paper's layout: the generator population (P, last in id order) on top,
    then the network populations in id order (the paper's ES, IS, ISL, EM, IM, IML)."""
    return (f.populations[-1],) + tuple(f.populations[:-1])


def pop_color(f: SpikeFile, pop: str) -> str:
    """One colour per population: the muscle-group populations (P, EM) by their first group's, the paper's others
    as POP_COLORS, any other in OTHER_COLORS order."""
    ids = np.arange(f.pop_start[pop], f.pop_stop[pop])
    if len(ids) and f.group[ids[0]] >= 0:
        return GROUP_COLORS[0] if pop == f.populations[-1] else GROUP_COLORS[3]
    others = [p for p in f.populations if p not in POP_COLORS]
    return POP_COLORS.get(pop) or OTHER_COLORS[others.index(pop) % len(OTHER_COLORS)]


def plt():
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:   # a notebook's own backend stays (a switch closes its figures)
        matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    return pyplot


class RunFolder:
    """The files of a `jaxarm train`/`test` folder that the figures read."""

    @classmethod
    def from_arguments(cls, ap: argparse.ArgumentParser, args, several_targets: bool = False) -> "RunFolder":
        """The folder of ``args.run``, with ``args.network`` checked against it; a bad value exits through
        ``ap.error`` with one line (the commands `jaxarm figures` and `jaxarm video`), a damaged file (not JSON,
        not an .npz, truncated, lacking a field) with one line naming it, status 2. ``several_targets``: a run of a
        task of several targets (centre-out) is read too (its spikes; the reaching figures are skipped)."""
        try:
            run = cls(args.run, several_targets)
        except FileNotFoundError as e:
            ap.error(str(e))
        except DamagedFile as e:
            ap.exit(2, f"{ap.prog}: error: {e}\n")
        if not 0 <= args.network < run.n:
            ap.error(f"--network {args.network}: the run has {run.n} networks (0..{run.n - 1})")
        return run

    def __init__(self, path, several_targets: bool = False):
        self.path = Path(path)
        if not (self.path / "results.json").is_file() or not (self.path / "trajectories.npz").is_file():
            raise FileNotFoundError(f"{self.path}: no results.json and trajectories.npz there; give a folder written "
                                    "by `jaxarm train` or `jaxarm test`")
        results = self.path / "results.json"
        self.results = read_json(results)
        #: the targets of a task of several (centre-out: every network tested on each), None for reaching
        self.targets = None
        if self.results.get("task") == "centre-out-8":
            if not several_targets:
                raise DamagedFile(f"{results}: a centre-out-8 run; the video draws a reaching run (one target per "
                                  "network)")
            self.targets = [str(t) for t in lookup(self.results, results, "targets")]
        self.history = None
        if (self.path / "history.npz").is_file():
            self.history = read_npz(self.path / "history.npz", ("rates_last10s_hz", "populations"))
        self.spikes = SpikeFile(self.path / SPIKES_FILE) if (self.path / SPIKES_FILE).is_file() else None
        self.muscles = None
        self.arm = lookup(self.results, results, "config", "arm")
        if self.targets is not None:   # its trajectories have a target axis; only the spike figures read it
            self.seeds = read_npz(self.path / "trajectories.npz", ("seeds",))["seeds"]
            return
        self.traj = read_npz(self.path / "trajectories.npz", TRAJECTORY_KEYS)
        if (self.path / MUSCLES_FILE).is_file():
            self.muscles = read_npz(self.path / MUSCLES_FILE, ("networks", "muscle_names"))
        task = lookup(self.results, results, "config", "loop", "task")
        lookup(self.results, results, "target")
        try:
            self.dt_s = float(lookup(task, results, "update_interval_s"))
            self.radius_m = float(lookup(task, results, "success_radius_m"))
            self.target_m = np.asarray(lookup(self.results, results, "target_xy_m"), float).reshape(2)
        except (TypeError, ValueError):
            raise DamagedFile(f"{results}: config.loop.task's update_interval_s / success_radius_m or target_xy_m "
                              "is not a number (pair)") from None
        self.seeds = self.traj["seeds"]
        t, n = self.traj["t"], len(np.atleast_1d(self.seeds))
        for key in ("hand", "naive_hand", "q", "naive_q"):
            shape = self.traj[key].shape
            if len(shape) != 3 or shape[:2] != (n, len(t)) or shape[2] != 2:
                raise DamagedFile(f"{self.path / 'trajectories.npz'}: {key} has shape {shape}, not ({n} networks, "
                                  f"{len(t)} steps, 2) as its seeds and t say")

    @property
    def n(self) -> int:
        return len(self.seeds)

    @property
    def label(self) -> str:
        if self.targets is not None:
            return f"{self.arm} arm, {len(self.targets)} centre-out targets"
        return f"{self.arm} arm, {self.results['target']} target"

    @property
    def default_window(self) -> str:
        """The window the raster and rates draw unless told: the test (of the first target, for several)."""
        return "test" if self.targets is None else f"test_{self.targets[0]}"


def _save(fig, path: Path, dpi: int) -> Path:
    fig.savefig(path, dpi=dpi)
    plt().close(fig)
    return path


def _write_csv(path: Path, header: list[str], rows) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)
    return path


# -- the raster ---------------------------------------------------------------------------------------------------

def cell_layout(f: SpikeFile):
    """Where each cell is drawn: (row (n_all,) int, top to bottom; colour (n_all, 4) RGBA; bands {pop: (lo, hi)}).
    P and EM cells are sorted by muscle group so each group is one block of its colour, and a target code's cells by
    direction group (so the group of the current target is one block)."""
    from matplotlib.colors import to_rgba

    row = np.empty(f.n_all, np.int64)
    color = np.empty((f.n_all, 4))
    bands, y = {}, 0
    for pop in band_order(f):
        ids = np.arange(f.pop_start[pop], f.pop_stop[pop])
        if len(ids) and f.group[ids[0]] >= 0:          # a muscle-group population (P, EM)
            ids = ids[np.lexsort((ids, f.group[ids]))]
            color[ids] = np.array([to_rgba(GROUP_COLORS[g]) for g in f.group[ids]])
        else:
            if f.target_group is not None and len(ids) and f.target_group[ids[0]] >= 0:
                ids = ids[np.lexsort((ids, f.target_group[ids]))]
            color[ids] = to_rgba(pop_color(f, pop))
        row[ids] = y + np.arange(len(ids))
        bands[pop] = (y, y + len(ids))
        y += len(ids)
    return row, color, bands


def draw_raster(ax, f: SpikeFile, layout, t_ms, cell, marker_size: float = 1.5, labels: bool = True):
    """Spikes as dots at (t s, the cell's row), the bands separated and (``labels``) named."""
    row, color, bands = layout
    ax.scatter(t_ms / 1000.0, row[cell], s=marker_size, c=color[cell], marker="s", linewidths=0)
    for lo, _ in list(bands.values())[1:]:
        ax.axhline(lo - 0.5, color="0.8", lw=0.5)
    ax.set_ylim(f.n_all - 0.5, -0.5)
    if labels:
        ax.set_yticks([(lo + hi - 1) / 2 for lo, hi in bands.values()], list(bands))
    else:
        ax.set_yticks([])


def group_legend(ax, **kw):
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=c, lw=3) for c in GROUP_COLORS]
    ax.legend(handles, [g.replace("_", " ") for g in GROUPS], **kw)


def raster_figure(run: RunFolder, out: Path, network: int, window: str, dpi: int) -> list[Path]:
    f = run.spikes
    r = f.row_of(network)
    t_ms, cell = f.spikes(window, r)
    layout = cell_layout(f)
    lo, hi = f.span_ms(window)
    p = plt()
    fig, (ax, axq, axu) = p.subplots(3, 1, sharex=True, figsize=(9, 8.5),
                                     gridspec_kw={"height_ratios": [5, 1.3, 1.3]})
    draw_raster(ax, f, layout, t_ms, cell)
    ax.set_title(f"{run.label}: network {network} (seed {int(f.seeds[r])}), {window.replace('_', ' ')}, "
                 f"{len(t_ms)} spikes")
    group_legend(ax, loc="upper right", fontsize=7, framealpha=0.9)
    t_arm = f.get(window, "t_ms") / 1000.0
    q, u = f.get(window, "q_rad")[r], f.get(window, "u")[r]
    axq.plot(t_arm, np.degrees(q[:, 0]), color="k", label="shoulder")
    axq.plot(t_arm, np.degrees(q[:, 1]), color="k", ls="--", label="elbow")
    axq.set_ylabel("joint angle (deg)")
    axq.legend(fontsize=7, loc="upper right")
    for g, c in enumerate(GROUP_COLORS):
        axu.plot(t_arm, u[:, g], color=c)
    axu.set_ylabel("EM readout\n(excitation)")
    axu.set_xlabel("time (s)")
    axu.set_xlim(lo / 1000.0, hi / 1000.0)
    fig.tight_layout()
    row, _, bands = layout
    np.savez_compressed(out / "raster.npz", t_ms=t_ms, cell=cell, row=row[cell], group=f.group[cell],
                        bands=np.asarray(list(bands)), band_rows=np.asarray(list(bands.values())),
                        t_arm_ms=f.get(window, "t_ms"), q_rad=q, u=u, seed=f.seeds[r], network=network,
                        window=window)
    return [_save(fig, out / "raster.png", dpi), out / "raster.npz"]


def raster_grid_figure(run: RunFolder, out: Path, window: str, dpi: int) -> list[Path]:
    f = run.spikes
    layout = cell_layout(f)
    n = len(f)
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    p = plt()
    fig, axes = p.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False, sharex=True)
    data = {}
    for r, ax in enumerate(axes.flat):
        if r >= n:
            ax.axis("off")
            continue
        t_ms, cell = f.spikes(window, r)
        draw_raster(ax, f, layout, t_ms, cell, marker_size=0.3, labels=r % cols == 0)
        ax.set_title(f"network {int(f.data['networks'][r])} (seed {int(f.seeds[r])})", fontsize=8)
        data[f"t_ms_{r}"], data[f"cell_{r}"] = t_ms, cell
    fig.suptitle(f"{run.label}: {window.replace('_', ' ')}")
    fig.tight_layout()
    np.savez_compressed(out / "raster_grid.npz", seeds=f.seeds, networks=f.data["networks"], window=window,
                        **data)
    return [_save(fig, out / "raster_grid.png", dpi), out / "raster_grid.npz"]


# -- rates --------------------------------------------------------------------------------------------------------

def population_rates(f: SpikeFile, window: str, r: int, bin_ms: float):
    """(bin edges ms, {pop: (bins,) Hz}) of recorded network r: spikes of each population per cell per second in
    right-closed bins (a spike at step s belongs to ((s - 1) dt, s dt]) from the window's start."""
    lo, hi = f.span_ms(window)
    n_bins = max(1, int(math.ceil((hi - lo) / bin_ms - 1e-9)))
    edges = lo + bin_ms * np.arange(n_bins + 1)
    edges[-1] = hi
    t_ms, cell = f.spikes(window, r)
    b = np.clip(np.ceil((t_ms - lo) / bin_ms - 1e-9).astype(np.int64) - 1, 0, n_bins - 1)
    rates = {}
    for pop in band_order(f):
        a, z = f.pop_start[pop], f.pop_stop[pop]
        sel = (cell >= a) & (cell < z)
        rates[pop] = np.bincount(b[sel], minlength=n_bins) / ((z - a) * np.diff(edges) / 1000.0)
    return edges, rates


def rates_figure(run: RunFolder, out: Path, network: int, window: str, bin_ms: float, dpi: int) -> list[Path]:
    f = run.spikes
    r = f.row_of(network)
    edges, rates = population_rates(f, window, r, bin_ms)
    mean = {pop: np.mean([population_rates(f, window, k, bin_ms)[1][pop] for k in range(len(f))], axis=0)
            for pop in band_order(f)}
    colors = {pop: pop_color(f, pop) for pop in band_order(f)}
    has_history = run.history is not None and run.history["rates_last10s_hz"].shape[0] > 0
    p = plt()
    fig, axes = p.subplots(2 if has_history else 1, 1, figsize=(9, 6.5 if has_history else 3.5), squeeze=False)
    ax = axes[0, 0]
    centre_s = (edges[:-1] + edges[1:]) / 2000.0
    for pop in band_order(f):
        ax.plot(centre_s, rates[pop], color=colors[pop], lw=1.0, label=pop,
                ls="--" if pop in ("ISL", "IML") else "-")
    ax.set(xlabel="time (s)", ylabel="rate (Hz)",
           title=f"{run.label}: population rates of network {network}, {window.replace('_', ' ')}, {bin_ms:g} ms bins")
    ax.legend(fontsize=7, ncol=7, loc="upper right")
    paths = []
    bands = band_order(f)
    header = ["t_start_ms", "t_stop_ms"] + [f"{p_}_hz" for p_ in bands] + [f"mean_{p_}_hz" for p_ in bands]
    rows = [[round(edges[i], 6), round(edges[i + 1], 6)] + [round(float(rates[p_][i]), 6) for p_ in bands]
            + [round(float(mean[p_][i]), 6) for p_ in bands] for i in range(len(edges) - 1)]
    paths.append(_write_csv(out / "rates.csv", header, rows))
    if has_history:
        h = run.history["rates_last10s_hz"]         # (epochs, networks, 6)
        pops = [str(x) for x in run.history["populations"]]
        epochs = np.arange(1, h.shape[0] + 1)
        ax2 = axes[1, 0]
        for j, pop in enumerate(pops):
            ax2.plot(epochs, h[:, :, j].mean(axis=1), marker="o", color=colors[pop], label=pop, ms=3,
                     ls="--" if pop in ("ISL", "IML") else "-")
        ax2.set(xlabel="training epoch", ylabel="rate (Hz)",
                title="last 10 s of each training epoch, mean over networks (history.npz)")
        ax2.set_xticks(epochs)
        paths.append(_write_csv(out / "rates_epochs.csv", ["epoch"] + [f"{p_}_hz" for p_ in pops],
                                [[int(e)] + [round(float(h[e - 1, :, j].mean()), 6) for j in range(len(pops))]
                                 for e in epochs]))
    fig.tight_layout()
    return [_save(fig, out / "rates.png", dpi)] + paths


# -- reaching -----------------------------------------------------------------------------------------------------

def reach_paths_figure(run: RunFolder, out: Path, dpi: int) -> list[Path]:
    from jaxarm.experiment import plot_reach

    t, hand, naive = run.traj["t"], run.traj["hand"], run.traj["naive_hand"]
    plot_reach(out / "reach_paths.png", t, hand, naive, run.target_m, run.radius_m, run.label)
    speed = np.linalg.norm(np.diff(hand, axis=1), axis=-1) / run.dt_s
    naive_speed = np.linalg.norm(np.diff(naive, axis=1), axis=-1) / run.dt_s
    np.savez_compressed(out / "reach_paths.npz", t_s=t, hand_m=hand, naive_hand_m=naive, speed_m_s=speed,
                        naive_speed_m_s=naive_speed, target_m=run.target_m, radius_m=run.radius_m, seeds=run.seeds)
    return [out / "reach_paths.png", out / "reach_paths.npz"]


def reach_paths_grid_figure(run: RunFolder, out: Path, dpi: int) -> list[Path]:
    hand, naive = run.traj["hand"], run.traj["naive_hand"]
    cols = math.ceil(math.sqrt(run.n))
    rows = math.ceil(run.n / cols)
    p = plt()
    fig, axes = p.subplots(rows, cols, figsize=(2.8 * cols, 2.8 * rows), squeeze=False, sharex=True, sharey=True)
    dist = np.linalg.norm(hand - run.target_m, axis=-1)
    for k, ax in enumerate(axes.flat):
        if k >= run.n:
            ax.axis("off")
            continue
        ax.plot(naive[k, :, 0] * 100, naive[k, :, 1] * 100, color="0.6", lw=0.8)
        ax.plot(hand[k, :, 0] * 100, hand[k, :, 1] * 100, color="tab:blue", lw=1.0)
        ax.add_patch(p.Circle(run.target_m * 100, run.radius_m * 100, fill=False, color="tab:red"))
        ax.plot(*(hand[k, 0] * 100), "k.")
        ax.set_title(f"seed {int(run.seeds[k])}: min {dist[k].min() * 100:.1f} cm", fontsize=8)
        ax.set_aspect("equal")
    fig.suptitle(f"{run.label}: hand paths, trained (blue) vs naive (grey), cm")
    fig.tight_layout()
    np.savez_compressed(out / "reach_paths_grid.npz", hand_m=hand, naive_hand_m=naive, min_distance_m=dist.min(axis=1),
                        target_m=run.target_m, seeds=run.seeds)
    return [_save(fig, out / "reach_paths_grid.png", dpi), out / "reach_paths_grid.npz"]


def jerk_box_figure(run: RunFolder, out: Path, dpi: int) -> list[Path]:
    from jaxarm.analysis.jerk import dimensionless_jerk, jerk_magnitude, path_length

    hand, naive, dt = run.traj["hand"], run.traj["naive_hand"], run.dt_s
    mag = {"trained": jerk_magnitude(hand, dt), "naive": jerk_magnitude(naive, dt)}
    dlj = {"trained": dimensionless_jerk(hand, dt), "naive": dimensionless_jerk(naive, dt)}
    length = {"trained": path_length(hand), "naive": path_length(naive)}
    p = plt()
    fig, (ax_a, ax_b) = p.subplots(1, 2, figsize=(9, 3.8))
    pooled = [mag[k][np.isfinite(mag[k]) & (mag[k] > 0)] for k in ("trained", "naive")]
    ax_a.boxplot([v if v.size else [np.nan] for v in pooled], whis=1.5, sym=".")
    ax_a.set_xticks([1, 2], [f"trained\n{pooled[0].size} samples", f"naive\n{pooled[1].size} samples"])
    ax_a.set_yscale("log")
    ax_a.set(ylabel="jerk (m/s$^3$)", title="A  jerk of the hand, every test sample")
    for i, (k, color) in enumerate((("trained", "tab:blue"), ("naive", "0.5"))):
        v = dlj[k][np.isfinite(dlj[k])]
        ax_b.plot(np.full(v.size, i) + np.linspace(-0.1, 0.1, v.size), v, "o", color=color, ms=4)
        if v.size:
            ax_b.hlines(np.median(v), i - 0.25, i + 0.25, color="k")
    ax_b.set_xticks([0, 1], ["trained", "naive"])
    ax_b.set_xlim(-0.6, 1.6)
    ax_b.set_yscale("log")
    ax_b.set(ylabel="dimensionless jerk", title="B  dimensionless jerk per network (median: bar)")
    fig.suptitle(run.label, fontsize=9)
    fig.tight_layout()
    rows = [[int(s), float(dlj["trained"][k]), float(dlj["naive"][k]), float(length["trained"][k]),
             float(length["naive"][k]), float(np.median(mag["trained"][k])), float(np.median(mag["naive"][k]))]
            for k, s in enumerate(run.seeds)]
    _write_csv(out / "jerk_box.csv", ["seed", "dlj_trained", "dlj_naive", "path_length_trained_m",
                                       "path_length_naive_m", "median_jerk_trained_m_s3", "median_jerk_naive_m_s3"],
               rows)
    np.savez_compressed(out / "jerk_box.npz", jerk_trained_m_s3=mag["trained"], jerk_naive_m_s3=mag["naive"],
                        dlj_trained=dlj["trained"], dlj_naive=dlj["naive"], dt_s=dt, seeds=run.seeds)
    return [_save(fig, out / "jerk_box.png", dpi), out / "jerk_box.csv", out / "jerk_box.npz"]


# -- muscles ------------------------------------------------------------------------------------------------------

def muscles_figure(run: RunFolder, out: Path, network: int, dpi: int) -> list[Path]:
    m = run.muscles
    nets = m["networks"].tolist()
    if network not in nets:
        raise KeyError(f"{run.path / MUSCLES_FILE}: network {network} was not recorded (recorded: {nets})")
    r = nets.index(network)
    t_s = m["test.t_ms"] / 1000.0
    names, group = [str(x) for x in m["muscle_names"]], m["group"]
    fields = (("activation", "activation", 1.0), ("force_n", "tendon force (N)", 1.0),
              ("fiber_length_m", "fibre length (mm)", 1000.0))
    p = plt()
    fig, axes = p.subplots(3, 1, sharex=True, figsize=(9, 8))
    for ax, (field, label, scale) in zip(axes, fields):
        y = m[f"test.{field}"][r] * scale
        for i in range(len(names)):
            g = int(group[i])
            ax.plot(t_s, y[:, i], color=GROUP_COLORS[g] if g >= 0 else PASSIVE_COLOR, lw=0.9,
                    ls="-" if g >= 0 else ":")
        ax.set_ylabel(label)
    axes[0].set_title(f"{run.label}: the 22 muscles of network {network} (seed {int(m['seeds'][r])}) in the test; "
                      "dotted: passive")
    group_legend(axes[0], fontsize=7, loc="upper left")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    np.savez_compressed(out / "muscles.npz", t_ms=m["test.t_ms"], muscle_names=m["muscle_names"], group=group,
                        seed=m["seeds"][r], network=network,
                        **{f: m[f"test.{f}"][r] for f in ("activation", "active_force_n", "passive_force_n",
                                                          "force_n", "fiber_length_m", "mtu_length_m")})
    return [_save(fig, out / "muscles.png", dpi), out / "muscles.npz"]


# -- the robot ----------------------------------------------------------------------------------------------------

def robot_figures(log_path: Path, out: Path) -> list[Path]:
    from jaxarm.robot import figures as rf
    from jaxarm.robot import metrics as rm

    log = rm.load_log(log_path)
    s = rm.signals(log)
    rf.hand_xy_figure(log, out / "robot_hand_xy.png")
    np.savez_compressed(out / "robot_hand_xy.npz", t_s=s["t"], virtual_hand_m=rm.hand_xy(s["target"]),
                        robot_hand_m=rm.hand_xy(s["robot"]), new_target=s["new"])
    rf.jerk_box_figure(log, out / "robot_jerk.png")
    report = rm.tracking_report(log)
    (out / "robot_jerk.json").write_text(json.dumps(report, indent=1, default=float))
    return [out / "robot_hand_xy.png", out / "robot_hand_xy.npz", out / "robot_jerk.png", out / "robot_jerk.json"]


# -- the command --------------------------------------------------------------------------------------------------

def _reaching_figures(run: RunFolder, out: Path, network: int, grid: bool, dpi: int) -> dict:
    """The figures of a reaching run's test: hand paths, jerk, muscles (when recorded)."""
    written = {}
    written["reach_paths"] = reach_paths_figure(run, out, dpi)
    if grid:
        written["reach_paths_grid"] = reach_paths_grid_figure(run, out, dpi)
    written["jerk_box"] = jerk_box_figure(run, out, dpi)
    if run.muscles is not None:
        written["muscles"] = muscles_figure(run, out, network, dpi)
    return written


def make_figures(run: RunFolder, out: Path, network: int = 0, window: str | None = None, bin_ms: float = 10.0,
                 robot_log: Path | None = None, grid: bool = False, dpi: int = 120) -> dict:
    """Write every figure the folder's files allow into ``out``; returns {"written": {figure: [files]},
    "skipped": {figure: why}} (also written to ``out/figures.json``)."""
    out.mkdir(parents=True, exist_ok=True)
    written, skipped = {}, {}
    window = window or run.default_window
    no_spikes = (f"no {SPIKES_FILE} in {run.path}: make it with `jaxarm test --from {run.path} --record-spikes` "
                 "(or train with --record-spikes)")
    if run.spikes is not None:
        run.spikes.window(window)
        written["raster"] = raster_figure(run, out, network, window, dpi)
        written["rates"] = rates_figure(run, out, network, window, bin_ms, dpi)
        if grid:
            written["raster_grid"] = raster_grid_figure(run, out, window, dpi)
    else:
        skipped["raster"] = skipped["rates"] = no_spikes
    if run.targets is not None:
        why = (f"a run of {len(run.targets)} centre-out targets: this figure draws a reaching run (one target per "
               "network); the hand paths per target are in trajectories.npz")
        skipped |= {name: why for name in ("reach_paths", "jerk_box", "muscles")}
    else:
        written |= _reaching_figures(run, out, network, grid, dpi)
        if run.muscles is None:
            skipped["muscles"] = (f"the {run.arm} arm has no muscles" if run.arm != "musculoskeletal" else
                                  f"no {MUSCLES_FILE} in {run.path}: record with --record-spikes")
    if robot_log is not None:
        files = robot_figures(robot_log, out)
        written["robot_hand_xy"], written["robot_jerk"] = files[:2], files[2:]
    else:
        skipped["robot_hand_xy"] = skipped["robot_jerk"] = "no --robot-log given"
    manifest = {"run": str(run.path), "network": network, "window": window,
                "written": {k: [p.name for p in v] for k, v in written.items()}, "skipped": skipped}
    (out / "figures.json").write_text(json.dumps(manifest, indent=1))
    return manifest


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="jaxarm figures", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, metavar="RUN", help="a folder written by `jaxarm train` or `jaxarm test`")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default RUN/figures)")
    ap.add_argument("--network", type=int, default=0,
                    help="the network (0-based index in the run) of the raster, rates and muscle figures")
    ap.add_argument("--window", default=None,
                    help="recorded window of the raster and rates: test, naive_test or epoch_E (default test); for "
                         "a centre-out run test_T or naive_test_T of a target T (default the first target's test)")
    ap.add_argument("--bin-ms", type=float, default=10.0, help="bin of the population rates, ms (default 10)")
    ap.add_argument("--robot-log", type=Path, default=None,
                    help="a `jaxarm wam-sim` CSV log: also draw the robot following the virtual arm (hand X/Y, jerk)")
    ap.add_argument("--grid", action="store_true", help="also draw one panel per network (raster and hand paths)")
    ap.add_argument("--dpi", type=int, default=120, help="resolution of the PNGs (default 120)")
    args = ap.parse_args(argv)
    run = RunFolder.from_arguments(ap, args, several_targets=True)
    if not 0 < args.bin_ms <= 10_000:
        ap.error(f"--bin-ms {args.bin_ms:g}: must be in (0, 10000] ms")
    if not 10 <= args.dpi <= 1200:
        ap.error(f"--dpi {args.dpi}: must be in [10, 1200]")
    if args.robot_log is not None and not args.robot_log.is_file():
        ap.error(f"--robot-log {args.robot_log}: no such file")
    if args.robot_log is not None:   # read and measured before any figure is written
        from jaxarm.robot import metrics as rm

        try:
            rm.tracking_report(rm.load_log(args.robot_log, required=rm.LOG_COLUMNS))
        except (OSError, ValueError) as e:
            ap.exit(2, f"{ap.prog}: error: --robot-log {args.robot_log}: "
                       f"{str(e).removeprefix(str(args.robot_log) + ': ')}\n")
    try:
        manifest = make_figures(run, args.out or run.path / "figures", args.network, args.window, args.bin_ms,
                                args.robot_log, args.grid, args.dpi)
    except KeyError as e:
        ap.error(str(e.args[0]))
    out = args.out or run.path / "figures"
    for name, files in manifest["written"].items():
        print(f"{name}: {', '.join(str(out / f) for f in files)}")
    for name, why in manifest["skipped"].items():
        print(f"skipped {name}: {why}", file=sys.stderr)
    return 0
