"""What training is made of, whatever the rule: the functions ``make_train`` returns (:class:`TrainFns`), what they
carry from epoch to epoch and leave (:class:`EpochCarry`, :class:`Trained`), what they report (:class:`EpochSummary`,
:class:`TestResult`), and the summaries' helpers. :mod:`jaxarm.train` builds them for the rules that learn inside
the loop's intervals; a rule with its own epoch loop (:mod:`jaxarm.learning.gradient`) builds the same ones here,
below the loop, without importing it (``jaxarm.train`` re-exports every name)."""
from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp


class Trained(NamedTuple):
    """What training leaves: the wiring (drawn from the key), the learned gains and the learning rule's state."""

    wiring: Any
    wgain: jnp.ndarray        # (n_syn,) dimensionless
    rule: Any                 # the rule's state across epochs (R-STDP's: the BabblingState)
    noise_key: jnp.ndarray    # the network's noise key (re-used every epoch by default)


class EpochCarry(NamedTuple):
    trained: Trained
    key: jnp.ndarray          # the learning rule's key stream (R-STDP's: babbling)
    epoch: jnp.ndarray        # () int32, epochs completed


class EpochSummary(NamedTuple):
    """Per epoch (leading axis = epoch under scan)."""

    rates_hz: jnp.ndarray          # (6,) mean firing rate of ES, IS, ISL, EM, IM, IML over the epoch, Hz
    rates_last10s_hz: jnp.ndarray  # (6,) the same over the epoch's last 10 s (the original model's convention)
    mean_wgain: jnp.ndarray        # (n_pathways,) mean gain per pathway at the end of the epoch
    final_distance_m: jnp.ndarray  # () hand–target distance at the end of the epoch, m
    min_distance_m: jnp.ndarray    # () closest approach during the epoch, m
    rewards: jnp.ndarray           # () critic rewards in the epoch
    punishments: jnp.ndarray       # () critic punishments
    lost_spikes: jnp.ndarray       # () spike-list overflow (must be 0)
    #: gradient learning only: every step of the epoch (jaxarm.learning.gradient.StepSummary, leading axis = step)
    gradient_steps: Any = None


class TestResult(NamedTuple):
    """The 1 s test of one trained network (T = test intervals of 10 ms); lengths in m, angles in rad."""

    hand_m: jnp.ndarray        # (T + 1, 2) hand positions at t = 0, 10, ..., 1000 ms, m
    q_rad: jnp.ndarray         # (T + 1, 2) joint angles, rad
    u: jnp.ndarray             # (T, 4) excitations
    distance_m: jnp.ndarray    # (T + 1,) hand–target distance, m
    min_distance_m: jnp.ndarray
    final_distance_m: jnp.ndarray
    success: jnp.ndarray       # () bool: entered the success circle
    rates_hz: jnp.ndarray      # (6,) firing rates in the test, Hz
    lost_spikes: jnp.ndarray
    record: Any = None         # jaxarm.record.Recording of the test when make_train was given a RecordConfig


class TrainFns(NamedTuple):
    """The pure functions of one configuration. ``target`` (a :class:`~jaxarm.task.config.Target`, traced) is
    optional everywhere: without it the task's named target; with it networks of one batch reach different targets."""

    loop: Any                 # the jaxarm.loop.ClosedLoop the functions run
    init: Callable            # key -> EpochCarry
    epoch: Callable           # (carry, mp[, target]) -> (carry, EpochSummary)
    train: Callable           # (key, mp[, target]) -> (Trained, EpochSummary stacked over epochs)
    test: Callable            # (key, Trained, mp[, target]) -> TestResult (with its record if recording)
    #: with RecordConfig.train_last_s > 0: (carry, mp[, target]) -> (carry, EpochSummary, Recording of the epoch's
    #: last train_last_s seconds); carry and summary equal ``epoch``'s
    epoch_recorded: Callable | None = None
    record: Any = None        # the RecordConfig (static), or None: nothing recorded, the loop compiled without it
    #: gradient learning only (``LoopConfig.gradient``): (carry, mp, target, k) -> (carry, (StepSummary, counts)),
    #: the k-th gradient step (jaxarm.learning.gradient)
    step: Callable | None = None
    #: gradient learning only: (gains, trained, mp, noise_key[, target]) -> (mean hand-target distance of one reach,
    #: m; (min, final distance, spike counts)), the loss a step differentiates (gains: the first n trained gains)
    reach_loss: Callable | None = None


def pop_rates(loop, counts, seconds):
    """(n_populations,) mean firing rate of each network population over ``seconds``, Hz, from the spike counts per
    cell (``loop``: the :class:`jaxarm.loop.ClosedLoop` that ran them)."""
    pops = loop.pops
    return jnp.stack([jnp.sum(counts[..., pops.slice(p)], axis=-1) / (loop.config.network.size(p) * seconds)
                      for p in loop.config.network.spec.network_populations])


def mean_gain_per_pathway(layout, wgain):
    """(n_pathways,) mean gain of each pathway's synapses."""
    pathway_of = jnp.asarray(layout.pathway_of_synapse())
    return jax.ops.segment_sum(wgain, pathway_of, num_segments=len(layout.in_degree)) / jnp.asarray(
        [layout.config.size(pw.post) * layout.in_degree[pw.name] for pw in layout.pathways], jnp.float32)
