"""A seeded, reach-like joint trajectory: a network-free stand-in for a network's trajectory.

Tests and quick robot experiments use it (``experiments/wam_tracking.py --network PRESET`` streams a real
network's training trajectory instead). It imitates the paper's "50-s training trajectory,
with enforced exploratory movements, where joint angles varied over 100 deg at angular velocities above 60 deg/s"
(§3.3): a chain of minimum-jerk movements (Flash & Hogan 1985 profile ``10 s^3 - 15 s^4 + 6 s^5``) between waypoints
drawn uniformly in the task's joint ranges (shoulder -10..110 deg, elbow 0..140 deg; paper §2.3), both joints moving
together, starting from the start posture (0.62, 1.53) rad, with durations growing with amplitude. The chain is
sped up or slowed down uniformly, and the elbow's excursions scaled by a factor <= 1 (so the ranges still hold), so
that each joint's total angular displacement equals a requested value;
the defaults are the paper-implied 1947 deg and 1450 deg (0.00095 and 0.0012 error/displacement of 1.85 deg and
1.74 deg; wam.md §3) over the 50 s the robot logged, i.e. 50 s x 10/15.09 = 33.1 s of simulated arm time at the
paper's packet rate.
"""
from __future__ import annotations

import numpy as np

from jaxarm.config.arm import ELBOW_RANGE_DEG, SHOULDER_RANGE_DEG, START_POSTURE_RAD

#: Paper-implied total displacement over the robot's 50 s record, deg (shoulder, elbow): 1.85/0.00095, 1.74/0.0012.
PAPER_DISPLACEMENT_DEG = (1.85 / 0.00095, 1.74 / 0.0012)
#: Simulated arm time that the paper's ~3300 packets (50 s at 15.09 ms per 10 ms packet) cover, s.
PAPER_VIRTUAL_DURATION_S = 50.0 * 0.010 / 0.01509


def min_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk position profile on s in [0, 1]."""
    return s ** 3 * (10.0 - 15.0 * s + 6.0 * s ** 2)


def reach_trajectory(seed: int = 0, duration_s: float = PAPER_VIRTUAL_DURATION_S, dt_s: float = 0.010,
                     total_displacement_deg=PAPER_DISPLACEMENT_DEG, shoulder_range_deg=SHOULDER_RANGE_DEG,
                     elbow_range_deg=ELBOW_RANGE_DEG, start_rad=START_POSTURE_RAD,
                     max_segments: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(t, q)``: times (s, step ``dt_s``, 0 to ``duration_s``) and (T, 2) angles (shoulder, elbow), rad.

    Construction: waypoints uniform in the ranges; movement ``i`` lasts ``(0.15 s + max_j |dq_ij| / (1 rad/s))``
    times a uniform factor in [0.8, 1.25] (larger movements take longer, as in reaching, so peak speeds stay
    similar); the chain is then uniformly sped up or slowed down so that the shoulder's total displacement over
    ``duration_s`` is exactly the requested one, and the elbow's excursions about the start posture are scaled
    by a factor <= 1 to match its requested displacement. ``total_displacement_deg=None`` skips both steps.
    """
    rng = np.random.Generator(np.random.PCG64(seed))
    lo = np.radians([shoulder_range_deg[0], elbow_range_deg[0]])
    hi = np.radians([shoulder_range_deg[1], elbow_range_deg[1]])
    start = np.asarray(start_rad, dtype=float)
    want = None if total_displacement_deg is None else np.radians(np.asarray(total_displacement_deg, float))
    # Draw movements until the chain holds enough shoulder displacement (or, without a target, enough time).
    waypoints, bounds, disp = [start], [0.0], 0.0
    while len(bounds) <= max_segments:
        nxt = rng.uniform(lo, hi)
        step = np.abs(nxt - waypoints[-1])
        bounds.append(bounds[-1] + (0.15 + step.max()) * rng.uniform(0.8, 1.25))
        waypoints.append(nxt)
        disp += step[0]
        if (want is not None and disp > want[0]) or (want is None and bounds[-1] >= duration_s):
            break
    else:
        raise ValueError(f"no trajectory within {max_segments} movements")
    waypoints, bounds = np.asarray(waypoints), np.asarray(bounds)

    def chain(tau):
        seg = np.clip(np.searchsorted(bounds, tau, side="right") - 1, 0, len(bounds) - 2)
        s = np.clip((tau - bounds[seg]) / (bounds[seg + 1] - bounds[seg]), 0.0, 1.0)
        return waypoints[seg] + min_jerk(s)[:, None] * (waypoints[seg + 1] - waypoints[seg])

    t = np.arange(int(round(duration_s / dt_s)) + 1) * dt_s
    if want is None:
        return t, chain(t)
    # Chain time at which the shoulder's cumulative displacement reaches the target (fine grid, then linear).
    tau = np.linspace(0.0, bounds[-1], 200 * len(bounds) + 1)
    cum = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(chain(tau)[:, 0])))])
    tau_end = float(np.interp(want[0], cum, tau))
    q = chain(t * (tau_end / t[-1]))
    have = np.abs(np.diff(q, axis=0)).sum(axis=0)
    scale = want / have
    scale[0] = 1.0 if abs(scale[0] - 1.0) < 0.02 else scale[0]  # the time warp already matched the shoulder
    if np.any(scale > 1.0):
        raise ValueError(f"the waypoints give {np.degrees(have).round(0)} deg of displacement, less than the "
                         f"requested {total_displacement_deg}; try another seed")
    return t, start + scale * (q - start)


def peak_speed_deg_s(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Peak |dq/dt| per joint, deg/s (finite differences)."""
    return np.degrees(np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]).max(axis=0)


__all__ = ["reach_trajectory", "min_jerk", "PAPER_DISPLACEMENT_DEG", "PAPER_VIRTUAL_DURATION_S",
           "peak_speed_deg_s"]
