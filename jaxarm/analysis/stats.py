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


def intraclass_correlation(groups) -> float | None:
    """ICC(1) of a one-way ANOVA over ``groups`` (one array of a measure per group, e.g. per metaparameter set over
    its networks; empty groups dropped): (MSB - MSW) / (MSB + (k0 - 1) MSW), k0 the ANOVA's average group size for
    unequal groups. The share of the measure's variance that belongs to the group. None with fewer than two groups,
    no within-group degrees of freedom or no within-group spread."""
    groups = [np.asarray(g, float) for g in groups if len(g) >= 1]
    n_total, a = sum(len(g) for g in groups), len(groups)
    if a < 2 or n_total <= a:
        return None
    grand = np.concatenate(groups).mean()
    ssb = sum(len(g) * (g.mean() - grand) ** 2 for g in groups)
    ssw = sum(((g - g.mean()) ** 2).sum() for g in groups)
    msb, msw = ssb / (a - 1), ssw / (n_total - a)
    k0 = (n_total - sum(len(g) ** 2 for g in groups) / n_total) / (a - 1)
    if msw == 0:
        return None
    return float((msb - msw) / (msb + (k0 - 1) * msw))


def set_mean_reliability(icc: float, k) -> float | np.ndarray:
    """Spearman-Brown: the reliability of a group's mean over ``k`` members, k ICC / (1 + (k - 1) ICC), i.e. the
    squared correlation between that mean and the group's true mean (ICC clipped at 0)."""
    icc = max(float(icc), 0.0)
    k = np.asarray(k, float)
    return k * icc / (1 + (k - 1) * icc)


def shrunk_means(groups, icc: float) -> np.ndarray:
    """Each group's mean pulled toward the grand mean by its reliability (the best linear predictor of its true
    mean under the one-way random-effects model): grand + r_k (mean - grand), r_k = :func:`set_mean_reliability` of
    its size. What a group chosen for its sample mean is expected to do on new members, without the winner's
    curse of the sample mean. Empty groups give NaN."""
    groups = [np.asarray(g, float) for g in groups]
    grand = np.concatenate([g for g in groups if len(g)]).mean()
    return np.array([grand + set_mean_reliability(icc, len(g)) * (g.mean() - grand) if len(g) else np.nan
                     for g in groups])
