"""Gradient learning on the reaching task: the same network, arm and test as R-STDP, the gains trained by Adam on
the reaching loss through the closed loop (network -> readout -> arm -> distance to target).

    fns = make_train(LoopConfig(arm="simple", learning="gradient"))   # the same TrainFns as R-STDP's
    trained, history = jax.jit(fns.train)(key, MetaParams.original())
    result = jax.jit(fns.test)(key, trained, MetaParams.original())      # R-STDP's test, the same code

How it differs from R-STDP training (and why):

* spikes carry a surrogate derivative (``NetworkConfig.spike_gradient = "fast_sigmoid"``,
  :mod:`jaxarm.network.surrogate`); forward, the network fires exactly as under R-STDP's XLA kernel;
* an epoch is a sequence of **reaches**, not one 30 s run: each gradient step runs one reach of
  ``GradientConfig.reach_s`` from the start posture (cells at rest, no R-STDP inside it) with the test's EM noise
  (no babbling: the gradient, not noise, explores), and descends the mean hand-target distance (m) over it. An
  epoch of ``epoch_duration_s`` holds ``epoch_duration_s / reach_s`` steps, so the budget in network-seconds is
  the R-STDP protocol's and ``jaxarm train`` checkpoints and resumes by epoch as it does for R-STDP;
* every training reach has background noise of its own, drawn from the network's noise key in a domain of its own
  (:data:`TRAIN_NOISE_FOLD`, then the step number), so no reach is trained on the noise of any test: not the test's
  (the key itself, restarted as the original does) nor the fresh-noise re-tests' (the key folded with 1000 + j);
* the test is R-STDP's, the same code on the same configuration: the published arm (not the smooth one the
  gradient trains through) and the configuration's kernel (``config.network.kernel``, native by default), so the
  two rules' networks are scored alike;
* the history keeps every step's loss, gradient norm and whether it was skipped (:class:`StepSummary`, in
  ``EpochSummary.gradient_steps``);
* the gains stay in R-STDP's range: plastic E->E in [0, plast_ee_maxw], E->I in [0, plast_ei_maxw]; with
  ``params = "all"`` every synapse's gain but P->ES is trained, in [0, plast_ee_maxw].
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from jaxarm.config.gradient import GradientConfig
from jaxarm.config.validate import ConfigError
from jaxarm.learning import babbling as bab
from jaxarm.learning.metaparams import MetaParams
from jaxarm.learning.rule import LearningRule, plastic_upper
from jaxarm.learning.training import EpochSummary, TrainFns, mean_gain_per_pathway, pop_rates
from jaxarm.task.config import Target

if TYPE_CHECKING:   # the loop imports the rule registry, which imports this module
    from jaxarm.loop import LoopConfig


#: What a training reach's noise key is folded with before its step number: a domain no test key is drawn from.
TRAIN_NOISE_FOLD = 0x67726164   # "grad"


class GradientCarry(NamedTuple):
    """What gradient training carries from epoch to epoch (``.trained`` as R-STDP's EpochCarry)."""

    trained: Any              # jaxarm.learning.training.Trained
    opt_state: Any            # Adam's state over the trained gains
    epoch: jnp.ndarray        # () int32, epochs completed


class StepSummary(NamedTuple):
    """Per gradient step (leading axis = step)."""

    loss_m: jnp.ndarray            # () mean hand-target distance over the reach, m
    min_distance_m: jnp.ndarray    # () closest approach in the reach, m
    final_distance_m: jnp.ndarray  # () distance at the end of the reach, m
    grad_norm: jnp.ndarray         # () norm of the loss gradient over the trained gains, m per unit gain (inf/NaN:
    #                                skipped)
    finite: jnp.ndarray            # () bool: the gradient was finite (else the step was skipped)


def differentiable_config(config: LoopConfig, grad: GradientConfig | None = None) -> LoopConfig:
    """The loop gradient training runs (``grad``, default the configuration's own or ``GradientConfig()``):
    surrogate spikes (XLA kernel) and the smooth musculoskeletal arm. Not the test's: that is
    :func:`published_config`."""
    grad = grad or (config.rule_config if config.learning == "gradient" else GradientConfig())
    network = dataclasses.replace(config.network, spike_gradient="fast_sigmoid", surrogate_width_mv=grad.width_mv,
                                  surrogate_scale=grad.scale, kernel="xla")
    return dataclasses.replace(config, network=network, smooth_arm=config.arm == "musculoskeletal",
                               learning="gradient", rule=grad)


def published_config(config: LoopConfig) -> LoopConfig:
    """The loop every network is tested on, whatever trained it: spikes without surrogate, the published arm, the
    configuration's kernel; the default rule, whose ``make_train`` runs the loop's test (no rule acts in a test)."""
    network = dataclasses.replace(config.network, spike_gradient="none")
    return dataclasses.replace(config, network=network, smooth_arm=False, learning="rstdp", rule=None)


def make_gradient_train(config: LoopConfig, record, interval_train):
    """:func:`jaxarm.train.make_train` for a ``config`` with ``learning = "gradient"`` (it calls this, with
    ``interval_train`` = :func:`jaxarm.train.make_interval_train`, which builds the loop and R-STDP's test): the
    same :class:`~jaxarm.learning.training.TrainFns` (init, epoch, train, test), with gradient epochs (see the
    module docstring) and R-STDP's test on :func:`published_config`, and ``step(carry, mp, target, k)`` -> (carry,
    (StepSummary, spike counts)), the k-th gradient step alone."""
    grad = config.rule_config
    tested = interval_train(published_config(config), record)
    config = differentiable_config(config, grad)
    if record is not None and record.train_last_s > 0:
        raise ConfigError("--record-train-s with gradient learning: training runs reaches, not recorded epochs "
                          "(record the test only)")
    base = interval_train(dataclasses.replace(config, learning="rstdp", rule=None))
    loop, task = base.loop, config.task
    reach = round(grad.reach_s / task.update_interval_s)
    per_epoch = round(task.epoch_duration_s / grad.reach_s)
    if abs(reach * task.update_interval_s - grad.reach_s) > 1e-9 or abs(per_epoch * grad.reach_s
                                                                         - task.epoch_duration_s) > 1e-9:
        raise ConfigError(f"GradientConfig.reach_s = {grad.reach_s:g}: must be a multiple of "
                          f"{task.update_interval_s * 1000:g} ms that divides the epoch, {task.epoch_duration_s:g} s")
    layout = loop.net.layout
    n_train = layout.n_plastic if grad.params == "plastic" else layout.offset["P->ES"]
    is_ee = loop.plastic_tables if grad.params == "plastic" else None
    # a diverged surrogate gradient (inf/NaN) skips its step, never poisons the gains: optax's guard, never giving up
    optimiser = optax.apply_if_finite(optax.adam(grad.learning_rate), max_consecutive_errors=2 ** 30)
    last10 = min(per_epoch, max(1, round(10.0 / grad.reach_s)))

    def upper(mp: MetaParams):
        if is_ee is None:
            return jnp.asarray(mp.plast_ee_maxw, jnp.float32)
        return plastic_upper(jnp.asarray(is_ee), mp)

    def init(key) -> GradientCarry:
        trained = base.init(key).trained
        return GradientCarry(trained, optimiser.init(trained.wgain[:n_train]), jnp.zeros((), jnp.int32))

    def reach_loss(gains, trained, mp: MetaParams, noise_key, target: Target | None = None):
        """Mean hand-target distance (m) of one reach with background noise ``noise_key`` and the first
        ``n_train`` gains replaced by ``gains``; aux: (min, final distance, spike counts (n_all,))."""
        state = loop.init(noise_key, trained.wgain.at[:n_train].set(gains), None,
                          bab.em_noise_rates_in_test(mp), target, mp.code_rate_scale)
        # the loop's keys feed the learning rule only, which a reach without learning does not run
        state, rec = loop.run(trained.wiring, state, jax.random.key(0), mp, reach, learn=False)
        dist = jnp.linalg.norm(rec.hand_m - state.target.xy_m, axis=-1)
        return jnp.mean(dist), (jnp.min(dist), dist[-1], state.net.spike_count)

    def step(carry: GradientCarry, mp: MetaParams, target: Target | None, k):
        trained = carry.trained
        noise_key = jax.random.fold_in(jax.random.fold_in(trained.noise_key, TRAIN_NOISE_FOLD), k)
        (value, (closest, final, counts)), g = jax.value_and_grad(reach_loss, has_aux=True)(
            trained.wgain[:n_train], trained, mp, noise_key, target)
        updates, opt_state = optimiser.update(g, carry.opt_state)   # zero updates on a skipped step
        w = jnp.clip(optax.apply_updates(trained.wgain[:n_train], updates), 0.0, upper(mp))
        carry = carry._replace(trained=trained._replace(wgain=trained.wgain.at[:n_train].set(w)),
                               opt_state=opt_state)
        return carry, (StepSummary(value, closest, final, jnp.linalg.norm(g), opt_state.last_finite), counts)

    def epoch(carry: GradientCarry, mp: MetaParams, target: Target | None = None):
        first = carry.epoch * per_epoch
        carry, (steps, counts) = jax.lax.scan(lambda c, i: step(c, mp, target, first + i), carry,
                                              jnp.arange(per_epoch))
        wgain = carry.trained.wgain
        summary = EpochSummary(
            rates_hz=pop_rates(loop, counts.sum(0), per_epoch * grad.reach_s),
            rates_last10s_hz=pop_rates(loop, counts[-last10:].sum(0), last10 * grad.reach_s),
            mean_wgain=mean_gain_per_pathway(layout, wgain), final_distance_m=steps.final_distance_m[-1],
            min_distance_m=steps.min_distance_m.min(), rewards=jnp.zeros((), jnp.int32),
            punishments=jnp.zeros((), jnp.int32), lost_spikes=jnp.zeros((), jnp.int32), gradient_steps=steps)
        return carry._replace(epoch=carry.epoch + 1), summary

    def train(key, mp: MetaParams, target: Target | None = None):
        carry, history = jax.lax.scan(lambda c, _: epoch(c, mp, target), init(key), None, length=task.epochs)
        return carry.trained, history

    return TrainFns(loop=loop, init=init, epoch=epoch, train=train, test=tested.test, record=record, step=step,
                    reach_loss=reach_loss)


class GradientLearning(LearningRule):
    """Gradient learning behind the rule interface: it trains by whole reaches, not in the loop's intervals, so it
    replaces the epoch loop (:func:`make_gradient_train`) instead of implementing the interval hooks."""

    Config = GradientConfig
    summary = ("Adam on the mean hand-target distance of 1 s reaches, through surrogate spikes and the arm, with the "
               "same network-seconds (docs/gradients.md)")
    make_train = staticmethod(make_gradient_train)

    @classmethod
    def add_arguments(cls, group) -> None:
        d = GradientConfig()
        group.add_argument("--gradient-lr", type=float, default=d.learning_rate, metavar="LR",
                           help=f"gradient learning: Adam's step size, per unit gain (default {d.learning_rate})")
        group.add_argument("--reach-s", type=float, default=d.reach_s, metavar="S",
                           help=f"gradient learning: length of one training reach (one step), s (default "
                                f"{d.reach_s:g})")
        group.add_argument("--gradient-params", choices=("plastic", "all"), default=d.params,
                           help="gradient learning: the gains trained: plastic (those R-STDP trains, default) or all")

    @classmethod
    def config_from_arguments(cls, args) -> GradientConfig:
        return GradientConfig(learning_rate=args.gradient_lr, reach_s=args.reach_s, params=args.gradient_params)
