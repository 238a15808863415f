"""Jerk and the dimensionless jerk of a planar hand path (paper §3.2, Fig. 7; Hogan & Sternad 2009).

What we compute (the paper's formula, exactly, in SI units):

    DLJ = ( ∫_{t1}^{t2} |x'''(t)|² dt ) · D³ / v_mean²,   D = t2 - t1,   v_mean = path length / D.

Discretisation (documented, deterministic, no smoothing):

* samples ``xy[i]`` at ``t_i = i·dt``, i = 0 … T-1, so D = (T-1)·dt; T >= 5.
* jerk ``x'''(t_i)`` by 5-point finite-difference stencils: the central stencil
  (x[i+2] - 2x[i+1] + 2x[i-1] - x[i-2]) / (2 dt³) wherever it fits, and at the first and last two samples the
  5-point stencil on the nearest five samples (weights from the Taylor/Vandermonde system). Every stencil is exact
  for polynomials of degree <= 4 and second-order accurate otherwise.
* the integral by the trapezoid rule over all T samples.
* v_mean = polyline length Σ|x[i+1] - x[i]| / D (exact for any monotone straight path).

Because every term is homogeneous, ``dt`` cancels: DLJ = (T-1)^5 · Σ_trapz |Δ³-stencil x|² / L², so the value is
independent of the time unit, the length unit, the amplitude and the duration. Known values: the cubic reach
x = A(3τ² - 2τ³) (zero velocity but non-zero acceleration at both ends) scores exactly 144; x = Aτ³ scores 36; the
minimum-jerk reach x = A(10τ³ - 15τ⁴ + 6τ⁵) scores 720 (to O(dt²)); uniform circular motion through an angle θ
scores θ⁴; a constant-velocity path scores 0.

The paper's absolute values (0.76, 1.72, 28.1; Dura-Bernal et al. 2015, §3.2 and Fig. 7) cannot come from this formula
for reaches like its own. A movement that starts at rest (zero velocity and acceleration) satisfies
|x(D) - x(0)| <= sqrt(∫|jerk|² dt) · sqrt(D⁵/20) (Cauchy-Schwarz), hence DLJ >= 20 · (displacement / path length)²
whatever happens at the end, and a straight reach with zero velocity and acceleration at both ends scores >= 720.
Compare the ordering and the ratios between conditions, not the absolute numbers. ``normalise="peak"`` gives
Hogan & Sternad's own recommended variant (v_peak instead of v_mean; the minimum-jerk reach scores
720 / 1.875² = 204.8).

Precision: third differences cancel digits (with float32 positions a minimum-jerk reach of 15 cm sampled every
1 ms, the arm's own step, scored 3381 instead of 720), so every function here converts its input to float64 and
computes with NumPy, whatever the caller's dtype. They analyse recorded paths; they are not traced. Positions that
were stored in float32 (the arm's own output) carry their rounding into the jerk, which float64 cannot undo:
:func:`dimensionless_jerk` estimates that noise floor and warns when it exceeds 1 % of the value (subsample to
10 ms, the closed loop's rate, or record in float64).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

#: Points per finite-difference stencil.
STENCIL_POINTS = 5


def _stencil(n_samples: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Index (T, 5) and weight (T, 5) arrays of the 5-point stencil for derivative ``order`` at every sample (dt = 1).

    At sample i the stencil uses samples s..s+4 with s = clip(i-2, 0, T-5); the weights solve
    Σ_j w_j o_j^m / m! = [m == order] for m = 0..4 (o_j = s + j - i), i.e. they are exact for quartics.
    """
    if n_samples < STENCIL_POINTS:
        raise ValueError(f"need at least {STENCIL_POINTS} samples for a 5-point stencil, got {n_samples}")
    starts = np.clip(np.arange(n_samples) - 2, 0, n_samples - STENCIL_POINTS)
    index = starts[:, None] + np.arange(STENCIL_POINTS)[None, :]
    weights = np.empty((n_samples, STENCIL_POINTS))
    cache: dict[int, np.ndarray] = {}
    for i, s in enumerate(starts):
        first = int(s - i)
        if first not in cache:
            offsets = np.arange(first, first + STENCIL_POINTS, dtype=np.float64)
            vander = np.stack([offsets ** m / math.factorial(m) for m in range(STENCIL_POINTS)])
            rhs = np.zeros(STENCIL_POINTS)
            rhs[order] = 1.0
            # The exact weights are rationals with denominators <= 12; rounding removes solver noise (1e-16).
            cache[first] = np.round(np.linalg.solve(vander, rhs), 12)
        weights[i] = cache[first]
    return index, weights


def _float64(xy) -> np.ndarray:
    return np.asarray(xy, dtype=np.float64)


def _derivative(xy, dt, order: int) -> np.ndarray:
    xy = _float64(xy)
    index, weights = _stencil(xy.shape[-2], order)
    return np.einsum("tk,...tkd->...td", weights, xy[..., index, :]) / float(dt) ** order


def jerk(xy, dt) -> np.ndarray:
    """Jerk x'''(t_i) at every sample, (..., T, 2) float64 in m/s³, by the 5-point stencils of this module.

    xy: (..., T, 2) positions in m sampled every dt s (T >= 5).
    """
    return _derivative(xy, dt, 3)


