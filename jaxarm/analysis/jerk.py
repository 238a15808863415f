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

The paper's absolute values (0.76, 1.72, 28.1; ``reference_values.md``) cannot come from this formula for reaches
like its own. A movement that starts at rest (zero velocity and acceleration) satisfies
|x(D) - x(0)| <= sqrt(∫|jerk|² dt) · sqrt(D⁵/20) (Cauchy-Schwarz), hence DLJ >= 20 · (displacement / path length)²
whatever happens at the end, and a straight reach with zero velocity and acceleration at both ends scores >= 720.
Compare the ordering and the ratios between conditions, not the absolute numbers. ``normalise="peak"`` gives
Hogan & Sternad's own recommended variant (v_peak instead of v_mean; the minimum-jerk reach scores
720 / 1.875² = 204.8).

Precision: finite differences of order 3 cancel digits. With float32 positions, a 15 cm reach sampled every 10 ms
keeps DLJ to about 0.1-1 %; finer sampling needs float64 (``jax.enable_x64``).
"""
from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
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


def _derivative(xy, dt, order: int):
    xy = jnp.asarray(xy)
    index, weights = _stencil(xy.shape[-2], order)
    w = jnp.asarray(weights, dtype=xy.dtype)
    return jnp.einsum("tk,...tkd->...td", w, xy[..., index, :]) / jnp.asarray(dt, xy.dtype) ** order


@jax.jit
def jerk(xy, dt):
    """Jerk x'''(t_i) at every sample, (..., T, 2) in m/s³, by the 5-point stencils of this module.

    xy: (..., T, 2) positions in m sampled every dt s (T >= 5).
    """
    return _derivative(xy, dt, 3)


@jax.jit
def velocity(xy, dt):
    """Velocity x'(t_i) at every sample, (..., T, 2) in m/s, by 5-point stencils (4th-order accurate)."""
    return _derivative(xy, dt, 1)


def jerk_magnitude(xy, dt):
    """|x'''(t_i)|, (..., T) in m/s³ (the quantity of the paper's Fig. 7A box plots)."""
    j = jerk(xy, dt)
    return jnp.sqrt(jnp.sum(j * j, axis=-1))


def path_length(xy):
    """Polyline length Σ|x[i+1] - x[i]| in m. xy: (..., T, 2)."""
    xy = jnp.asarray(xy)
    seg = jnp.diff(xy, axis=-2)
    return jnp.sum(jnp.sqrt(jnp.sum(seg * seg, axis=-1)), axis=-1)


@partial(jax.jit, static_argnames=("normalise",))
def dimensionless_jerk(xy, dt, normalise: str = "mean"):
    """Dimensionless jerk (∫|x'''|² dt) · D³ / v² of a hand path (see the module docstring for the exact scheme).

    Args:
        xy: (..., T, 2) hand positions in m, sampled every ``dt`` s, T >= 5 (leading axes are batch axes).
        dt: sample period in s (cancels out; must be > 0).
        normalise: "mean" (the paper: v = path length / D) or "peak" (Hogan & Sternad's variant: v = max speed,
            speed from the 5-point velocity stencils).

    Returns:
        (...,) dimensionless values; NaN where the hand does not move (v = 0).
    """
    if normalise not in ("mean", "peak"):
        raise ValueError(f"normalise = {normalise!r}: must be 'mean' or 'peak'")
    xy = jnp.asarray(xy)
    if not jnp.issubdtype(xy.dtype, jnp.floating):
        xy = xy.astype(jnp.float32)
    n = xy.shape[-2]
    dt = jnp.asarray(dt, xy.dtype)
    duration = (n - 1) * dt
    j2 = jnp.sum(jerk(xy, dt) ** 2, axis=-1)
    integral = dt * (jnp.sum(j2, axis=-1) - 0.5 * (j2[..., 0] + j2[..., -1]))
    if normalise == "mean":
        v = path_length(xy) / duration
    else:
        vel = velocity(xy, dt)
        v = jnp.max(jnp.sqrt(jnp.sum(vel * vel, axis=-1)), axis=-1)
    v2 = v * v
    return jnp.where(v2 > 0, integral * duration ** 3 / jnp.where(v2 > 0, v2, 1.0), jnp.nan)
