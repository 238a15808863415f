"""Learning-rule primitives: critic thresholds, tagging windows, soft-bounded R-STDP, scaling, babbling, MetaParams."""
import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config.validate import ConfigError
from jaxarm.learning import (BOUNDS, EXPLORE_PATTERNS, NAMES, NO_TAG_MS, ORIGINAL, BabblingConfig, EligibilityConfig,
                             MetaParams, apply_synaptic_scaling, babble, clip_to_bounds, critic_signal,
                             dopamine_update, em_noise_rates_in_test, from_unit, init_babbling, is_plastic,
                             pathway_inc, pathway_maxw, rl_update_due, scaling_due, scaling_factor, stack,
                             start_epoch, tag_on_spikes, tag_post_before_pre, tag_pre_before_post, tag_spiking_rows,
                             to_unit)

MP = MetaParams.original()


# ---- critic ---------------------------------------------------------------------------------------------------

def test_critic_thresholds_are_one_millimetre_both_ways():
    # exact binary values: 2^-10 m = 0.98 mm (below threshold), 2^-9 m = 1.95 mm (above)
    older = jnp.asarray([0.5, 0.5, 0.5, 0.5, 0.5])
    newer = jnp.asarray([0.5 - 2 ** -9, 0.5 - 2 ** -10, 0.5, 0.5 + 2 ** -10, 0.5 + 2 ** -9])
    np.testing.assert_array_equal(np.asarray(critic_signal(older, newer)), [1, 0, 0, 0, -1])
    assert float(critic_signal(0.150, 0.140)) == 1.0 and float(critic_signal(0.140, 0.150)) == -1.0
    assert float(critic_signal(0.5, 0.5 - 2 ** -10, threshold_m=2 ** -11)) == 1.0


def test_rl_updates_run_every_60_ms_with_the_original_rl_dt():
    last, times = 0.0, []
    for step in range(1, 40):
        t = 10.0 * step
        if bool(rl_update_due(t, last, ORIGINAL["rl_dt_ms"])):
            times.append(t)
            last = t
    assert times == [60.0, 120.0, 180.0, 240.0, 300.0, 360.0]


# ---- tagging --------------------------------------------------------------------------------------------------

def small_block():
    presyn = jnp.asarray([[0, 1, 2], [2, 3, 4]])
    pdope = jnp.full((2, 3), NO_TAG_MS, jnp.float32)
    return presyn, pdope


def test_forward_tags_only_pre_before_post_within_the_window():
    presyn, pdope = small_block()
    t = 1000.0
    # cell 0: 10 ms before (in), 1: 80 ms before (out of 69.57), 2: never, 3: same time (d = 0, in), 4: 69 ms (in)
    last = jnp.asarray([t - 10, t - 80, -1e9, t, t - 69.0])
    plastic = jnp.ones((2, 3), bool)
    out = tag_pre_before_post(pdope, presyn, last, jnp.asarray([True, True]), t, ORIGINAL["max_plast_t_ms"], plastic)
    np.testing.assert_array_equal(np.asarray(out), [[t, NO_TAG_MS, NO_TAG_MS], [NO_TAG_MS, t, t]])
    # only cells that spike now get tags, and only on plastic synapses
    out = tag_pre_before_post(pdope, presyn, last, jnp.asarray([False, True]), t, 69.57,
                              jnp.asarray([[True] * 3, [True, True, False]]))
    np.testing.assert_array_equal(np.asarray(out), [[NO_TAG_MS] * 3, [NO_TAG_MS, t, NO_TAG_MS]])
    # a presynaptic spike "after" t (inconsistent input) never tags: no post-before-pre in the default rule
    out = tag_pre_before_post(pdope, presyn, jnp.full((5,), t + 5.0), jnp.asarray([True, True]), t, 69.57, plastic)
    assert np.all(np.asarray(out) == NO_TAG_MS)


