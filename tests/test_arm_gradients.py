"""Gradients through the musculoskeletal arm: the smooth formulation against finite differences, and its cost.

The reference is independent of autodiff: central finite differences of the hand position, Richardson-extrapolated
(``(4 D(h/2) - D(h)) / 3`` at h = 1e-4), computed with x64 on (float32 rounding would swamp differences at these
steps; the arm's fitted constants stay float32, the arithmetic is float64). Inputs as in
``experiments/arm_gradients.py``, which measured jvp against this reference to ~1e-6 relative at 300 ms and 1 s.
"""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import make_arm
from jaxarm.arm.inputs import smooth_random_excitations
from jaxarm.config.arm import MusculoskeletalArmConfig
from jaxarm.config.validate import ConfigError

HORIZONS_MS = (300, 1000)


def hand_at_horizons(arm, us):
    """Hand position (m) after each of HORIZONS_MS of excitations us (T, 4): (len(HORIZONS_MS), 2)."""
    def body(s, u):
        s = arm.step(s, u)
        return s, arm.observe(s).hand
    return jax.lax.scan(body, arm.init(), us)[1][np.asarray(HORIZONS_MS) - 1]


@pytest.mark.slow  # three float64 programs of the 1 s arm to compile: 70-100 s from a fresh clone
def test_smooth_arm_jvp_and_grad_match_richardson_finite_differences():
    arm = make_arm("musculoskeletal", smooth=True)
    seed = 7
    base = smooth_random_excitations(seed, seconds=HORIZONS_MS[-1] / 1000)
    # Smooth directions that keep base + h d inside [0, 1] (the input clip is never met): base times a factor in [-1, 1].
    ds = np.stack([base * (2 * smooth_random_excitations(1000 + 10 * seed + k, seconds=len(base) / 1000, high=1.0) - 1)
                   for k in range(3)])
    with jax.enable_x64(True):
        f = lambda u: hand_at_horizons(arm, u)  # noqa: E731
        us, ds = jnp.asarray(base, jnp.float64), jnp.asarray(ds, jnp.float64)
        h = 1e-4
        steps = jnp.asarray([h, -h, h / 2, -h / 2], jnp.float64)
        hands = jax.jit(jax.vmap(jax.vmap(lambda d, s: f(us + s * d), (None, 0)), (0, None)))(ds, steps)
        fd_h = (hands[:, 0] - hands[:, 1]) / (2 * h)
        fd_h2 = (hands[:, 2] - hands[:, 3]) / h
        richardson = np.asarray((4 * fd_h2 - fd_h) / 3)                          # (directions, horizons, 2)
        jvp = np.asarray(jax.jit(jax.vmap(lambda d: jax.jvp(f, (us,), (d,))[1]))(ds))
        jac = jax.jit(jax.jacrev(f))(us)                                          # (horizons, 2, T, 4)
        grad_dir = np.asarray(jnp.einsum("hxtg,dtg->dhx", jac, ds))
    scale = np.linalg.norm(richardson, axis=-1)
    assert scale.min() > 1e-3, scale  # the hand really moves along every direction (m per unit step)
    # The reference itself has converged: the two step sizes agree far inside the tolerance.
    assert (np.linalg.norm(np.asarray(fd_h) - richardson, axis=-1) / scale).max() < 1e-3
    for name, d in (("jvp", jvp), ("grad", grad_dir)):
        rel = np.linalg.norm(d - richardson, axis=-1) / scale
        assert rel.max() < 1e-3, (name, rel)   # measured ~1e-6 (jvp) and ~1e-6 (grad)


@pytest.fixture(scope="module")
def paths():
    """Joint paths (rad) over 1 s of the default and the smooth arm (float32) on three smooth random inputs."""
    us = jnp.asarray(np.stack([smooth_random_excitations(s) for s in (7, 8, 9)]))
    out = {}
    for smooth in (False, True):
        arm = make_arm("musculoskeletal", smooth=smooth)

        def one(u, arm=arm):
            def body(s, e):
                s = arm.step(s, e)
                return s, s.q
            return jax.lax.scan(body, arm.init(), u)[1]
        out[smooth] = np.asarray(jax.jit(jax.vmap(one))(us))
    return out


def test_smooth_arm_stays_within_the_default_arms_integration_error(paths):
    # The default fast arm is 0.05-0.3 deg from a converged run on these inputs (experiments/arm_convergence.py) and
    # 0.44 deg from MJX: the smooth formulation must change the path by no more than that noise (measured 0.16-0.25).
    diff_deg = np.degrees(np.abs(paths[True] - paths[False])).max()
    assert diff_deg < 0.3, diff_deg
    assert np.degrees(np.abs(paths[False][:, -1] - paths[False][:, 0])).max() > 10  # and the arm did move


def test_smooth_option_validation():
    assert make_arm("musculoskeletal", smooth=True).config.smooth is True
    cfg = MusculoskeletalArmConfig(smooth=("tendon_slack",))
    assert make_arm("musculoskeletal", config=cfg).smooth == ("tendon_slack",)
    assert make_arm("musculoskeletal", config=dataclasses.replace(cfg, smooth=False)).smooth == ()
    with pytest.raises(ConfigError, match="MusculoskeletalArmConfig.smooth"):
        MusculoskeletalArmConfig(smooth=("slack",))
    with pytest.raises(ConfigError, match="smooth"):
        make_arm("simple", smooth=True)


@pytest.mark.slow  # MJX compiles for ~1 min
def test_smooth_arm_passes_the_default_arms_backend_and_limit_checks():
    """The checks the published arm passes (tests/test_musculoskeletal_arm.py), on the smooth arm: within 1 deg of
    MJX (the reference geometry, default muscles) over 1 s on four smooth random inputs, and full excitation of any
    group combination stops the joints at most 3.6 deg (shoulder) / 2.1 deg (elbow) past their ranges."""
    import itertools
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent.parent / "experiments"))
    from arm_convergence import paths

    smooth = make_arm("musculoskeletal", smooth=True)
    us = np.stack([smooth_random_excitations(seed) for seed in range(7, 11)])
    q0 = np.array([0.62, 1.53])
    diff = np.degrees(np.abs(paths(smooth, q0, us) - paths(make_arm("musculoskeletal", backend="mjx"), q0, us)))
    assert diff.max() < 1.0, diff.max()

    def hold(u):
        def body(s, e):
            s = smooth.step(s, e)
            return s, s.q
        return jax.lax.scan(body, smooth.init(), jnp.tile(u, (1000, 1)))[1]
    roll = jax.jit(hold)
    lo, hi = np.radians([-10, 0]), np.radians([110, 140])
    worst = np.full(2, -np.inf)
    for r in range(1, 5):
        for groups in itertools.combinations(range(4), r):
            q = np.asarray(roll(jnp.zeros(4).at[jnp.array(groups)].set(1.0)))
            worst = np.maximum(worst, np.maximum(lo - q.min(0), q.max(0) - hi))
    assert worst[0] < np.radians(3.6) and worst[1] < np.radians(2.1), np.degrees(worst)
