"""Tracking metrics of a robot following a virtual arm (paper §3.3, Figs. 9-10); NumPy only, no simulator needed.

Definitions (each fixed here, because the paper's numbers depend on them; wam.md §6):

* **Packet intervals**: differences of the robot times at which a new target was taken (``new_target`` rows of
  the log; quantised to the 2 ms tick), in ms: mean, SD, max, 2.5-97.5 % range.
* **Angle error**: ``|target - robot|`` per joint at every 500 Hz row, both on the robot's clock, no time
  alignment (as the paper: "mean absolute angle difference"); mean and SD of that absolute error, deg.
* **Error / displacement**: mean absolute error divided by the total angular displacement of the target (the
  virtual arm as received), ``sum |diff(target)|``; both in the same unit. (``error_over_displacement(...,
  reference="robot")`` divides by the robot's displacement instead.)
* **Delay**: the lag L in [0, ``max_lag_s``] that maximises the cross-correlation (as a correlation coefficient
  of the overlapping parts ``a[n]`` and ``b[n + L]``) of target ``a`` and robot ``b`` (positive: robot behind). Whole signal, and per window
  (``window_s`` long, hop ``window_s / 2``; mean and SD over windows, as the paper reports 312 ms, SD 127.64 ms).
* **Hand XY**: the authors' planar forward kinematics with their segment lengths (0.2904, 0.2535) m applied to
  both the target and the robot angles, so both are compared in one space.
* **Jerk**: ``6 x`` times the third divided difference on each signal's own sample times (``diff(x, 3) / dt^3``
  for uniform samples), giving N - 3 values; this reproduces the paper's Fig. 10 counts (24997 robot samples of
  25000; 3297 virtual samples of 3300). The virtual signal is sampled at the ticks where a new packet
  was taken (robot clock); no smoothing filter.
* **Dimensionless jerk** (Hogan & Sternad 2009, as the paper): ``(integral |jerk|^2 dt) * D^3 / v_mean^2``,
  D the duration and v_mean the path length over D.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from jaxarm.config.arm import ARM_SEGMENTS_M

#: The paper's robot numbers (§3.3), for reports.
PAPER = {
    "packet_interval_ms": {"mean": 15.09, "sd": 5.65, "max": 46.0, "p95_range": (6.0, 26.0)},
    "mean_abs_error_deg": {"shoulder": 1.85, "elbow": 1.74},
    "sd_abs_error_deg": {"shoulder": 2.19, "elbow": 2.11},
    "error_over_displacement": {"shoulder": 0.00095, "elbow": 0.0012},
    "delay_ms": {"mean": 312.0, "sd": 127.64},
}
JOINTS = ("shoulder", "elbow")


#: The columns of a simulator log that the metrics read.
LOG_COLUMNS = ("t", "target_shoulder", "target_elbow", "robot_shoulder", "robot_elbow", "new_target")


def load_log(path: str | Path, required: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Read a simulator CSV log (header row of column names) into ``{column: array}``. A file that is not such a
    CSV, or lacks a column of ``required`` (e.g. :data:`LOG_COLUMNS`), raises ValueError naming the file and what is
    wrong (OSError when it cannot be read)."""
    path = Path(path)
    try:
        with open(path) as f:
            names = [h.strip() for h in f.readline().split(",")]
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text CSV (binary data)") from None
    except ValueError as e:
        why = str(e).strip().splitlines()[0][:120] if str(e).strip() else "unreadable"
        raise ValueError(f"{path}: not a CSV of numbers below its header ({why})") from None
    missing = [c for c in required if c not in names]
    if missing:
        raise ValueError(f"{path}: lacks the column(s) {', '.join(missing)} of a `jaxarm wam-sim --log` CSV "
                         f"(its header: {','.join(names)[:120]})")
    if data.size and data.shape[1] != len(names):
        raise ValueError(f"{path}: {data.shape[1]} values per row but {len(names)} column names in its header")
    if required and data.shape[0] < 2:
        raise ValueError(f"{path}: {data.shape[0]} data row(s); a log needs at least 2")
    return {name: data[:, i] if data.size else np.zeros(0) for i, name in enumerate(names)}