def test_forward_tagging_matches_a_direct_loop_on_random_data():
    rng = np.random.default_rng(3)
    n_cells, n_post, k, t, window = 40, 12, 7, 500.0, 69.57
    presyn = rng.integers(0, n_cells, size=(n_post, k))
    last = np.where(rng.random(n_cells) < 0.2, -1e9, t - rng.uniform(0, 150, n_cells)).astype(np.float32)
    spiked = rng.random(n_post) < 0.5
    plastic = rng.random((n_post, k)) < 0.8
    old = np.where(rng.random((n_post, k)) < 0.3, t - 20.0, NO_TAG_MS).astype(np.float32)
    out = np.asarray(tag_pre_before_post(jnp.asarray(old), jnp.asarray(presyn), jnp.asarray(last),
                                         jnp.asarray(spiked), t, window, jnp.asarray(plastic)))
    for i in range(n_post):
        for j in range(k):
            lp = last[presyn[i, j]]
            hit = spiked[i] and plastic[i, j] and lp >= 0 and 0 <= t - lp <= window
            assert out[i, j] == (t if hit else old[i, j])


def test_sparse_row_tagging_equals_dense_tagging():
    rng = np.random.default_rng(5)
    n_cells, n_post, k, t = 30, 10, 6, 400.0
    presyn = jnp.asarray(rng.integers(0, n_cells, size=(n_post, k)))
    last = jnp.asarray(np.where(rng.random(n_cells) < 0.2, -1e9, t - rng.uniform(0, 120, n_cells)), jnp.float32)
    plastic = jnp.asarray(rng.random((n_post, k)) < 0.8)
    old = jnp.asarray(np.where(rng.random((n_post, k)) < 0.3, t - 20.0, NO_TAG_MS), jnp.float32)
    spiking = np.array([7, 2, 0])
    post_spiked = jnp.zeros(n_post, bool).at[spiking].set(True)
    dense = tag_pre_before_post(old, presyn, last, post_spiked, t, 69.57, plastic)
    # capacity 5: three real rows, two unused slots whose (garbage) row ids must not be written
    rows = jnp.asarray([7, 2, 0, 0, 7])
    valid = jnp.asarray([True, True, True, False, False])
    sparse = tag_spiking_rows(old, presyn, last, rows, valid, t, 69.57, plastic)
    np.testing.assert_array_equal(np.asarray(sparse), np.asarray(dense))
    assert not np.array_equal(np.asarray(dense), np.asarray(old))           # the case is not trivial
    # per-row spike times
    per_row = tag_spiking_rows(old, presyn, last, rows, valid, jnp.asarray([t, t - 1, t, 0, 0]), 69.57, plastic)
    row2 = tag_pre_before_post(old, presyn, last, jnp.zeros(n_post, bool).at[2].set(True), t - 1, 69.57, plastic)
    np.testing.assert_array_equal(np.asarray(per_row)[2], np.asarray(row2)[2])


def test_backward_tags_are_negative_and_off_by_default():
    presyn, pdope = small_block()
    t = 300.0
    post_ids = jnp.asarray([5, 6])
    spiked = jnp.zeros(7, bool).at[2].set(True)        # presynaptic cell 2 spikes now
    last = jnp.full((7,), -1e9).at[2].set(t).at[5].set(t - 30).at[6].set(t - 100)
    plastic = jnp.ones((2, 3), bool)
    out = tag_post_before_pre(pdope, presyn, spiked, last[post_ids], t, 69.57, plastic)
    # synapse 2->5 (post spiked 30 ms before) is tagged -t; 2->6 (100 ms) is not
    np.testing.assert_array_equal(np.asarray(out), [[NO_TAG_MS, NO_TAG_MS, -t], [NO_TAG_MS] * 3])
    assert np.all(np.asarray(tag_on_spikes(pdope, presyn, post_ids, spiked, last, t, 69.57, plastic)) == NO_TAG_MS)
    both = tag_on_spikes(pdope, presyn, post_ids, spiked, last, t, 69.57, plastic, EligibilityConfig(backward=True))
    np.testing.assert_array_equal(np.asarray(both), np.asarray(out))


# ---- reward-modulated update ----------------------------------------------------------------------------------

