"""The Schutte 1993 muscle in isolation (fixed muscle-tendon length)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.arm import muscle as mus


@pytest.fixture(scope="module")
def params():
    table = mus.load_muscle_table()
    return mus.make_muscle_params(table, time_scale_s=0.1, activation1=7.667, activation2=1.459854), table


def _isometric(p, u, lmt, dt, n):
    s = mus.MuscleState(jnp.zeros_like(lmt), mus.equilibrium_fiber_length(p, jnp.zeros_like(lmt), lmt))

    def body(s, _):
        s = mus.step(p, s, u, lmt, dt)
        return s, mus.forces(p, s, lmt).tendon_force_n

    return jax.lax.scan(body, s, None, length=n)


def test_activation_time_course_matches_the_ode(params):
    p, _ = params
    a = jnp.zeros(p.max_force_n.shape)
    rate_on = (7.667 + 1.459854) / 0.1  # 1/s at u = 1
    for _ in range(10):
        a = a + (1.0 - a) * (1 - jnp.exp(-rate_on * 0.001))
    s = mus.MuscleState(jnp.zeros_like(a), jnp.asarray(p.optimal_fiber_length_m))
    lmt = p.optimal_fiber_length_m + p.tendon_slack_length_m
    for _ in range(10):
        s = mus.step(p, s, jnp.ones_like(a), lmt, 0.001)
    np.testing.assert_allclose(s.activation, a, rtol=1e-5)
    np.testing.assert_allclose(s.activation, 1 - np.exp(-rate_on * 0.01), rtol=1e-4)


def test_stiff_short_tendon_is_stable_at_1ms_and_agrees_with_01ms(params):
    """PECM1 has a 2.8 mm tendon: explicit Euler diverges at 1 ms; the linearly-implicit step must not."""
    p, table = params
    lmt = p.optimal_fiber_length_m * jnp.cos(p.pennation_rad) + p.tendon_slack_length_m * 1.02
    u = jnp.ones_like(lmt)
    _, f_1ms = _isometric(p, u, lmt, 1e-3, 500)
    _, f_01ms = _isometric(p, u, lmt, 1e-4, 5000)
    assert bool(jnp.isfinite(f_1ms).all())
    ratio = np.asarray(f_1ms[-1] / p.max_force_n)
    assert np.all((ratio > 0.85) & (ratio < 1.05)), ratio  # full activation at optimal length: about F_max
    np.testing.assert_allclose(f_1ms[-1], f_01ms[-1], rtol=5e-3)
    pecm1 = [m["name"] for m in table].index("PECM1")
    assert np.max(np.abs(np.diff(np.asarray(f_1ms[:, pecm1])))) < 0.2 * float(p.max_force_n[pecm1])


def test_unexcited_muscle_in_equilibrium_stays_there(params):
    p, _ = params
    lmt = p.optimal_fiber_length_m + p.tendon_slack_length_m * 1.01
    s, f = _isometric(p, jnp.zeros_like(lmt), lmt, 1e-3, 200)
    np.testing.assert_allclose(f[-1], f[0], atol=1e-2 * float(p.max_force_n.max()) * 1e-2)


@pytest.mark.parametrize("key, lo, hi", [("tendon_force_length", -0.01, 0.3), ("active_force_length", 0.3, 2.0),
                                         ("passive_force_length", 0.5, 2.0)])
def test_piecewise_spline_matches_the_natural_spline(key, lo, hi):
    from scipy.interpolate import CubicSpline

    table = mus.load_muscle_table()
    spline = mus.natural_cubic_spline([m[key]["x"] for m in table], [m[key]["y"] for m in table])
    x = np.linspace(lo, hi, 100_001)
    exact = CubicSpline(table[0][key]["x"], table[0][key]["y"], bc_type="natural")(x)
    got = np.asarray(mus.eval_spline(spline, jnp.asarray(x, jnp.float32)))
    assert np.abs(got - exact).max() < 2e-6 * np.abs(exact).max() + 1e-6


def test_spline_cut_below_lower_is_exact_above_it_and_per_muscle_curves_pad():
    from scipy.interpolate import CubicSpline

    xs = [np.array([-1.0, 0.0, 0.5, 1.0, 2.0]), np.array([-2.0, -0.5, 0.25, 3.0])]
    ys = [np.array([0.0, 0.1, 0.4, 0.2, 1.0]), np.array([1.0, 0.0, 2.0, 0.5])]
    cut = mus.natural_cubic_spline(xs, ys, lower=0.1)
    assert cut.knots.shape == (2, 3) and np.isinf(np.asarray(cut.knots)[1, 2])  # 4 pieces -> 3; 3 -> 2, padded
    x = np.linspace(0.1, 2.5, 2001)
    for m in range(2):
        exact = CubicSpline(xs[m], ys[m], bc_type="natural")(x)
        got = np.asarray(jax.vmap(lambda v: mus.eval_spline(cut, jnp.full(2, v))[m])(jnp.asarray(x, jnp.float32)))
        np.testing.assert_allclose(got, exact, atol=2e-6)
    below = CubicSpline(xs[0], ys[0], bc_type="natural")(-0.5)
    assert abs(float(mus.eval_spline(cut, jnp.full(2, -0.5))[0]) - below) > 1e-3  # the dropped piece is gone


def test_spline_reproduces_its_knots(params):
    p, table = params
    knots = jnp.asarray([table[i]["tendon_force_length"]["x"][5] for i in range(len(table))], jnp.float32)
    values = np.array([table[i]["tendon_force_length"]["y"][5] for i in range(len(table))])
    np.testing.assert_allclose(mus.eval_spline(p.tendon_fl, knots), values, atol=1e-5)