def interval_stats(times_s) -> dict:
    """Statistics of the intervals between consecutive event times (s), in ms."""
    d = np.diff(np.asarray(times_s, dtype=float)) * 1e3
    if d.size == 0:
        return {"n": 0}
    lo, hi = np.percentile(d, [2.5, 97.5])
    return {"n": int(d.size), "mean_ms": float(d.mean()), "sd_ms": float(d.std(ddof=1)) if d.size > 1 else 0.0,
            "max_ms": float(d.max()), "min_ms": float(d.min()), "p2_5_ms": float(lo), "p97_5_ms": float(hi)}


def abs_error_deg(target, robot) -> dict:
    """Mean and SD of |target - robot| per joint (arrays (T, 2) in rad), deg."""
    e = np.degrees(np.abs(np.asarray(target, float) - np.asarray(robot, float)))
    return {"mean": dict(zip(JOINTS, e.mean(axis=0).tolist())), "sd": dict(zip(JOINTS, e.std(axis=0).tolist()))}


def total_displacement(q) -> np.ndarray:
    """Sum of |increments| per joint (same unit as q)."""
    return np.abs(np.diff(np.asarray(q, float), axis=0)).sum(axis=0)


def error_over_displacement(target, robot, reference: str = "target") -> dict:
    """Mean absolute error / total displacement of ``reference`` (``"target"`` or ``"robot"``), per joint."""
    target, robot = np.asarray(target, float), np.asarray(robot, float)
    err = np.abs(target - robot).mean(axis=0)
    disp = total_displacement(target if reference == "target" else robot)
    with np.errstate(divide="ignore", invalid="ignore"):
        return dict(zip(JOINTS, (err / disp).tolist()))


def _pearson_by_lag(a: np.ndarray, b: np.ndarray, max_lag: int) -> np.ndarray:
    """Correlation coefficient of ``a[:n - L]`` with ``b[L:]`` for L = 0..max_lag (FFT for the cross sums)."""
    a = a - a.mean()
    b = b - b.mean()
    n = len(a)
    size = 1 << int(math.ceil(math.log2(2 * n)))
    lags = np.arange(max_lag + 1)
    sab = np.fft.irfft(np.conj(np.fft.rfft(a, size)) * np.fft.rfft(b, size), size)[:max_lag + 1]
    m = n - lags
    ca, ca2 = np.concatenate([[0], np.cumsum(a)]), np.concatenate([[0], np.cumsum(a * a)])
    cb, cb2 = np.concatenate([[0], np.cumsum(b)]), np.concatenate([[0], np.cumsum(b * b)])
    sa, sa2 = ca[n - lags], ca2[n - lags]                 # sums over a[0 : n - L]
    sb, sb2 = cb[n] - cb[lags], cb2[n] - cb2[lags]        # sums over b[L : n]
    cov = sab - sa * sb / m
    var = np.maximum(sa2 - sa * sa / m, 0.0) * np.maximum(sb2 - sb * sb / m, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var > 0, cov / np.sqrt(var), -np.inf)


