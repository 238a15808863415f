"""Learning rules behind one interface (issue 47): R-STDP as a rule equals the loop's code before the interface to the
bit, the registry feeds the configuration and the command line, and weight perturbation, a rule of one module,
climbs a finite-difference slope and trains end to end on both arms."""
import json
import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.batching import when_any
from jaxarm.config.gradient import GradientConfig
from jaxarm.config.validate import ConfigError
from jaxarm.learning import babbling as bab
from jaxarm.learning import critic as crit
from jaxarm.learning import stdp
from jaxarm.learning.metaparams import MetaParams
from jaxarm.learning.perturbation import PerturbationConfig, WeightPerturbation
from jaxarm.learning.registry import RULES, learning_meta, rule_from_meta
from jaxarm.learning.rstdp import RSTDPConfig
from jaxarm.learning.rule import Moment
from jaxarm.loop import LoopConfig
from jaxarm.network import noise as noise_mod
from jaxarm.network import readout as ro
from jaxarm.task.config import TaskConfig
from jaxarm.train import make_train


# ---- R-STDP through the interface against the frozen code it replaced -------------------------------------------

class FrozenState(NamedTuple):
    """The loop state before the rule interface (commit 676bc43)."""

    net: Any
    arm: Any
    readout: Any
    babble: bab.BabblingState
    err_hist_m: jnp.ndarray
    last_rl_ms: jnp.ndarray
    last_scaling_ms: jnp.ndarray
    target: Any


def frozen_interval(loop, wiring, state: FrozenState, key, mp):
    """``ClosedLoop.interval(learn=True)`` as it was before the rule interface, R-STDP written into the loop (copied,
    not imported: the reference must not move with the code under test)."""
    c = loop.config
    n_plastic = loop.net.layout.n_plastic
    base, s0 = loop.rule.scaling_tables    # static tables, numpy

    def reinforce(x, aux):
        (wgain, pdope), (mp, t_ms, signal) = x, aux
        maxw = jnp.where(loop.plastic_tables, mp.plast_ee_maxw, mp.plast_ei_maxw)
        w_plastic, pdope = stdp.dopamine_update(wgain[:n_plastic], pdope, True, maxw, mp.learn_rate, t_ms, signal,
                                                mp.max_elig_tr_dur_ms, config=stdp.EligibilityConfig())
        return wgain.at[:n_plastic].set(w_plastic), pdope

    def scale(wgain, _):
        factor = s0 / jnp.maximum(jnp.dot(base, wgain), 1e-12)
        return jnp.where((base > 0) & (factor < 1.0), wgain * factor, wgain)

    def set_em_rates(noise, rates_hz):
        return noise_mod.set_em_rates(c.network, noise, rates_hz)

    net, _ = loop.net.run(wiring, state.net, loop.net_params(mp), loop.steps_per_interval)
    em_counts = ro.em_group_counts(c.network, net.spike_count - state.net.spike_count)
    readout = ro.push(state.readout, em_counts)
    t_ms = readout.pushes.astype(jnp.float32) * c.network.interface_ms
    u = ro.excitation(c.network, readout, v_em_max=mp.v_em_max, window_ms=mp.mcmd_spk_wd_ms)
    arm_state = loop._move_arm(state.arm, u)
    obs = loop.arm.observe(arm_state)
    err = loop._critic_error(obs, state.target)
    net = loop.net.set_lengths(net, obs.proprio)
    due = crit.rl_update_due(t_ms, state.last_rl_ms, mp.rl_dt_ms)
    signal = jnp.where(due, crit.critic_signal(state.err_hist_m[0], state.err_hist_m[1]), 0.0)
    wgain, pdope = when_any(signal != 0, reinforce, (net.wgain, net.pdope_ms), (mp, t_ms, signal))
    scale_due = (t_ms - state.last_scaling_ms) >= mp.syn_scaling_dt_ms
    wgain = when_any(scale_due, scale, wgain)
    net = net._replace(wgain=wgain, pdope_ms=pdope)
    last_scaling = jnp.where(scale_due, t_ms, state.last_scaling_ms)
    new_babble, rates = bab.babble(key, state.babble, t_ms, mp, config=bab.BabblingConfig())
    babble = jax.tree_util.tree_map(lambda a, b: jnp.where(due, a, b), new_babble, state.babble)
    net = net._replace(noise=when_any(due, set_em_rates, net.noise, rates))
    last_rl = jnp.where(due, t_ms, state.last_rl_ms)
    state = FrozenState(net=net, arm=arm_state, readout=readout, babble=babble,
                        err_hist_m=jnp.stack([state.err_hist_m[1], err]), last_rl_ms=last_rl,
                        last_scaling_ms=last_scaling, target=state.target)
    return state, (obs.hand, signal)