def test_reward_and_punishment_steps_are_the_soft_bounded_ones():
    w = jnp.asarray([1.0, 1.0, 7.0])
    pdope = jnp.asarray([100.0, 100.0, 100.0])
    maxw = jnp.asarray([7.85, 5.0, 7.85])
    inc, t = 0.04, 120.0
    up, _ = dopamine_update(w, pdope, True, maxw, inc, t, 1.0, 62.28)
    np.testing.assert_allclose(np.asarray(up), [1 + inc * (1 - 1 / 7.85), 1 + inc * (1 - 1 / 5.0),
                                                7 + inc * (1 - 7 / 7.85)], rtol=1e-6)
    down, _ = dopamine_update(w, pdope, True, maxw, inc, t, -1.0, 62.28)
    np.testing.assert_allclose(np.asarray(down), [1 - inc / 7.85, 1 - inc / 5.0, 7 - inc * 7 / 7.85], rtol=1e-6)
    same, _ = dopamine_update(w, pdope, True, maxw, inc, t, 0.0, 62.28)
    np.testing.assert_array_equal(np.asarray(same), np.asarray(w))


def test_only_live_tags_on_plastic_synapses_learn():
    t = 1000.0
    w = jnp.ones(5)
    pdope = jnp.asarray([t - 62.0, t - 63.0, NO_TAG_MS, t, t - 10.0])
    plastic = jnp.asarray([True, True, True, True, False])
    up, tags = dopamine_update(w, pdope, plastic, 7.85, 0.04, t, 1.0, 62.28)
    changed = np.asarray(up) != 1.0
    np.testing.assert_array_equal(changed, [True, False, False, True, False])
    np.testing.assert_array_equal(np.asarray(tags), np.asarray(pdope))        # tags are not consumed


def test_a_tag_serves_two_critic_updates_60_ms_apart():
    w, pdope = jnp.ones(1), jnp.asarray([1000.0])
    applied = []
    for t in (1001.0, 1061.0, 1121.0):
        new, pdope = dopamine_update(w, pdope, True, 7.85, 0.04, t, 1.0, ORIGINAL["max_elig_tr_dur_ms"])
        applied.append(bool(new[0] != w[0]))
        w = new
    assert applied == [True, True, False]


def test_soft_bounds_keep_weights_in_zero_to_maxw():
    rng = np.random.default_rng(0)
    n = 4000
    maxw = jnp.asarray(rng.choice([7.85, 5.0, 1.0], size=n))
    inc = jnp.asarray(rng.uniform(0.0, 1.0, size=n)) * maxw          # any inc <= maxw
    w = jnp.asarray(rng.uniform(0.0, 1.0, size=n)) * maxw
    pdope = jnp.zeros(n)
    signals = jnp.asarray(rng.choice([-1.0, 1.0], size=300))

    def body(w, s):
        w, _ = dopamine_update(w, pdope, True, maxw, inc, 10.0, s, 62.28)
        return w, (jnp.min(w), jnp.max(w - maxw))

    w, (lo, over) = jax.lax.scan(body, w, signals)
    assert float(jnp.min(lo)) >= 0.0 and float(jnp.max(over)) <= 1e-5
    # all-reward drives weights to maxw from below; all-punishment towards 0
    w_up, _ = jax.lax.scan(lambda w, _: (dopamine_update(w, jnp.zeros(3), True, 7.85, 0.5, 10.0, 1.0, 62.28)[0], None),
                           jnp.ones(3), None, length=500)
    np.testing.assert_allclose(np.asarray(w_up), 7.85, rtol=1e-4)
    assert float(jnp.max(w_up)) <= 7.85


