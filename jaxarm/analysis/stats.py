"""Statistics over many networks: success counts and the paper's "mean (SD) across successful trajectories".

Post-processing on host arrays (NumPy); the per-trial metrics come batched from ``vmap(reach_metrics)``.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from jaxarm.analysis.reach import ReachMetrics

#: Per-trial reach metrics summarised as mean (SD) over successful trajectories (as the paper reports them), with
#: display units.
SUCCESS_METRICS = {
    "speed_before_m_s": "m/s",
    "speed_after_m_s": "m/s",
    "distance_after_m": "m",
    "time_inside_s": "s",
}


def success_count(success) -> int:
    """Number of trials (networks) that reached the target. success: (N,) bool."""
    return int(np.sum(np.asarray(success, dtype=bool)))


def mean_sd(values, mask=None) -> dict:
    """{"mean", "sd", "n"} of the finite entries of ``values`` (where ``mask``), sample SD (ddof = 1).

    Empty selections give NaN mean and SD; a single value gives SD NaN. Values are plain floats (JSON-ready).
    """
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    keep = np.isfinite(v)
    if mask is not None:
        keep &= np.asarray(mask, dtype=bool).reshape(-1)
    v = v[keep]
    mean = float(np.mean(v)) if v.size else math.nan
    sd = float(np.std(v, ddof=1)) if v.size > 1 else math.nan
    return {"mean": mean, "sd": sd, "n": int(v.size)}


def summarize_reaches(metrics: ReachMetrics, extra: Mapping[str, np.ndarray] | None = None) -> dict:
    """Summary of N trials: success count and rate, min/final distance over all trials, and the reach metrics
    (:data:`SUCCESS_METRICS`) over successful trials only.

    metrics: a :class:`ReachMetrics` whose fields have leading shape (N,). extra: further per-trial arrays (e.g.
    ``{"dimensionless_jerk": ...}``) summarised over successful trials too.
    """
    success = np.asarray(metrics.success, dtype=bool).reshape(-1)
    n = int(success.size)
    out = {
        "n": n,
        "success_count": success_count(success),
        "success_rate": float(success.mean()) if n else math.nan,
        "min_distance_m": mean_sd(metrics.min_distance_m),
        "final_distance_m": mean_sd(metrics.final_distance_m),
    }
    for name in SUCCESS_METRICS:
        out[name] = mean_sd(getattr(metrics, name), success)
    for name, values in (extra or {}).items():
        out[name] = mean_sd(values, success)
    return out
