"""The authors' Hill-type muscle (Schutte 1993, as stored in the .osim), written once in JAX for both arm backends.

Each muscle has two states: activation ``a`` (dimensionless) and fibre length ``lm`` (m). Given the excitation ``u``
in [0, 1] and the muscle-tendon length ``lmt`` (m) the model is (all forces normalised by the max isometric force,
fibre lengths by the optimal fibre length ``l_opt``, time by ``time_scale``):

* activation (paper §2.1, Schutte 1993): ``da/dt = (u - a)(A1 u + A2) / time_scale`` if ``u >= a`` else
  ``(u - a) A2 / time_scale``;
* pennation at constant muscle thickness: ``sin(alpha) = sin(alpha0) / (lm / l_opt)``;
* tendon: strain ``(lt - l_s) / l_s`` with ``lt = lmt - lm cos(alpha)``; force from the stored tendon spline, zero
  when slack (compliant tendon);
* fibre: active force-length and passive force-length from the stored splines;
* force balance: the velocity-dependent force ``f_v = max(f_t / cos(alpha) - f_p, 0)`` fixes the normalised fibre
  velocity through Schutte's inverse force-velocity relation with damping (three branches: stretch beyond the
  damping limit, shortening, lengthening; constants kv = 0.15, slope_k = 0.13, f_max = 1.4), and
  ``dlm/dt = v_norm * l_opt / time_scale``.

The tendon force along the muscle-tendon path is ``f_t * F_max`` (N): that is what pulls on the bones.

Numerics: the fibre-length ODE is stiff for short-tendon muscles (PECM1's tendon is 2.8 mm, local rate ~100 l_opt/l_s
per s), so :func:`step` uses a diagonal linearly-implicit Euler step ``lm += dt f / (1 - dt min(df/dlm, 0))`` with
``df/dlm`` from one forward-mode derivative (muscles are independent, so the Jacobian is diagonal).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

ASSETS = Path(__file__).parent / "assets"

# Schutte's inverse force-velocity constants (Schutte 1993 / Raasch), dimensionless.
_KV, _SLOPE_K, _FMAX = 0.15, 0.13, 1.4
# Pennation is capped below 90 deg so that cos(alpha) stays positive (OpenSim switches to a rigid-tendon
# approximation at exactly 90 deg; the cap keeps the state in the compliant-tendon regime).
_MAX_SIN_PENNATION = 0.99


class Spline(NamedTuple):
    """Natural cubic splines as their own pieces: one per muscle, or one shared by all.

    Piece ``i`` is the cubic valid from ``knots[:, i]`` on (the first one also below it, the last one also beyond
    the last knot, as OpenSim continues the end pieces), stored as 4 coefficients about its own knot. Evaluating
    walks the knots with compare-and-select (no gather, no search), which XLA fuses into one vectorised loop;
    per-muscle curves with fewer pieces are padded with knots at +inf that are never selected.
    """

    knots: jnp.ndarray  # (S, P) start of each piece
    c: jnp.ndarray      # (S, P, 4) coefficients (a, b, c, d) of a h^3 + b h^2 + c h + d, h = x - knots[:, i]


class MuscleParams(NamedTuple):
    """Per-muscle constants, each (M,). Lengths in m, forces in N, time in s."""

    max_force_n: jnp.ndarray
    optimal_fiber_length_m: jnp.ndarray
    tendon_slack_length_m: jnp.ndarray
    pennation_rad: jnp.ndarray
    damping: jnp.ndarray
    time_scale_s: jnp.ndarray
    activation1: jnp.ndarray
    activation2: jnp.ndarray
    tendon_fl: Spline
    active_fl: Spline
    passive_fl: Spline


class MuscleState(NamedTuple):
    activation: jnp.ndarray      # (M,) dimensionless
    fiber_length_m: jnp.ndarray  # (M,) m


class MuscleForces(NamedTuple):
    """Forces (N) and lengths (m) of every muscle at one instant."""

    tendon_force_n: jnp.ndarray   # total force along the path
    active_force_n: jnp.ndarray   # tendon force minus the passive part, along the path
    passive_force_n: jnp.ndarray  # passive fibre force projected on the path
    fiber_velocity_m_s: jnp.ndarray


# --------------------------------------------------------------------------------------------------------------
# Splines


def natural_cubic_spline(xs: list[np.ndarray], ys: list[np.ndarray], lower: float = -np.inf) -> Spline:
    """Natural cubic splines (one per muscle; identical curves are stored once) as a :class:`Spline`.

    Natural end conditions (zero second derivative) as in OpenSim's ``NaturalCubicSpline``; outside the knots the
    end cubic is continued, and every stored curve spans far beyond the physiological range. Pieces that end at or
    below ``lower`` are not stored (the first kept piece is continued below it): the spline is exact on
    ``[lower, inf)``, which is all the muscle ever asks for (strain >= 0, fibre length >= 0), and each dropped
    piece is one compare-and-select less per evaluation.
    """
    from scipy.interpolate import CubicSpline

    curves = [(np.asarray(x, float), np.asarray(y, float)) for x, y in zip(xs, ys)]
    if all(np.array_equal(cx, curves[0][0]) and np.array_equal(cy, curves[0][1]) for cx, cy in curves):
        curves = curves[:1]
    kept = [slice(max(int(np.searchsorted(x, lower, side="right")) - 1, 0), len(x) - 1) for x, _ in curves]
    pieces = max(k.stop - k.start for k in kept)
    knots = np.full((len(curves), pieces), np.inf)
    coef = np.zeros((len(curves), pieces, 4))
    for i, ((x, y), k) in enumerate(zip(curves, kept)):
        cs = CubicSpline(x, y, bc_type="natural")
        knots[i, : k.stop - k.start] = x[k]
        coef[i, : k.stop - k.start] = cs.c.T[k]  # (a, b, c, d) of piece j about x[j]
    return Spline(jnp.asarray(knots, jnp.float32), jnp.asarray(coef, jnp.float32))


def eval_spline(s: Spline, x):
    """Evaluate each muscle's spline at its own x (M,) (or the shared spline at every x)."""
    origin, coef = s.knots[:, 0], [s.c[:, 0, j] for j in range(4)]
    for i in range(1, s.knots.shape[1]):
        past = x >= s.knots[:, i]
        origin = jnp.where(past, s.knots[:, i], origin)
        coef = [jnp.where(past, s.c[:, i, j], cj) for j, cj in enumerate(coef)]
    h = x - origin
    return ((coef[0] * h + coef[1]) * h + coef[2]) * h + coef[3]