def frozen_train(fns, key, mp, epochs):
    """``make_train(config).train`` as it was (epochs of at most 10 s: one segment of keys), on the frozen
    interval. Returns (gains, babbling state, hand (epochs, intervals, 2), critic signals)."""
    loop = fns.loop
    n = loop.config.task.epoch_steps
    k_wire, k_noise, k_babble = jax.random.split(key, 3)
    wiring = loop.net.make_wiring(k_wire)
    wgain, babble = jnp.ones((loop.net.layout.n_syn,), jnp.float32), bab.init_babbling()
    hands, signals = [], []
    for e in range(epochs):
        babble = bab.start_epoch(babble)
        s = loop.init(k_noise, wgain, None, babble.rates_hz)
        zero = jnp.zeros((), jnp.float32)
        s = FrozenState(s.net, s.arm, s.readout, babble, s.err_hist_m, zero, zero, s.target)
        _, k2 = jax.random.split(jax.random.fold_in(k_babble, e))
        s, (hand, signal) = jax.lax.scan(lambda st, k: frozen_interval(loop, wiring, st, k, mp), s,
                                         jax.random.split(k2, n))
        wgain, babble = s.net.wgain, s.babble
        hands.append(hand)
        signals.append(signal)
    return wgain, babble, jnp.stack(hands), jnp.stack(signals)


def rule_hands(fns, key, mp, epochs):
    """The hand paths of the same epochs through the loop with its rule (``make_train``'s epoch, its keys)."""
    loop, n = fns.loop, fns.loop.config.task.epoch_steps
    carry = fns.init(key)
    tr, hands = carry.trained, []
    for e in range(epochs):
        run, em_rates_hz = loop.rule.begin_epoch(tr.rule, tr.wgain, mp)
        s = loop.init(tr.noise_key, tr.wgain, run, em_rates_hz)
        _, k2 = jax.random.split(jax.random.fold_in(carry.key, e))
        s, rec = loop.run_keys(tr.wiring, s, jax.random.split(k2, n), mp, learn=True)
        rule_state, wgain = loop.rule.end_epoch(s.rule, s.net, mp)
        tr = tr._replace(wgain=wgain, rule=rule_state)
        hands.append(rec.hand_m)
    return jnp.stack(hands)


