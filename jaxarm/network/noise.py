"""Background Poisson input per receptor and population ([model: network](../model.md#network-inputs-and-delays)), with
per-group EM rates that babbling changes.

Every network cell has one independent Poisson source per receptor (distal AMPA, proximal GABA, distal GABA; no
NMDA noise), with the weight and rate its population gives (``Population.noise`` of the spec). The paper's
(``NetworkSpec.dura_bernal_2015()``; stim.hoc setwmatex, EXGain 15 included), weights (mV) and rates (Hz):

=========  ===============  ============  ============
post       AMPA-distal      GABA-prox     GABA-dist
=========  ===============  ============  ============
ES         3.75 @ 200       1.875 @ 100   1.875 @ 100
EM         3.9375 @ 200*    1.875 @ 100   1.875 @ 100
IS, IM     4.125 @ 200      1.875 @ 100   1.875 @ 100
ISL, IML   3.0 @ 200        1.875 @ 100   1.875 @ 100
=========  ===============  ============  ============

\\* the AMPA rate of the readout population (EM) is set per muscle group with :func:`set_em_rates` (babbling,
test noise).

Each step every (receptor, cell) "lane" draws the number of events in that step, N ~ Poisson(rate dt), by
inverting the Poisson CDF with one 32-bit uniform: N = #{k < kmax : u >= CDF(k)}. ``kmax`` (config.noise_kmax) is
the smallest count with P(N > kmax) below the resolution of the draw at the highest configured rate, so the
truncation is invisible. Thresholds are stored in the state (recomputed only when rates change).

Random numbers: a counter-based integer hash of (network seed, step, lane) — u = H(lane_key XOR H(step * phi + seed))
with H the "lowbias32" 32-bit finaliser. It is pure, deterministic, and needs no RNG state beyond the seeds. We use
it instead of ``jax.random`` because on the 2-core CPU it draws the 3 x 512 numbers of a step several times faster
than threefry (a development microbenchmark: about 0.1 vs 0.6 ms per step for 60 networks); the per-network seeds
themselves come from a ``jax.random`` key. tests/test_network_io.py checks rates, Poisson variance and the absence of
correlations between lanes and between steps.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.config.spec import NOISE_RECEPTORS  # noqa: F401 - the rows of every (3, n_cells) noise array
from jaxarm.network.populations import Populations

DEFAULT_EM_RATE_HZ = 200.0

_GOLDEN = np.uint32(0x9E3779B9)


#: ``events_left`` of a lane without an event limit: such lanes (>= this value) never spend their budget.
UNLIMITED_EVENTS = 1 << 30


class NoiseState(NamedTuple):
    step_seed: jnp.ndarray    # () uint32, mixed with the step counter
    lane_key: jnp.ndarray     # (3, n_cells) uint32, one key per lane
    thresholds: jnp.ndarray   # (kmax, 3, n_cells) uint32, Poisson CDF thresholds for this dt
    events_left: jnp.ndarray  # (3, n_cells) int32, events a lane may still emit (a NetStim's `number`; see
    #                           limit_em_events); UNLIMITED_EVENTS unless limited


def hash32(x):
    """"lowbias32" integer finaliser (a bijection of uint32 with strong avalanche)."""
    x = x ^ (x >> 16)
    x = x * jnp.uint32(0x7FEB352D)
    x = x ^ (x >> 15)
    x = x * jnp.uint32(0x846CA68B)
    return x ^ (x >> 16)


def noise_weights(config: NetworkConfig) -> np.ndarray:
    """(3, n_cells) float32 event weight of every lane, mV; with ``event_summation="sequential"`` the event's load
    (:func:`jaxarm.network.cell.event_load`), so k events in a step add k loads."""
    spec = config.spec
    w = np.concatenate([np.repeat(np.array([[w for w, _ in spec.population(p).noise]], np.float32).T,
                                  config.size(p), 1) for p in spec.network_populations], axis=1)
    if config.event_summation == "sequential":
        from jaxarm.network.cell import event_load
        ph = spec.physics
        f = ph.max_jump_fraction
        w = np.stack([event_load(w[0], ph.e_ampa_mv, f), event_load(w[1], -ph.e_gaba_mv, f),
                      event_load(w[2], -ph.e_gaba_mv, f)])
    return w.astype(np.float32)


def base_rates_hz(config: NetworkConfig) -> np.ndarray:
    """(3, n_cells) float32 rate of every lane as the spec gives it (the readout's AMPA rate before babbling), Hz."""
    spec = config.spec
    return np.concatenate([np.repeat(np.array([[r for _, r in spec.population(p).noise]], np.float32).T,
                                     config.size(p), 1) for p in spec.network_populations], axis=1)


def lane_rates_hz(config: NetworkConfig, em_rates_hz) -> jnp.ndarray:
    """(3, n_cells) rates with the readout population's (EM's) AMPA lanes set from ``em_rates_hz`` (4,) per
    muscle group (id % 4)."""
    pops = Populations(config)
    em = pops.slice(config.spec.readout)
    em_cell_rates = jnp.asarray(em_rates_hz, jnp.float32)[jnp.asarray(pops.em_groups())]
    return jnp.asarray(base_rates_hz(config)).at[0, em].set(em_cell_rates)


def poisson_thresholds(rates_hz, dt_ms: float, kmax: int):
    """(kmax, ...) uint32 thresholds T_k = CDF(k) * 2^32 of Poisson(rate dt) for k = 0..kmax-1."""
    lam = jnp.asarray(rates_hz, jnp.float32) * (dt_ms / 1000.0)
    term = jnp.exp(-lam)
    cdf = term
    rows = []
    for k in range(kmax):
        rows.append(cdf)
        term = term * lam / (k + 1)
        cdf = cdf + term
    cdf = jnp.stack(rows)
    return jnp.where(cdf >= 1.0, jnp.uint32(0xFFFFFFFF), (cdf * 4294967296.0).astype(jnp.uint32))


def init_noise(config: NetworkConfig, key, em_rates_hz=None) -> NoiseState:
    """Seeds from ``key``; EM AMPA rates default to 200 Hz per group."""
    seeds = jax.random.bits(key, (2,), jnp.uint32)
    lanes = jnp.arange(3 * config.n_cells, dtype=jnp.uint32).reshape(3, config.n_cells)
    lane_key = hash32(hash32(lanes * _GOLDEN + seeds[1]))
    em = jnp.full((4,), DEFAULT_EM_RATE_HZ, jnp.float32) if em_rates_hz is None else em_rates_hz
    thresholds = poisson_thresholds(lane_rates_hz(config, em), config.dt_ms, config.noise_kmax)
    return NoiseState(step_seed=seeds[0], lane_key=lane_key, thresholds=thresholds,
                      events_left=jnp.full((3, config.n_cells), UNLIMITED_EVENTS, jnp.int32))


def limit_em_events(config: NetworkConfig, noise: NoiseState, max_events) -> NoiseState:
    """Let every EM AMPA lane emit at most ``max_events`` more events (a traced int is fine); other lanes unchanged.

    The original's test noise to EM is a NetStim per cell with ``number = tstop * rate / 1000`` (99 for 1 s at
    99.01 Hz; [model: babbling](../model.md#learning-reward-modulated-stdp)): its Poisson train stops after that many
    events, for about half the cells before the end of the 1 s test. Events beyond the budget within a step are dropped,
    as the train's last events would be."""
    em = Populations(config).slice(config.spec.readout)
    return noise._replace(events_left=noise.events_left.at[0, em].set(jnp.asarray(max_events, jnp.int32)))


def set_em_rates(config: NetworkConfig, noise: NoiseState, em_rates_hz) -> NoiseState:
    """Set the EM AMPA background rate of each muscle group (4,), Hz (babbling / test noise)."""
    return noise._replace(thresholds=poisson_thresholds(lane_rates_hz(config, em_rates_hz), config.dt_ms,
                                                        noise.thresholds.shape[0]))


def noise_counts(noise: NoiseState, step):
    """(3, n_cells) float32 number of background events of every lane in clock step ``step`` (int), before any
    event limit (:func:`draw_events` applies it)."""
    s = hash32(jnp.asarray(step).astype(jnp.uint32) * _GOLDEN + noise.step_seed)
    u = hash32(noise.lane_key ^ s)
    return jnp.sum(u[None] >= noise.thresholds, axis=0, dtype=jnp.int32).astype(jnp.float32)


#: Salt of the order coins' stream (:func:`excitation_first`): XORed into the AMPA lane's hash input, so a coin and
#: that lane's noise draw of the same step are different inputs of the bijection ``hash32``.
ORDER_SALT = np.uint32(0x5BD1E995)


def excitation_first(noise: NoiseState, step):
    """(n_cells,) bool: whether, in clock step ``step``, a cell's excitatory events of that step come before its
    inhibitory ones (``NetworkConfig.same_step_inhibition = "random_order"``); probability 1/2 each, independent
    across cells and steps and of the noise counts (a test checks both): the top bit of
    ``hash32(ampa_lane_key ^ hash32(step * phi + step_seed) ^ ORDER_SALT)``."""
    s = hash32(jnp.asarray(step).astype(jnp.uint32) * _GOLDEN + noise.step_seed)
    return (hash32(noise.lane_key[0] ^ s ^ ORDER_SALT) >> 31) != 0


def draw_events(noise: NoiseState, step):
    """The events of clock step ``step`` within each lane's budget: ((3, n_cells) float32 counts, noise with the
    budget spent). Unlimited lanes (``events_left >= UNLIMITED_EVENTS``) give :func:`noise_counts`'s counts and
    keep their value."""
    left = noise.events_left
    limited = left < UNLIMITED_EVENTS
    counts = noise_counts(noise, step).astype(jnp.int32)
    counts = jnp.where(limited, jnp.minimum(counts, left), counts)
    return counts.astype(jnp.float32), noise._replace(events_left=jnp.where(limited, left - counts, left))
