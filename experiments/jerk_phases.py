"""Where the trained reaches' jerk is: the dimensionless jerk's trained/naive ratio of a reproduction, taken apart
(issue 49 item 3).

    python experiments/jerk_phases.py --from runs/repro-msarm [--json-out FILE] [--figure FILE.png]

``--from``: a ``jaxarm reproduce`` folder (``TARGET/seeds`` and ``TARGET/top30``, each with its trajectories.npz:
the trained and naive 1 s test paths at 10 ms). The dimensionless jerk of a path of duration D is its jerk energy
E = ∫|x'''|² dt times D⁵ / L², L its path length (``jaxarm.analysis.jerk``), so for one target and mode

    mean trained DLJ / mean naive DLJ  (the results table's ratio, the paper's Fig. 7 measure)

moves with two things: how much more jerk energy the trained paths carry than the naive ones, and how much longer
they are (the naive hand drifts a few cm, a trained one travels to the target, so (L_naive / L_trained)² is small).
Per target and mode it prints and writes: the table's ratio; the median energy ratio and the median squared
length ratio (trained against naive of the same network); where the energy lies in time (shares of the median
path's energy in 0-0.2, 0.2-0.4, 0.4-0.7 and 0.7-1 s, trained and naive) and, over the trained networks that
entered the 4 cm circle, its share before and after the first entry (the approach against the stop and what follows
it). The figure: the median jerk magnitude over time, trained and naive, one panel per target, (a) and (b).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

from jaxarm.analysis.jerk import dimensionless_jerk, jerk_energy, jerk_magnitude, path_length

#: Time windows of the energy shares, s (the test's start, where the start-of-run volley launches the arm; the
#: approach; the stop; the rest of the test).
WINDOWS_S = ((0.0, 0.2), (0.2, 0.4), (0.4, 0.7), (0.7, 1.0))
MODES = {"seeds": "(a)", "top30": "(b)"}
RADIUS_M = 0.04


def window_name(a_s: float, b_s: float) -> str:
    """The result file's key of a window (no dots: the docs address fields by dotted paths)."""
    return f"ms_{round(a_s * 1000)}_{round(b_s * 1000)}"


def phases(traj: dict, dt_s: float) -> dict:
    """The decomposition of one target and mode's jerk ratio (module docstring) from its trajectories.npz arrays."""
    trained, naive, t = traj["hand"], traj["naive_hand"], np.asarray(traj["t"])
    e_t, e_n = jerk_energy(trained, dt_s), jerk_energy(naive, dt_s)
    length_t, length_n = path_length(trained), path_length(naive)
    inside = np.asarray(traj["distance"]) < RADIUS_M
    entered = inside.any(axis=1)
    first = np.where(entered, inside.argmax(axis=1), len(t))
    before = np.arange(len(t))[None, :] < first[:, None]   # samples before the first one inside the circle
    share_before = jerk_energy(trained, dt_s, before)[entered] / e_t[entered]
    last = t[-1] + dt_s / 2

    def window_share(paths, energy, a, b):
        return float(np.median(jerk_energy(paths, dt_s, (t >= a) & (t < (b if b < t[-1] else last))) / energy))

    dlj_t, dlj_n = dimensionless_jerk(trained, dt_s), dimensionless_jerk(naive, dt_s)
    return {
        "networks": int(len(trained)),
        "jerk_ratio_of_means": float(np.mean(dlj_t) / np.mean(dlj_n)),
        "median_energy_ratio": float(np.median(e_t / e_n)),
        "median_length_factor": float(np.median((length_n / length_t) ** 2)),
        "median_path_length_m": {"trained": float(np.median(length_t)), "naive": float(np.median(length_n))},
        "energy_share_by_window": {window_name(a, b): {"trained": window_share(trained, e_t, a, b),
                                                       "naive": window_share(naive, e_n, a, b)}
                                   for a, b in WINDOWS_S},
        "entered": int(entered.sum()),
        "energy_share_before_first_entry": {"median": float(np.median(share_before)),
                                            "min": float(np.min(share_before)), "max": float(np.max(share_before))}
        if entered.any() else None,
        "median_jerk_m_s3": {"trained": np.median(jerk_magnitude(trained, dt_s), axis=0).round(4).tolist(),
                             "naive": np.median(jerk_magnitude(naive, dt_s), axis=0).round(4).tolist()},
    }


