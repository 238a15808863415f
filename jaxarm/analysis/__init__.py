"""Analysis: dimensionless jerk, reach metrics, statistics over networks, and the paper's numbers (§3.2)."""
from jaxarm.analysis.jerk import dimensionless_jerk, jerk, jerk_energy, jerk_magnitude, path_length, velocity
from jaxarm.analysis.reach import (ONSET_SPEED_M_S, SUCCESS_RADIUS_M, DistanceMetrics, ReachMetrics, distance_metrics,
                                   interval_speeds, reach_metrics)
from jaxarm.analysis.stats import SUCCESS_METRICS, mean_sd, success_count, summarize_reaches

__all__ = [
    "dimensionless_jerk", "jerk", "jerk_energy", "jerk_magnitude", "path_length", "velocity",
    "ONSET_SPEED_M_S", "SUCCESS_RADIUS_M", "DistanceMetrics", "ReachMetrics", "distance_metrics", "interval_speeds",
    "reach_metrics",
    "SUCCESS_METRICS", "mean_sd", "success_count", "summarize_reaches",
]
