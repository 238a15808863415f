"""Dimensionless jerk on trajectories with closed-form answers; reach metrics on synthetic paths; statistics."""
import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.analysis import (dimensionless_jerk, jerk, jerk_energy, jerk_magnitude, mean_sd, path_length,
                             reach_metrics, summarize_reaches, velocity)


def straight_reach(profile, n, duration=1.0, amplitude=0.15, angle=0.7, origin=(0.1, 0.3)):
    """A straight reach x(t) = origin + amplitude * profile(t/D) * (cos a, sin a), sampled at n points."""
    t = np.linspace(0.0, duration, n)
    s = amplitude * profile(t / duration)
    xy = np.stack([origin[0] + s * np.cos(angle), origin[1] + s * np.sin(angle)], axis=-1)
    return xy, duration / (n - 1)


MIN_JERK = lambda u: 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5   # noqa: E731
CUBIC = lambda u: 3 * u ** 2 - 2 * u ** 3                     # noqa: E731


@pytest.mark.parametrize("duration, amplitude, angle, n", [(1.0, 0.15, 0.7, 101), (0.37, 2.0, -2.0, 23),
                                                           (5.0, 0.01, 3.0, 7)])
def test_cubic_reach_scores_exactly_144(duration, amplitude, angle, n):
    # x = A(3τ² - 2τ³): jerk = -12A/D³ everywhere, ∫jerk² = 144 A²/D⁵, v_mean = A/D -> DLJ = 144 for any A, D, dt.
    # The 5-point stencils are exact for quartics and the trapezoid rule for constants, so this is exact.
    with jax.enable_x64(True):
        xy, dt = straight_reach(CUBIC, n, duration, amplitude, angle)
        assert float(dimensionless_jerk(xy, dt)) == pytest.approx(144.0, rel=1e-9)
        np.testing.assert_allclose(np.asarray(jerk_magnitude(xy, dt)), 12 * amplitude / duration ** 3, rtol=1e-7)
        # x = Aτ³ (starts at rest, free end): jerk 6A/D³, ∫jerk² = 36 A²/D⁵, v_mean = A/D -> exactly 36
        xy, dt = straight_reach(lambda u: u ** 3, n, duration, amplitude, angle)
        assert float(dimensionless_jerk(xy, dt)) == pytest.approx(36.0, rel=1e-9)


def test_jerk_energy_of_the_cubic_reach_and_its_parts():
    # x = A(3τ² - 2τ³): jerk² = 144 A²/D⁶ at every sample, so ∫jerk² dt = 144 A²/D⁵ exactly, and a part of the
    # samples gets its trapezoid weights: the first k samples get (k - 0.5) dt of the D = (n - 1) dt
    duration, amplitude, n = 0.8, 0.12, 41
    xy, dt = straight_reach(CUBIC, n, duration, amplitude)
    whole = 144 * amplitude ** 2 / duration ** 5
    assert float(jerk_energy(xy, dt)) == pytest.approx(whole, rel=1e-9)
    first = np.arange(n) < 10
    assert float(jerk_energy(xy, dt, first)) == pytest.approx(whole * (10 - 0.5) / (n - 1), rel=1e-9)
    assert float(jerk_energy(xy, dt, first) + jerk_energy(xy, dt, ~first)) == pytest.approx(whole, rel=1e-9)
    # the dimensionless jerk is the energy times D^5 / L^2 (L = A for a straight reach)
    assert float(dimensionless_jerk(xy, dt)) == pytest.approx(whole * duration ** 5 / amplitude ** 2, rel=1e-9)


def test_stencils_are_exact_for_quartics():
    with jax.enable_x64(True):
        t = np.linspace(0.0, 0.8, 9)
        dt = t[1] - t[0]
        x = 0.3 * t ** 4 - 0.7 * t ** 3 + 0.2 * t ** 2 - t + 0.05
        y = -0.1 * t ** 4 + 0.5 * t ** 3
        xy = np.stack([x, y], axis=-1)
        j = np.asarray(jerk(xy, dt))
        np.testing.assert_allclose(j[:, 0], 7.2 * t - 4.2, atol=1e-8)
        np.testing.assert_allclose(j[:, 1], -2.4 * t + 3.0, atol=1e-8)
        v = np.asarray(velocity(xy, dt))
        np.testing.assert_allclose(v[:, 0], 1.2 * t ** 3 - 2.1 * t ** 2 + 0.4 * t - 1, atol=1e-8)


def test_minimum_jerk_reach_scores_720_with_second_order_convergence():
    # x = A(10τ³ - 15τ⁴ + 6τ⁵): ∫jerk² dt = 720 A²/D⁵ and v_mean = A/D -> DLJ = 720 exactly in the continuum.
    with jax.enable_x64(True):
        errors = []
        for n in (201, 401, 801):
            xy, dt = straight_reach(MIN_JERK, n)
            errors.append(float(dimensionless_jerk(xy, dt)) - 720.0)
        assert 0 < errors[-1] < 0.02                         # 720.011 at 801 samples; 720.47 at 101
        # halving dt divides the error by ~4 (3.61, 3.81, -> 4): second-order accurate
        assert 3.4 < errors[0] / errors[1] < 4.2 and 3.4 < errors[1] / errors[2] < 4.2
        # Hogan & Sternad's peak-speed variant: v_peak = 1.875 A/D -> 720 / 1.875² = 204.8
        xy, dt = straight_reach(MIN_JERK, 401)
        assert float(dimensionless_jerk(xy, dt, normalise="peak")) == pytest.approx(204.8, rel=1e-3)


@pytest.mark.parametrize("dt", [0.001, 0.002, 0.010])
@pytest.mark.parametrize("amplitude", [0.01, 0.15, 0.5])
def test_jerk_at_the_arm_and_loop_sampling_rates_scores_the_closed_form(dt, amplitude):
    # A 1 s minimum-jerk reach sampled at the arm's step (1 ms), 2 ms and the loop's 10 ms: only the O(dt^2)
    # discretisation error remains (0.47 at 10 ms, 0.027 at 2 ms, 0.007 at 1 ms), for any amplitude. With the
    # arithmetic in float32, as before, the 1 ms path scored 3381.
    xy, step = straight_reach(MIN_JERK, round(1.0 / dt) + 1, amplitude=amplitude)
    value = float(dimensionless_jerk(xy, step))
    assert 0 < value - 720.0 < 0.7 * (dt / 0.010) ** 2 + 0.003, value