def xcorr_delay(a, b, dt_s: float, max_lag_s: float = 1.0) -> float:
    """Lag (s, >= 0) of ``b`` behind ``a`` that maximises the correlation coefficient of the overlapping parts
    (``a[:n - L]`` with ``b[L:]``); exact for a pure shift."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    max_lag = min(int(round(max_lag_s / dt_s)), len(a) - 3)
    if max_lag < 0:
        return math.nan         # fewer than 3 samples: no lag can be measured
    return float(np.argmax(_pearson_by_lag(a, b, max_lag)) * dt_s)


def windowed_delay(a, b, dt_s: float, window_s: float = 5.0, max_lag_s: float = 1.0) -> dict:
    """Delay per window of ``window_s`` (hop ``window_s / 2``): the lag maximising the correlation coefficient of
    the window of ``a`` with the window of ``b`` shifted by the lag; mean and SD over windows (s)."""
    from numpy.lib.stride_tricks import sliding_window_view

    w = int(round(window_s / dt_s))
    extra = int(round(max_lag_s / dt_s))
    a, b = np.asarray(a, float), np.asarray(b, float)
    lags = []
    for start in range(0, len(a) - w - extra + 1, max(w // 2, 1)):
        aw = a[start:start + w] - a[start:start + w].mean()
        bws = sliding_window_view(b[start:start + w + extra], w)          # (extra + 1, w): b shifted by each lag
        bws = bws - bws.mean(axis=1, keepdims=True)
        den = np.sqrt((aw @ aw) * np.einsum("ij,ij->i", bws, bws))
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.where(den > 0, bws @ aw / den, -np.inf)
        lags.append(np.argmax(c) * dt_s)
    lags = np.asarray(lags)
    return {"n_windows": int(lags.size), "mean_s": float(lags.mean()) if lags.size else math.nan,
            "sd_s": float(lags.std(ddof=1)) if lags.size > 1 else math.nan}


def hand_xy(q, segments_m=ARM_SEGMENTS_M) -> np.ndarray:
    """The authors' planar forward kinematics: (..., 2) angles (rad) -> (..., 2) hand position (m)."""
    q = np.asarray(q, float)
    l1, l2 = segments_m
    q12 = q[..., 0] + q[..., 1]
    return np.stack([l1 * np.cos(q[..., 0]) + l2 * np.cos(q12), l1 * np.sin(q[..., 0]) + l2 * np.sin(q12)], -1)


def jerk(t, x) -> tuple[np.ndarray, np.ndarray]:
    """Jerk by third divided differences: ``6 x[t_i, .., t_i+3]`` at the mean of those four times. Exact for cubics
    on any sampling; ``diff(x, 3) / dt^3`` on uniform samples. Returns (times (T-3,), jerk (T-3, ...))."""
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    shape = (-1,) + (1,) * (x.ndim - 1)
    d = x
    for k in range(1, 4):
        d = np.diff(d, axis=0) / (t[k:] - t[:-k]).reshape(shape)
    tj = (t[:-3] + t[1:-2] + t[2:-1] + t[3:]) / 4.0
    return tj, 6.0 * d


def dimensionless_jerk(t, xy) -> float:
    """``(integral |jerk|^2 dt) * D^3 / v_mean^2`` with D the duration and v_mean = path length / D."""
    t = np.asarray(t, float)
    xy = np.asarray(xy, float)
    tj, j = jerk(t, xy)
    j2 = np.sum(j ** 2, axis=-1)
    weights = np.gradient(tj) if len(tj) > 1 else np.ones(1)
    if len(t) < 4:
        return math.nan         # no jerk below 4 samples
    duration = t[-1] - t[0]
    v_mean = np.linalg.norm(np.diff(xy, axis=0), axis=-1).sum() / duration
    if not v_mean > 0:
        return math.nan         # a hand that never moves has no dimensionless jerk
    return float(np.sum(j2 * weights) * duration ** 3 / v_mean ** 2)


def boxplot_stats(values) -> dict:
    """Median, quartiles, 1.5-IQR whiskers and the outlier count (matplotlib's boxplot convention)."""
    v = np.asarray(values, float).ravel()
    if v.size == 0:
        return {"n": 0, "median": None, "q1": None, "q3": None, "whisker_lo": None, "whisker_hi": None,
                "n_outliers": 0}
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    iqr = q3 - q1
    lo_fence, hi_fence = q1 - 1.5 * iqr, q3 + 1.5 * iqr
    inside = v[(v >= lo_fence) & (v <= hi_fence)]
    return {"n": int(v.size), "median": float(med), "q1": float(q1), "q3": float(q3),
            "whisker_lo": float(inside.min()) if inside.size else float(q1),
            "whisker_hi": float(inside.max()) if inside.size else float(q3),
            "n_outliers": int(np.sum((v < lo_fence) | (v > hi_fence)))}


