"""The authors' fitness for the search ([model: metaparameters](../model.md#metaparameters)): train one network per
target, test it, worst target's distance.

Per target the distance is the mean of the test's hand–target distance at ~20 ms and at its last sample (the
original's ``trajAccuracy`` with a 2-element index list); the fitness is the maximum over targets, in m (lower is
better). ``success_rate`` (fraction of targets whose test entered the 4 cm circle) is reported beside it.

``reaching-closest`` is the same search with each target scored by its closest approach during the test instead:
the quantity the paper's success criterion (closest approach < 4 cm) looks at. The authors' fitness penalises a hand
that passes through the target and leaves it; this one does not (the paper's test has no stopping mechanism).

``reaching-shortfall`` aims at the paper's statistic, the number of networks per target that enter the circle: each
target is scored by how far its closest approach stays outside a circle ``SHORTFALL_MARGIN_M`` smaller than the
success circle (0 when the hand entered it with that much to spare), and the targets are averaged instead of taking
the worst, so a candidate gains from every network that reaches, on either target, and the target that misses by
more weighs more. With ``--seeds-per-candidate N`` (seeds averaged) it is the candidate's expected shortfall, m. Two variants:
``reaching-shortfall-2cm`` shrinks the circle by 2 cm (to 2 cm): once most candidates enter the 3 cm circle on every
evaluation the 1 cm version scores them all 0 and can no longer rank them; ``reaching-shortfall-worst`` takes the
worst target instead of the mean, for an arm whose targets pull the metaparameters apart (a set that trades one
target for the other scores no better than its weaker target). ``reaching-stay`` adds to the 2 cm shortfall how far
the hand strays outside the success circle after first entering it, so a search prefers controllers that stay.

``centre-out`` scores one network trained on several targets at once (:mod:`jaxarm.task.centre_out`: the targets
alternate epoch by epoch and a target code tells the network which one is current; ``--task centre-out-8`` gives
the original's eight): the mean over targets of the 2 cm shortfall, every target tested on the same trained network.
The network gets the default target code (:func:`~jaxarm.task.centre_out.with_target_code`) unless its spec
already has one. ``success_rate`` is then the fraction of targets entered.

The training length per evaluation is static (it sets the compiled loop's length): ``train_s`` seconds, run as
``round(train_s / 30)`` epochs of 30 s (or one shorter epoch when ``train_s < 30``), so the ``epochs``
metaparameter is ignored (the CLI freezes it).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxarm.evolve import fitness
from jaxarm.learning.metaparams import CODE_NAMES
from jaxarm.loop import LoopConfig
from jaxarm.task.config import TaskConfig

EPOCH_S = 30.0


def _task(target: str, train_s: float) -> TaskConfig:
    if train_s < EPOCH_S:
        return TaskConfig(target=target, epochs=1, epoch_duration_s=train_s)
    return TaskConfig(target=target, epochs=max(1, round(train_s / EPOCH_S)), epoch_duration_s=EPOCH_S)


def _authors_distance(distance_m, radius_m):
    """The original's trajAccuracy: mean of the distance at ~20 ms (sample 2) and at the last sample, m."""
    return 0.5 * (distance_m[2] + distance_m[-1])


def _closest_distance(distance_m, radius_m):
    """The closest approach during the test, m: what the paper's success criterion (< 4 cm) looks at."""
    return jnp.min(distance_m)


SHORTFALL_MARGIN_M = 0.01


def _shortfall(distance_m, radius_m, margin_m=SHORTFALL_MARGIN_M):
    """How far the closest approach stays outside the circle of ``radius_m - margin_m``, m (0 inside)."""
    return jnp.maximum(jnp.min(distance_m) - (radius_m - margin_m), 0.0)


def _shortfall_with_margin(margin_m: float):
    """``_shortfall`` with another margin, m: a deeper circle keeps ranking candidates that all enter the 3 cm one."""
    def per_target(distance_m, radius_m):
        return _shortfall(distance_m, radius_m, margin_m)
    return per_target


def _reach_and_stay(distance_m, radius_m, margin_m=0.02):
    """Reaching and staying, m: the closest approach's shortfall from the circle ``margin_m`` inside the success
    circle (as ``reaching-shortfall-2cm``) plus how far, on average, the hand is outside the success circle from its
    first entry to the end of the test (0 for a hand that enters and stays; 0 when it never enters, where the
    shortfall scores it). The paper's trained arms "slow down and stay near the target" (mean distance after entry
    3.9 and 3.2 cm); a controller that sweeps through the target scores the excursions beyond 4 cm."""
    inside = distance_m <= radius_m
    entered = jnp.any(inside)
    after = (jnp.arange(distance_m.shape[0]) >= jnp.argmax(inside)) & entered
    outside = jnp.maximum(distance_m - radius_m, 0.0)
    stay = jnp.sum(jnp.where(after, outside, 0.0)) / jnp.maximum(jnp.sum(after), 1)
    return _shortfall(distance_m, radius_m, margin_m) + stay


