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
``df/dlm`` from one forward-mode derivative (muscles are independent, so the Jacobian is diagonal). Where a tendon
goes slack the rate jumps by orders of magnitude, and one such step of 1 ms chatters; the arm takes ten of them per
millisecond. :func:`step_backward_euler` instead solves the fully implicit (backward Euler) step
``x = lm + dt f(x)`` by a few safeguarded Newton iterations from the fibre length that keeps the tendon's length:
stable and free of chatter at 1 ms (see its docstring).

Smooth formulation (``smooth``: names from ``jaxarm.config.arm.SMOOTH_KINKS``): the model above is only piecewise smooth (a slack
tendon pulls with zero force, forces are clamped at zero, the force-velocity relation switches branch at isometric,
the activation rate switches at u = a, ...). Each crossing of such a kink bends the map from excitations to the
path, and over a 1 s reach the map is too rough for a finite-difference-checked gradient
(``experiments/arm_gradients.py``). With a kink named in ``smooth`` it is replaced by a C-infinity version that
differs from it only within a stated width (the ``W_*`` constants, each in its quantity's units): clamps at zero
by ``w softplus(x / w)``, switches by a logistic blend ``sigmoid(x / w)``.
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

# Widths of the softened kinks, each in its quantity's units. Each is small against the quantity's working range
# (strains of 1-3 %, forces of 0.1-1 F_max, excitations 0-0.6) so that the smooth arm stays within the
# integration error of the piecewise one, and wide enough to be resolved by float32 arithmetic.
#: Tendon strain (dimensionless) over which a slack tendon takes up force: softplus of the strain.
W_STRAIN = 1e-4
#: Normalised force (of F_max) of the clamps at zero of the passive, active and velocity-dependent forces.
W_FORCE = 1e-4
#: Normalised force over which the force-velocity relation blends its shortening and lengthening branches
#: (they meet at v = 0 with slopes that differ by up to 2.6x).
W_FORCE_VELOCITY = 1e-2
#: Excitation minus activation (dimensionless) over which the activation rate blends deactivation into activation.
W_ACTIVATION = 1e-2
#: Rate (1/s) of the soft ``min(df/dlm, 0)`` of the linearly-implicit fibre step (stiff muscles have |df| ~ 1e4).
W_IMPLICIT_RATE = 10.0
#: Sine of the pennation angle over which the pennation cap bends in.
W_SIN_PENNATION = 5e-3
#: Fibre length, as a fraction of the optimal fibre length, over which the fibre-length clip bends in.
W_FIBER_CLIP = 1e-3


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
# Smooth replacements of the kinks


def soft_max0(x, width):
    """``max(x, 0)`` softened over ``width`` (x's units): ``width softplus(x / width)``, C-infinity, above ``max(x, 0)``
    by at most ``width ln 2`` (at x = 0) and by less than ``width exp(-|x| / width)`` elsewhere."""
    return width * jax.nn.softplus(x / width)


def soft_min(x, cap, width):
    """``min(x, cap)`` softened over ``width``."""
    return cap - soft_max0(cap - x, width)


def soft_clip(x, lo, hi, width):
    """``clip(x, lo, hi)`` softened over ``width`` at each end (for hi - lo much wider than width)."""
    return soft_min(lo + soft_max0(x - lo, width), hi, width)


# --------------------------------------------------------------------------------------------------------------
# Dynamics


def _rate_constant(p: MuscleParams, u, a, smooth=()):
    """(A1 u + A2) while activating (u >= a), A2 while deactivating; blended over ``W_ACTIVATION`` if smooth. The
    rate multiplies (u - a), so da/dt is continuous either way; only its slope jumps at u = a."""
    if "activation" in smooth:
        return p.activation1 * u * jax.nn.sigmoid((u - a) / W_ACTIVATION) + p.activation2
    return jnp.where(u >= a, p.activation1 * u + p.activation2, p.activation2)


def activation_rate(p: MuscleParams, u, a, smooth=()):
    """da/dt (1/s) of the paper's excitation-activation ODE (§2.1)."""
    return (u - a) * _rate_constant(p, u, a, smooth) / p.time_scale_s


def cos_pennation(p: MuscleParams, lm, smooth=()):
    sin_a = jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m / lm
    if "pennation_cap" in smooth:
        sin_a = soft_min(sin_a, _MAX_SIN_PENNATION, W_SIN_PENNATION)
    else:
        sin_a = jnp.minimum(sin_a, _MAX_SIN_PENNATION)
    return jnp.sqrt(1.0 - sin_a**2)


def min_fiber_length(p: MuscleParams):
    """Shortest admissible fibre length (m): where pennation reaches the cap."""
    return jnp.maximum(jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m / _MAX_SIN_PENNATION,
                       0.05 * p.optimal_fiber_length_m)


def max_fiber_length(p: MuscleParams, lmt):
    """Longest admissible fibre length (m): the whole path is fibre (zero tendon), at constant thickness."""
    w = jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m
    return jnp.maximum(jnp.sqrt(lmt**2 + w**2), min_fiber_length(p) * 1.001)


def _tendon_force_norm(p: MuscleParams, strain, smooth=()):
    """Normalised tendon force at ``strain``: zero when slack. The stored curve leaves zero at strain 0 with slope
    ~4 (per unit strain), so the slack switch is a kink; smooth, the curve is read at the strain's softplus."""
    if "tendon_slack" in smooth:
        return eval_spline(p.tendon_fl, soft_max0(strain, W_STRAIN))
    return jnp.where(strain >= 0.0, jnp.maximum(eval_spline(p.tendon_fl, jnp.maximum(strain, 0.0)), 0.0), 0.0)


def _max0(x, smooth, width):
    return soft_max0(x, width) if "force_clamps" in smooth else jnp.maximum(x, 0.0)


def _normalised_forces(p: MuscleParams, lm, lmt, smooth=()):
    # Divisions by per-muscle constants are written as products with their reciprocals: one divide per muscle,
    # not one per muscle and arm (XLA keeps a true division by a non-power-of-two constant).
    ln = lm * (1.0 / p.optimal_fiber_length_m)
    ca = cos_pennation(p, lm, smooth)
    lt = lmt - lm * ca
    strain = lt * (1.0 / p.tendon_slack_length_m) - 1.0
    ft = _tendon_force_norm(p, strain, smooth)
    # The natural spline through the stored knots dips up to ~2e-4 below zero where the curve is flat at zero; a negative
    # passive force would hold a slack fibre stretched, so it is clipped.
    fp = _max0(eval_spline(p.passive_fl, ln), smooth, W_FORCE)
    fa = _max0(eval_spline(p.active_fl, ln), smooth, W_FORCE)
    return ca, ft, fp, fa


def _inverse_force_velocity(a, fa, fv, d, smooth=()):
    """Normalised fibre velocity from Schutte's inverse force-velocity relation with damping ``d``.

    The shortening and lengthening branches meet at ``fv = a fa`` (v = 0) with different slopes. Smooth, they are
    blended by a logistic step of width ``W_FORCE_VELOCITY``; each branch continued past the meeting point keeps a
    non-negative discriminant (it is a sum of squares for fv >= 0), and a tiny offset keeps sqrt's derivative
    finite where it touches zero.
    """
    afa = a * fa
    inv_d = 1.0 / d
    # Shortening branch (f_v < a f_a).
    c1 = _KV * (fv - afa) * inv_d
    b1 = -(fv + _KV * afa + _KV * d) * inv_d
    sqrt_offset = 1e-12 if "force_velocity" in smooth else 0.0
    v_short = (-b1 - jnp.sqrt(jnp.maximum(b1 * b1 - 4.0 * c1, 0.0) + sqrt_offset)) / 2.0
    # Lengthening branch.
    c2 = -(_SLOPE_K * _KV / (_KV + 1.0)) * inv_d * (fv - afa)
    b2 = -((fv - _FMAX * afa) * inv_d - _SLOPE_K * _KV / (_KV + 1.0))
    v_long = (-b2 + jnp.sqrt(jnp.maximum(b2 * b2 - 4.0 * c2, 0.0) + sqrt_offset)) / 2.0
    if "force_velocity" in smooth:
        v = v_short + jax.nn.sigmoid((fv - afa) / W_FORCE_VELOCITY) * (v_long - v_short)
    else:
        v = jnp.where(fv < afa, v_short, v_long)
    return jnp.where(fv < -d, fv * inv_d, v)


def fiber_velocity(p: MuscleParams, a, lm, lmt, smooth=()):
    """dlm/dt (m/s) from the force balance between fibre and tendon."""
    ca, ft, fp, fa = _normalised_forces(p, lm, lmt, smooth)
    fv = _max0(ft / ca - fp, smooth, W_FORCE)
    return _inverse_force_velocity(a, fa, fv, p.damping, smooth) * (p.optimal_fiber_length_m / p.time_scale_s)


def tendon_force(p: MuscleParams, lm, lmt, smooth=()):
    """Force along each muscle-tendon path (N): the tendon's force at fibre length lm (m) and path length lmt (m)."""
    lt = lmt - lm * cos_pennation(p, lm, smooth)
    strain = lt * (1.0 / p.tendon_slack_length_m) - 1.0
    return _tendon_force_norm(p, strain, smooth) * p.max_force_n


def forces(p: MuscleParams, state: MuscleState, lmt, smooth=()) -> MuscleForces:
    """Tendon, active and passive forces (N) along each path, and the fibre velocity (m/s)."""
    lm = state.fiber_length_m
    ca, ft, fp, _ = _normalised_forces(p, lm, lmt, smooth)
    tendon = ft * p.max_force_n
    passive = jnp.minimum(fp * ca * p.max_force_n, tendon)
    return MuscleForces(tendon, tendon - passive, passive, fiber_velocity(p, state.activation, lm, lmt, smooth))


def step(p: MuscleParams, state: MuscleState, u, lmt, dt_s: float, smooth=()) -> MuscleState:
    """Advance activation and fibre length by ``dt_s`` at fixed muscle-tendon length ``lmt`` (m).

    Activation: exact exponential step of the linear ODE with the rate frozen over the step (stable for any dt).
    Fibre length: diagonal linearly-implicit Euler (see module docstring). ``smooth``: names of the
    kinks to soften (see the module docstring).
    """
    a = state.activation
    rate = _rate_constant(p, u, a, smooth) * (1.0 / p.time_scale_s)
    a_new = u + (a - u) * jnp.exp(-rate * dt_s)

    lm = state.fiber_length_m
    f, df = jax.jvp(lambda x: fiber_velocity(p, a_new, x, lmt, smooth), (lm,), (jnp.ones_like(lm),))
    stiff = -soft_max0(-df, W_IMPLICIT_RATE) if "implicit_step" in smooth else jnp.minimum(df, 0.0)
    lm_new = lm + dt_s * f / (1.0 - dt_s * stiff)
    lo, hi = min_fiber_length(p), max_fiber_length(p, lmt)
    if "fiber_clip" in smooth:
        lm_new = soft_clip(lm_new, lo, hi, W_FIBER_CLIP * p.optimal_fiber_length_m)
    else:
        lm_new = jnp.clip(lm_new, lo, hi)
    # a_new is a convex combination of a and u, so in [0, 1]; the clip only catches rounding.
    return MuscleState(jnp.clip(a_new, 0.0, 1.0), lm_new)


def step_backward_euler(p: MuscleParams, state: MuscleState, u, lmt_start, lmt, dt_s: float, iterations: int,
                        smooth=()) -> MuscleState:
    """Advance activation and fibre length by ``dt_s``: backward Euler for the fibre, the path length going from
    ``lmt_start`` to ``lmt`` (m) over the step.

    Activation: the exact exponential step of :func:`step` (exact for an excitation held over the step: the rate's
    branch cannot change while ``a`` moves towards ``u``). Fibre length: the root ``x`` of the backward-Euler
    residual ``g(x) = x - lm - dt f(x)``, ``f = fiber_velocity`` at the new activation and ``lmt``, by
    ``iterations`` Newton steps ``x -= g / (1 - dt min(df/dlm, 0))`` (``df/dlm`` by one forward-mode derivative):

    * the first guess keeps the tendon's length (and force) over the step, the fibre taking up the path's change.
      From the old fibre length instead, a stiff tendon's guess lies far across the toe of its force curve or its
      slack kink: over 30,000 arm steps of step, ramp and smooth random excitations PECM1 (2.8 mm tendon) was
      still off the root by more than 1e-4 of its tendon's length in 38 % of steps after 2 iterations (6 needed);
      from this guess in 0.09 %, the other 21 muscles in under 0.001 %;
    * ``g`` increases with ``x`` (``df/dlm`` is negative where the tendon or the passive fibre carries load and was
      at most 8 /s elsewhere: ``dt df/dlm << 1``), so the sign of ``g`` at each iterate narrows a bracket that
      starts as ``[min_fiber_length, max_fiber_length]``; a Newton step that leaves it is replaced by the bracket's
      midpoint. The result always lies in the admissible range (no clip).

    A fixed iteration count and selects instead of branches: the same vectorised code for every muscle. Two
    iterations are not always enough in the fastest transients: PECM1 taking up slack while its path lengthens at
    0.36 m/s (a 4 Hz, +-10 % l_opt sweep at excitation 0.5) had a one-step tendon-force error of 0.24 F_max (3
    iterations, the arm's default ``MusculoskeletalArmConfig.muscle_newton_iterations``: 0.071; 8: 0.072; ten
    0.1 ms linearly-implicit steps: 0.13), gone within a few steps.
    ``smooth``: as :func:`step` (``implicit_step`` softens the ``min(df, 0)``).
    """
    a = state.activation
    rate = _rate_constant(p, u, a, smooth) * (1.0 / p.time_scale_s)
    a_new = jnp.clip(u + (a - u) * jnp.exp(-rate * dt_s), 0.0, 1.0)

    lm = state.fiber_length_m
    lo = min_fiber_length(p) * jnp.ones_like(lmt)
    hi = max_fiber_length(p, lmt)
    # First guess: the tendon keeps its length, lt = lmt - lm cos(alpha) with lm cos(alpha) = sqrt(lm^2 - w^2) at
    # constant thickness w (a floor of 1e-3 l_opt on w keeps the square root's derivative finite where w = 0).
    lt = lmt_start - lm * cos_pennation(p, lm, smooth)
    w2 = jnp.maximum(jnp.sin(p.pennation_rad) * p.optimal_fiber_length_m, 1e-3 * p.optimal_fiber_length_m) ** 2
    x = jnp.clip(jnp.sqrt(jnp.maximum(lmt - lt, 0.0) ** 2 + w2), lo, hi)

    x = _newton_backward_euler(p, a_new, lm, lmt, dt_s, x, lo, hi, iterations, smooth)
    return MuscleState(a_new, x)


def _newton_backward_euler(p, a, lm, lmt, dt_s, x, lo, hi, iterations, smooth):
    """``iterations`` safeguarded Newton steps on ``g(x) = x - lm - dt f(x)`` from ``x`` in the bracket ``[lo, hi]``
    that holds the root; returns the last iterate.

    The bracket is carried as the iterates themselves: sign(g(x_k)) = -sign(x_{k+1} - x_k) (a Newton step with a
    positive slope, or the bisection towards the root), so each iteration's only output that depends on the fibre's
    forces is the next iterate (XLA:CPU copies an elementwise producer into every consumer fusion: with the bracket
    carried as values of g the force curves were evaluated once per carried array, and the arm ran at half speed).
    """
    x_prev = None
    for _ in range(iterations):
        if x_prev is not None:
            lo = jnp.where(x > x_prev, x_prev, lo)
            hi = jnp.where(x < x_prev, x_prev, hi)
        f, df = jax.jvp(lambda y: fiber_velocity(p, a, y, lmt, smooth), (x,), (jnp.ones_like(x),))
        g = x - lm - dt_s * f
        stiff = -soft_max0(-df, W_IMPLICIT_RATE) if "implicit_step" in smooth else jnp.minimum(df, 0.0)
        x_newton = x - g / (1.0 - dt_s * stiff)
        # the bracket with x's own sign of g: a Newton step that leaves it is replaced by its midpoint
        lo_x = jnp.where(g < 0.0, x, lo)
        hi_x = jnp.where(g > 0.0, x, hi)
        x_prev, x = x, jnp.where((x_newton >= lo_x) & (x_newton <= hi_x), x_newton, 0.5 * (lo_x + hi_x))
    return x


def equilibrium_fiber_length(p: MuscleParams, a, lmt, iterations: int = 60, smooth=()):
    """Fibre length (m) at which fibre and tendon forces balance with zero fibre velocity, by bisection.

    The imbalance ``f_t / cos(alpha) - f_p - a f_a`` falls monotonically as the fibre lengthens (the tendon
    shortens), so bisection between the shortest admissible fibre and the whole path finds the root; where a
    muscle is slack over an interval (all forces zero), any point in it is an equilibrium and one is returned.
    """
    lo = min_fiber_length(p) * jnp.ones_like(lmt)
    hi = max_fiber_length(p, lmt)

    def imbalance(lm):
        ca, ft, fp, fa = _normalised_forces(p, lm, lmt, smooth)
        return ft / ca - fp - a * fa

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        pos = imbalance(mid) > 0.0  # tendon pulls harder than the fibre resists: fibre must lengthen
        return jnp.where(pos, mid, lo), jnp.where(pos, hi, mid)

    lo, hi = jax.lax.fori_loop(0, iterations, body, (lo, hi))
    return 0.5 * (lo + hi)
