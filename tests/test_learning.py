"""Learning-rule primitives: critic thresholds, tagging windows, soft-bounded R-STDP, scaling, babbling, MetaParams."""
import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config.validate import ConfigError
from jaxarm.learning import (BOUNDS, EXPLORE_PATTERNS, NAMES, NO_TAG_MS, ORIGINAL, BabblingConfig, EligibilityConfig,
                             MetaParams, babble, clip_to_bounds, critic_signal, dopamine_update,
                             em_noise_rates_in_test, from_unit, init_babbling, rl_update_due, stack, start_epoch,
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


# ---- tagging: tests/test_network_sim.py::test_tags_match_brute_force_pairing checks the kernels' tags ----------

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


def test_variants_exponential_reset_and_hard_bounds():
    t = 200.0
    w = jnp.asarray([2.0, 2.0])
    pdope = jnp.asarray([150.0, 190.0])                    # tags 50 and 10 ms old
    up, _ = dopamine_update(w, pdope, True, 5.0, 0.1, t, 1.0, 62.28)
    np.testing.assert_allclose(np.asarray(up), 2 + 0.1 * (1 - 2 / 5), rtol=1e-6)
    decayed, _ = dopamine_update(w, pdope, True, 5.0, 0.1, t, 1.0, 62.28, EligibilityConfig(exponential=True))
    np.testing.assert_allclose(np.asarray(decayed - w), np.asarray(up - w) * np.exp(-np.array([50, 10]) / 20),
                               rtol=1e-4)
    _, cleared = dopamine_update(w, pdope, True, 5.0, 0.1, t, 1.0, 62.28, EligibilityConfig(reset_after_use=True))
    assert np.all(np.asarray(cleared) == NO_TAG_MS)
    hard, _ = dopamine_update(jnp.asarray([4.95]), jnp.asarray([150.0]), True, 5.0, 0.1, t, 1.0, 62.28,
                              EligibilityConfig(soft_bounds=False))
    assert float(hard[0]) == pytest.approx(5.0)


def test_eligibility_config_validation_names_the_field():
    with pytest.raises(ConfigError, match="EligibilityConfig.exp_tau_ms"):
        EligibilityConfig(exp_tau_ms=0.0)
    with pytest.raises(ConfigError, match="EligibilityConfig.exponential"):
        EligibilityConfig(exponential=1)


def test_plastic_pathways_and_their_maxima_are_the_originals():
    """spec §4: the eight E->E and E->I pathways of the sensory and motor layers are plastic; E->E synapses are
    bounded by plast_ee_maxw, E->I by plast_ei_maxw (the loop's per-synapse table)."""
    from jaxarm.loop import ClosedLoop
    from jaxarm.config.spec import NetworkSpec

    PATHWAYS = NetworkSpec.dura_bernal_2015().pathways
    plastic = {(pw.pre, pw.post) for pw in PATHWAYS if pw.plastic}
    assert plastic == {("ES", "ES"), ("ES", "IS"), ("ES", "ISL"), ("ES", "EM"), ("EM", "EM"), ("EM", "IM"),
                       ("EM", "IML"), ("EM", "ES")}
    loop = ClosedLoop()
    layout = loop.net.layout
    is_ee = loop.plastic_tables
    for pw in PATHWAYS[:8]:
        block = np.asarray(layout.view(is_ee, pw.name))
        assert np.all(block == (pw.post in ("ES", "EM"))), pw.name


# ---- the loop's learning steps against references --------------------------------------------------------------

@pytest.fixture(scope="module")
def tagged_loop_state():
    """A simple-arm loop state after 0.6 s of training (live tags, learned gains), and its loop."""
    from jaxarm.loop import ClosedLoop, LoopConfig

    loop = ClosedLoop(LoopConfig(arm="simple"))
    wiring = loop.net.make_wiring(jax.random.PRNGKey(0))
    run, em_rates_hz = loop.rule.begin_epoch(loop.rule.init(None), None, MP)
    state = loop.init(jax.random.PRNGKey(1), None, run, em_rates_hz)
    state, _ = jax.jit(lambda s: loop.run(wiring, s, jax.random.PRNGKey(2), MP, 60, learn=True))(state)
    return loop, state


@pytest.mark.parametrize("signal", [1.0, -1.0])
def test_a_reward_potentiates_and_a_punishment_depresses_exactly_the_live_tagged_plastic_synapses(
        tagged_loop_state, signal):
    loop, state = tagged_loop_state
    layout = loop.net.layout
    t_ms = 600.0
    wgain, pdope = np.asarray(state.net.wgain), np.asarray(state.net.pdope_ms)
    new, _ = loop.rule.reinforce((state.net.wgain, state.net.pdope_ms), (MP, jnp.float32(t_ms), jnp.float32(signal)))
    new = np.asarray(new)
    live = np.zeros(layout.n_syn, bool)
    live[:layout.n_plastic] = (pdope > NO_TAG_MS) & (t_ms - pdope <= float(MP.max_elig_tr_dur_ms))
    assert 50 < live.sum() < layout.n_plastic                  # a real mix of tagged and untagged synapses
    np.testing.assert_array_equal(new[~live], wgain[~live])   # nothing else moves, fixed pathways included
    assert np.all(np.sign(new[live] - wgain[live]) == signal)
    # the soft-bounded step, from the hand formula with each synapse's bound
    maxw = np.where(np.asarray(loop.plastic_tables), float(MP.plast_ee_maxw), float(MP.plast_ei_maxw))
    w, m, inc = wgain[:layout.n_plastic], maxw, float(MP.learn_rate)
    expected = w + inc * (1 - w / m) if signal > 0 else w - inc * w / m
    np.testing.assert_allclose(new[:layout.n_plastic][live[:layout.n_plastic]],
                               expected[live[:layout.n_plastic]], rtol=1e-6)


def reference_scaling(wgain, pre, base, n_cells):
    """The original's synScaling, per presynaptic cell (spec §4): S0 and S summed over the cells whose outgoing
    gains do not all vanish; every gain times S0/S if S0/S < 1. Written from the spec, in float64."""
    wgain, base = np.asarray(wgain, np.float64), np.asarray(base, np.float64)
    counted = np.zeros(n_cells, bool)
    total_gain = np.bincount(pre, weights=wgain, minlength=n_cells + 1)[:n_cells]
    counted[total_gain > 0] = True
    use = (pre < n_cells) & counted[np.minimum(pre, n_cells - 1)] & (base > 0)
    s0, s = base[use].sum(), (base * wgain)[use].sum()
    factor = min(1.0, s0 / s)
    return np.where(base > 0, wgain * factor, wgain), factor


def test_the_loops_synaptic_scaling_equals_the_per_cell_original():
    from jaxarm.loop import ClosedLoop

    loop = ClosedLoop()
    layout = loop.net.layout
    wiring = loop.net.make_wiring(jax.random.PRNGKey(0))
    pre = np.asarray(wiring.pre)[:layout.n_syn]
    base, _ = loop.rule.scaling_tables
    rng = np.random.default_rng(0)
    for spread in (0.8, 1.8):   # total shrunk (no scaling) and grown (scaled back)
        wgain = (rng.uniform(0.5, 1.0, layout.n_syn) * spread).astype(np.float32)
        expected, factor = reference_scaling(wgain, pre, base, loop.config.network.n_cells)
        got = np.asarray(loop.rule.scale(jnp.asarray(wgain), None))
        np.testing.assert_allclose(got, expected, rtol=2e-6)
        assert (factor < 1.0) == (spread > 1.0)
        if factor < 1.0:   # the total of the network's base weights is back at S0
            assert float((base * got).sum()) == pytest.approx(float(base.sum()), rel=1e-5)


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
    with pytest.raises(ConfigError, match="BabblingConfig.max_dt_ms"):
        BabblingConfig(max_dt_ms=50.0)


def test_a_rule_record_with_the_former_babbling_field_name_reads():
    # BabblingConfig.paper_max_dt_ms became max_dt_ms: a run folder's learning record written before still reads
    from jaxarm.learning.registry import rule_from_meta
    from jaxarm.learning.rstdp import RSTDPConfig

    old = {"learning": {"rule": "rstdp", "babbling": {"variant": "paper", "min_dt_ms": 100.0, "paper_max_dt_ms": 800.0,
                                                       "initial_dt_ms": 1000.0, "initial_rate_hz": 200.0,
                                                       "off_rate_hz": 50.0}, "plasticity": False}}
    assert rule_from_meta(old) == ("rstdp", RSTDPConfig(babbling=BabblingConfig(variant="paper", max_dt_ms=800.0),
                                                        plasticity=False))


# ---- metaparameters -------------------------------------------------------------------------------------------

def test_metaparams_hold_the_original_values():
    d = MP.to_dict()
    assert d["learn_rate"] == 0.04 and d["plast_ee_maxw"] == 7.85 and d["plast_ei_maxw"] == 5.0
    assert d["max_plast_t_ms"] == 69.57 and d["max_elig_tr_dur_ms"] == 62.28 and d["v_em_max"] == 117.92
    assert d["mcmd_spk_wd_ms"] == 76.08 and d["rl_dt_ms"] == 55.55 and d["random_muscle_dt_max_ms"] == 624.12
    assert d["em_noise_rate_train_hz"] == 152.76 and d["em_noise_rate_test_hz"] == 99.01
    assert d["syn_scaling_dt_ms"] == 5000.0 and d["explore_tot"] == 16.0 and len(d) == 16
    assert all(jnp.asarray(leaf).dtype == jnp.float32 for leaf in jax.tree_util.tree_leaves(MP))
    with pytest.raises(KeyError, match="learning_rate"):
        MetaParams.from_dict({"learning_rate": 0.1})


def test_sets_saved_before_the_target_code_names_load_with_them_at_1():
    from jaxarm.learning.metaparams import CODE_NAMES
    from jaxarm.paper.presets import check_metaparams

    old = {k: v for k, v in ORIGINAL.items() if k not in CODE_NAMES} | {"learn_rate": 0.05}
    assert len(old) == 13
    assert MetaParams.from_dict(old).to_dict() == {**ORIGINAL, "learn_rate": 0.05}
    assert check_metaparams(old, "best") == {**ORIGINAL, "learn_rate": 0.05}
    assert all(ORIGINAL[n] == 1.0 for n in CODE_NAMES)


def test_sets_saved_with_the_retired_names_load_without_them():
    # a set saved before max_w_scaling (no effect) and epochs (the protocol's) left the metaparameters
    old = {**ORIGINAL, "max_w_scaling": 0.7, "epochs": 6.0, "learn_rate": 0.05}
    assert MetaParams.from_dict(old).to_dict() == {**ORIGINAL, "learn_rate": 0.05}
    with pytest.raises(KeyError, match="max_w"):
        MetaParams.from_dict({"max_w": 0.7})


def _unread_metaparameters(train, test) -> list[str]:
    """The MetaParams fields that nothing in the traced training and test reads (jaxpr dead-code elimination); the
    check itself flags an extra input nothing reads."""
    from jax._src.interpreters import partial_eval as pe

    def train_and_test(mp, unread):
        trained, history = train(jax.random.PRNGKey(0), mp)
        return jax.tree.leaves((trained, history, test(jax.random.PRNGKey(1), trained, mp)))

    closed = jax.make_jaxpr(train_and_test)(MP, jnp.float32(0.0))
    _, used = pe.dce_jaxpr(closed.jaxpr, [True] * len(closed.jaxpr.outvars))
    names = [jax.tree_util.keystr(path) for path, _ in jax.tree_util.tree_flatten_with_path((MP, 0.0))[0]]
    assert len(names) == len(NAMES) + 1 and all(n in names[i] for i, n in enumerate(NAMES))
    unread = [name for name, u in zip(names, used) if not u]
    assert unread[-1:] == ["[1]"], "the check lost its unread input"
    return [name.split(".")[-1] for name in unread[:-1]]


@pytest.mark.parametrize("arm", ["simple", "musculoskeletal"])
def test_every_metaparameter_is_read_by_training_or_the_test(arm):
    """MetaParams holds only what the model reads: no field is dead code in the traced training and test (a field
    the kernel ignored, as max_w_scaling was, fails here), but the target code's three, which a network without a
    target code (the paper's) must not read."""
    from jaxarm.learning.metaparams import CODE_NAMES
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    fns = make_train(LoopConfig(arm=arm, task=TaskConfig(epochs=1, epoch_duration_s=0.3, test_duration_s=0.1)))
    assert _unread_metaparameters(fns.train, fns.test) == list(CODE_NAMES)


def test_a_network_with_a_target_code_reads_every_metaparameter():
    """The centre-out task's network (the paper's and a target code) reads all of them, the code's three included."""
    from jaxarm.loop import LoopConfig
    from jaxarm.run_centre_out import make_centre_out_train
    from jaxarm.config.network import NetworkConfig
    from jaxarm.config.spec import NetworkSpec
    from jaxarm.task.centre_out import CentreOut, with_target_code

    task = CentreOut(targets=("right", "left"), epochs_per_target=1, epoch_duration_s=0.3, test_duration_s=0.1)
    network = NetworkConfig(spec=with_target_code(NetworkSpec.dura_bernal_2015(), task))
    fns = make_centre_out_train(LoopConfig(arm="simple", network=network, task=task.task_config()), task)
    assert _unread_metaparameters(fns.train, fns.test) == []


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
