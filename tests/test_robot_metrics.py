"""Tracking metrics on signals with known answers (no simulator)."""
import numpy as np
import pytest

from jaxarm.robot.metrics import (boxplot_stats, dimensionless_jerk, error_over_displacement, hand_xy,
                                  interval_stats, jerk, load_log, total_displacement, tracking_report,
                                  windowed_delay, xcorr_delay)
from jaxarm.robot.synthetic import min_jerk


def _smooth_signal(n, dt, seed=0):
    rng = np.random.Generator(np.random.PCG64(seed))
    t = np.arange(n) * dt
    return sum(rng.uniform(0.2, 1) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6)) for f in (0.3, 0.7, 1.1, 1.9))


def test_interval_stats():
    s = interval_stats([0.0, 0.010, 0.030, 0.040])
    assert s["n"] == 3 and s["mean_ms"] == pytest.approx(40 / 3) and s["max_ms"] == pytest.approx(20)
    assert s["sd_ms"] == pytest.approx(np.std([10, 20, 10], ddof=1))


@pytest.mark.parametrize("lag_ticks", [0, 7, 25, 156])
def test_xcorr_delay_recovers_a_known_shift(lag_ticks):
    dt = 0.002
    x = _smooth_signal(12000 + lag_ticks, dt)
    a, b = x[lag_ticks:], x[:len(x) - lag_ticks]            # b(t) = a(t - lag): b lags a
    assert xcorr_delay(a, b, dt) == pytest.approx(lag_ticks * dt, abs=1e-12)
    w = windowed_delay(a, b, dt, window_s=5.0)
    assert w["n_windows"] >= 5
    assert w["mean_s"] == pytest.approx(lag_ticks * dt, abs=1e-12) and w["sd_s"] == pytest.approx(0, abs=1e-12)


def test_jerk_is_exact_for_a_cubic_on_uneven_times():
    rng = np.random.Generator(np.random.PCG64(1))
    t = np.cumsum(rng.uniform(0.005, 0.03, size=200))
    tj, j = jerk(t, 2.0 * t ** 3 - t)
    assert len(tj) == len(t) - 3                             # N - 3 samples, as in the paper's Fig. 10 counts
    np.testing.assert_allclose(j, 12.0, rtol=1e-6)


def test_dimensionless_jerk_of_a_minimum_jerk_reach_is_720():
    # x = A mj(t/D): integral of jerk^2 = 720 A^2 / D^5, v_mean = A / D, so DLJ = 720 for any A, D.
    for amp, dur in [(0.15, 0.5), (0.3, 2.0)]:
        t = np.linspace(0, dur, 20001)
        x = amp * min_jerk(t / dur)
        xy = np.column_stack([0.6 * x, 0.8 * x])             # a straight 2-D reach of length amp
        assert dimensionless_jerk(t, xy) == pytest.approx(720, rel=2e-3)


def test_error_over_displacement_and_hand_xy():
    target = np.column_stack([np.linspace(0, 1, 101), np.zeros(101)])
    robot = target + [0.01, 0.02]
    r = error_over_displacement(target, robot)
    assert r["shoulder"] == pytest.approx(0.01 / 1.0)
    assert np.isinf(r["elbow"])                               # no displacement: undefined, reported as inf
    np.testing.assert_allclose(total_displacement([[0, 0], [1, -1], [0, 1]]), [2, 3])
    np.testing.assert_allclose(hand_xy([0.0, 0.0]), [0.2904 + 0.2535, 0.0], atol=1e-4)


def test_boxplot_outliers():
    s = boxplot_stats(np.r_[np.arange(100.0), 1e6])
    assert s["n"] == 101 and s["n_outliers"] == 1 and s["median"] == 50


def test_tracking_report_on_a_delayed_copy(tmp_path):
    dt, lag = 0.002, 20
    n = 10000
    x = 0.5 + 0.3 * _smooth_signal(n + lag, dt)
    y = 1.2 + 0.3 * _smooth_signal(n + lag, dt, seed=3)
    t = np.arange(n) * dt
    new = np.zeros(n)
    new[::7] = 1
    log = {"t": t, "target_shoulder": x[lag:], "target_elbow": y[lag:], "robot_shoulder": x[:n],
           "robot_elbow": y[:n], "new_target": new}
    r = tracking_report(log)
    assert r["delay_ms"]["whole_signal"]["shoulder"] == pytest.approx(40.0)
    assert r["delay_ms"]["whole_signal"]["elbow"] == pytest.approx(40.0)
    assert r["samples"] == {"virtual": int(new.sum()), "robot": n}
    assert r["packet_intervals"]["mean_ms"] == pytest.approx(14.0)
    err = np.degrees(np.abs(x[lag:] - x[:n])).mean()
    assert r["mean_abs_error_deg"]["shoulder"] == pytest.approx(err)
    # The CSV reader gives the same dict back.
    path = tmp_path / "log.csv"
    np.savetxt(path, np.column_stack([log[k] for k in log]), delimiter=",", header=",".join(log), comments="")
    back = load_log(path)
    np.testing.assert_allclose(back["robot_elbow"], log["robot_elbow"])