def test_float32_positions_warn_where_their_rounding_matters():
    # float32 positions (the arm's own output) at the loop's 10 ms rate: accurate (721.4 for a 15 cm reach), silent
    xy, dt = straight_reach(MIN_JERK, 101)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert float(dimensionless_jerk(jnp.asarray(xy, jnp.float32), dt)) == pytest.approx(720.0, rel=5e-3)
    # at 1 ms the rounding of float32 positions dominates the third differences (11070 for 15 cm): a warning
    xy, dt = straight_reach(MIN_JERK, 1001)
    with pytest.warns(RuntimeWarning, match="rounding noise"):
        dimensionless_jerk(xy.astype(np.float32), dt)


def test_circular_motion_scores_theta_to_the_fourth():
    # |jerk| = R ω³ constant, v = R ω -> DLJ = ω⁴ D⁴ = θ⁴ (θ = swept angle), independent of R.
    with jax.enable_x64(True):
        theta, n = 2.0, 801
        t = np.linspace(0.0, 1.0, n)
        xy = 0.07 * np.stack([np.cos(theta * t), np.sin(theta * t)], axis=-1) + 0.2
        assert float(dimensionless_jerk(xy, t[1] - t[0])) == pytest.approx(theta ** 4, rel=1e-5)


def test_constant_velocity_path_has_zero_jerk_and_a_still_hand_is_undefined():
    with jax.enable_x64(True):
        xy, dt = straight_reach(lambda u: u, 50)
        assert np.max(np.asarray(jerk_magnitude(xy, dt))) < 1e-8
        assert abs(float(dimensionless_jerk(xy, dt))) < 1e-9
        assert float(path_length(xy)) == pytest.approx(0.15, rel=1e-12)
    assert math.isnan(float(dimensionless_jerk(np.ones((20, 2)), 0.01)))


def test_invariances_and_batching():
    with jax.enable_x64(True):
        rng = np.random.default_rng(0)
        xy = np.cumsum(rng.normal(size=(60, 2)), axis=0) * 1e-3     # an irregular path
        base = float(dimensionless_jerk(xy, 0.01))
        rot = np.array([[np.cos(1.0), -np.sin(1.0)], [np.sin(1.0), np.cos(1.0)]])
        for other, dt in ((xy * 7.0 + 3.0, 0.01), (xy, 0.5), (xy[::-1], 0.01), (xy @ rot.T, 0.01)):
            assert float(dimensionless_jerk(other, dt)) == pytest.approx(base, rel=1e-9)
        batch = np.stack([xy, straight_reach(CUBIC, 60)[0]])
        out = dimensionless_jerk(batch, 0.01)
        assert float(out[0]) == pytest.approx(base, rel=1e-9) and float(out[1]) == pytest.approx(144.0, rel=1e-9)
    with pytest.raises(ValueError, match="at least 5"):
        dimensionless_jerk(np.zeros((4, 2)), 0.01)
    with pytest.raises(ValueError, match="normalise"):
        dimensionless_jerk(xy, 0.01, normalise="median")


# ---- reach metrics --------------------------------------------------------------------------------------------

DT = 0.01
TARGET = np.array([0.15, 0.0])


def synthetic_reach():
    """Still for 0.1 s, then 0.6 m/s straight at the target (entering the 4 cm circle at sample 29, 3.6 cm away),
    then 0.1 m/s onward through the centre (sample 65) to 3.5 cm beyond it at sample 100."""
    x = np.zeros(101)
    for k in range(101):
        if k <= 10:
            x[k] = 0.0
        elif k <= 29:
            x[k] = 0.006 * (k - 10)
        else:
            x[k] = 0.114 + 0.001 * (k - 29)
    return np.stack([x, np.zeros_like(x)], axis=-1)


def test_reach_metrics_on_a_path_with_known_answers():
    m = reach_metrics(synthetic_reach(), TARGET, DT)
    assert bool(m.success)
    assert float(m.onset_s) == pytest.approx(0.10, abs=1e-6)
    assert float(m.first_entry_s) == pytest.approx(0.29, abs=1e-6)
    assert float(m.speed_before_m_s) == pytest.approx(0.6, rel=1e-4)
    assert float(m.speed_after_m_s) == pytest.approx(0.1, rel=1e-4)
    assert float(m.min_distance_m) == pytest.approx(0.0, abs=1e-6)
    assert float(m.final_distance_m) == pytest.approx(0.035, abs=1e-6)
    assert float(m.time_inside_s) == pytest.approx(0.72, abs=1e-6)           # samples 29..100
    expected_after = np.mean(np.abs(0.114 + 0.001 * np.arange(72) - 0.15))   # samples 29..100
    assert float(m.distance_after_m) == pytest.approx(expected_after, rel=1e-4)


def test_reach_metrics_of_a_miss_and_of_a_pass_through():
    miss = synthetic_reach() * 0.5                       # stops at 9.25 cm from the target
    m = reach_metrics(miss, TARGET, DT)
    assert not bool(m.success) and float(m.time_inside_s) == 0.0
    for name in ("first_entry_s", "speed_before_m_s", "speed_after_m_s", "distance_after_m"):
        assert math.isnan(float(getattr(m, name))), name
    assert float(m.min_distance_m) == pytest.approx(0.15 - 0.5 * 0.185, abs=1e-6)
    # crossing the circle through its centre at 1 cm per sample, x = 0.005 ... 0.295 m: inside for
    # |x - 0.15| <= 0.04, i.e. x = 0.115 ... 0.185 -> 8 samples
    x = 0.005 + 0.01 * np.arange(30)
    m = reach_metrics(np.stack([x, np.zeros_like(x)], axis=-1), TARGET, DT)
    assert bool(m.success) and float(m.time_inside_s) == pytest.approx(0.08, abs=1e-6)
    assert float(m.final_distance_m) == pytest.approx(0.145, abs=1e-6)


