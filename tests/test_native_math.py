"""The native kernel's own exp, expm1 and log1p (vectorisable, used instead of the C library's scalar calls) against
the exact functions (float64 numpy), in units in the last place of the float32 result."""
import numpy as np
import pytest

from jaxarm.network import native

pytestmark = pytest.mark.skipif(not native.available(), reason="native kernel unavailable (no C++ compiler)")


def ulp_error(got, exact):
    """|got - exact| in ulps of the float32 nearest to exact (float64 arithmetic)."""
    exact32 = exact.astype(np.float32)
    ulp = np.spacing(np.abs(exact32)).astype(np.float64)
    ulp = np.where(ulp == 0, np.spacing(np.float32(np.finfo(np.float32).tiny)), ulp)
    return np.abs(got.astype(np.float64) - exact) / ulp


def grid(lo, hi, n=400_001, seed=0):
    """Dense uniform points in [lo, hi], plus random ones, as float32."""
    rng = np.random.default_rng(seed)
    return np.concatenate([np.linspace(lo, hi, n), rng.uniform(lo, hi, n)]).astype(np.float32)


@pytest.mark.parametrize("name, lo, hi, max_ulp", [
    ("exp", -87.0, 88.0, 1.0),           # measured 0.97
    ("exp", -5.0, 5.0, 1.0),             # the Mg block's range
    ("expm1", -1e-6, 1e-6, 1.0),
    ("expm1", -0.5, 0.5, 1.5),           # measured 1.48, at x = ln2 / 2 where the reduction starts
    ("expm1", -2.0, 2.0, 1.5),           # loads over reversal distances: mostly in [-1, 0]
    ("expm1", -80.0, 80.0, 1.5),
    ("log1p", -1e-6, 1e-6, 1.0),
    ("log1p", -0.9, 0.0, 1.5),           # -min(w / E, max_jump_fraction)
    ("log1p", -0.999, 100.0, 1.5),       # measured 1.13
])
def test_fast_math_is_within_a_few_ulp_of_the_exact_function(name, lo, hi, max_ulp):
    x = grid(lo, hi)
    exact = {"exp": np.exp, "expm1": np.expm1, "log1p": np.log1p}[name](x.astype(np.float64))
    got = native.fast_math(name, x)
    err = ulp_error(got, exact)
    assert np.all(np.isfinite(got))
    assert err.max() <= max_ulp, (name, float(x[np.argmax(err)]), float(err.max()))
    # and as accurate as the C library on average (its float functions are within 1 ulp)
    assert err.mean() < 0.5, err.mean()


def test_fast_math_edges():
    assert native.fast_math("expm1", np.array([0.0, -0.0], np.float32)).tolist() == [0.0, 0.0]
    assert native.fast_math("log1p", np.array([0.0], np.float32)).tolist() == [0.0]
    assert native.fast_math("exp", np.array([0.0], np.float32)).tolist() == [1.0]
    # below the clamp the result is tiny and positive, not a wrapped exponent
    assert 0.0 < native.fast_math("exp", np.array([-200.0], np.float32))[0] < 1e-37


@pytest.mark.parametrize("name, lo, hi", [("exp", -90.0, 90.0), ("expm1", -90.0, 90.0), ("log1p", -0.999, 100.0),
                                          ("log1p", -2e-3, 2e-3)])
def test_eight_lanes_give_the_one_float_bits(name, lo, hi):
    """The kernel's vector path (cells' jumps, delivery's event loads) and its one-cell tail take the same
    operations: every lane's bits equal the scalar function's, the branch points (log's mantissa split, log1p's
    series below 1e-3) included."""
    x = np.concatenate([grid(lo, hi, 100_001, seed=1), np.float32([1e-3, -1e-3, 0.41421356, 0.0, -0.0])])
    np.testing.assert_array_equal(native.fast_math(name, x, lanes=True).view(np.int32),
                                  native.fast_math(name, x).view(np.int32))
