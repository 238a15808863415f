"""The closed loop of [model: closed loop](../model.md#the-closed-loop): network ↔ arm every 10 ms, with the learning
rule in training.

One interface period (``interval``) at time t (ms since the start of the run), in the original's order:

1. the network runs 10 ms (its own dt inside, ms/mV units);
2. the EM spikes of those 10 ms are pushed into the readout history, and the readout gives 4 excitations from the
   spikes in (t − 130, t − 60] ms ÷ v_em_max;
3. the arm advances 10 ms under those excitations (SI units: m, s, rad);
4. the hand–target distance (m) is computed; the 4 proprioceptive lengths (m) update the P code;
5. training only: the learning rule's ``update`` (:mod:`jaxarm.learning.rule`; R-STDP's critic, dopamine update,
   synaptic scaling and babbling by default, :mod:`jaxarm.learning.rstdp`) sees the time, the stored distances
   and the new one, and may change the network's gains, tags and noise;
6. the distance is appended to the history.

Everything is a pure function of (state, key, metaparameters) so it can be ``vmap``-ed over networks and over
metaparameter sets and ``lax.scan``-ned over intervals and epochs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.arm import make_arm
from jaxarm.arm.registry import ARMS, BACKENDS
from jaxarm.config.gradient import GradientConfig
from jaxarm.config.network import NetworkConfig
from jaxarm.config.validate import ConfigError, check_choice
from jaxarm.learning.metaparams import BOUNDS, MetaParams
from jaxarm.learning.registry import DEFAULT, RULES
from jaxarm.learning.rule import Moment
from jaxarm.network import readout as ro
from jaxarm.network.network import Network, NetworkParams
from jaxarm.network.populations import Populations
from jaxarm.task.config import Target, TaskConfig

#: Longest run (epoch or test) in network clock steps: float32 times step * dt keep a quarter-step resolution.
MAX_RUN_STEPS = 2 ** 22


@dataclass(frozen=True)
class LoopConfig:
    """Static structure of a closed-loop run.

    Attributes:
        arm: a name of :data:`jaxarm.arm.registry.ARMS`: "simple" (the authors' kinematic arm, their default) or
            "musculoskeletal".
        backend: geometry backend of the musculoskeletal arm, "fast" or "mjx".
        network, task: the sub-configurations.
        reseed_noise_each_epoch: False (the original) restarts the background-noise streams identically at every
            epoch; True draws fresh streams per epoch.
        learning: the learning rule, a name of :data:`jaxarm.learning.registry.RULES`: "rstdp" (default: R-STDP
            with babbling, the paper's), "gradient" (gradient descent through the loop, which trains on its
            differentiable version of this configuration and tests on this one) or "weight-perturbation".
        rule: that rule's static configuration (its ``Config``, e.g. :class:`~jaxarm.learning.rstdp.RSTDPConfig`
            with R-STDP's babbling, eligibility and plasticity switch); None: its defaults (:attr:`rule_config`;
            the defaults given explicitly are stored as None).
        gradient: shorthand for ``learning="gradient", rule=gradient`` (a
            :class:`~jaxarm.config.gradient.GradientConfig`); stored that way, so it reads None afterwards.
        smooth_arm: the musculoskeletal arm's C-infinity formulation (``make_arm(..., smooth=True)``), for
            gradients through the loop (``docs/gradients.md``); the simple arm is smooth already.
        critic_error: what the critic compares 10 ms apart: "xy" (the original's training setting, XYERR: the
            hand-target distance, m, 1 mm threshold) or "angle" (not what the original trained with: the joint-space
            distance to the target posture, rad, sqrt(d_shoulder^2 + d_elbow^2), with the same numeric threshold,
            0.001 rad). A diagnostic: with "xy", elbow flexion alone also brings the hand toward the left target,
            so it is rewarded though it cannot get there (experiments/joint_excursions.py).
    """

    arm: str = "simple"
    backend: str = "fast"
    network: NetworkConfig = field(default_factory=NetworkConfig)
    task: TaskConfig = field(default_factory=TaskConfig)
    reseed_noise_each_epoch: bool = False
    critic_error: str = "xy"
    smooth_arm: bool = False
    learning: str = DEFAULT
    rule: Any = None
    gradient: GradientConfig | None = None

    def __post_init__(self):
        check_choice(self, "arm", ARMS)
        check_choice(self, "critic_error", ("xy", "angle"))
        check_choice(self, "backend", BACKENDS)
        if self.gradient is not None:
            if not isinstance(self.gradient, GradientConfig):
                raise ConfigError(f"LoopConfig.gradient = {self.gradient!r}: must be None or a GradientConfig")
            if self.learning not in (DEFAULT, "gradient") or self.rule is not None:
                raise ConfigError(f"LoopConfig.gradient = {self.gradient!r} with learning = {self.learning!r}, "
                                  f"rule = {self.rule!r}: give gradient alone, or learning and rule")
            object.__setattr__(self, "learning", "gradient")
            object.__setattr__(self, "rule", self.gradient)
            object.__setattr__(self, "gradient", None)
        check_choice(self, "learning", RULES)
        kind = RULES[self.learning].Config
        if self.rule is not None and not isinstance(self.rule, kind):
            raise ConfigError(f"LoopConfig.rule = {self.rule!r}: must be None or a {kind.__name__} (learning = "
                              f"{self.learning!r})")
        if self.rule == kind():   # one spelling of the defaults, so equal configurations compare and hash equal
            object.__setattr__(self, "rule", None)
        for name in ("reseed_noise_each_epoch", "smooth_arm"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"LoopConfig.{name} = {getattr(self, name)!r}: must be True or False")
        if abs(self.network.interface_ms - 1000.0 * self.task.update_interval_s) > 1e-9:
            raise ConfigError(f"LoopConfig: network.interface_ms = {self.network.interface_ms} must equal "
                              f"task.update_interval_s = {self.task.update_interval_s} s")
        # Spike and tag times are float32 ms (step * dt): exact to a quarter step up to 2**22 steps per run.
        for name in ("epoch_duration_s", "test_duration_s"):
            seconds = getattr(self.task, name)
            if seconds * 1000.0 / self.network.dt_ms > MAX_RUN_STEPS:
                raise ConfigError(f"TaskConfig.{name} = {seconds:g} s: at NetworkConfig.dt_ms = {self.network.dt_ms:g} "
                                  f"a run may be at most {MAX_RUN_STEPS * self.network.dt_ms / 1000.0:g} s (2**22 "
                                  "steps: float32 spike times resolve a quarter step up to there)")
        window_hi = BOUNDS["mcmd_spk_wd_ms"].hi + ro.LAG_MS
        if (self.network.readout_bins - 1) * self.network.interface_ms < window_hi:
            raise ConfigError(f"NetworkConfig.readout_bins = {self.network.readout_bins}: the readout history must "
                              f"reach back {window_hi:g} ms (mcmd_spk_wd_ms up to {BOUNDS['mcmd_spk_wd_ms'].hi:g} ms "
                              f"plus the {ro.LAG_MS:g} ms lag): at least "
                              f"{math.ceil(window_hi / self.network.interface_ms) + 1} bins")

    @property
    def rule_config(self):
        """The learning rule's static configuration: :attr:`rule`, or the rule's defaults."""
        return RULES[self.learning].Config() if self.rule is None else self.rule


class LoopState(NamedTuple):
    net: Any                    # network State (ms/mV inside)
    arm: Any                    # arm state (SI)
    readout: ro.ReadoutState
    rule: Any                   # the learning rule's state within the run (None in a test)
    err_hist_m: jnp.ndarray     # (2,) the critic's error at the last two interface times, older first: hand–target
    #                             distance, m (rad, joint-space distance, with LoopConfig.critic_error = "angle")
    target: Target              # where this network reaches (traced, so networks of a batch may differ)


class IntervalRecord(NamedTuple):
    """What one 10 ms interval leaves behind (time-major under scan)."""

    hand_m: jnp.ndarray       # (2,) hand position after the arm moved, m
    q_rad: jnp.ndarray        # (2,) joint angles, rad
    u: jnp.ndarray            # (4,) excitations sent to the arm
    em_counts: jnp.ndarray    # (4,) EM spikes per group in this interval
    critic: jnp.ndarray       # () the rule's signal: +1 reward, -1 punishment, 0 none (always 0 in the test)


class ClosedLoop:
    """Pure functions of one closed-loop configuration."""

    def __init__(self, config: LoopConfig = LoopConfig()):
        self.config = config
        self.net = Network(config.network)
        self.arm = make_arm(config.arm, backend=config.backend,
                            smooth=config.smooth_arm and ARMS[config.arm].smooth)
        arm_dt_ms = self.arm.dt_s * 1000.0
        self.arm_steps = int(round(config.network.interface_ms / arm_dt_ms))
        if abs(self.arm_steps * arm_dt_ms - config.network.interface_ms) > 1e-6:
            raise ConfigError(f"arm step {arm_dt_ms} ms does not divide the interface period "
                              f"{config.network.interface_ms} ms")
        self.start_q = jnp.asarray(config.task.start_posture_rad, jnp.float32)
        self.steps_per_interval = config.network.steps_per_interface
        self.pops = Populations(config.network)

    # -- static per-synapse tables and the learning rule ------------------------------------------------------
    @cached_property
    def plastic_tables(self):
        """Per plastic synapse: whether it ends on an excitatory cell (E->E, bounded by plast_ee_maxw; else E->I,
        by plast_ei_maxw), from the pathway of each synapse."""
        layout = self.net.layout
        spec = self.net.config.spec
        pw = layout.pathway_of_synapse()[: layout.n_plastic]
        is_ee = np.array([spec.output(layout.pathways[i].post) == "excitatory" for i in pw])
        return is_ee  # numpy: a cached jax array would leak from the first trace that built it

    @cached_property
    def rule(self):
        """The learning rule (:mod:`jaxarm.learning.rule`) of ``config.learning`` with ``config.rule_config``."""
        return RULES[self.config.learning](self.config.rule_config, self)

    # -- pieces ------------------------------------------------------------------------------------------------
    def net_params(self, mp: MetaParams) -> NetworkParams:
        return NetworkParams(max_plast_t_ms=jnp.asarray(mp.max_plast_t_ms, jnp.float32))

    def init(self, noise_key, wgain, rule, em_rates_hz, target: Target | None = None,
             code_rate_scale=1.0) -> LoopState:
        """State at the start of a run (an epoch or the test): cells at rest, arm at the start posture. ``rule``: the
        learning rule's state within the run (its ``begin_epoch``'s; None for a run without learning),
        ``em_rates_hz``: (4,) EM noise rates, Hz; ``target``: where to reach (default: the task's named target);
        ``code_rate_scale``: a target code's rate scale (``MetaParams.code_rate_scale``; read only with a code)."""
        target = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32),
                              self.config.task.target_params if target is None else target)
        arm_state = self.arm.init(self.start_q)
        # No P update at t = 0: every P cell fires its start spike at 1 ms and the first update comes at the end of
        # the first interval (10 ms), as in the original (msarm.hoc); an update here moved the start spike of the
        # ~12 cells in range at the start posture to 10 ms.
        net = self.net.init(noise_key, wgain=wgain, em_rates_hz=em_rates_hz)
        if self.config.network.spec.target_codes:   # target-coding generators: the target's direction
            start_xy = jnp.asarray(self.config.task.start_xy_m, jnp.float32)
            net = self.net.set_target(net, jnp.arctan2(target.xy_m[1] - start_xy[1], target.xy_m[0] - start_xy[0]),
                                      code_rate_scale)
        err0 = self._critic_error(self.arm.observe(arm_state), target)
        return LoopState(net=net, arm=arm_state, readout=ro.init_readout(self.config.network), rule=rule,
                         err_hist_m=jnp.stack([err0, err0]), target=target)

    def _critic_error(self, obs, target: Target):
        """What the critic compares (LoopConfig.critic_error): hand–target distance, m, or joint-space distance, rad."""
        if self.config.critic_error == "angle":
            return jnp.linalg.norm(obs.q - target.q_rad)
        return jnp.linalg.norm(obs.hand - target.xy_m)

    def _move_arm(self, arm_state, u):
        def body(s, _):
            return self.arm.step(s, u), None

        return jax.lax.scan(body, arm_state, None, length=self.arm_steps)[0]

    def interval(self, wiring, state: LoopState, key, mp: MetaParams, learn: bool, record: bool = False):
        """One 10 ms interface period (see module docstring). ``learn`` and ``record`` are static. With ``record``
        it returns (state, IntervalRecord, spikes (steps, n_all) bool of the interval, the arm's MuscleObs or
        None) instead of (state, IntervalRecord); the state and record are the same either way."""
        c = self.config
        if self.net.differentiable:
            # float32 spikes with a surrogate derivative: the counts are the same numbers, and differentiable
            net, spikes = self.net.run(wiring, state.net, self.net_params(mp), self.steps_per_interval)
            em_counts = ro.em_group_counts(c.network, jnp.sum(spikes, axis=0))
            spikes = spikes > 0.5
        else:
            net, spikes = self.net.run(wiring, state.net, self.net_params(mp), self.steps_per_interval,
                                       collect=record)
            em_counts = ro.em_group_counts(c.network, net.spike_count - state.net.spike_count)
        readout = ro.push(state.readout, em_counts)
        # The loop's clock counts whole intervals (an integer), so its times are exact multiples of interface_ms
        # whatever the network's dt (float32(step) * dt is not exact for dt = 0.1 ms).
        t_ms = readout.pushes.astype(jnp.float32) * c.network.interface_ms
        u = ro.excitation(c.network, readout, v_em_max=mp.v_em_max, window_ms=mp.mcmd_spk_wd_ms)
        arm_state = self._move_arm(state.arm, u)
        obs = self.arm.observe(arm_state)
        err = self._critic_error(obs, state.target)
        net = self.net.set_lengths(net, obs.proprio)
        signal = jnp.zeros((), jnp.float32)
        rule = state.rule
        if learn:
            rule, net, signal = self.rule.update(rule, net, key, Moment(t_ms, state.err_hist_m, err), mp)
        state = LoopState(net=net, arm=arm_state, readout=readout, rule=rule,
                          err_hist_m=jnp.stack([state.err_hist_m[1], err]), target=state.target)
        if record:
            return state, IntervalRecord(obs.hand, obs.q, u, em_counts, signal), spikes, obs.muscles
        return state, IntervalRecord(obs.hand, obs.q, u, em_counts, signal)

    def code_wiring(self, wiring, mp: MetaParams):
        """``wiring`` with a target code's weight and density scaled by ``mp`` (``code_weight_scale``,
        ``code_density_scale``); ``wiring`` itself in a network without a target code."""
        return self.net.target_code_wiring(wiring, mp.code_weight_scale, mp.code_density_scale)

    def run(self, wiring, state: LoopState, key, mp: MetaParams, n_intervals: int, learn: bool):
        """``n_intervals`` interface periods by ``lax.scan``. Returns (state, IntervalRecord time-major)."""
        return self.run_keys(wiring, state, jax.random.split(key, n_intervals), mp, learn)

    def run_keys(self, wiring, state: LoopState, keys, mp: MetaParams, learn: bool):
        """One interface period per key of ``keys`` (intervals, 2); :meth:`run` with the keys already split."""
        wiring = self.code_wiring(wiring, mp)

        def body(s, k):
            return self.interval(wiring, s, k, mp, learn)

        return jax.lax.scan(body, state, keys)

    def run_recorded(self, wiring, state: LoopState, keys, mp: MetaParams, learn: bool, buf, start_step,
                     muscles: bool = True):
        """:meth:`run_keys` that also appends every spike to ``buf`` (a :class:`jaxarm.record.SpikeBuffer` of a
        window that began after clock step ``start_step``). Returns (state, IntervalRecord, buf, MuscleObs per
        interval, or None for the simple arm or without ``muscles`` (static): stacking them is not free); state and
        IntervalRecord equal :meth:`run_keys`'s."""
        from jaxarm import record as rec_mod

        wiring = self.code_wiring(wiring, mp)

        def body(carry, k):
            s, b = carry
            interval = (s.net.step - start_step) // self.steps_per_interval
            s, rec, spikes, obs_muscles = self.interval(wiring, s, k, mp, learn, record=True)
            return (s, rec_mod.push(b, spikes, interval)), (rec, obs_muscles if muscles else None)

        (state, buf), (rec, stacked) = jax.lax.scan(body, (state, buf), keys)
        return state, rec, buf, stacked
