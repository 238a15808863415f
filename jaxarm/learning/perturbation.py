"""Weight perturbation: REINFORCE on the plastic gains (Fiete & Seung 2006 style), a learning rule
(:mod:`jaxarm.learning.rule`) in one module.

At every critic moment (t - last > rl_dt_ms, as R-STDP's critic) the rule

1. takes the reward r: how much the critic's error (the hand-target distance, m) fell since the last critic moment;
2. moves the mean gains along the perturbation that reward is credited to,
   ``w += learning_rate * (r - baseline) * xi / sigma``, clipped to R-STDP's range (plastic E->E in [0,
   plast_ee_maxw], E->I in [0, plast_ei_maxw]), and the baseline (a running mean of r) toward r;
3. draws a fresh perturbation xi ~ N(0, 1) per plastic synapse and runs the next critic period with the gains
   ``w + sigma * xi`` (clipped the same way).

Over perturbations, E[(r - baseline) xi] / sigma is the slope of the reward along the gains, so the mean update
climbs it. The reward credited to a perturbation is that of ``credit_delay`` critic periods later: the motor readout
counts EM spikes 60-130 ms before the arm moves (``mcmd_spk_wd_ms`` plus the 50 ms lag), so a perturbation held for
one 60 ms period moves the hand in the next one. No babbling: the perturbations explore, and the EM noise is the
test's (``em_noise_rate_test_hz`` to every group), as gradient learning's. What an epoch trains is the mean gains
``w`` (the test runs them unperturbed); the baseline is carried from epoch to epoch.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.batching import when_any
from jaxarm.config.validate import check_range
from jaxarm.learning import babbling as bab
from jaxarm.learning import critic as crit
from jaxarm.learning.rule import LearningRule, plastic_upper


@dataclass(frozen=True)
class PerturbationConfig:
    """Static form of weight perturbation.

    Attributes:
        sigma: standard deviation of a perturbation, in units of a gain (every gain starts at 1).
        learning_rate: step of the mean gains, in gain per m of reward above the baseline (per unit of xi / sigma);
            3 was the best of 0.3, 1, 3 and 10 on docs/extending.md's task at 60 s (10 silences the arm).
        baseline_rate: fraction of the way the baseline moves toward each reward (a running mean over about
            1 / baseline_rate critic moments).
        credit_delay: critic periods between a perturbation's period and the period whose reward is credited to it
            (1: the readout's lag; 0: the same period, for a plant without lag).
    """

    sigma: float = 0.1
    learning_rate: float = 3.0
    baseline_rate: float = 0.1
    credit_delay: int = 1

    def __post_init__(self):
        check_range(self, "sigma", 0.0, 10.0, lo_open=True)
        check_range(self, "learning_rate", 0.0, 1e6, lo_open=True)
        check_range(self, "baseline_rate", 0.0, 1.0, lo_open=True)
        check_range(self, "credit_delay", 0, 10, integer=True)


class PerturbationState(NamedTuple):
    """Carried from epoch to epoch."""

    baseline_m: jnp.ndarray    # () running mean of the reward, m


class PerturbationRun(NamedTuple):
    """Within an epoch."""

    w: jnp.ndarray             # (n_plastic,) the mean gains (the network runs w + sigma * xi[0])
    xi: jnp.ndarray            # (credit_delay + 1, n_plastic) the last perturbations, newest first
    baseline_m: jnp.ndarray    # () running mean of the reward, m
    err_last_m: jnp.ndarray    # () the critic's error at the last critic moment, m (NaN before the first)
    last_rl_ms: jnp.ndarray    # () time of the last critic moment, ms


class WeightPerturbation(LearningRule):
    Config = PerturbationConfig
    summary = ("REINFORCE on the plastic gains: Gaussian perturbations at every critic moment, the mean gains moved "
               "by the distance gained (Fiete & Seung 2006 style)")

    def init(self, key) -> PerturbationState:
        return PerturbationState(baseline_m=jnp.zeros((), jnp.float32))

    def begin_epoch(self, state: PerturbationState, wgain, mp):
        n = self.loop.net.layout.n_plastic
        run = PerturbationRun(w=wgain[:n], xi=jnp.zeros((self.config.credit_delay + 1, n), jnp.float32),
                              baseline_m=state.baseline_m, err_last_m=jnp.full((), jnp.nan, jnp.float32),
                              last_rl_ms=jnp.zeros((), jnp.float32))
        return run, bab.em_noise_rates_in_test(mp)

    def end_epoch(self, run: PerturbationRun, net, mp):
        return PerturbationState(baseline_m=run.baseline_m), net.wgain.at[: run.w.shape[0]].set(run.w)

    def _step(self, x, aux):
        """One critic moment: learn from the reward, then perturb anew. x = (run, wgain, signal)."""
        (run, wgain, _), (mp, key, err_m) = x, aux
        c = self.config
        # no reward before the first critic moment of an epoch: the arm restarted
        r = jnp.where(jnp.isnan(run.err_last_m), run.baseline_m, run.err_last_m - err_m)
        advantage = r - run.baseline_m
        upper = plastic_upper(self.loop.plastic_tables, mp)
        w = jnp.clip(run.w + c.learning_rate * advantage * run.xi[-1] / c.sigma, 0.0, upper)
        xi = jax.random.normal(key, run.w.shape, jnp.float32)
        run = run._replace(w=w, xi=jnp.concatenate([xi[None], run.xi[:-1]]),
                           baseline_m=run.baseline_m + c.baseline_rate * (r - run.baseline_m), err_last_m=err_m)
        wgain = wgain.at[: w.shape[0]].set(jnp.clip(w + c.sigma * xi, 0.0, upper))
        return run, wgain, jnp.sign(advantage)

    def update(self, run: PerturbationRun, net, key, moment, mp):
        due = crit.rl_update_due(moment.t_ms, run.last_rl_ms, mp.rl_dt_ms)
        run, wgain, signal = when_any(due, self._step, (run, net.wgain, jnp.zeros((), jnp.float32)),
                                      (mp, key, moment.err_m))
        run = run._replace(last_rl_ms=jnp.where(due, moment.t_ms, run.last_rl_ms))
        return run, net._replace(wgain=wgain), signal

    @classmethod
    def add_arguments(cls, group) -> None:
        d = PerturbationConfig()
        group.add_argument("--perturbation-sigma", type=float, default=d.sigma, metavar="SIGMA",
                           help=f"weight-perturbation: standard deviation of a perturbation, per unit gain "
                                f"(default {d.sigma:g})")
        group.add_argument("--perturbation-lr", type=float, default=d.learning_rate, metavar="LR",
                           help=f"weight-perturbation: step of the mean gains, gain per m of reward above the "
                                f"baseline (default {d.learning_rate:g})")

    @classmethod
    def config_from_arguments(cls, args) -> PerturbationConfig:
        return PerturbationConfig(sigma=args.perturbation_sigma, learning_rate=args.perturbation_lr)
