"""Training and testing in the PureJaxRL style: ``make_train(config)`` returns pure functions.

    train_fns = make_train(LoopConfig(arm="simple"))
    trained, history = jax.jit(train_fns.train)(key, MetaParams.original())
    result = jax.jit(train_fns.test)(key, trained, MetaParams.original())

``train`` and ``test`` are pure functions of (key, [trained,] metaparams): ``vmap`` them over keys (networks) and
over metaparameter sets alike. ``train`` is ``lax.scan`` over epochs of :func:`TrainFns.epoch`; the command line runs
the same ``epoch`` function one epoch per call so a killed run resumes from its last completed epoch with identical
results.

Protocol ([model: task](../model.md#task-and-success)): each epoch is a fresh run of the network (cells, tags and noise
streams reset; weights kept) and of the arm (start posture); the learning rule's state carries over (R-STDP's babbling
draws continue). The test is 1 s without learning, with every EM group receiving ``em_noise_rate_test_hz`` of AMPA
noise. The rule is ``config.learning`` (:mod:`jaxarm.learning.rule`): ``make_train`` calls its ``init``, ``begin_epoch``
and ``end_epoch``, the loop its ``update`` after every training interval. The types it returns are
:mod:`jaxarm.learning.training`'s (re-exported here).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxarm.config.validate import ConfigError
from jaxarm.learning import babbling as bab
from jaxarm.learning.metaparams import MetaParams
from jaxarm.learning.registry import RULES
from jaxarm.learning.training import (EpochCarry, EpochSummary, TestResult, Trained, TrainFns,  # noqa: F401
                                     mean_gain_per_pathway, pop_rates)
from jaxarm.loop import ClosedLoop, LoopConfig
from jaxarm.network import noise as noise_mod
from jaxarm.task.config import Target


#: What the rule's key stream is folded with for its ``init``: a domain no epoch (folded with its number) draws from.
RULE_INIT_FOLD = 0x72756C65   # "rule"


def fresh_noise(trained: Trained, j: int) -> Trained:
    """The same trained networks with fresh background-noise streams: each network's noise key folded with
    ``1000 + j`` (the test re-uses the training streams otherwise, as the original does; gradient learning's
    training reaches draw from a domain of their own, so these streams are held out from every rule)."""
    return trained._replace(noise_key=jax.vmap(lambda k: jax.random.fold_in(k, 1000 + j))(trained.noise_key))


def make_train(config: LoopConfig = LoopConfig(), record=None) -> TrainFns:
    """Build the pure training and test functions of one static configuration.

    Args:
        config (LoopConfig): the static configuration (arm, network, task, babbling, clock step in ms); compiled
            into the functions, so it is not traced.
        record (jaxarm.record.RecordConfig | None): static spike recording. With it, the test also returns a
            :class:`jaxarm.record.Recording` (spikes of every cell, the arm, the muscles) and, with
            ``record.train_last_s`` > 0, ``epoch_recorded`` records an epoch's last seconds. Without it (the
            default) the compiled loop holds no recording at all.

    Returns:
        TrainFns: ``init(key)``, ``epoch(carry, mp[, target])``, ``train(key, mp[, target])`` (all
        ``config.task.epochs`` epochs under ``lax.scan``) and ``test(key, trained, mp[, target])`` (the 1 s test
        without learning). ``key`` is a JAX PRNG key (a network's wiring, noise and babbling), ``mp`` a
        :class:`~jaxarm.learning.metaparams.MetaParams` (each field in its own unit: ms, Hz or dimensionless).
        Each is pure: ``jit`` it and ``vmap`` it over keys (networks), metaparameter sets or targets. A rule with its
        own ``make_train`` (gradient learning, :mod:`jaxarm.learning.gradient`) builds the same functions its way,
        given :func:`make_interval_train` to build the loop's and the test's.
    """
    own = RULES[config.learning].make_train
    if own is not None:
        return own(config, record, make_interval_train)
    return make_interval_train(config, record)


def make_interval_train(config: LoopConfig = LoopConfig(), record=None) -> TrainFns:
    """:func:`make_train` of a rule that learns inside the loop's intervals (``init``, ``begin_epoch``, ``update``,
    ``end_epoch``; :mod:`jaxarm.learning.rule`), whatever ``config.learning`` says: the epoch loop and the 1 s test
    every rule's networks are tested with."""
    from jaxarm import record as rec_mod

    loop = ClosedLoop(config)
    rule = loop.rule
    net, task = loop.net, config.task
    n_intervals = task.epoch_steps
    last10_intervals = min(n_intervals, round(10.0 / task.update_interval_s))
    layout = net.layout

    def init(key) -> EpochCarry:
        k_wire, k_noise, k_rule = jax.random.split(key, 3)
        wiring = net.make_wiring(k_wire)
        trained = Trained(wiring=wiring, wgain=jnp.ones((layout.n_syn,), jnp.float32),
                          rule=rule.init(jax.random.fold_in(k_rule, RULE_INIT_FOLD)), noise_key=k_noise)
        return EpochCarry(trained=trained, key=k_rule, epoch=jnp.zeros((), jnp.int32))

    n_all = config.network.n_all
    rec_intervals = 0
    if record is not None and record.train_last_s > 0:
        rec_intervals = round(record.train_last_s / task.update_interval_s)
        if not 1 <= rec_intervals <= n_intervals or abs(rec_intervals * task.update_interval_s
                                                        - record.train_last_s) > 1e-9:
            raise ConfigError(f"--record-train-s {record.train_last_s:g}: must be a multiple of "
                              f"{task.update_interval_s * 1000:g} ms and at most the epoch, "
                              f"{task.epoch_duration_s:g} s")
        rec_mod.check_window(n_all, loop.steps_per_interval, rec_intervals, "--record-train-s")
    if record is not None:
        rec_mod.check_window(n_all, loop.steps_per_interval, task.test_steps, "--test-s")

    def _recorded_segments(tr, state, k1, k2, mp):
        """The epoch's intervals as ``epoch`` runs them (the same keys, the same order), the last ``rec_intervals``
        recorded. Returns (state, IntervalRecord, spike counts after the first segment, Recording)."""
        n1 = n_intervals - last10_intervals
        start = n_intervals - rec_intervals
        start_step = start * loop.steps_per_interval
        buf = rec_mod.empty(record.capacity(n_all, rec_intervals * config.network.interface_ms))
        parts, window, counts0, counts_mid = [], [], None, None
        for keys, lo in ((jax.random.split(k1, n1), 0), (jax.random.split(k2, last10_intervals), n1)):
            n = keys.shape[0]
            cut = min(max(start - lo, 0), n)
            if cut > 0:
                state, r = loop.run_keys(tr.wiring, state, keys[:cut], mp, learn=True)
                parts.append(r)
            if cut < n:
                if counts0 is None:
                    counts0 = state.net.spike_count
                state, r, buf, _ = loop.run_recorded(tr.wiring, state, keys[cut:], mp, True, buf, start_step,
                                                     muscles=False)
                parts.append(r)
                window.append(r)
            if counts_mid is None:
                counts_mid = state.net.spike_count
        cat = lambda rs: jax.tree_util.tree_map(lambda *a: jnp.concatenate(a), *rs)  # noqa: E731
        rec, win = cat(parts), cat(window)
        return state, rec, counts_mid, rec_mod.Recording(spikes=buf, counts=state.net.spike_count - counts0,
                                                         hand_m=win.hand_m, q_rad=win.q_rad, u=win.u)

    def epoch(carry: EpochCarry, mp: MetaParams, target: Target | None = None):
        return _epoch(carry, mp, target, False)

    def epoch_recorded(carry: EpochCarry, mp: MetaParams, target: Target | None = None):
        return _epoch(carry, mp, target, True)

    def _epoch(carry: EpochCarry, mp: MetaParams, target: Target | None, recorded: bool):
        tr = carry.trained
        noise_key = jax.random.fold_in(tr.noise_key, carry.epoch) if config.reseed_noise_each_epoch else tr.noise_key
        run, em_rates_hz = rule.begin_epoch(tr.rule, tr.wgain, mp)
        state = loop.init(noise_key, tr.wgain, run, em_rates_hz, target, mp.code_rate_scale)
        k_epoch = jax.random.fold_in(carry.key, carry.epoch)
        # Run all but the last 10 s, snapshot the spike counts, run the rest: rates over the last 10 s as the spec.
        k1, k2 = jax.random.split(k_epoch)
        if recorded:
            state, rec, counts_mid, recording = _recorded_segments(tr, state, k1, k2, mp)
        else:
            state, rec1 = loop.run(tr.wiring, state, k1, mp, n_intervals - last10_intervals, learn=True)
            counts_mid = state.net.spike_count
            state, rec2 = loop.run(tr.wiring, state, k2, mp, last10_intervals, learn=True)
            rec = jax.tree_util.tree_map(lambda a, b: jnp.concatenate([a, b]), rec1, rec2)
        counts = state.net.spike_count
        dist = jnp.linalg.norm(rec.hand_m - state.target.xy_m, axis=-1)
        rule_state, wgain = rule.end_epoch(state.rule, state.net, mp)
        mean_w = mean_gain_per_pathway(layout, wgain)
        summary = EpochSummary(
            rates_hz=pop_rates(loop, counts, task.epoch_duration_s),
            rates_last10s_hz=pop_rates(loop, counts - counts_mid, last10_intervals * task.update_interval_s),
            mean_wgain=mean_w, final_distance_m=dist[-1], min_distance_m=dist.min(),
            rewards=jnp.sum(rec.critic > 0), punishments=jnp.sum(rec.critic < 0),
            lost_spikes=state.net.counters.lost_spikes)
        trained = tr._replace(wgain=wgain, rule=rule_state)
        carry = EpochCarry(trained=trained, key=carry.key, epoch=carry.epoch + 1)
        return (carry, summary, recording) if recorded else (carry, summary)

    def train(key, mp: MetaParams, target: Target | None = None):
        carry = init(key)
        carry, history = jax.lax.scan(lambda c, _: epoch(c, mp, target), carry, None, length=task.epochs)
        return carry.trained, history

    def test(key, trained: Trained, mp: MetaParams, target: Target | None = None) -> TestResult:
        rates = bab.em_noise_rates_in_test(mp)
        # The original re-seeds the noise streams identically at every run(), the test included.
        state = loop.init(trained.noise_key, trained.wgain, None, rates, target, mp.code_rate_scale)
        if task.test_em_noise_events == "netstim":
            # a NetStim stops once its event count reaches number = tstop * rate / 1000 (a real number)
            number = task.test_duration_s * jnp.asarray(mp.em_noise_rate_test_hz, jnp.float32)
            state = state._replace(net=state.net._replace(noise=noise_mod.limit_em_events(
                config.network, state.net.noise, jnp.ceil(number - 1e-4).astype(jnp.int32))))
        hand0, q0 = loop.arm.observe(state.arm).hand, loop.arm.observe(state.arm).q
        recording = None
        if record is None:
            state, rec = loop.run(trained.wiring, state, key, mp, task.test_steps, learn=False)
        else:
            buf = rec_mod.empty(record.capacity(n_all, task.test_steps * config.network.interface_ms))
            state, rec, buf, muscles = loop.run_recorded(trained.wiring, state, jax.random.split(key, task.test_steps),
                                                         mp, False, buf, 0)
            recording = rec_mod.Recording(spikes=buf, counts=state.net.spike_count, hand_m=rec.hand_m,
                                          q_rad=rec.q_rad, u=rec.u, muscles=muscles)
        hand = jnp.concatenate([hand0[None], rec.hand_m])
        q = jnp.concatenate([q0[None], rec.q_rad])
        dist = jnp.linalg.norm(hand - state.target.xy_m, axis=-1)
        return TestResult(hand_m=hand, q_rad=q, u=rec.u, distance_m=dist, min_distance_m=dist.min(),
                          final_distance_m=dist[-1], success=jnp.any(dist <= task.success_radius_m),
                          rates_hz=pop_rates(loop, state.net.spike_count, task.test_duration_s),
                          lost_spikes=state.net.counters.lost_spikes, record=recording)

    return TrainFns(loop=loop, init=init, epoch=epoch, train=train, test=test,
                    epoch_recorded=epoch_recorded if rec_intervals else None, record=record)