def load(folder: Path) -> dict:
    """{target: {mode: trajectories}} of a reproduce folder."""
    out = {}
    for target_dir in sorted(p for p in folder.iterdir() if p.is_dir() and (p / "seeds").is_dir()):
        out[target_dir.name] = {mode: dict(np.load(target_dir / mode / "trajectories.npz"))
                                for mode in MODES if (target_dir / mode / "trajectories.npz").is_file()}
    if not out:
        raise SystemExit(f"--from {folder}: no TARGET/seeds/trajectories.npz there; give a `jaxarm reproduce` folder")
    return out


def figure(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    targets = list(result["targets"])
    fig, axes = plt.subplots(1, len(targets), figsize=(5.5 * len(targets), 3.8), sharey=True, squeeze=False)
    for ax, target in zip(axes[0], targets):
        for mode, style in (("seeds", "-"), ("top30", "--")):
            row = result["targets"][target].get(mode)
            if row is None:
                continue
            t = np.arange(len(row["median_jerk_m_s3"]["trained"])) * result["dt_s"]
            ax.plot(t, row["median_jerk_m_s3"]["trained"], style, color="C0",
                    label=f"trained {MODES[mode]} (ratio {row['jerk_ratio_of_means']:.2f})")
            ax.plot(t, row["median_jerk_m_s3"]["naive"], style, color="0.5", label=f"naive {MODES[mode]}")
        ax.set_yscale("log")
        ax.set_title(f"{result['arm']} arm, {target} target")
        ax.set_xlabel("time in the test (s)")
        ax.legend(fontsize=8)
    axes[0][0].set_ylabel("median |jerk| over 30 networks (m/s³)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from", dest="src", type=Path, required=True, help="a `jaxarm reproduce` folder")
    ap.add_argument("--json-out", type=Path, default=None, help="write the result here (default: print only)")
    ap.add_argument("--figure", type=Path, default=None, help="the jerk-over-time PNG (default: none)")
    args = ap.parse_args(argv)
    trajectories = load(args.src)
    dt_s = float(np.diff(next(iter(next(iter(trajectories.values())).values()))["t"])[0])
    table = json.loads((args.src / "success_table.json").read_text()) if (args.src / "success_table.json").is_file() \
        else {}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    result = {"what": "issue 49 item 3: the dimensionless jerk's trained/naive ratio taken apart (energy x length "
                      "factor, energy over time and before/after the first entry)",
              "command": "python experiments/jerk_phases.py --from " + str(args.src), "date": time.strftime("%Y-%m-%d"),
              "machine": f"{platform.machine()}, {len(os.sched_getaffinity(0))} cores", "commit": commit,
              "reproduction": {k: table.get(k) for k in ("command", "date", "commit", "preset")},
              "arm": table.get("arm", "musculoskeletal"), "dt_s": dt_s,
              "targets": {target: {mode: phases(traj, dt_s) for mode, traj in modes.items()}
                          for target, modes in trajectories.items()}}
    for target, modes in result["targets"].items():
        for mode, r in modes.items():
            w = r["energy_share_by_window"]
            before = r["energy_share_before_first_entry"]
            print(f"{target} {MODES[mode]}: jerk ratio {r['jerk_ratio_of_means']:.2f} = energy x{r['median_energy_ratio']:.1f}"
                  f" (median) times length factor {r['median_length_factor']:.2f}; energy in "
                  + ", ".join(f"{a:g}-{b:g} s {w[window_name(a, b)]['trained'] * 100:.0f}%/"
                              f"{w[window_name(a, b)]['naive'] * 100:.0f}%" for a, b in WINDOWS_S)
                  + " (trained/naive)"
                  + ("" if before is None else f"; before the first entry {before['median'] * 100:.0f}% "
                                               f"({r['entered']} networks entered)"))
    if args.json_out:
        args.json_out.parent.mkdir(parents=True, exist_ok=True)
        args.json_out.write_text(json.dumps(result, indent=1) + "\n")
    if args.figure:
        figure(result, args.figure)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