def signals(log: dict) -> dict:
    """The series the metrics use, from a log dict (:func:`load_log` or ``SimLog`` columns)."""
    t = np.asarray(log["t"], float)
    target = np.column_stack([log["target_shoulder"], log["target_elbow"]])
    robot = np.column_stack([log["robot_shoulder"], log["robot_elbow"]])
    new = np.asarray(log["new_target"]) > 0
    return {"t": t, "target": target, "robot": robot, "new": new}


def tracking_report(log: dict, window_s: float = 5.0, max_lag_s: float = 1.0,
                    skip_until_first_packet: bool = True) -> dict:
    """Every robot metric of the paper for one log, with the paper's values beside them. A metric the log cannot
    give (a joint that never moved, too few samples for a jerk or a delay window) is None, never NaN, so the report
    is valid JSON; a log in which the robot took no target at all raises ValueError."""
    s = signals(log)
    t, target, robot, new = s["t"], s["target"], s["robot"], s["new"]
    if not new.any():
        raise ValueError(f"the robot took none of the targets sent ({len(t)} rows, no new_target): nothing to "
                         "compare")
    if skip_until_first_packet and new.any():
        first = int(np.argmax(new))
        t, target, robot, new = t[first:], target[first:], robot[first:], new[first:]
    dt = float(np.median(np.diff(t)))
    errors = abs_error_deg(target, robot)
    whole = {j: xcorr_delay(target[:, i], robot[:, i], dt, max_lag_s) for i, j in enumerate(JOINTS)}
    windows = {j: windowed_delay(target[:, i], robot[:, i], dt, window_s, max_lag_s) for i, j in enumerate(JOINTS)}
    hand_t, hand_r = hand_xy(target), hand_xy(robot)
    hand_delay = {axis: xcorr_delay(hand_t[:, k], hand_r[:, k], dt, max_lag_s) for k, axis in enumerate("xy")}
    tv, virt = t[new], hand_t[new]
    _, j_virtual = jerk(tv, virt)
    _, j_robot = jerk(t, hand_r)
    report = {
        "duration_s": float(t[-1] - t[0] + dt),
        "samples": {"virtual": int(new.sum()), "robot": int(len(t))},
        "packet_intervals": interval_stats(tv),
        "mean_abs_error_deg": errors["mean"],
        "sd_abs_error_deg": errors["sd"],
        "total_displacement_deg": dict(zip(JOINTS, np.degrees(total_displacement(target)).tolist())),
        "error_over_displacement": error_over_displacement(target, robot),
        "error_over_robot_displacement": error_over_displacement(target, robot, reference="robot"),
        "delay_ms": {
            "whole_signal": {k: v * 1e3 for k, v in whole.items()},
            "hand_xy_whole_signal": {k: v * 1e3 for k, v in hand_delay.items()},
            "windowed": {k: {"window_s": window_s, "n": v["n_windows"], "mean": v["mean_s"] * 1e3,
                             "sd": v["sd_s"] * 1e3} for k, v in windows.items()},
        },
        "jerk_m_s3": {"virtual": boxplot_stats(np.linalg.norm(j_virtual, axis=-1)),
                      "robot": boxplot_stats(np.linalg.norm(j_robot, axis=-1))},
        "dimensionless_jerk": {"virtual": dimensionless_jerk(tv, virt), "robot": dimensionless_jerk(t, hand_r)},
        "paper": PAPER,
    }
    return _finite_or_none(report)


def _finite_or_none(x):
    """``x`` with every NaN or infinite float replaced by None (JSON's null; ``json.dumps`` would write bare
    ``NaN``, which is not JSON)."""
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return type(x)(_finite_or_none(v) for v in x)
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
