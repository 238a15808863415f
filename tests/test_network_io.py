"""The network's inputs and output: P population code, background noise, motor readout (spec §2-§3)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.network import NetworkConfig, Populations
from jaxarm.network import noise as N
from jaxarm.network import proprio as P
from jaxarm.network import readout as R

W = 0.2 / 48  # P tuning step, m


@pytest.mark.parametrize("tuning, positions", [("code", [9, 10, 11]), ("paper", [9, 10])])
def test_p_code_activates_the_right_units(tuning, positions):
    config = NetworkConfig(p_tuning=tuning)
    lengths = jnp.array([0.03 + 10.25 * W, 0.03, 0.23, 0.03 + 30.25 * W])
    active = np.flatnonzero(np.asarray(P.active_cells(config, lengths)))
    groups, k = active % 4, active // 4
    # group 0 at 10.25 steps: code window [k-1, k+2] steps -> k = 9..11; paper [k-0.5, k+1.5] -> k = 9, 10
    assert sorted(k[groups == 0]) == positions
    assert sorted(k[groups == 3]) == [p + 20 for p in positions]
    # group 1 at the bottom of the range, group 2 at the top (inclusive bounds)
    assert sorted(k[groups == 1]) == ([0, 1] if tuning == "code" else [0])
    assert sorted(k[groups == 2]) == ([46, 47] if tuning == "code" else [47])
    lo, hi = P.tuning_windows(config)
    width = 3 * W if tuning == "code" else 2 * W
    np.testing.assert_allclose(hi - lo, width, rtol=1e-5)   # 12.5 mm (code) / 8.33 mm (paper)


def test_p_trains_follow_nsloc_semantics():
    config = NetworkConfig(dt_ms=0.5)
    p = P.init_p(config)
    spikes = []
    lengths_on = jnp.array([0.03 + 10.25 * W, 0.1, 0.1, 0.1])
    lengths_off = jnp.array([0.2, 0.1, 0.1, 0.1])  # group 0 moves away: its three cells switch off
    for m in range(1, 121):                        # 60 ms; the loop sets lengths after a step, at 10 and 40 ms
        p, s = P.p_step(p, m)
        spikes.append(np.asarray(s))
        if m == 20:
            p = P.set_lengths(config, p, lengths_on, m)
        if m == 80:
            p = P.set_lengths(config, p, lengths_off, m)
    spikes = np.array(spikes)
    cell = 4 * 10  # group 0, position 10
    times = (np.flatnonzero(spikes[:, cell]) + 1) * config.dt_ms
    # the start spike at 1 ms, then 100 Hz from one interval after switching on (10 ms -> 20 ms), and one last
    # already-scheduled spike after switching off at 40 ms
    np.testing.assert_allclose(times, [1.0, 20.0, 30.0, 40.0, 50.0])
    assert spikes[1].sum() == 192   # every P cell fires at 1 ms


def test_readout_window_is_exactly_t_minus_130_to_t_minus_60():
    config = NetworkConfig()
    # one EM spike of group 2 at time tau: it is counted at t iff t - 130 < tau <= t - 60
    for tau in (3.0, 10.0, 10.5, 57.0, 60.0, 61.0):
        state = R.init_readout(config)
        for t in np.arange(10.0, 400.0, 10.0):
            counts = jnp.zeros(4).at[2].set(1.0 if t - 10.0 < tau <= t else 0.0)
            state = R.push(state, counts)
            u = float(R.excitation(config, state, v_em_max=1.0)[2])
            expected = 1.0 if (t - 130.0 < tau <= t - 60.0 and t >= 126.08) else 0.0
            assert u == expected, (tau, t, u)


def test_readout_scales_and_clips():
    state = R.init_readout(NetworkConfig())
    for _ in range(13):
        state = R.push(state, jnp.array([10.0, 20.0, 0.0, 40.0]))
    u_clip = R.excitation(NetworkConfig(), state)
    u_raw = R.excitation(NetworkConfig(readout_clip=False), state)
    np.testing.assert_allclose(u_raw, np.array([70.0, 140.0, 0.0, 280.0]) / 117.92, rtol=1e-6)
    np.testing.assert_allclose(u_clip, np.minimum(u_raw, 1.0), rtol=1e-6)


def test_em_group_counts_use_id_mod_4():
    config = NetworkConfig()
    counts = jnp.zeros(config.n_all, jnp.int32).at[256 + 5].set(3).at[256 + 8].set(2).at[0].set(7)
    np.testing.assert_array_equal(R.em_group_counts(config, counts), [2.0, 3.0, 0.0, 0.0])


def test_noise_counts_are_poisson_at_the_table_rates():
    config = NetworkConfig(dt_ms=0.5)
    noise = N.init_noise(config, jax.random.key(0), em_rates_hz=jnp.array([152.76, 50.0, 50.0, 50.0]))
    steps = 20_000  # 10 s
    total = jax.jit(lambda nz: jax.lax.fori_loop(
        0, steps, lambda m, acc: acc + N.noise_counts(nz, m + 1), jnp.zeros((3, config.n_cells))))(noise)
    total = np.asarray(total)
    pops = Populations(config)
    rate = total / 10.0  # Hz per lane
    np.testing.assert_allclose(rate[0, pops.slice("ES")].mean(), 200.0, rtol=0.01)
    np.testing.assert_allclose(rate[1].mean(), 100.0, rtol=0.01)
    np.testing.assert_allclose(rate[2].mean(), 100.0, rtol=0.01)
    em = rate[0, pops.slice("EM")]
    groups = pops.em_groups()
    np.testing.assert_allclose(em[groups == 0].mean(), 152.76, rtol=0.02)
    np.testing.assert_allclose(em[groups != 0].mean(), 50.0, rtol=0.02)


def test_order_coins_are_fair_and_independent_of_the_noise():
    """The coins of same_step_inhibition = "random_order" (N.excitation_first): probability 1/2, uncorrelated across
    cells and steps, and independent of the AMPA lane's own draw in the same step (which picks the cells whose
    coins are read). 2,000 steps x 512 cells = 1.02 M coins: the standard error of a proportion is 0.0005, so
    +-0.003 (6 s.e.) fails a bias of 0.005 with certainty; among the ~50 k coins of steps with an AMPA event,
    +-0.01 (4.5 s.e.) fails a bias of 0.02 (power > 0.99)."""
    config = NetworkConfig(dt_ms=0.5)
    noise = N.init_noise(config, jax.random.key(5))
    steps = jnp.arange(1, 2001)
    coins = np.asarray(jax.vmap(lambda m: N.excitation_first(noise, m))(steps)).astype(float)   # (t, cells)
    events = np.asarray(jax.vmap(lambda m: N.noise_counts(noise, m))(steps))[:, 0] > 0          # AMPA lanes
    assert coins.mean() == pytest.approx(0.5, abs=0.003)
    assert events.sum() > 40_000
    assert coins[events].mean() == pytest.approx(0.5, abs=0.01)
    assert coins[~events].mean() == pytest.approx(0.5, abs=0.003)
    lane_corr = np.mean([np.corrcoef(coins[:, i], coins[:, i + 1])[0, 1] for i in range(511)])
    step_corr = np.mean([np.corrcoef(coins[:-1, i], coins[1:, i])[0, 1] for i in range(512)])
    assert max(abs(lane_corr), abs(step_corr)) < 0.01
    # another network's coins are another stream
    other = np.asarray(jax.vmap(lambda m: N.excitation_first(N.init_noise(config, jax.random.key(6)), m))(steps))
    assert np.mean(other == coins.astype(bool)) == pytest.approx(0.5, abs=0.003)


def test_noise_variance_matches_poisson():
    config = NetworkConfig(dt_ms=1.0)
    noise = N.init_noise(config, jax.random.key(3))
    all_counts = np.asarray(jax.vmap(lambda m: N.noise_counts(noise, m))(jnp.arange(1, 4001)))  # (t, 3, cells)
    counts = all_counts[:, 0]  # AMPA lanes, 200 Hz
    lam = 0.2
    # lanes are independent and steps are independent: correlations at the sampling noise level (1/sqrt(4000))
    es = counts[:, :192]
    lane_corr = np.mean([np.corrcoef(es[:, i], es[:, i + 1])[0, 1] for i in range(191)])
    step_corr = np.mean([np.corrcoef(es[:-1, i], es[1:, i])[0, 1] for i in range(192)])
    gaba_corr = np.mean([np.corrcoef(all_counts[:, 1, i], all_counts[:, 2, i])[0, 1] for i in range(192)])
    assert max(abs(lane_corr), abs(step_corr), abs(gaba_corr)) < 0.01
    assert counts.mean() == pytest.approx(lam, rel=0.02)
    assert counts.var() == pytest.approx(lam, rel=0.03)
    assert np.mean(counts >= 2) == pytest.approx(1 - np.exp(-lam) * (1 + lam), rel=0.05)