def test_slow_drift_below_the_onset_threshold_is_not_movement():
    xy = synthetic_reach()
    xy[:11, 1] = 1e-4 * np.arange(11)                     # 1 cm/s drift before the reach (< 2 cm/s threshold)
    m = reach_metrics(xy, TARGET, DT)
    assert float(m.onset_s) == pytest.approx(0.10, abs=1e-6)
    assert float(reach_metrics(xy, TARGET, DT, onset_speed_m_s=0.005).onset_s) == pytest.approx(0.0, abs=1e-6)


def test_distance_metrics_enter_and_stay_pass_through_never_enter():
    from jaxarm.analysis import distance_metrics

    # enters at sample 20 (3.5 cm) and stays at 3.5, 3.0, ... 1.0 cm then 1.0 cm to the end (samples 20..100)
    stay = np.concatenate([np.linspace(15.0, 5.0, 20), np.linspace(3.5, 1.0, 6), np.full(75, 1.0)])
    m = distance_metrics(stay, DT, 4.0)
    assert bool(m.success) and float(m.first_entry_s) == pytest.approx(0.20, abs=1e-6)
    assert float(m.time_inside_s) == pytest.approx(0.81, abs=1e-6)                     # 81 samples
    assert float(m.distance_after_m) == pytest.approx((3.5 + 3.0 + 2.5 + 2.0 + 1.5 + 1.0 + 75 * 1.0) / 81, rel=1e-5)
    # passes through: inside for samples 40..44 only (3.9, 2, 1, 2, 3.9 cm), then out to 14 cm
    through = np.concatenate([np.linspace(15.0, 5.0, 40), [3.9, 2.0, 1.0, 2.0, 3.9], np.linspace(5.0, 14.0, 56)])
    m = distance_metrics(through, DT, 4.0)
    assert float(m.first_entry_s) == pytest.approx(0.40, abs=1e-6)
    assert float(m.time_inside_s) == pytest.approx(0.05, abs=1e-6)
    assert float(m.distance_after_m) == pytest.approx(through[40:].mean(), rel=1e-5)
    never = np.linspace(15.0, 4.5, 101)
    m = distance_metrics(never, DT, 4.0)
    assert not bool(m.success) and float(m.time_inside_s) == 0.0
    assert math.isnan(float(m.first_entry_s)) and math.isnan(float(m.distance_after_m))
    # batched: the same three at once, and reach_metrics's fields equal distance_metrics's on an xy path
    b = distance_metrics(np.stack([stay, through, never]), DT, 4.0)
    assert b.success.tolist() == [True, True, False]
    xy = synthetic_reach()
    r = reach_metrics(xy, TARGET, DT)
    d = distance_metrics(np.linalg.norm(xy - TARGET, axis=-1), DT)
    for name in ("success", "first_entry_s", "time_inside_s", "distance_after_m"):
        assert float(getattr(d, name)) == pytest.approx(float(getattr(r, name)), rel=1e-6), name


def test_reach_metrics_vmap_and_summary_over_networks():
    paths = np.stack([synthetic_reach(), synthetic_reach() * 0.5, synthetic_reach()])
    batch = jax.jit(jax.vmap(reach_metrics, in_axes=(0, None, None)))(paths, TARGET, DT)
    assert batch.success.shape == (3,)
    s = summarize_reaches(batch, extra={"dimensionless_jerk": np.array([1.0, 50.0, 3.0])})
    assert s["n"] == 3 and s["success_count"] == 2 and s["success_rate"] == pytest.approx(2 / 3)
    assert s["speed_before_m_s"]["n"] == 2 and s["speed_before_m_s"]["mean"] == pytest.approx(0.6, rel=1e-4)
    assert s["speed_before_m_s"]["sd"] == pytest.approx(0.0, abs=1e-4)
    assert s["dimensionless_jerk"] == {"mean": 2.0, "sd": pytest.approx(math.sqrt(2.0)), "n": 2}
    assert s["min_distance_m"]["n"] == 3                  # min / final distance over all networks


def test_mean_sd_ignores_nan_and_masked_entries():
    assert mean_sd([1.0, 3.0, float("nan")]) == {"mean": 2.0, "sd": pytest.approx(math.sqrt(2.0)), "n": 2}
    assert mean_sd([1.0, 3.0, 5.0], mask=[True, False, True])["mean"] == 3.0
    empty = mean_sd([], None)
    assert math.isnan(empty["mean"]) and empty["n"] == 0


def test_intraclass_correlation_by_hand_and_on_a_known_random_effects_model():
    from jaxarm.analysis.stats import intraclass_correlation, set_mean_reliability, shrunk_means

    # by hand: groups {1, 3}, {5, 7}: grand 4, SSB = 2*(2-4)^2 + 2*(6-4)^2 = 16 (MSB 16), SSW = 4 * 1 = 4 over 2
    # df (MSW 2), k0 = 2: ICC = (16 - 2) / (16 + 2) = 7/9
    assert intraclass_correlation([[1.0, 3.0], [5.0, 7.0]]) == pytest.approx(7 / 9)
    assert intraclass_correlation([[1.0, 2.0]]) is None and intraclass_correlation([[1.0], [2.0]]) is None
    # a random-effects model with a known ICC: group effects of SD 1, members' noise of SD 1.5 -> 1 / 3.25;
    # unequal group sizes (4-12 members)
    rng = np.random.default_rng(0)
    effects = rng.normal(0.0, 1.0, 3000)
    groups = [b + rng.normal(0.0, 1.5, rng.integers(4, 13)) for b in effects]
    icc = intraclass_correlation(groups)
    assert icc == pytest.approx(1 / 3.25, abs=0.02)
    # Spearman-Brown is the squared correlation of a group's mean with its true effect
    eight = np.array([b + rng.normal(0.0, 1.5, 8).mean() for b in effects])
    assert np.corrcoef(eight, effects)[0, 1] ** 2 == pytest.approx(float(set_mean_reliability(1 / 3.25, 8)),
                                                                   abs=0.03)
    # shrinkage predicts the true effect better than the raw mean, and without the winner's curse: over the groups
    # with the 10 % largest means the shrunk mean is on average the true effect
    shrunk, raw = shrunk_means(groups, icc), np.array([g.mean() for g in groups])
    assert np.mean((shrunk - effects) ** 2) < 0.8 * np.mean((raw - effects) ** 2)
    top = raw > np.quantile(raw, 0.9)
    assert abs(np.mean(shrunk[top] - effects[top])) < 0.1 < np.mean(raw[top] - effects[top])