# --------------------------------------------------------------------------------------------------------------
# Loading


def load_muscle_table(path: Path | str | None = None) -> list[dict]:
    """The per-muscle parameter table written by ``python -m jaxarm.arm.convert`` (osim order)."""
    data = json.loads(Path(path or ASSETS / "muscles.json").read_text())
    return data["muscles"] if isinstance(data, dict) else data


def make_muscle_params(table: list[dict], *, time_scale_s: float, activation1: float, activation2: float,
                       damping_override: float | None = None) -> MuscleParams:
    """Build :class:`MuscleParams` from the table. Stored zeros of time_scale/activation1/activation2 (every muscle
    of the authors' file) are replaced by the given defaults; other stored values are kept."""
    def col(key):
        return np.array([float(m[key]) for m in table])

    def or_default(values, default):
        return np.where(values > 0, values, default)

    def spline(key):
        # Tendon strain is clamped at 0 before the curve is read, fibre lengths are positive.
        return natural_cubic_spline([m[key]["x"] for m in table], [m[key]["y"] for m in table], lower=0.0)

    damping = col("damping") if damping_override is None else np.full(len(table), damping_override)
    f32 = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
    return MuscleParams(
        max_force_n=f32(col("max_isometric_force_n")),
        optimal_fiber_length_m=f32(col("optimal_fiber_length_m")),
        tendon_slack_length_m=f32(col("tendon_slack_length_m")),
        pennation_rad=f32(col("pennation_angle_rad")),
        damping=f32(or_default(damping, 1.0)),
        time_scale_s=f32(or_default(col("time_scale_s"), time_scale_s)),
        activation1=f32(or_default(col("activation1"), activation1)),
        activation2=f32(or_default(col("activation2"), activation2)),
        tendon_fl=spline("tendon_force_length"),
        active_fl=spline("active_force_length"),
        passive_fl=spline("passive_force_length"),
    )


# --------------------------------------------------------------------------------------------------------------
# Dynamics


def activation_rate(p: MuscleParams, u, a):
    """da/dt (1/s) of the paper's excitation-activation ODE (§2.1)."""
    rate = jnp.where(u >= a, p.activation1 * u + p.activation2, p.activation2)
    return (u - a) * rate / p.time_scale_s


def cos_pennation(p: MuscleParams, lm):
    sin_a = jnp.minimum(jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m / lm, _MAX_SIN_PENNATION)
    return jnp.sqrt(1.0 - sin_a**2)


def min_fiber_length(p: MuscleParams):
    """Shortest admissible fibre length (m): where pennation reaches the cap."""
    return jnp.maximum(jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m / _MAX_SIN_PENNATION,
                       0.05 * p.optimal_fiber_length_m)


def max_fiber_length(p: MuscleParams, lmt):
    """Longest admissible fibre length (m): the whole path is fibre (zero tendon), at constant thickness."""
    w = jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m
    return jnp.maximum(jnp.sqrt(lmt**2 + w**2), min_fiber_length(p) * 1.001)


def _normalised_forces(p: MuscleParams, lm, lmt):
    # Divisions by per-muscle constants are written as products with their reciprocals: one divide per muscle,
    # not one per muscle and arm (XLA keeps a true division by a non-power-of-two constant).
    ln = lm * (1.0 / p.optimal_fiber_length_m)
    ca = cos_pennation(p, lm)
    lt = lmt - lm * ca
    strain = lt * (1.0 / p.tendon_slack_length_m) - 1.0
    ft = jnp.where(strain >= 0.0, jnp.maximum(eval_spline(p.tendon_fl, jnp.maximum(strain, 0.0)), 0.0), 0.0)
    # The natural spline through the stored knots dips ~1e-6 below zero where the curve is flat at zero; a negative
    # passive force would hold a slack fibre stretched, so it is clipped.
    fp = jnp.maximum(eval_spline(p.passive_fl, ln), 0.0)
    fa = jnp.maximum(eval_spline(p.active_fl, ln), 0.0)
    return ca, ft, fp, fa


