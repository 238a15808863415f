"""``jaxarm video RUN --network K --out reach.mp4``: one network's test as a video, like the authors' video of the
arm and the network.

Left: the arm seen from above, in the authors' planar frame (shoulder at the origin, m): the simple arm as its two
segments; the musculoskeletal arm as its bones and the 22 muscle paths of the MJCF model (MuJoCo's tendon path
points at the frame's joint angles, projected onto the plane of motion) coloured and thickened by activation;
the target's success circle and the hand's trace so far. Right: the network's spikes scrolling in time (the bands of
``jaxarm figures``' raster) above the EM readout. Frames are drawn with matplotlib (Agg) and encoded to H.264 by
imageio-ffmpeg, whose wheel ships its own ffmpeg.

With ``--robot-log`` (a `jaxarm wam-sim` CSV of the streamed test) the simulated WAM follows as a second arm.
With ``--renderer mujoco`` (musculoskeletal arm; ``MUJOCO_GL=egl`` or ``osmesa``) MuJoCo renders the arm panel from
the MJCF model offscreen (:mod:`jaxarm.viz.mujoco_render`).

Frame k (k = 0 .. round((stop - start) x fps) - 1) shows time start + k / fps; the arm between the 10 ms samples of
``trajectories.npz`` is interpolated linearly. Needs ``spikes.npz`` for the raster (``--record-spikes``); without
it the video shows the arm alone and says so.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from jaxarm.viz.arm_projection import MuscleProjector, planar_joints
from jaxarm.viz.figures import GROUP_COLORS, RunFolder, cell_layout, draw_raster, group_legend, plt

#: Colour map of muscle activation (0 white-grey to 1 dark red).
ACTIVATION_CMAP = "Reds"


def _interp(t_s, times_s, values):
    """values (T, ...) sampled at times_s, linearly interpolated at t_s (clamped to the ends)."""
    i = int(np.clip(np.searchsorted(times_s, t_s, side="right") - 1, 0, len(times_s) - 2))
    w = float(np.clip((t_s - times_s[i]) / (times_s[i + 1] - times_s[i]), 0.0, 1.0))
    return (1 - w) * values[i] + w * values[i + 1]


def frame_times(start_s: float, stop_s: float, fps: float) -> np.ndarray:
    return start_s + np.arange(int(round((stop_s - start_s) * fps))) / fps


def make_video(run: RunFolder, out: Path, network: int = 0, fps: float = 30.0, start_s: float = 0.0,
               stop_s: float | None = None, size=(960, 540), raster_s: float = 0.5, naive: bool = False,
               progress: bool = True, renderer: str = "matplotlib", robot_log: Path | None = None) -> dict:
    """Write the MP4 and return {"frames", "size", "fps", "path", "renderer"}. ``renderer``: "matplotlib" draws the
    arm panel itself; "mujoco" (musculoskeletal arm) has MuJoCo render the MJCF model offscreen
    (:mod:`jaxarm.viz.mujoco_render`). ``robot_log``: a `jaxarm wam-sim` CSV log of this network's trajectory
    streamed to the simulated WAM: the WAM's joint angles (its first packet at the test's time 0) drawn as a second
    arm following the virtual one."""
    import imageio.v2 as imageio
    from tqdm import tqdm

    p = plt()
    prefix = "naive_" if naive else ""
    window = "naive_test" if naive else "test"
    t_arm = run.traj["t"]
    hand = run.traj[f"{prefix}hand"][network]
    q = run.traj[f"{prefix}q"][network]
    stop_s = float(t_arm[-1]) if stop_s is None else stop_s
    times = frame_times(start_s, stop_s, fps)
    segments = tuple(run.results["config"]["loop"]["task"]["segments_m"])
    width, height = size
    dpi = 100
    fig = p.figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    gs = fig.add_gridspec(2, 2, width_ratios=[1, 1.25], height_ratios=[3, 1])
    ax_arm = fig.add_subplot(gs[:, 0])
    target, radius = run.target_m, run.radius_m
    ax_arm.add_patch(p.Circle(target, radius, fill=False, color="tab:red", lw=1.5))
    ax_arm.plot(*target, "+", color="tab:red")
    ax_arm.set_aspect("equal")
    ax_arm.set_xlabel("x (m)")
    ax_arm.set_ylabel("y (m)")
    reach = sum(segments) + 0.05
    ax_arm.set_xlim(-reach, reach)
    ax_arm.set_ylim(-0.15, reach)
    trace, = ax_arm.plot([], [], color="tab:blue", lw=1.0, alpha=0.8)

    muscles = None
    if run.arm == "musculoskeletal" and run.muscles is not None and network in run.muscles["networks"].tolist():
        r_m = run.muscles["networks"].tolist().index(network)
        activation = run.muscles[f"{window}.activation"][r_m]
        t_act = np.concatenate([[0.0], run.muscles[f"{window}.t_ms"] / 1000.0])
        activation = np.concatenate([np.zeros((1, activation.shape[1])), activation])   # at rest before the test
        projector = MuscleProjector([str(m) for m in run.muscles["muscle_names"]], segments)
        cmap = p.get_cmap(ACTIVATION_CMAP)
        muscle_lines = [ax_arm.plot([], [], lw=1.0, solid_capstyle="round")[0] for _ in projector.tendons]
        muscles = (projector, activation, t_act, cmap, muscle_lines)
    elif run.arm == "musculoskeletal":
        print(f"note: no muscles.npz record of network {network}: the video shows the bones only", file=sys.stderr)
    bones, = ax_arm.plot([], [], "-o", color="0.25", lw=4 if muscles is None else 2.5, ms=5, zorder=3)
    title = ax_arm.set_title("")

    raster = run.spikes is not None and network in run.spikes.data["networks"].tolist()
    ax_r = fig.add_subplot(gs[0, 1])
    ax_u = fig.add_subplot(gs[1, 1], sharex=ax_r)
    cursors = []
    if raster:
        f = run.spikes
        r = f.row_of(network)
        t_ms, cell = f.spikes(window, r)
        draw_raster(ax_r, f, cell_layout(f), t_ms, cell, marker_size=2.0)
        group_legend(ax_r, loc="lower left", fontsize=6, framealpha=0.9)
        u = f.get(window, "u")[r]
        t_u = f.get(window, "t_ms") / 1000.0
        for g, c in enumerate(GROUP_COLORS):
            ax_u.plot(t_u, u[:, g], color=c, lw=1.0)
        ax_r.set_title("spikes (scrolling)", fontsize=9)
    else:
        print(f"note: no spikes.npz record of network {network} in {run.path}: the video shows the arm alone "
              f"(record with `jaxarm test --from {run.path} --record-spikes`)", file=sys.stderr)
        u = run.traj["u"][network] if not naive else None
        if u is not None:
            for g, c in enumerate(GROUP_COLORS):
                ax_u.plot(t_arm[1:], u[:, g], color=c, lw=1.0)
        ax_r.axis("off")
    ax_u.set_ylabel("EM readout")
    ax_u.set_xlabel("time (s)")
    ax_u.set_ylim(-0.02, 1.02)
    for ax in (ax_r, ax_u):
        cursors.append(ax.axvline(start_s, color="k", lw=0.8))
    wam = None
    if robot_log is not None:
        wam_t, wam_q = robot_angles(robot_log)
        wam_line, = ax_arm.plot([], [], "--o", color="tab:purple", lw=2, ms=4, zorder=4, label="WAM (simulated)")
        ax_arm.legend(loc="lower left", fontsize=7)
        wam = (wam_t, wam_q, wam_line)
    fig.tight_layout()
    mj = None
    if renderer == "mujoco":
        mj = _mujoco_panel(run, ax_arm, muscles, segments, target, radius)
    writer = imageio.get_writer(out, fps=fps, codec="libx264", macro_block_size=2, quality=7)
    # ffmpeg is started by fork + exec at the first frame; JAX's warning about forking a multithreaded process is
    # about a child that goes on running Python, which this one does not.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        try:
            for t in tqdm(times, desc=f"video of network {network}", unit="frame", disable=not progress):
                qt = _interp(t, t_arm, q)
                k = int(np.searchsorted(t_arm, t, side="right"))
                path = np.vstack([hand[:k], _interp(t, t_arm, hand)[None]])
                trace.set_data(path[:, 0], path[:, 1])
                wam_joints = None if wam is None else planar_joints(_interp(t, wam[0], wam[1]), segments)
                if mj is not None:
                    render, image, activation, t_act = mj
                    a = np.zeros(len(render.tendons)) if activation is None else _interp(t, t_act, activation)
                    image.set_data(render.frame(qt, a, path, wam_joints))
                    joints = planar_joints(qt, segments)
                elif muscles is not None:
                    projector, activation, t_act, cmap, lines = muscles
                    joints, paths = projector.frame(qt)
                    a = np.clip(_interp(t, t_act, activation), 0.0, 1.0)
                    for line, pts, ai in zip(lines, paths, a):
                        line.set_data(pts[:, 0], pts[:, 1])
                        line.set_color(cmap(0.25 + 0.75 * ai))
                        line.set_linewidth(0.8 + 4.0 * ai)
                else:
                    joints = planar_joints(qt, segments)
                bones.set_data(joints[:, 0], joints[:, 1])
                if wam_joints is not None:
                    wam[2].set_data(wam_joints[:, 0], wam_joints[:, 1])
                dist = np.linalg.norm(path[-1] - target)
                title.set_text(f"{run.label}\nnetwork {network}{' (naive)' if naive else ''}, t = {t:.2f} s, "
                               f"{dist * 100:.1f} cm from the target")
                ax_r.set_xlim(t - raster_s, t)
                for c in cursors:
                    c.set_xdata([t, t])
                fig.canvas.draw()
                writer.append_data(np.asarray(fig.canvas.buffer_rgba())[..., :3])
        finally:
            writer.close()
            p.close(fig)
            if mj is not None:
                mj[0].close()
    return {"frames": len(times), "size": [width, height], "fps": fps, "path": str(out), "renderer": renderer}


def robot_angles(log_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(times s, (T, 2) joint angles rad) of the robot in a `jaxarm wam-sim` CSV log, the times counted from the
    first packet received (the streamed trajectory's time 0)."""
    from jaxarm.robot import metrics as rm

    s = rm.signals(rm.load_log(log_path))
    first = int(np.argmax(s["new"])) if s["new"].any() else 0
    return s["t"][first:] - s["t"][first], s["robot"][first:]