def velocity(xy, dt) -> np.ndarray:
    """Velocity x'(t_i) at every sample, (..., T, 2) float64 in m/s, by 5-point stencils (4th-order accurate).

    xy: (..., T, 2) positions in m sampled every dt s (T >= 5).
    """
    return _derivative(xy, dt, 1)


def jerk_magnitude(xy, dt) -> np.ndarray:
    """|x'''(t_i)|, (..., T) float64 in m/s³ (the quantity of the paper's Fig. 7A box plots).

    xy: (..., T, 2) positions in m sampled every dt s (T >= 5).
    """
    return np.linalg.norm(jerk(xy, dt), axis=-1)


def path_length(xy) -> np.ndarray:
    """Polyline length Σ|x[i+1] - x[i]| in m, float64. xy: (..., T, 2)."""
    return np.linalg.norm(np.diff(_float64(xy), axis=-2), axis=-1).sum(axis=-1)


def jerk_energy(xy, dt, where=None) -> np.ndarray:
    """∫|x'''(t)|² dt in m²/s⁵ by the trapezoid rule over all T samples (the integral of :func:`dimensionless_jerk`),
    counting only the samples where ``where`` ((..., T) bool) is True: the whole path's trapezoid weights, so the
    parts over a partition of the samples add up to the whole. ``dimensionless_jerk(xy, dt) = jerk_energy(xy, dt) ·
    D⁵ / L²`` (D the duration, L the path length), so the trained/naive ratio of two paths of one duration is their
    energy ratio times (L_naive / L_trained)².
    """
    j2 = np.sum(jerk(xy, dt) ** 2, axis=-1)
    if where is not None:
        j2 = np.where(where, j2, 0.0)
    return float(dt) * (np.sum(j2, axis=-1) - 0.5 * (j2[..., 0] + j2[..., -1]))


def dimensionless_jerk(xy, dt, normalise: str = "mean") -> np.ndarray:
    """Dimensionless jerk (∫|x'''|² dt) · D³ / v² of a hand path (see the module docstring for the exact scheme).

    Args:
        xy (ArrayLike): (..., T, 2) hand positions in m, sampled every ``dt`` s, T >= 5 (leading axes are batch axes); any
            float dtype, computed in float64.
        dt (float): sample period in s (cancels out; must be > 0).
        normalise (str): "mean" (the paper: v = path length / D) or "peak" (Hogan & Sternad's variant: v = max speed,
            speed from the 5-point velocity stencils).

    Returns:
        (...,) float64 dimensionless values; NaN where the hand does not move (v = 0).
    """
    if normalise not in ("mean", "peak"):
        raise ValueError(f"normalise = {normalise!r}: must be 'mean' or 'peak'")
    if not float(dt) > 0:
        raise ValueError(f"dt = {dt!r}: the sample period must be > 0 s")
    xy_in, xy = xy, _float64(xy)
    duration = (xy.shape[-2] - 1) * float(dt)
    integral = jerk_energy(xy, dt)
    if normalise == "mean":
        v = path_length(xy) / duration
    else:
        v = np.max(np.linalg.norm(velocity(xy, dt), axis=-1), axis=-1)
    v2 = v * v
    value = np.where(v2 > 0, integral * duration ** 3 / np.where(v2 > 0, v2, 1.0), np.nan)
    _warn_if_rounding_dominates(np.asarray(xy_in).dtype, xy, float(dt), integral, duration, v2, value)
    return value


def _warn_if_rounding_dominates(dtype, xy, dt, integral, duration, v2, value) -> None:
    """Warn when positions rounded to ``dtype`` (float32 or coarser) make the DLJ uncertain by more than 1 %.

    Rounding error per coordinate: uniform over one ulp at the path's largest coordinate, sd = ulp / sqrt(12);
    through the 3rd-derivative stencil (sum of squared weights 2.5) it adds sd_j = sqrt(2.5) sd / dt^3 per
    component. The jerk integral gains ~2 D sd_j^2 and fluctuates by ~2 sqrt(dt I sd_j^2) (I = the integral);
    three times the latter is the bound used.
    """
    if not np.issubdtype(dtype, np.floating) or np.finfo(dtype).bits >= 64:
        return
    ulp = np.spacing(np.max(np.abs(xy), axis=(-2, -1)).astype(dtype)).astype(np.float64)
    sd_j2 = 2.5 * ulp ** 2 / 12.0 / dt ** 6
    noise = (2.0 * duration * sd_j2 + 6.0 * np.sqrt(dt * integral * sd_j2)) * duration ** 3 / np.where(v2 > 0, v2, 1.0)
    with np.errstate(invalid="ignore"):
        bad = np.any(noise > 0.01 * np.abs(value))
    if bad:
        warnings.warn(f"dimensionless_jerk: positions stored as {np.dtype(dtype).name} and sampled every {dt * 1e3:g} ms "
                      "carry rounding noise of more than 1 % of the value; subsample (e.g. to 10 ms) or record the "
                      "path in float64", RuntimeWarning, stacklevel=3)