def test_variants_backward_exponential_reset_and_hard_bounds():
    t = 200.0
    w = jnp.asarray([2.0, 2.0])
    pdope = jnp.asarray([150.0, -150.0])                   # forward tag, backward tag (both 50 ms old)
    up, _ = dopamine_update(w, pdope, True, 5.0, 0.1, t, 1.0, 62.28)
    np.testing.assert_allclose(np.asarray(up), [2 + 0.1 * (1 - 2 / 5), 2 - 0.1 * 2 / 5], rtol=1e-6)  # reward: LTP, LTD
    down, _ = dopamine_update(w, pdope, True, 5.0, 0.1, t, -1.0, 62.28)
    np.testing.assert_allclose(np.asarray(down), [2 - 0.1 * 2 / 5, 2 + 0.1 * (1 - 2 / 5)], rtol=1e-6)
    decayed, _ = dopamine_update(w, pdope, True, 5.0, 0.1, t, 1.0, 62.28, EligibilityConfig(exponential=True))
    np.testing.assert_allclose(np.asarray(decayed - w), np.asarray(up - w) * math.exp(-50 / 20), rtol=1e-4)
    _, cleared = dopamine_update(w, pdope, True, 5.0, 0.1, t, 1.0, 62.28, EligibilityConfig(reset_after_use=True))
    assert np.all(np.asarray(cleared) == NO_TAG_MS)
    hard, _ = dopamine_update(jnp.asarray([4.95]), jnp.asarray([150.0]), True, 5.0, 0.1, t, 1.0, 62.28,
                              EligibilityConfig(soft_bounds=False))
    assert float(hard[0]) == pytest.approx(5.0)


def test_eligibility_config_validation_names_the_field():
    with pytest.raises(ConfigError, match="EligibilityConfig.exp_tau_ms"):
        EligibilityConfig(exp_tau_ms=0.0)
    with pytest.raises(ConfigError, match="EligibilityConfig.backward"):
        EligibilityConfig(backward=1)


def test_plastic_pathways_and_their_maxima():
    assert is_plastic("ES", "EM") and is_plastic("EM", "ES") and not is_plastic("ES", "IM")
    assert not is_plastic("IM", "EM")
    assert float(pathway_maxw("ES", "EM", MP)) == pytest.approx(7.85)
    assert float(pathway_maxw("EM", "IML", MP)) == pytest.approx(5.0)
    assert float(pathway_maxw("IS", "ES", MP)) == pytest.approx(2.1)
    assert float(pathway_inc("EM", "IM", MP)) == pytest.approx(0.04) and float(pathway_inc("ES", "IML", MP)) == 0.0


# ---- synaptic scaling -----------------------------------------------------------------------------------------

def scaling_network():
    # dict of two blocks; 4 cells; base |w1| + |w2| per synapse
    presyn = {"ee": jnp.asarray([[0, 1], [1, 2]]), "ie": jnp.asarray([[3], [3]])}
    base = {"ee": jnp.asarray([[2.0, 2.0], [2.0, 2.0]]), "ie": jnp.asarray([[4.0], [4.0]])}
    return presyn, base


def test_scaling_restores_the_total_weight_when_it_grew():
    presyn, base = scaling_network()
    wgain = {"ee": jnp.asarray([[1.5, 1.2], [1.2, 1.0]]), "ie": jnp.asarray([[0.9], [1.0]])}
    s0 = 4 * 2.0 + 2 * 4.0
    s = 2.0 * (1.5 + 1.2 + 1.2 + 1.0) + 4.0 * (0.9 + 1.0)
    scaled, factor = apply_synaptic_scaling(wgain, base, presyn, 4)
    assert float(factor) == pytest.approx(s0 / s, rel=1e-6)
    total = sum(float(jnp.sum(scaled[k] * base[k])) for k in scaled)
    assert total == pytest.approx(s0, rel=1e-6)                          # every gain, incl. inhibitory, scaled
    np.testing.assert_allclose(np.asarray(scaled["ie"]), np.asarray(wgain["ie"]) * s0 / s, rtol=1e-6)


def test_scaling_never_scales_up_and_skips_silent_presynaptic_cells():
    presyn, base = scaling_network()
    shrunk = {"ee": jnp.full((2, 2), 0.8), "ie": jnp.ones((2, 1))}
    assert float(scaling_factor(shrunk, base, presyn, 4)) == 1.0
    # cell 0's only outgoing gain is 0 -> its base weight is excluded from S0 (the original's wgain.sum() > 0 test)
    wgain = {"ee": jnp.asarray([[0.0, 1.2], [1.2, 1.0]]), "ie": jnp.ones((2, 1))}
    s0 = 3 * 2.0 + 2 * 4.0
    s = 2.0 * (1.2 + 1.2 + 1.0) + 8.0
    assert float(scaling_factor(wgain, base, presyn, 4)) == pytest.approx(s0 / s, rel=1e-6)
    # padding excluded by the valid mask
    valid = {"ee": jnp.asarray([[True, True], [True, False]]), "ie": jnp.ones((2, 1), bool)}
    grown = {"ee": jnp.asarray([[1.1, 1.1], [1.1, 99.0]]), "ie": jnp.ones((2, 1))}
    assert float(scaling_factor(grown, base, presyn, 4, valid)) == pytest.approx(14.0 / 14.6, rel=1e-6)
    assert bool(scaling_due(5000.0, 0.0, 5000.0)) and not bool(scaling_due(4990.0, 0.0, 5000.0))