def _mujoco_panel(run: RunFolder, ax_arm, muscles, segments, target, radius):
    """The arm panel as an image that MuJoCo renders each frame, at the panel's size in pixels; the panel's own
    artists are hidden. Returns (renderer, image artist, activations (T, muscles) or None, their times s)."""
    from jaxarm.viz.mujoco_render import MujocoArmRenderer

    if muscles is not None:
        projector, activation, t_act, _, _ = muscles
    else:
        from jaxarm.arm.geometry import load_mjmodel, tendon_names

        projector, activation, t_act = MuscleProjector(tendon_names(load_mjmodel()), segments), None, None
    ax_arm.set_aspect("auto")                              # the image fills its panel (pixels = panel's pixels),
    pos = ax_arm.get_position()                            # less room for the title
    ax_arm.set_position([pos.x0, pos.y0, pos.width, pos.height * 0.9])
    box = ax_arm.get_window_extent()
    w, h = int(box.width) // 2 * 2, int(box.height) // 2 * 2
    render = MujocoArmRenderer(projector, w, h, target, radius)
    for artist in list(ax_arm.patches) + list(ax_arm.lines):
        artist.set_visible(False)
    ax_arm.set_xlim(-0.5, w - 0.5)
    ax_arm.set_ylim(h - 0.5, -0.5)
    ax_arm.set_xticks([])
    ax_arm.set_yticks([])
    ax_arm.set_xlabel("MuJoCo: the MJCF arm, muscles by activation")
    ax_arm.set_ylabel("")
    image = ax_arm.imshow(np.zeros((h, w, 3), np.uint8), interpolation="nearest", aspect="auto")
    return render, image, activation, t_act


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size {text}: expected WIDTHxHEIGHT in pixels, e.g. 960x540") from None
    if not (64 <= w <= 3840 and 64 <= h <= 2160 and w % 2 == 0 and h % 2 == 0):
        raise argparse.ArgumentTypeError(f"--size {text}: width in [64, 3840] and height in [64, 2160], both even "
                                         "(H.264 needs even sizes)")
    return w, h


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="jaxarm video", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, metavar="RUN", help="a folder written by `jaxarm train` or `jaxarm test`")
    ap.add_argument("--network", type=int, default=0, help="the network (0-based index in the run; default 0)")
    ap.add_argument("--out", type=Path, default=None, help="the MP4 to write (default RUN/video_network<K>.mp4)")
    ap.add_argument("--fps", type=float, default=30.0, help="frames per second of the video (default 30)")
    ap.add_argument("--start-s", type=float, default=0.0, help="first time shown, s into the test (default 0)")
    ap.add_argument("--stop-s", type=float, default=None, help="time the video ends, s (default: the test's end)")
    ap.add_argument("--size", type=_size, default=(960, 540), metavar="WxH",
                    help="frame size in pixels (default 960x540)")
    ap.add_argument("--raster-s", type=float, default=0.5, help="seconds of spikes shown by the raster (default 0.5)")
    ap.add_argument("--naive", action="store_true", help="show the naive (untrained) network's test instead")
    ap.add_argument("--robot-log", type=Path, default=None, metavar="CSV",
                    help="a `jaxarm wam-sim --log` CSV of this network's streamed test: also draw the simulated WAM "
                         "following the arm")
    ap.add_argument("--renderer", choices=("matplotlib", "mujoco"), default="matplotlib",
                    help="who draws the arm: matplotlib (default, works everywhere) or MuJoCo offscreen (the MJCF "
                         "model of the musculoskeletal arm; needs MUJOCO_GL=egl or osmesa set before starting)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    run = RunFolder.from_arguments(ap, args)
    if not 1 <= args.fps <= 120:
        ap.error(f"--fps {args.fps:g}: must be in [1, 120]")
    end = float(run.traj["t"][-1])
    stop = end if args.stop_s is None else args.stop_s
    if not 0 <= args.start_s < stop <= end + 1e-9:
        ap.error(f"--start-s {args.start_s:g} / --stop-s {stop:g}: need 0 <= start < stop <= {end:g} s (the test)")
    if round((stop - args.start_s) * args.fps) < 1:
        ap.error(f"--start-s/--stop-s/--fps: {stop - args.start_s:g} s at {args.fps:g} fps is no whole frame")
    if not 0 < args.raster_s <= 60:
        ap.error(f"--raster-s {args.raster_s:g}: must be in (0, 60] s")
    if args.renderer == "mujoco" and run.arm != "musculoskeletal":
        ap.error(f"--renderer mujoco: the {run.arm} arm has no MJCF model; it needs a musculoskeletal run")
    if args.robot_log is not None and not args.robot_log.is_file():
        ap.error(f"--robot-log {args.robot_log}: no such file")
    if args.robot_log is not None:
        from jaxarm.robot import metrics as rm

        try:
            rm.load_log(args.robot_log, required=rm.LOG_COLUMNS)
        except (OSError, ValueError) as e:
            ap.exit(2, f"{ap.prog}: error: --robot-log {args.robot_log}: "
                       f"{str(e).removeprefix(str(args.robot_log) + ': ')}\n")
    out = args.out or run.path / f"video_network{args.network}.mp4"
    out.parent.mkdir(parents=True, exist_ok=True)
    from jaxarm.viz.mujoco_render import RenderUnavailable

    try:
        info = make_video(run, out, args.network, args.fps, args.start_s, stop, args.size, args.raster_s, args.naive,
                          progress=not args.no_progress, renderer=args.renderer, robot_log=args.robot_log)
    except RenderUnavailable as e:
        print(f"jaxarm video: {e}", file=sys.stderr)
        return 2
    print(f"{info['frames']} frames of {info['size'][0]}x{info['size'][1]} at {info['fps']:g} fps -> {out}")
    return 0