def make_reaching(options: fitness.FitnessOptions, per_target=_authors_distance, combine=jnp.max) -> fitness.Fitness:
    """Train and test one network per target; ``per_target(distance_m, radius_m)`` scores a test's distance trace,
    ``combine`` reduces the targets' scores (the authors': the worst, ``jnp.max``)."""
    from jaxarm.train import make_train

    train_s = 360.0 if options.train_s is None else float(options.train_s)
    network = options.network_config()
    fns = [make_train(LoopConfig(arm=options.arm, network=network, task=_task(t, train_s))) for t in options.targets]

    radius_m = fns[0].loop.config.task.success_radius_m

    def fn(key, mp):
        dist, success, lost = [], [], jnp.zeros((), jnp.int32)
        for f, k in zip(fns, jax.random.split(key, len(fns))):  # a few targets: unrolled
            k_train, k_test = jax.random.split(k)
            trained, history = f.train(k_train, mp)
            result = f.test(k_test, trained, mp)
            dist.append(per_target(result.distance_m, radius_m))
            success.append(result.success)
            lost = lost + jnp.sum(history.lost_spikes) + result.lost_spikes + trained.wiring.out_overflow
        # a fixed-capacity overflow (lost spike or synapse) is an error: the evaluation fails (NaN: counted and
        # reported as a failed evaluation, ranked last)
        value = jnp.where(lost > 0, jnp.nan, combine(jnp.stack(dist)))
        return value, {"success_rate": jnp.mean(jnp.stack(success).astype(jnp.float32))}

    test_s = fns[0].loop.config.task.test_duration_s
    return fitness.Fitness(fn, network_seconds_per_eval=len(options.targets) * (train_s + test_s),
                           ignores=() if network.spec.target_codes else CODE_NAMES,
                           epochs=fns[0].loop.config.task.epochs)


def _centre_out_task(targets, train_s: float):
    """The CentreOut protocol of ``train_s`` seconds in all: ``round(train_s / (30 x n))`` epochs of 30 s per target
    (at least one, shorter when ``train_s < 30 x n``)."""
    from jaxarm.task.centre_out import CentreOut

    n = len(targets)
    per_target = max(1, round(train_s / (EPOCH_S * n)))
    return CentreOut(targets=tuple(targets), epochs_per_target=per_target,
                     epoch_duration_s=min(EPOCH_S, train_s / (per_target * n)))


def make_centre_out(options: fitness.FitnessOptions, margin_m: float = 0.02) -> fitness.Fitness:
    """Train one network on all ``options.targets`` (alternating, with a target code), test it on each; the mean
    over targets of how far the closest approach stays outside the circle ``margin_m`` inside the success circle."""
    import dataclasses

    from jaxarm.run_centre_out import make_centre_out_train
    from jaxarm.task.centre_out import ensure_target_code

    train_s = 8 * 3 * EPOCH_S if options.train_s is None else float(options.train_s)
    task = _centre_out_task(options.targets, train_s)
    network = options.network_config()
    network = dataclasses.replace(network, spec=ensure_target_code(network.spec, task))
    fns = make_centre_out_train(LoopConfig(arm=options.arm, network=network, task=task.task_config()), task)
    radius_m = task.success_radius_m

    def fn(key, mp):
        k_train, k_test = jax.random.split(key)
        trained, history = fns.train(k_train, mp)
        result = fns.test(k_test, trained, mp)                       # leading target axis
        short = jax.vmap(lambda d: _shortfall(d, radius_m, margin_m))(result.distance_m)
        lost = jnp.sum(history.lost_spikes) + jnp.sum(result.lost_spikes) + trained.wiring.out_overflow
        value = jnp.where(lost > 0, jnp.nan, jnp.mean(short))
        return value, {"success_rate": jnp.mean(result.success.astype(jnp.float32))}

    cfg = task.task_config()
    return fitness.Fitness(fn, network_seconds_per_eval=cfg.epochs * cfg.epoch_duration_s
                           + len(task.targets) * cfg.test_duration_s,
                           epochs=task.epochs_per_target)   # as this task's --epochs counts them: per target


fitness.register("reaching", make_reaching, "worst target's test hand-target distance, m (the authors' fitness)")
fitness.register("reaching-closest", lambda options: make_reaching(options, _closest_distance),
                 "worst target's closest approach in the test, m (the paper's success criterion, not its fitness)")
fitness.register("reaching-shortfall", lambda options: make_reaching(options, _shortfall, jnp.mean),
                 "mean over targets of how far the closest approach stays outside the success circle shrunk by "
                 "1 cm, m (0 = every target entered with 1 cm to spare; aims at the paper's success counts)")
fitness.register("reaching-shortfall-2cm", lambda options: make_reaching(options, _shortfall_with_margin(0.02),
                                                                          jnp.mean),
                 "as reaching-shortfall with the circle shrunk by 2 cm (to 2 cm): keeps ranking candidates that all "
                 "enter the 3 cm circle")
fitness.register("reaching-shortfall-worst", lambda options: make_reaching(options, _shortfall, jnp.max),
                 "as reaching-shortfall with the worst target instead of the mean over targets")
fitness.register("reaching-stay", lambda options: make_reaching(options, _reach_and_stay, jnp.mean),
                 "mean over targets of reaching-shortfall-2cm plus the mean distance outside the success circle "
                 "after first entering it, m (0 = every target entered within 2 cm and never left the circle)")
fitness.register("centre-out", make_centre_out,
                 "one network trained on all --targets in turn (a target code says which is current; --task "
                 "centre-out-8), tested on each: mean over targets of how far the closest approach stays outside the "
                 "2 cm circle, m")