# ---- babbling -------------------------------------------------------------------------------------------------

def run_babbling(key, mp=MP, config=BabblingConfig(), n_updates=3000):
    """Babbling at every RL update (60 ms) over n_updates; returns stacked states and rates."""
    return _run_babbling(key, mp, config, n_updates)


@partial(jax.jit, static_argnames=("config", "n_updates"))
def _run_babbling(key, mp, config, n_updates):
    def body(state, i):
        t = 60.0 * (i + 1)
        state, rates = babble(jax.random.fold_in(key, i), state, t, mp, config)
        return state, (state, rates)

    _, (states, rates) = jax.lax.scan(body, init_babbling(config), jnp.arange(n_updates))
    return states, rates


def changes(states):
    pattern, dt_ms, last = (np.asarray(x) for x in (states.pattern, states.change_dt_ms, states.last_change_ms))
    changed = np.concatenate([[last[0] > 0], last[1:] != last[:-1]])
    return pattern[changed], dt_ms[changed], last[changed]


def test_babbling_durations_patterns_and_rates_as_the_code_did():
    states, rates = run_babbling(jax.random.PRNGKey(7))
    patterns, dts, when = changes(states)
    assert when[0] == pytest.approx(1020.0)                 # initial 1000 ms, checked every 60 ms
    assert len(dts) > 200
    assert dts.min() >= 100.0 and dts.max() <= 624.12
    assert set(patterns.tolist()) == set(range(8))          # exploreTot 16: 4 singles and 4 pairs
    gaps = np.diff(when)
    assert np.all(gaps >= dts[:-1] - 1e-3) and np.all(gaps < dts[:-1] + 60.0 + 1e-3)
    rates = np.asarray(rates)
    on = EXPLORE_PATTERNS[np.asarray(states.pattern)]
    np.testing.assert_allclose(rates[on], 152.76, rtol=1e-6)
    np.testing.assert_allclose(rates[~on], 50.0)
    assert init_babbling().rates_hz.tolist() == [200.0] * 4


def test_babbling_is_deterministic_for_a_pinned_key():
    a, _ = run_babbling(jax.random.PRNGKey(11))
    b, _ = run_babbling(jax.random.PRNGKey(11))
    c, _ = run_babbling(jax.random.PRNGKey(12))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert not np.array_equal(np.asarray(a.change_dt_ms), np.asarray(c.change_dt_ms))


def test_babbling_explore_tot_cycle_mode_and_paper_variant():
    singles, _ = run_babbling(jax.random.PRNGKey(1), MP.replace(explore_tot=jnp.asarray(8.0)))
    assert set(changes(singles)[0].tolist()) == {0, 1, 2, 3}
    cycle, _ = run_babbling(jax.random.PRNGKey(1), MP.replace(random_muscle_dt_max_ms=jnp.asarray(0.0)))
    patterns, dts, _ = changes(cycle)
    assert patterns[:9].tolist() == [1, 2, 3, 4, 5, 6, 7, 0, 1] and np.all(dts == 1000.0)
    paper, _ = run_babbling(jax.random.PRNGKey(1), config=BabblingConfig(variant="paper"))
    patterns, dts, _ = changes(paper)
    assert set(patterns.tolist()) == {0, 1, 2, 3}
    assert dts.min() >= 100.0 and dts.max() <= 1500.0 and dts.max() > 624.12


