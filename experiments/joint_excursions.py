"""Which joint the trained networks move in the test, and whether that is why they miss the target.

    python experiments/joint_excursions.py runs/repro-simple-cmaes-shortfall-rerank --markdown
    python experiments/joint_excursions.py runs/repro-simple-original/left/seeds runs/x --target left

For each run folder (one target; a ``jaxarm reproduce`` folder gives its ``<target>/seeds`` sub-folders) it reads the
1 s test's joint angles (``trajectories.npz``: ``q``, (networks, samples, 2), rad) and, for the networks that reached
the target and those that did not, reports the median largest excursion of each joint from the start posture (rad)
and how many networks moved the elbow further than the shoulder ("elbow-led"). It also prints the task's geometry:
how much 0.1 rad of each joint alone changes the hand-target distance at the start posture (cm), and how close
each joint alone can bring the hand (cm). On the simple arm and the left target, elbow flexion alone also brings
the hand closer (the critic rewards it) but cannot get nearer than ~10 cm: networks that learned it fail.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxarm.paper.comparison import run_folders
from jaxarm.task.config import START_POSTURE_RAD, TARGET_ANGLES_RAD, forward_kinematics_m

JOINTS = ("shoulder", "elbow")


def geometry(target: str, step_rad: float = 0.1) -> dict:
    """Hand-target distance change (cm) for +/- ``step_rad`` of each joint alone at the start posture, and the
    closest each joint alone can bring the hand (cm, over +/- 1 rad)."""
    start = np.asarray(START_POSTURE_RAD, float)
    goal = np.asarray(forward_kinematics_m(TARGET_ANGLES_RAD[target]))
    dist = lambda q: float(np.linalg.norm(np.asarray(forward_kinematics_m(q)) - goal))   # noqa: E731
    d0, out = dist(start), {"start_distance_cm": 100 * dist(start)}
    for j, name in enumerate(JOINTS):
        def moved(dq, j=j):
            q = start.copy()
            q[j] += dq
            return dist(q)
        out[f"{name}_plus_cm"] = 100 * (moved(step_rad) - d0)
        out[f"{name}_minus_cm"] = 100 * (moved(-step_rad) - d0)
        grid = np.linspace(-1.0, 1.0, 2001)
        best = min(grid, key=moved)
        out[f"{name}_alone_best_rad"] = float(best)
        out[f"{name}_alone_closest_cm"] = 100 * moved(best)
    return out


def excursions(folder: Path) -> dict:
    """Success split of the largest joint excursions in the test of one run folder."""
    res = json.loads((folder / "results.json").read_text())
    q = np.load(folder / "trajectories.npz")["q"]                              # (N, T, 2) rad
    dq = np.abs(q - np.asarray(START_POSTURE_RAD)).max(axis=1)                  # (N, 2) rad
    ok = np.array([n["success"] for n in res["networks"]], bool)
    elbow_led = dq[:, 1] > dq[:, 0]
    med = lambda m: [round(float(x), 3) for x in np.median(dq[m], axis=0)] if m.any() else None   # noqa: E731
    return {"folder": str(folder), "target": res["target"], "n": int(ok.size), "success": int(ok.sum()),
            "failures_elbow_led": int((elbow_led & ~ok).sum()), "successes_elbow_led": int((elbow_led & ok).sum()),
            "median_excursion_rad_success": med(ok), "median_excursion_rad_failure": med(~ok)}


def markdown(rows: list[dict]) -> str:
    lines = ["| run | target | reached | failures elbow-led | successes elbow-led | median excursion shoulder / elbow, "
             "reached (rad) | same, missed (rad) |", "|---|---|---|---|---|---|---|"]
    fmt = lambda v: "–" if v is None else f"{v[0]:.2f} / {v[1]:.2f}"   # noqa: E731
    for r in rows:
        fails = r["n"] - r["success"]
        lines.append(f"| {r['folder']} | {r['target']} | {r['success']}/{r['n']} | {r['failures_elbow_led']}/{fails} "
                     f"| {r['successes_elbow_led']}/{r['success']} | {fmt(r['median_excursion_rad_success'])} "
                     f"| {fmt(r['median_excursion_rad_failure'])} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="run folders (results.json + trajectories.npz) or reproduce folders")
    ap.add_argument("--target", default=None, help="only folders of this target")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    try:
        rows = [excursions(f) for f in run_folders(args.runs)]
    except FileNotFoundError as e:
        raise SystemExit(str(e)) from None
    rows = [r for r in rows if args.target is None or r["target"] == args.target]
    for target in sorted({r["target"] for r in rows}):
        g = geometry(target)
        print(f"{target}: start {g['start_distance_cm']:.1f} cm away; +0.1 rad shoulder {g['shoulder_plus_cm']:+.2f} "
              f"cm, elbow {g['elbow_plus_cm']:+.2f} cm; one joint alone gets within {g['shoulder_alone_closest_cm']:.1f}"
              f" cm (shoulder, {g['shoulder_alone_best_rad']:+.2f} rad) / {g['elbow_alone_closest_cm']:.1f} cm "
              f"(elbow, {g['elbow_alone_best_rad']:+.2f} rad)")
    if args.markdown:
        print(markdown(rows))
    else:
        for r in rows:
            print(json.dumps(r))


if __name__ == "__main__":
    main()
