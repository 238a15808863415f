"""Test inputs for the arms: excitation time courses with known properties (SI: s; excitations in [0, 1])."""
from __future__ import annotations

import numpy as np


def smooth_random_excitations(seed: int, seconds: float = 1.0, knots: int = 11, high: float = 0.6,
                              dt_s: float = 0.001) -> np.ndarray:
    """(T, 4) float32 excitations: per muscle group, ``knots`` values U(0, high) evenly spaced over ``seconds``
    (numpy ``default_rng(seed)``), linearly interpolated at every arm step ``dt_s``. Smooth enough that a converged
    arm's path depends smoothly on them, rough enough to swing both joints through tens of degrees."""
    rng = np.random.default_rng(seed)
    values = rng.uniform(0.0, high, size=(knots, 4))
    t = np.arange(int(round(seconds / dt_s))) * dt_s
    grid = np.linspace(0.0, seconds, knots)
    return np.stack([np.interp(t, grid, values[:, g]) for g in range(4)], axis=-1).astype(np.float32)