def test_babbling_epoch_restart_and_test_noise():
    state, _ = babble(jax.random.PRNGKey(0), init_babbling(), 1020.0, MP)
    restarted = start_epoch(state)
    assert float(restarted.last_change_ms) == 0.0
    assert int(restarted.pattern) == int(state.pattern)
    np.testing.assert_array_equal(np.asarray(restarted.rates_hz), np.asarray(state.rates_hz))
    np.testing.assert_allclose(np.asarray(em_noise_rates_in_test(MP)), 99.01, rtol=1e-6)
    with pytest.raises(ConfigError, match="BabblingConfig.variant"):
        BabblingConfig(variant="random")
    with pytest.raises(ConfigError, match="BabblingConfig.paper_max_dt_ms"):
        BabblingConfig(paper_max_dt_ms=50.0)


# ---- metaparameters -------------------------------------------------------------------------------------------

def test_metaparams_hold_the_original_values():
    d = MP.to_dict()
    assert d["learn_rate"] == 0.04 and d["plast_ee_maxw"] == 7.85 and d["plast_ei_maxw"] == 5.0
    assert d["max_plast_t_ms"] == 69.57 and d["max_elig_tr_dur_ms"] == 62.28 and d["v_em_max"] == 117.92
    assert d["mcmd_spk_wd_ms"] == 76.08 and d["rl_dt_ms"] == 55.55 and d["random_muscle_dt_max_ms"] == 624.12
    assert d["em_noise_rate_train_hz"] == 152.76 and d["em_noise_rate_test_hz"] == 99.01
    assert d["syn_scaling_dt_ms"] == 5000.0 and d["explore_tot"] == 16.0 and d["epochs"] == 12.0
    assert d["max_w_scaling"] == 0.7 and float(MP.maxw_ix) == pytest.approx(2.1)
    assert all(jnp.asarray(leaf).dtype == jnp.float32 for leaf in jax.tree_util.tree_leaves(MP))
    with pytest.raises(KeyError, match="learning_rate"):
        MetaParams.from_dict({"learning_rate": 0.1})


def test_bounds_table_and_unit_cube_mapping():
    assert tuple(BOUNDS) == NAMES
    for name, b in BOUNDS.items():
        assert b.lo <= ORIGINAL[name] <= b.hi and b.scale in ("log", "linear")
    u = to_unit(MP)
    assert u.shape == (len(NAMES),) and bool(jnp.all((u >= 0) & (u <= 1)))
    back = from_unit(u)
    for name in NAMES:
        assert float(getattr(back, name)) == pytest.approx(ORIGINAL[name], rel=1e-5)
    wild = from_unit(jax.random.uniform(jax.random.PRNGKey(0), (64, len(NAMES)), minval=-1.0, maxval=2.0))
    for name in NAMES:
        v = np.asarray(getattr(wild, name))
        assert v.shape == (64,) and v.min() >= BOUNDS[name].lo and v.max() <= BOUNDS[name].hi, name
    log_mid = float(from_unit(jnp.full((len(NAMES),), 0.5)).learn_rate)
    assert log_mid == pytest.approx(math.sqrt(0.001 * 0.2), rel=1e-5)      # geometric mean on a log scale
    clipped = clip_to_bounds(MP.replace(learn_rate=jnp.asarray(5.0)))
    assert clipped.learn_rate.dtype == jnp.float32 and float(clipped.learn_rate) == np.float32(0.2)


def test_metaparams_vmap_and_compile_once():
    traces = []

    @jax.jit
    def soft_step(mp):
        traces.append(1)
        w, _ = dopamine_update(jnp.ones(3), jnp.zeros(3), True, mp.plast_ee_maxw, mp.learn_rate, 10.0, 1.0,
                               mp.max_elig_tr_dur_ms)
        return w

    batch = stack([MP, MP.replace(learn_rate=jnp.asarray(0.1))])
    out = jax.vmap(soft_step)(batch)
    out2 = jax.vmap(soft_step)(stack([MP.replace(learn_rate=jnp.asarray(0.2)), MP]))
    assert len(traces) == 1
    np.testing.assert_allclose(np.asarray(out[:, 0]), [1 + 0.04 * (1 - 1 / 7.85), 1 + 0.1 * (1 - 1 / 7.85)], rtol=1e-6)
    assert float(out2[0, 0]) == pytest.approx(1 + 0.2 * (1 - 1 / 7.85), rel=1e-6)