def test_stay_frontier_selections_on_a_ranking_by_hand(tmp_path):
    # experiments/stay_frontier.py on a ranking of 40 sets x 4 seeds with known rates and distances: at lam = 0 the
    # 30 sets that stay closest, at a large lam the ranking's own 30 best (rate first); a selection's expected count
    # is the sum of its rates and its distance the rate-weighted mean; a fixed metaparameter is skipped.
    import importlib.util
    from pathlib import Path

    from jaxarm.paper.rerank import rank

    path = Path(__file__).resolve().parents[1] / "experiments" / "stay_frontier.py"
    spec = importlib.util.spec_from_file_location("stay_frontier", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    sets = []
    for i in range(40):
        hits = 4 if i % 2 else 2                       # odd sets reach on every seed, even ones on half
        after_cm = 2.0 + 0.1 * i + (0.0 if i % 2 else -1.5)
        spread = [-0.2, 0.2, -0.1, 0.1]
        sets.append({"source": f"p top[{i}]", "metaparams": {"a": float(i), "fixed": 1.0},
                     "runs": [{"seeds": [0, 1, 2, 3], "success": [k < hits for k in range(4)],
                               "min_distance_m": [0.01] * 4,
                               "distance_after_m": [(after_cm + spread[k]) / 100 if k < hits else None
                                                    for k in range(4)]}]})
    result = mod.frontier({"sets": rank(sets, "stay")}, top=30)
    by_lam = {float(lam): c["raw"] for lam, c in result["frontier"].items()}
    closest = sorted(range(40), key=lambda i: 2.0 + 0.1 * i + (0.0 if i % 2 else -1.5))[:30]
    rate = lambda i: 1.0 if i % 2 else 0.5   # noqa: E731
    dist = lambda i: 2.0 + 0.1 * i + (0.0 if i % 2 else -1.5)   # noqa: E731
    assert by_lam[0.0]["count"] == pytest.approx(sum(rate(i) for i in closest))
    assert by_lam[0.0]["distance_after_cm"] == pytest.approx(
        sum(rate(i) * dist(i) for i in closest) / sum(rate(i) for i in closest), abs=1e-3)
    # the ranking's 30: the 20 sets that always reach, then the 10 half-reaching ones that stay closest
    top = list(range(1, 40, 2)) + list(range(0, 20, 2))
    assert result["ranking_top"]["raw"]["count"] == pytest.approx(sum(rate(i) for i in top)) == 25.0
    assert by_lam[1000]["count"] == 25.0
    assert by_lam[0.0]["distance_after_cm"] < by_lam[1000]["distance_after_cm"]
    assert list(result["metaparameter_correlations"]) == ["a"]
    assert result["reliability_of_a_set_mean"]["seeds"] == 4


def test_paired_sets_compares_set_by_set_and_refuses_other_protocols(tmp_path):
    # experiments/paired_sets.py: six sets all closer after the change -> the exact two-sided signed-rank p is
    # 2 / 2^6; a set that entered in only one run is left out of the pairs; runs on other seeds are refused.
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "paired_sets.py"
    spec = importlib.util.spec_from_file_location("paired_sets", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    config = {"preset": "p", "arm": "musculoskeletal", "target": "left", "sets": 7, "seeds": 4, "first_seed": 4000,
              "epochs": 12, "epoch_s": 30.0}
    base_d = [5.0, 6.0, 4.5, 7.0, 5.5, 6.5, None]
    low_d = [4.0, 4.9, 3.2, 5.4, 3.5, 5.0, 3.0]
    run = lambda ds, extra: {"config": {**config, **extra}, "pooled_distance_after_cm": 1.0,   # noqa: E731
                             "rows": [{"set": i, "reached": 0 if d is None else 4, "networks": 4,
                                       "distance_after_cm": d} for i, d in enumerate(ds)]}
    out = mod.compare(run(base_d, {}), run(low_d, {"set": ["plast_ee_maxw=2.3"]}))
    assert out["sets_compared"] == 6 and out["sets_closer"] == 6
    assert out["wilcoxon_p"] == pytest.approx(2 / 2 ** 6, rel=2e-3)   # stored to 3 significant digits
    assert out["base"]["reached"] == 24 and out["changed"]["reached"] == 28
    assert out["median_difference_cm"] == pytest.approx(-1.4)   # differences -1.0 -1.1 -1.3 -1.6 -2.0 -1.5
    with pytest.raises(SystemExit, match="first_seed"):
        mod.compare(run(base_d, {}), run(low_d, {"first_seed": 5000}))


# ------------------------------------------------------------------------------ jaxarm.paper.comparison
def _fake_run(folder, arm, target, hands, naive_hands, successes):
    """A run folder as `jaxarm train` writes it, with only what reach_stats reads."""
    import json

    from jaxarm.analysis.reach import reach_metrics

    folder.mkdir(parents=True)
    tgt = np.array([0.0, 0.0], np.float32)
    nets = []
    for i, xy in enumerate(hands):
        m = reach_metrics(jnp.asarray(xy), jnp.asarray(tgt), 0.01)
        nets.append({k: (bool(v) if k == "success" else float(v)) for k, v in m._asdict().items()} | {"seed": i})
        assert nets[-1]["success"] == successes[i]
    naive = [{"min_distance_m": float(np.min(np.linalg.norm(xy - tgt, axis=-1)))} for xy in naive_hands]
    res = {"target": target, "networks": nets, "naive": {"success_count": 0, "networks": naive},
           "config": {"arm": arm}}
    (folder / "results.json").write_text(json.dumps(res))
    np.savez(folder / "trajectories.npz", t=np.arange(101) * 0.01, hand=np.stack(hands),
             naive_hand=np.stack(naive_hands))


def test_paper_stats_report_successful_networks_beside_the_paper(tmp_path):
    from jaxarm.paper import comparison as mod

    t = np.linspace(0.0, 1.0, 101)[:, None]
    start = np.array([0.15, 0.0])
    reach = start * (1 - np.clip(t / 0.5, 0, 1))             # straight in at 0.3 m/s, then stays at the target
    stay = np.repeat(start[None], 101, axis=0) + 1e-4 * t   # barely moves
    _fake_run(tmp_path / "r" / "left" / "seeds", "musculoskeletal", "left", [reach, stay], [stay, stay], [True, False])
    _fake_run(tmp_path / "r" / "bottom" / "seeds", "musculoskeletal", "bottom", [stay, stay], [stay, stay],
              [False, False])
    folders = mod.run_folders([tmp_path / "r"])
    assert [f.parent.name for f in folders] == ["left", "bottom"]
    left, bottom = (mod.target_stats(f) for f in folders)
    assert (left["success_count"], bottom["success_count"]) == (1, 0)
    # only the successful network enters the paper's metrics: it entered the 4 cm circle at 0.37 s, moving 0.3 m/s
    assert left["speed_before_m_s"]["n"] == 1 and left["speed_before_m_s"]["mean"] == pytest.approx(0.3, rel=0.05)
    assert left["time_inside_s"]["mean"] == pytest.approx(640.0, abs=20.0)   # ms
    assert bottom["speed_before_m_s"]["n"] == 0
    table = mod.markdown([left, bottom])
    assert "1/2 (0/2) / 29/30" in table and "0/2 (0/2) / 26/30" in table and "0.327 (0.051)" in table
    with pytest.raises(FileNotFoundError, match="no results.json"):
        mod.run_folders([tmp_path])


def test_original_test_comparison_places_the_original_run_among_ours(tmp_path):
    import json

    from jaxarm.paper import comparison as mod

    # four networks whose distance falls linearly from 15.1 cm to 0, 2, 4 and 6 cm at 1 s
    t = np.arange(101) * 0.01
    ends = np.array([0.0, 2.0, 4.0, 6.0])
    dist = (15.1 + (ends[:, None] - 15.1) * t[None]) / 100.0
    folder = tmp_path / "run"
    folder.mkdir()
    em = [3.0, 4.0, 6.0, 7.0]
    res = {"target": "left", "success_count": 3, "config": {"arm": "simple"},
           "networks": [{"test_rates_hz": dict.fromkeys(mod.ORIGINAL_TEST_RATES_HZ, 1.0) | {"EM": r}} for r in em],
           "test_rates_hz": {"ES": 5.0, "IS": 5.0, "ISL": 3.0, "EM": 4.0, "IM": 9.0, "IML": 3.0}}
    (folder / "results.json").write_text(json.dumps(res))
    q = np.zeros((4, 101, 2)) + np.array([0.62, 1.53])
    q[:, -1] = [[0.8, 1.6], [0.9, 1.6], [1.0, 1.7], [1.1, 1.7]]
    np.savez(folder / "trajectories.npz", t=t, distance=dist, q=q)
    c = mod.original_test_comparison(folder)
    rows = {r["t_ms"]: r for r in c["distance"]}
    assert min(rows) == 200                                       # the original had not moved before
    assert rows[1000]["median_cm"] == pytest.approx(3.0)
    assert rows[1000]["original_percentile"] == 50.0              # 3.3 cm: above 0 and 2, below 4 and 6
    assert c["final"]["original_percentile"] == 50.0 and c["closest"]["original_percentile"] == 25.0   # 1.59 > 0
    assert c["final_q_rad"]["median"] == pytest.approx([0.95, 1.65])
    assert c["test_rates_hz"]["original"]["EM"] == 5.1 and c["test_rates_hz"]["ours"]["EM"] == 4.0
    assert c["test_rates_hz"]["original_percentile"]["EM"] == 50.0     # 5.1 Hz: above 3 and 4, below 6 and 7
    assert c["test_rates_hz"]["original_percentile"]["IM"] == 100.0    # 9.9 Hz: above all our 1.0 Hz
    res["target"] = "bottom"
    (folder / "results.json").write_text(json.dumps(res))
    with pytest.raises(ValueError, match="left target"):
        mod.original_test_comparison(folder)


def test_joint_excursions_splits_reached_and_missed(tmp_path):
    # experiments/joint_excursions.py: the geometry of the left target (shoulder flexion is the way there; the elbow
    # alone also brings the hand closer but stops ~10 cm short) and the success split of a run's joint excursions.
    import importlib.util
    import json
    from pathlib import Path

    from jaxarm.task.config import START_POSTURE_RAD

    path = Path(__file__).resolve().parents[1] / "experiments" / "joint_excursions.py"
    spec = importlib.util.spec_from_file_location("joint_excursions", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    g = mod.geometry("left")
    assert abs(g["start_distance_cm"] - 15.1) < 0.2
    assert g["shoulder_plus_cm"] < g["elbow_plus_cm"] < 0 < g["shoulder_minus_cm"]
    assert g["shoulder_alone_closest_cm"] < 4 < g["elbow_alone_closest_cm"]
    # three networks: one flexes the shoulder 0.4 rad and reaches, two lead with the elbow and miss
    q = np.tile(np.asarray(START_POSTURE_RAD), (3, 5, 1))
    q[0, 1:, 0] += np.linspace(0.1, 0.4, 4)
    q[1, 1:, 1] += 0.5
    q[2, 2:] += (0.1, 0.3)
    run = tmp_path / "left" / "seeds"
    run.mkdir(parents=True)
    np.savez(run / "trajectories.npz", q=q)
    (run / "results.json").write_text(json.dumps({"target": "left", "networks": [
        {"success": True}, {"success": False}, {"success": False}]}))
    (row,) = [mod.excursions(f) for f in mod.run_folders([tmp_path])]
    assert (row["n"], row["success"], row["failures_elbow_led"], row["successes_elbow_led"]) == (3, 1, 2, 0)
    np.testing.assert_allclose(row["median_excursion_rad_success"], (0.4, 0.0), atol=1e-6)
    np.testing.assert_allclose(row["median_excursion_rad_failure"], (0.05, 0.4), atol=1e-6)
    assert "| left | 1/3 | 2/2 | 0/1 | 0.40 / 0.00 | 0.05 / 0.40 |" in mod.markdown([row])


def test_selection_counts_reads_the_search_ranking_and_its_own_evaluations(tmp_path):
    # experiments/selection_counts.py: the top sets are taken in the search's order (search_rank, not the
    # re-evaluation's rank) and counted on the search's own success_rate; a folder without a search is refused.
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "selection_counts.py"
    spec = importlib.util.spec_from_file_location("selection_counts", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    rows = [{"rank": 1, "search_rank": 3, "metrics": {"success_rate": 0.0}},
            {"rank": 2, "search_rank": 1, "metrics": {"success_rate": 1.0}},
            {"rank": 3, "search_rank": 2, "metrics": {"success_rate": 0.5}}]
    (tmp_path / "top_k.json").write_text(json.dumps({"top_k": rows}))
    (tmp_path / "history.json").write_text(json.dumps({
        "config": {"seed_mode": "fixed", "seeds_per_candidate": 1, "population_size": 16},
        "fitness": {"name": "reaching", "arm": "simple", "targets": ["left"]}, "generations_done": 8,
        "history": {"metrics_mean": {"success_rate": [0.5, 0.25] + [float("nan")] * 6}}}))
    two = mod.selection_count(tmp_path, top=2)
    assert (two["top"], two["reached"], two["candidates_evaluated"], two["candidates_reached"]) == (2, 1.5, 128, 12)
    assert mod.selection_count(tmp_path)["reached"] == 1.5
    assert "1.5/3" in mod.markdown([mod.selection_count(tmp_path)])
    with pytest.raises(SystemExit, match="not a finished"):
        mod.selection_count(tmp_path / "nothing")


def test_training_history_places_the_original_among_our_networks(tmp_path):
    # experiments/training_history.py --percentiles: the original's one network as a percentile of ours per epoch
    import importlib.util
    from pathlib import Path

    from jaxarm.paper import comparison as paper
    from jaxarm.paper.comparison import ORIGINAL_HISTORY, ORIGINAL_HISTORY_GAINS, ORIGINAL_HISTORY_RATES

    path = Path(__file__).resolve().parents[1] / "experiments" / "training_history.py"
    spec = importlib.util.spec_from_file_location("training_history", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    pops = ["IML", "ES", "IS", "ISL", "EM", "IM"]                 # any order: the script looks the names up
    pws = list(ORIGINAL_HISTORY_GAINS)[::-1] + ["P->ES"]
    n_epochs, n_net = 2, 10
    # network i holds the original's value x (1 + (i - 6.5) / 100): 7 of 10 below it, every column, every epoch
    scale = 1.0 + (np.arange(n_net) - 6.5) / 100.0
    rates = np.zeros((n_epochs, n_net, 6))
    gains = np.ones((n_epochs, n_net, len(pws)))
    for e in range(n_epochs):
        orig = ORIGINAL_HISTORY[e + 1]
        for j, p in enumerate(ORIGINAL_HISTORY_RATES):
            rates[e, :, pops.index(p)] = orig[j] * scale
        for j, g in enumerate(ORIGINAL_HISTORY_GAINS):
            gains[e, :, pws.index(g)] = orig[len(ORIGINAL_HISTORY_RATES) + j] * scale
    hist = {"populations": np.array(pops), "pathways": np.array(pws), "rates_last10s_hz": rates, "mean_wgain": gains}
    rows = paper.original_history_percentiles(hist)
    assert [e for e, _ in rows] == [1, 2]
    for _, cols in rows:
        assert len(cols) == len(ORIGINAL_HISTORY_RATES) + len(ORIGINAL_HISTORY_GAINS)
        assert all(p == 70.0 and lo < hi for p, lo, hi in cols)
    np.savez(tmp_path / "history.npz", **hist)
    (tmp_path / "results.json").write_text("{}")
    assert mod.main([str(tmp_path / "results.json"), "--percentiles"]) == 0
    with pytest.raises(SystemExit):   # no history.npz: a clear error, not a traceback
        mod.main([str(tmp_path / "nowhere" / "results.json"), "--percentiles"])


def test_original_seed_runs_are_the_reference_runs():
    # the packaged measurements of the original NEURON model over 60 seeds (docs/results.md): run 0 is the published
    # seed pair, so it must be the spec's reference test; every run's success is its closest approach within 4 cm
    from jaxarm.paper import comparison as mod

    d = mod.original_seed_runs("left")
    runs = d["runs"]
    assert len(runs) == 60 and [r["k"] for r in runs] == list(range(60))
    assert all(len(r["fresh_noise_min_distance_cm"]) == 9 for r in runs)
    assert [bool(r.get("epochs")) for r in runs] == [True] * 30 + [False] * 30
    assert {"model", "protocol", "seeds", "machine"} <= set(d["measured"])
    r0 = runs[0]
    assert (r0["inputseed"], r0["dvseed"]) == (1235, 398115)
    assert r0["min_distance_cm"] == pytest.approx(mod.ORIGINAL_TEST_CLOSEST_CM, abs=0.005)
    assert r0["final_distance_cm"] == pytest.approx(mod.ORIGINAL_TEST_FINAL_CM, abs=0.005)
    for r in runs:
        dist = np.asarray(r["distance_cm"])
        assert dist.shape == (101,) and dist[0] == pytest.approx(15.12, abs=0.01)
        assert r["success"] == (dist.min() <= 4.0) and r["min_distance_cm"] == pytest.approx(dist.min())
    with pytest.raises(ValueError, match="run with many seeds on"):
        mod.original_seed_runs("right")


def test_seed_distribution_comparison_counts_and_tests(tmp_path):
    import json

    from jaxarm.paper import comparison as mod

    t = np.arange(101) * 0.01
    folder = tmp_path / "run"
    folder.mkdir()
    ends_ours = np.array([1.0, 2.0, 5.0, 6.0, 7.0, 8.0])         # 2 of 6 within 4 cm
    ends_orig = np.array([0.5, 1.0, 2.0, 3.0, 3.5, 9.0])          # 5 of 6
    line = lambda ends: 15.1 + (ends[:, None] - 15.1) * t[None]   # noqa: E731  falls linearly to `ends` at 1 s
    res = {"target": "left", "config": {"arm": "simple"}, "networks": [{"success": bool(e <= 4)} for e in ends_ours]}
    (folder / "results.json").write_text(json.dumps(res))
    np.savez(folder / "trajectories.npz", t=t, distance=line(ends_ours) / 100.0)
    fresh = []
    for j, successes in enumerate(([True, False, False, False, False, False], [True, True, False, False, False, True])):
        f = tmp_path / f"fresh{j}"
        f.mkdir()
        (f / "results.json").write_text(json.dumps({"networks": [{"success": s} for s in successes]}))
        fresh.append(f)
    original = {"measured": {"model": "synthetic"}, "runs": [
        {"success": bool(e <= 4), "distance_cm": line(np.array([e]))[0].tolist(),
         "fresh_noise_min_distance_cm": [e, e + 2.0]} for e in ends_orig]}
    c = mod.seed_distribution_comparison(folder, original, fresh_folders=fresh, goal=6, goal_of=6)
    assert (c["success"]["ours"]["k"], c["success"]["original"]["k"]) == (2, 5)
    lo, hi = c["success"]["original"]["ci95"]
    assert lo < 5 / 6 < hi and 0 < c["success"]["fisher_p"] < 1
    assert c["closest"]["ours"]["median_cm"] == pytest.approx(5.5)
    assert c["closest"]["original"]["median_cm"] == pytest.approx(2.5)
    assert c["distance_at_ms"][1000]["mannwhitney_p"] == pytest.approx(c["final"]["mannwhitney_p"])
    assert c["distance_at_ms"][200]["ours"]["median_cm"] > c["distance_at_ms"][1000]["ours"]["median_cm"]
    # fresh re-tests: the original's e and e + 2 cm -> 5 + 3 of 12 within 4 cm; ours 1 + 3 of 12
    assert (c["fresh"]["original"]["k"], c["fresh"]["original"]["n"]) == (8, 12)
    assert c["fresh"]["original"]["own_noise"]["k"] == 5
    assert (c["fresh"]["ours"]["k"], c["fresh"]["ours"]["n"], c["fresh"]["ours"]["tests_per_network"]) == (4, 12, 2)
    assert c["goal"]["p_at_original_rate"] == pytest.approx((5 / 6) ** 6)
    # after entry (networks that reached; lines fall to their end distance at 1 s): ours end at 1 and 2 cm, entering
    # the 4 cm circle when 15.1 - (15.1 - e) t <= 4, i.e. t >= 11.1 / (15.1 - e)
    a = c["after_entry"]
    for e, model in ((np.array([1.0, 2.0]), "ours"), (np.array([0.5, 1.0, 2.0, 3.0, 3.5]), "original")):
        d = line(e)
        inside = d <= 4.0
        first = inside.argmax(axis=1)
        after = [d[i, first[i]:].mean() for i in range(len(e))]
        assert a["distance_after_cm"][model]["mean"] == pytest.approx(np.mean(after), rel=1e-5)
        assert a["distance_after_cm"][model]["n"] == len(e)
        assert a["time_inside_ms"][model]["mean"] == pytest.approx(10.0 * inside.sum(axis=1).mean(), rel=1e-6)
        assert a["first_entry_ms"][model]["mean"] == pytest.approx(10.0 * first.mean(), rel=1e-6)
    assert 0 < a["distance_after_cm"]["mannwhitney_p"] <= 1
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "original_seeds.py"
    spec = importlib.util.spec_from_file_location("original_seeds", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    row = [ln for ln in script.markdown(c).splitlines() if "distance to the centre after first entry" in ln][0]
    assert f"n {a['distance_after_cm']['original']['n']})" in row and f"{a['distance_after_cm']['ours']['mean']:.2f}" in row
    # several folders pool their networks (seeds 0-29 and 30-59); the goal stays "k of goal_of"
    pooled = mod.seed_distribution_comparison([folder, str(folder)], original, goal=6, goal_of=6)
    assert (pooled["success"]["ours"]["k"], pooled["success"]["ours"]["n"]) == (4, 12)
    assert pooled["closest"]["ours"]["median_cm"] == pytest.approx(5.5) and pooled["goal"]["n"] == 6
    # blocks of goal_of seeds: the original's 6 runs are one block (5/6, fresh 8/12); ours one per folder
    assert [(b["own_noise"]["k"], b["fresh"]["k"]) for b in c["blocks"]["original"]] == [(5, 8)]
    assert [b["own_noise"]["k"] for b in pooled["blocks"]["ours"]] == [2, 2]
    halves = mod.seed_distribution_comparison(folder, original, goal=2, goal_of=3)
    assert [b["own_noise"]["k"] for b in halves["blocks"]["original"]] == [3, 2]     # runs 0-2, 3-5
    other = tmp_path / "bottom"
    other.mkdir()
    (other / "results.json").write_text(json.dumps(res | {"target": "bottom"}))
    np.savez(other / "trajectories.npz", t=t, distance=line(ends_ours) / 100.0)
    with pytest.raises(ValueError, match="target="):
        mod.seed_distribution_comparison([folder, other], original)
    res["config"]["arm"] = "musculoskeletal"
    (folder / "results.json").write_text(json.dumps(res))
    with pytest.raises(ValueError, match="simple arm"):
        mod.seed_distribution_comparison(folder, original)


def test_original_epoch_comparison_lines_up_epochs_and_columns():
    from jaxarm.paper import comparison as mod

    pathways = np.array(["ES->ES", "ES->IS", "ES->EM", "EM->EM", "EM->IM", "EM->ES", "IS->ES", "P->ES"])
    pops = np.array(["ES", "IS", "ISL", "EM", "IM", "IML"])
    n_ep, n_net = 3, 4
    gains = np.ones((n_ep, n_net, len(pathways)))
    gains[:, :, 2] = 1.0 + 0.1 * np.arange(1, n_ep + 1)[:, None]          # ES->EM grows 0.1 per epoch
    history = {"rewards": np.full((n_ep, n_net), 10.0), "punishments": np.tile(np.arange(n_net, dtype=float), (n_ep, 1)),
               "rates_hz": np.full((n_ep, n_net, 6), 2.0), "mean_wgain": gains, "populations": pops,
               "pathways": pathways}
    epoch = {"rewards": 5, "punishments": 7, "em_rate_hz_by_group": [1.0, 2.0, 3.0, 2.0],
             "mean_wgain": dict.fromkeys(mod.EPOCH_GAINS, 1.0) | {"ES->EM": 1.5}}
    original = {"runs": [{"epochs": [epoch] * 2}, {"epochs": None}, {"epochs": [epoch] * 2}]}
    rows = mod.original_epoch_comparison(history, original)
    assert [r["epoch"] for r in rows] == [1, 2]                            # the shorter of the two
    assert rows[1]["ES->EM"]["ours"]["median"] == pytest.approx(1.2)
    assert rows[0]["ES->EM"]["original"] == {"median": 1.5, "p10": 1.5, "p90": 1.5, "n": 2}
    assert rows[0]["EM_hz"]["original"]["median"] == pytest.approx(2.0) and rows[0]["EM_hz"]["ours"]["median"] == 2.0
    assert rows[0]["punishments"]["ours"]["median"] == pytest.approx(1.5) and rows[0]["rewards"]["original"]["n"] == 2
    with pytest.raises(ValueError, match="per-epoch"):
        mod.original_epoch_comparison(history, {"runs": [{"epochs": None}]})


def test_original_bottom_runs_do_not_reach():
    # the original's 30 runs on the bottom target (docs/results.md): none enters the circle
    from jaxarm.paper import comparison as mod

    d = mod.original_seed_runs("bottom")
    assert d["target"] == "bottom" and [r["k"] for r in d["runs"]] == list(range(30))
    assert not any(r["success"] for r in d["runs"])
    assert all(min(r["distance_cm"]) > 4.0 and r["distance_cm"][0] == pytest.approx(15.12, abs=0.02)
               for r in d["runs"])


def test_beside_paper_gives_each_measure_with_the_papers_value_and_ratio(tmp_path):
    """A path that enters and stays, one that passes through, one that never enters: the after-entry measures
    average the two that entered (hand-computed), sit beside the paper's musculoskeletal left values, and the ratio
    is ours / the paper's; the simple arm has no paper values for them."""
    from jaxarm.paper import comparison as mod

    t = np.arange(101)[:, None] * 0.01
    start = np.array([0.15, 0.0])
    stays = start * (1 - np.clip(t / 0.5, 0, 1))                   # 0.3 m/s straight in, then still at the centre
    through = np.concatenate([0.15 - 0.003 * np.arange(101)[:, None], np.zeros((101, 1))], axis=1)   # 0.3 m/s on
    never = np.repeat(start[None], 101, axis=0) + 1e-4 * t
    _fake_run(tmp_path / "ms", "musculoskeletal", "left", [stays, through, never], [never] * 3, [True, True, False])
    row = mod.beside_paper(mod.target_stats(tmp_path / "ms"))
    assert {k for k, _ in mod.MEASURES} == set(row)
    # first entry: the first sample within 4 cm, at x <= 0.04 m: sample 37 for both (0.15 - 0.003 k <= 0.04)
    d_stays = np.mean(np.abs(stays[37:, 0]))
    d_through = np.mean(np.abs(through[37:, 0]))
    dist = row["distance_after_m"]
    assert dist["n"] == 2 and dist["mean"] == pytest.approx(100 * (d_stays + d_through) / 2, rel=1e-3)   # cm
    assert dist["paper"] == 3.87 and dist["paper_sd"] == 0.78
    assert dist["ratio"] == pytest.approx(dist["mean"] / 3.87, rel=1e-3)
    assert row["speed_after_m_s"]["mean"] == pytest.approx((0.3 * 13 / 63 + 0.3) / 2, rel=1e-2)   # still after 0.5 s
    assert row["time_inside_s"]["mean"] == pytest.approx((640 + 270) / 2, abs=10)   # ms: 64 and 27 samples inside
    assert row["jerk_trained"]["paper"] == 0.76 and row["jerk_ratio"]["paper"] == pytest.approx(0.76 / 1.72)
    assert row["jerk_trained"]["ratio"] is None and row["jerk_naive"]["ratio"] is None   # incomparable absolutes
    jr = row["jerk_ratio"]
    assert jr["ratio"] == pytest.approx(jr["mean"] / (0.76 / 1.72), rel=1e-2)
    _fake_run(tmp_path / "simple", "simple", "left", [stays], [never], [True])
    simple = mod.beside_paper(mod.target_stats(tmp_path / "simple"))
    assert simple["distance_after_m"]["paper"] is None and simple["distance_after_m"]["ratio"] is None


def test_jerk_phases_takes_the_ratio_apart_on_reaches_with_known_answers():
    # experiments/jerk_phases.py on cubic reaches (constant jerk 12A/D^3): a trained reach of 15 cm and a naive one
    # of 3 cm have the same dimensionless jerk (144), so the ratio is 1 = energy ratio 25 x length factor 1/25, and
    # every window holds the energy share of its samples' trapezoid weights; the hand enters a 4 cm circle around
    # the end at the sample where the remaining distance drops below it
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "jerk_phases.py"
    spec = importlib.util.spec_from_file_location("jerk_phases", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    n, dt = 101, 0.01
    trained, _ = straight_reach(CUBIC, n, 1.0, 0.15)
    naive, _ = straight_reach(CUBIC, n, 1.0, 0.03)
    t = np.arange(n) * dt
    distance = np.linalg.norm(trained - trained[-1], axis=-1)
    r = mod.phases({"hand": trained[None], "naive_hand": naive[None], "t": t, "distance": distance[None]}, dt)
    assert r["jerk_ratio_of_means"] == pytest.approx(1.0, rel=1e-9)
    assert r["median_energy_ratio"] == pytest.approx(25.0, rel=1e-9)
    assert r["median_length_factor"] == pytest.approx(1 / 25, rel=1e-9)
    weights = np.full(n, dt)
    weights[[0, -1]] /= 2
    for (a, b) in mod.WINDOWS_S:
        share = weights[(t >= a - 1e-9) & (t < b - 1e-9 if b < 1.0 else t <= 1.0)].sum() / weights.sum()
        got = r["energy_share_by_window"][mod.window_name(a, b)]
        assert got["trained"] == pytest.approx(share, rel=1e-9) and got["naive"] == pytest.approx(share, rel=1e-9)
    first = int(np.argmax(distance < 0.04))
    assert r["entered"] == 1
    assert r["energy_share_before_first_entry"]["median"] == pytest.approx(weights[:first].sum() / weights.sum(),
                                                                           rel=1e-9)