def _inverse_force_velocity(a, fa, fv, d):
    """Normalised fibre velocity from Schutte's inverse force-velocity relation with damping ``d``."""
    afa = a * fa
    inv_d = 1.0 / d
    # Shortening branch (f_v < a f_a).
    c1 = _KV * (fv - afa) * inv_d
    b1 = -(fv + _KV * afa + _KV * d) * inv_d
    v_short = (-b1 - jnp.sqrt(jnp.maximum(b1 * b1 - 4.0 * c1, 0.0))) / 2.0
    # Lengthening branch.
    c2 = -(_SLOPE_K * _KV / (_KV + 1.0)) * inv_d * (fv - afa)
    b2 = -((fv - _FMAX * afa) * inv_d - _SLOPE_K * _KV / (_KV + 1.0))
    v_long = (-b2 + jnp.sqrt(jnp.maximum(b2 * b2 - 4.0 * c2, 0.0))) / 2.0
    return jnp.where(fv < -d, fv * inv_d, jnp.where(fv < afa, v_short, v_long))


def fiber_velocity(p: MuscleParams, a, lm, lmt):
    """dlm/dt (m/s) from the force balance between fibre and tendon."""
    ca, ft, fp, fa = _normalised_forces(p, lm, lmt)
    fv = jnp.maximum(ft / ca - fp, 0.0)
    return _inverse_force_velocity(a, fa, fv, p.damping) * (p.optimal_fiber_length_m / p.time_scale_s)


def tendon_force(p: MuscleParams, lm, lmt):
    """Force along each muscle-tendon path (N): the tendon's force at fibre length lm (m) and path length lmt (m)."""
    lt = lmt - lm * cos_pennation(p, lm)
    strain = lt * (1.0 / p.tendon_slack_length_m) - 1.0
    ft = jnp.where(strain >= 0.0, jnp.maximum(eval_spline(p.tendon_fl, jnp.maximum(strain, 0.0)), 0.0), 0.0)
    return ft * p.max_force_n


def forces(p: MuscleParams, state: MuscleState, lmt) -> MuscleForces:
    """Tendon, active and passive forces (N) along each path, and the fibre velocity (m/s)."""
    lm = state.fiber_length_m
    ca, ft, fp, _ = _normalised_forces(p, lm, lmt)
    tendon = ft * p.max_force_n
    passive = jnp.minimum(fp * ca * p.max_force_n, tendon)
    return MuscleForces(tendon, tendon - passive, passive, fiber_velocity(p, state.activation, lm, lmt))


def step(p: MuscleParams, state: MuscleState, u, lmt, dt_s: float) -> MuscleState:
    """Advance activation and fibre length by ``dt_s`` at fixed muscle-tendon length ``lmt`` (m).

    Activation: exact exponential step of the linear ODE with the rate frozen over the step (stable for any dt).
    Fibre length: diagonal linearly-implicit Euler (see module docstring).
    """
    a = state.activation
    rate = jnp.where(u >= a, p.activation1 * u + p.activation2, p.activation2) * (1.0 / p.time_scale_s)
    a_new = u + (a - u) * jnp.exp(-rate * dt_s)

    lm = state.fiber_length_m
    f, df = jax.jvp(lambda x: fiber_velocity(p, a_new, x, lmt), (lm,), (jnp.ones_like(lm),))
    lm_new = lm + dt_s * f / (1.0 - dt_s * jnp.minimum(df, 0.0))
    lm_new = jnp.clip(lm_new, min_fiber_length(p), max_fiber_length(p, lmt))
    return MuscleState(jnp.clip(a_new, 0.0, 1.0), lm_new)


def equilibrium_fiber_length(p: MuscleParams, a, lmt, iterations: int = 60):
    """Fibre length (m) at which fibre and tendon forces balance with zero fibre velocity, by bisection.

    The imbalance ``f_t / cos(alpha) - f_p - a f_a`` falls monotonically as the fibre lengthens (the tendon
    shortens), so bisection between the shortest admissible fibre and the whole path finds the root; where a
    muscle is slack over an interval (all forces zero), any point in it is an equilibrium and one is returned.
    """
    lo = min_fiber_length(p) * jnp.ones_like(lmt)
    hi = max_fiber_length(p, lmt)

    def imbalance(lm):
        ca, ft, fp, fa = _normalised_forces(p, lm, lmt)
        return ft / ca - fp - a * fa

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        pos = imbalance(mid) > 0.0  # tendon pulls harder than the fibre resists: fibre must lengthen
        return jnp.where(pos, mid, lo), jnp.where(pos, hi, mid)

    lo, hi = jax.lax.fori_loop(0, iterations, body, (lo, hi))
    return 0.5 * (lo + hi)