@pytest.mark.parametrize("arm", ["simple", pytest.param("musculoskeletal", marks=pytest.mark.slow)])
def test_rstdp_as_a_rule_trains_to_the_bit_as_the_loop_did_before(arm):
    # Two networks (vmap: the batch-skipping updates), two epochs of 1.2 s, scaling every 0.5 s so it runs in each
    # epoch, the critic and babbling at every 60 ms: gains, babbling, hand paths and signals equal to the bit.
    epochs = 2
    fns = make_train(LoopConfig(arm=arm, task=TaskConfig(epochs=epochs, epoch_duration_s=1.2)))
    mp = MetaParams.from_dict({"syn_scaling_dt_ms": 500.0, "random_muscle_dt_max_ms": 300.0})
    keys = jnp.stack([jax.random.PRNGKey(i) for i in range(2)])
    trained, history = jax.jit(jax.vmap(fns.train, in_axes=(0, None)))(keys, mp)
    wgain, babble, hand, signal = jax.jit(jax.vmap(lambda k: frozen_train(fns, k, mp, epochs)))(keys)
    np.testing.assert_array_equal(np.asarray(trained.wgain), np.asarray(wgain))
    for a, b in zip(jax.tree.leaves(trained.rule), jax.tree.leaves(babble)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    np.testing.assert_array_equal(np.asarray(jax.jit(jax.vmap(lambda k: rule_hands(fns, k, mp, epochs)))(keys)),
                                  np.asarray(hand))
    np.testing.assert_array_equal(np.asarray(history.rewards), np.sum(np.asarray(signal) > 0, axis=-1))
    np.testing.assert_array_equal(np.asarray(history.punishments), np.sum(np.asarray(signal) < 0, axis=-1))
    # the protocol exercised what it should: rewards, punishments, scaling and a babbling change
    assert np.all(np.asarray(history.rewards).sum(0) > 0) and np.all(np.asarray(history.punishments) > 0)
    assert np.all(np.asarray(trained.rule.last_change_ms) > 0)
    assert float(np.abs(np.asarray(trained.wgain) - 1.0).max()) > 0.01


# ---- the registry --------------------------------------------------------------------------------------------------

def test_the_registry_names_the_rules_and_checks_configurations_in_one_line():
    assert list(RULES) == ["rstdp", "gradient", "weight-perturbation"]
    with pytest.raises(ConfigError, match=r"^LoopConfig.learning = 'hebb': must be one of 'rstdp', 'gradient', "
                                          r"'weight-perturbation'$"):
        LoopConfig(learning="hebb")
    with pytest.raises(ConfigError, match=r"LoopConfig.rule = .*must be None or a PerturbationConfig"):
        LoopConfig(learning="weight-perturbation", rule=RSTDPConfig())
    with pytest.raises(ConfigError, match="PerturbationConfig.sigma"):
        PerturbationConfig(sigma=0.0)
    with pytest.raises(ConfigError, match="RSTDPConfig.plasticity"):
        RSTDPConfig(plasticity=1)
    # the gradient shorthand is stored as the rule it names
    short = LoopConfig(gradient=GradientConfig(reach_s=0.5))
    assert short == LoopConfig(learning="gradient", rule=GradientConfig(reach_s=0.5)) and short.gradient is None
    assert LoopConfig(rule=RSTDPConfig()) == LoopConfig() and LoopConfig().rule_config == RSTDPConfig()
    assert hash(LoopConfig(learning="weight-perturbation", rule=PerturbationConfig(sigma=0.2)))


def test_a_run_folder_records_its_rule_and_reads_it_back():
    assert learning_meta("rstdp", RSTDPConfig()) == {}     # the default: folders read as before the registry
    for name, config in (("gradient", GradientConfig(reach_s=0.5)), ("weight-perturbation", PerturbationConfig()),
                         ("rstdp", RSTDPConfig(babbling=bab.BabblingConfig(variant="paper"), plasticity=False))):
        meta = json.loads(json.dumps(learning_meta(name, config)))
        assert rule_from_meta(meta) == (name, config)
    # a gradient folder from before the registry: its record without the rule's name
    old = {"learning": {"learning_rate": 0.05, "reach_s": 1.0, "params": "plastic", "width_mv": 2.0, "scale": 0.05}}
    assert rule_from_meta(old) == ("gradient", GradientConfig())
    assert rule_from_meta({}) == ("rstdp", RSTDPConfig())


def test_the_command_line_takes_its_learning_choices_from_the_registry():
    from jaxarm.cli import parser

    ap = parser("train")
    action = next(a for a in ap._actions if a.dest == "learning")
    assert tuple(action.choices) == tuple(RULES) and action.default == "rstdp"
    args = ap.parse_args(["--out", "x", "--learning", "weight-perturbation", "--perturbation-sigma", "0.2"])
    assert RULES[args.learning].config_from_arguments(args) == PerturbationConfig(sigma=0.2)


def test_a_checkpoint_written_before_the_rename_reads_into_the_new_structure(tmp_path):
    # Trained.babble became Trained.rule: a run folder from before resumes and re-tests (jaxarm.checkpoint)
    from jaxarm.checkpoint import Checkpointer
    from jaxarm.train import EpochCarry, Trained

    class OldTrained(NamedTuple):
        wiring: Any
        wgain: Any
        babble: Any
        noise_key: Any

    babble = bab.init_babbling()._replace(pattern=jnp.asarray(5, jnp.int32))
    old = EpochCarry(OldTrained(jnp.arange(3), jnp.full(4, 2.0), babble, jax.random.PRNGKey(7)), jax.random.PRNGKey(1),
                     jnp.asarray(3, jnp.int32))
    with Checkpointer(tmp_path) as ckpt:
        ckpt.save(3, old, {"epochs": 3})
    like = EpochCarry(Trained(jnp.zeros(3, jnp.int32), jnp.zeros(4), bab.init_babbling(), jax.random.PRNGKey(0)),
                      jax.random.PRNGKey(0), jnp.asarray(0, jnp.int32))
    with Checkpointer(tmp_path) as ckpt:
        new, meta = ckpt.restore(like)
    assert isinstance(new.trained, Trained) and meta == {"epochs": 3}
    for a, b in zip(jax.tree.leaves(new), jax.tree.leaves(old)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


# ---- weight perturbation -------------------------------------------------------------------------------------------

class ToyNet(NamedTuple):
    wgain: jnp.ndarray


def test_weight_perturbation_moves_the_gains_down_the_finite_difference_slope():
    # A plant without lag (credit_delay 0): the error is a quadratic of the three gains the network runs. From w0,
    # the first learning step of many independent perturbations, averaged, has the sign of minus the error's slope,
    # taken by central differences (independently of the rule), and about its size times the learning rate.
    scale, centre = jnp.array([3.0, 0.5, 1.0]), jnp.array([0.5, 1.4, 1.0])

    def error_m(w):
        return 0.01 * jnp.sum(scale * (w - centre) ** 2)

    w0 = np.array([1.0, 1.0, 1.3])
    h = 1e-3
    slope = np.array([(error_m(w0 + h * e) - error_m(w0 - h * e)) / (2 * h) for e in np.eye(3)])
    loop = SimpleNamespace(net=SimpleNamespace(layout=SimpleNamespace(n_plastic=3)),
                           plastic_tables=np.array([True, True, False]))
    config = PerturbationConfig(sigma=0.02, learning_rate=1.0, credit_delay=0)
    rule = WeightPerturbation(config, loop)
    mp = MetaParams.original()

    def first_step(key):
        run, _ = rule.begin_epoch(rule.init(None), jnp.asarray(w0, jnp.float32), mp)
        net = ToyNet(jnp.asarray(w0, jnp.float32))
        for i, t_ms in enumerate((60.0, 120.0)):   # perturb at the first critic moment, learn at the second
            moment = Moment(jnp.float32(t_ms), jnp.zeros(2), error_m(net.wgain))
            run, net, _ = rule.update(run, net, jax.random.fold_in(key, i), moment, mp)
        return run.w - w0

    # 8000 perturbations: a batch of arrays over 2**15 elements hits an XLA:CPU miscompile in jaxlib 0.10.2 (a
    # fused sum-and-broadcast wrong from row 10922 of a (12000, 3) array on; issue 47's report has the reproducer)
    steps = np.asarray(jax.jit(jax.vmap(first_step))(jax.random.split(jax.random.PRNGKey(0), 8000)))
    mean, sem = steps.mean(0), steps.std(0) / np.sqrt(len(steps))
    assert np.all(np.sign(mean) == -np.sign(slope)), (mean, slope)
    assert np.all(np.abs(mean + config.learning_rate * slope) < 4 * sem + 0.1 * np.abs(slope)), (mean, slope, sem)


def test_weight_perturbation_runs_perturbed_and_keeps_the_mean_gains():
    # Inside the loop: at every critic moment the network runs the mean gains plus a fresh perturbation within
    # R-STDP's bounds, the fixed pathways untouched; the epoch keeps the mean gains, the baseline carries over.
    fns = make_train(LoopConfig(learning="weight-perturbation", task=TaskConfig(epochs=1, epoch_duration_s=0.3)))
    loop, mp = fns.loop, MetaParams.original()
    n = loop.net.layout.n_plastic
    carry = fns.init(jax.random.PRNGKey(0))
    tr = carry.trained
    run, rates = loop.rule.begin_epoch(tr.rule, tr.wgain, mp)
    np.testing.assert_array_equal(np.asarray(rates), np.full(4, np.float32(mp.em_noise_rate_test_hz)))
    state = loop.init(tr.noise_key, tr.wgain, run, rates)
    state, rec = jax.jit(lambda s: loop.run(tr.wiring, s, jax.random.PRNGKey(1), mp, 30, learn=True))(state)
    perturbed = np.asarray(state.net.wgain)
    upper = np.where(loop.plastic_tables, float(mp.plast_ee_maxw), float(mp.plast_ei_maxw))
    assert np.all(perturbed[:n] >= 0) and np.all(perturbed[:n] <= upper) and np.all(perturbed[n:] == 1.0)
    assert 0.05 < np.std(perturbed[:n] - np.asarray(state.rule.w)) < 0.15    # sigma 0.1, some clipped at 0
    assert float(state.rule.last_rl_ms) == 300.0 and int(np.sum(np.asarray(rec.critic) != 0)) > 0
    rule_state, wgain = loop.rule.end_epoch(state.rule, state.net, mp)
    np.testing.assert_array_equal(np.asarray(wgain[:n]), np.asarray(state.rule.w))
    assert float(rule_state.baseline_m) == float(state.rule.baseline_m) != 0.0


@pytest.mark.parametrize("arm", ["simple", pytest.param("musculoskeletal", marks=pytest.mark.slow)])
def test_jaxarm_train_learning_weight_perturbation_trains_and_retests(arm, tmp_path, capsys):
    from jaxarm.experiment import test_main, train_main

    out = tmp_path / arm
    assert train_main(["--learning", "weight-perturbation", "--arm", arm, "--networks", "2", "--epochs", "2",
                       "--epoch-s", "0.3", "--test-s", "0.2", "--perturbation-lr", "50", "--no-progress",
                       "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())
    assert res["config"]["learning"] == {"rule": "weight-perturbation", "sigma": 0.1, "learning_rate": 50.0,
                                         "baseline_rate": 0.1, "credit_delay": 1}
    assert res["history"]["lost_spikes"] == 0 and len(res["networks"]) == 2
    assert test_main(["--from", str(out), "--test-s", "0.2"]) == 0
    again = json.loads((out / "test" / "results.json").read_text())
    assert [n["min_distance_m"] for n in again["networks"]] == [n["min_distance_m"] for n in res["networks"]]
    capsys.readouterr()


# ---- docs/extending.md's worked examples ---------------------------------------------------------------------------

def extending_blocks() -> list[str]:
    """The python blocks of docs/extending.md, in order: the new rule, the new arm, the new task."""
    page = (Path(__file__).resolve().parents[1] / "docs" / "extending.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, flags=re.S)
    assert len(blocks) == 3, len(blocks)
    return blocks


def test_the_worked_example_of_docs_extending_runs(capsys):
    # the page's python block as written: a rule defined, registered, trained and tested (two networks, 2 x 1 s)
    block = extending_blocks()[0]
    scope = {"__name__": "extending"}
    try:
        exec(compile(block, "docs/extending.md", "exec"), scope)
    finally:
        RULES.pop("critic-hebb", None)
    history, trained = scope["history"], scope["trained"]
    assert int(np.sum(history.rewards + history.punishments)) > 0                 # the critic spoke
    assert float(jnp.abs(trained.wgain - 1.0).max()) > 0.01                          # and the gains moved
    assert "closest approach in the test" in capsys.readouterr().out


@pytest.mark.slow   # a third compiled loop: the default suite's 8-minute budget
def test_the_new_arm_of_docs_extending_trains_and_moves_with_inertia(capsys):
    # the page's second block as written: an arm defined, registered, trained and tested (two networks, 2 x 1 s)
    from jaxarm.arm.registry import ARMS

    scope = {"__name__": "extending"}
    try:
        exec(compile(extending_blocks()[1], "docs/extending.md", "exec"), scope)
    finally:
        ARMS.pop("inertial", None)
    arm, result = scope["InertialArm"](), scope["result"]
    assert "closest approach in the test" in capsys.readouterr().out
    assert np.all(np.isfinite(np.asarray(result.hand_m)))
    # inertia by hand: one full flexor command from rest moves the shoulder by gain x dt / tau (not by gain)
    s = arm.step(arm.init(jnp.array([0.62, 1.53])), jnp.array([0.0, 1.0, 0.0, 0.0]))
    gain, dt, tau = arm.config.gain_rad, arm.dt_s, arm.config.tau_s
    assert float(s.q[0]) == pytest.approx(0.62 + gain / dt * (dt / tau) * dt, rel=1e-5)
    # and, commanded to stop, it keeps moving (a first-order lag): the second step still moves the shoulder
    s2 = arm.step(s, jnp.zeros(4))
    assert float(s2.q[0]) > float(s.q[0])


@pytest.mark.slow   # a compiled loop of its own: the default suite's 8-minute budget
def test_the_new_task_of_docs_extending_trains_through_the_runner(capsys):
    # the page's third block as written: a curriculum task trained and tested by the runner (two networks, 2 x 1 s)
    from jaxarm.arm.base import hand_position
    from jaxarm.task.config import Target

    scope = {"__name__": "extending"}
    exec(compile(extending_blocks()[2], "docs/extending.md", "exec"), scope)
    assert "closest approach to the real target" in capsys.readouterr().out
    assert np.all(np.isfinite(np.asarray(scope["result"].min_distance_m)))
    # the schedule by hand: epoch 0 trains toward the joint-space midpoint, epoch 1 (of a ramp of 2) the target
    task = scope["task"]
    seen = []
    epoch = task.epoch(lambda carry, mp, target: seen.append(target))
    real = task.network_target()
    q0 = np.asarray(task.reach.start_posture_rad, np.float32)
    for e, f in ((0, 0.5), (1, 1.0), (5, 1.0)):
        epoch(SimpleNamespace(epoch=jnp.int32(e)), None, Target(jnp.asarray(real.xy_m), jnp.asarray(real.q_rad)))
        q = q0 + f * (np.asarray(real.q_rad) - q0)
        np.testing.assert_allclose(np.asarray(seen[-1].q_rad), q, rtol=1e-6)
        np.testing.assert_allclose(np.asarray(seen[-1].xy_m), np.asarray(hand_position(q)), atol=1e-6)
    np.testing.assert_allclose(np.asarray(seen[-1].xy_m), np.asarray(real.xy_m), atol=1e-6)
