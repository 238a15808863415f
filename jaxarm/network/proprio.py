"""Proprioceptive (P) population code and spike generators ([model: closed loop](../model.md#the-closed-loop); msarm.hoc
assignDP/updateDP, nsloc.mod).

Tuning: P cell j codes muscle group j % 4 at position k = j // 4 (48 positions per group). With the length range
[lo, hi] = [0.03, 0.23] m and step w = (hi - lo) / 48 = 4.17 mm, cell k responds to lengths (inclusive bounds)

* ``p_tuning="code"``: [lo + (k - 1) w, lo + (k + 2) w], width 3w = 12.5 mm (what the code does);
* ``p_tuning="paper"``: [lo + (k - 0.5) w, lo + (k + 1.5) w], width 2w = 8.33 mm (the paper's text), same centres.

Generators (NSLOC with noise 0, ``PState``; times in clock steps since the start of the run):

* every P cell fires once at ``p_start_ms`` (1 ms), whatever its tuning;
* a cell in its window fires a regular train at ``p_rate_hz`` (100 Hz); outside, its interval is effectively infinite;
* :func:`set_lengths` (called by the closed loop every 10 ms) changes the intervals the way NSLOC reacts: a shorter
  interval restarts the train with the first spike one new interval after the change; a longer one takes effect
  after the spike already scheduled (so a cell leaving its window fires once more).
* Before the first :func:`set_lengths` every interval is infinite, so only the start spike happens (the original's
  first P update is at t = 10 ms).

Ambiguity resolved here: NSLOC polls interval changes every 1 ms; we apply a change at the step of the call.

Target codes (generator populations with ``code="target"``, none in the paper's network; ``PState`` holds every
generator cell, ids n_cells .. n_all - 1): cell j of such a population belongs to direction group j % groups and
fires a regular train at its ``rate_hz`` while the current target lies in that direction (:func:`set_target`, at
the start of every run: the direction of the target from the start hand position, rounded to the nearest group);
its other cells are silent. No start spike.
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.network.populations import Populations
from jaxarm.network.wiring import WiringLayout

#: "Never" for a P interval or next spike, in steps (the original's 1e8 ms interval).
NEVER_STEPS = 2 ** 30


class PState(NamedTuple):
    next_step: jnp.ndarray      # (n_generators,) int32 step of each generator cell's next spike (the paper's: P)
    interval_steps: jnp.ndarray  # (n_generators,) int32 current interval, steps (NEVER_STEPS when silent)


def tuning_windows(config: NetworkConfig) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) float32 arrays (n_P,) of every P cell's length window, m (inclusive)."""
    pops = Populations(config)
    k = pops.p_tuning_index().astype(np.float64)
    lo_m, hi_m = config.p_length_range_m
    w = (hi_m - lo_m) / config.p_positions_per_group
    if config.p_tuning == "code":
        lo, hi = lo_m + (k - 1) * w, lo_m + (k + 2) * w
    else:
        lo, hi = lo_m + (k - 0.5) * w, lo_m + (k + 1.5) * w
    return lo.astype(np.float32), hi.astype(np.float32)


def active_cells(config: NetworkConfig, lengths_m):
    """(n_P,) bool: which P cells code the 4 muscle lengths ``lengths_m`` (m, GROUPS order)."""
    lo, hi = tuning_windows(config)
    groups = jnp.asarray(Populations(config).p_groups())
    length = jnp.asarray(lengths_m, jnp.float32)[groups]
    return (length >= lo) & (length <= hi)


def _p_cells(config: NetworkConfig) -> slice:
    """The P cells' slice of the generator cells."""
    start = Populations(config).start[config.spec.proprio] - config.n_cells
    return slice(start, start + config.n_p)


def init_p(config: NetworkConfig) -> PState:
    """Every generator silent; the P cells' start spike at ``p_start_ms``."""
    n = config.n_generators
    if n == config.n_p:
        next_step = jnp.full((n,), config.steps(config.p_start_ms), jnp.int32)
    else:
        first = np.full((n,), NEVER_STEPS, np.int32)
        first[_p_cells(config)] = config.steps(config.p_start_ms)
        next_step = jnp.asarray(first)
    return PState(next_step=next_step, interval_steps=jnp.full((n,), NEVER_STEPS, jnp.int32))


def _retime(p: PState, interval, step, cells: slice | None = None) -> PState:
    """New intervals for ``cells`` (None: every generator cell) with NSLOC semantics: a shorter interval restarts
    the train one interval after ``step``; a longer one takes effect after the spike already scheduled."""
    old_next, old_interval = (p.next_step, p.interval_steps) if cells is None else (p.next_step[cells],
                                                                                      p.interval_steps[cells])
    shorter = interval < old_interval
    next_step = jnp.where(shorter, jnp.asarray(step, jnp.int32) + interval, old_next).astype(jnp.int32)
    if cells is None:
        return PState(next_step=next_step, interval_steps=interval)
    return PState(next_step=p.next_step.at[cells].set(next_step),
                  interval_steps=p.interval_steps.at[cells].set(interval))


def set_lengths(config: NetworkConfig, p: PState, lengths_m, step) -> PState:
    """Update the P trains for new muscle lengths (m) at clock step ``step`` (NSLOC interval-change semantics)."""
    on = active_cells(config, lengths_m)
    interval = jnp.where(on, config.steps(1000.0 / config.p_rate_hz), NEVER_STEPS).astype(jnp.int32)
    return _retime(p, interval, step, None if config.n_generators == config.n_p else _p_cells(config))


def target_group(config: NetworkConfig, population: str, direction_rad):
    """The direction group of a target code nearest ``direction_rad`` (the target's direction from the start hand
    position, counterclockwise from +x)."""
    groups = config.spec.population(population).groups
    return jnp.round(jnp.asarray(direction_rad, jnp.float32) * (groups / (2.0 * np.pi))).astype(jnp.int32) % groups


#: The highest ``rate_scale`` :func:`set_target` is given (``MetaParams.code_rate_scale``'s upper bound): the P
#: window's delivery loop is sized for the shortest interval a train can have.
MAX_CODE_RATE_SCALE = 2.0


def set_target(config: NetworkConfig, p: PState, direction_rad, step, rate_scale=1.0) -> PState:
    """Switch every target code to the direction ``direction_rad`` (rad) at clock step ``step``: the cells of the
    nearest direction group fire at the population's ``rate_hz`` times ``rate_scale`` (a traced metaparameter,
    ``MetaParams.code_rate_scale``, clipped to :data:`MAX_CODE_RATE_SCALE`), the others fall silent. A no-op without
    target codes (the paper's network)."""
    pops = Populations(config)
    for name in config.spec.target_codes:
        pop = config.spec.population(name)
        cells = slice(pops.start[name] - config.n_cells, pops.stop[name] - config.n_cells)
        group = jnp.asarray(pops.target_groups(name))
        on = group == target_group(config, name, direction_rad)
        # above MAX_CODE_RATE_SCALE the XLA kernel's P window would drop spikes: clipped, as the bounds do
        scale = jnp.minimum(jnp.asarray(rate_scale, jnp.float32), MAX_CODE_RATE_SCALE)
        scaled = jnp.maximum(1, jnp.round(1000.0 / (pop.rate_hz * scale) / config.dt_ms)).astype(jnp.int32)
        # at scale 1 the spec's own interval (rounded in Python, float64), so an unscaled code keeps its bits
        interval = jnp.where(scale == 1.0, max(1, config.steps(1000.0 / pop.rate_hz)), scaled)
        interval = jnp.where(on, interval, NEVER_STEPS).astype(jnp.int32)
        p = _retime(p, interval, step, cells)
    return p


def target_code_wiring(config: NetworkConfig, wiring, weight_scale, density_scale):
    """``wiring`` with every target code's pathways scaled by two traced metaparameters: their AMPA and NMDA weights
    times ``weight_scale`` (``MetaParams.code_weight_scale``), and in every post cell only the first
    ``int(0.5 + pmat x density_scale x N_pre)`` of its inputs from the code kept, the others at weight 0
    (``MetaParams.code_density_scale``, at most 1: the spec's ``pmat`` is the largest density).

    The wiring draws a cell's partners as the largest of uniform keys, in descending order, so its first k inputs are
    the partners that a wiring of the spec with in-degree k draws from the same key: a density scale gives the
    spec's network at that density (the kept synapses' delays are drawn from the same law, not the same numbers).
    At both scales 1 the wiring is unchanged, bit for bit. The plastic gains of the dropped synapses still change,
    but they deliver nothing. ``wiring`` is the network's :class:`~jaxarm.network.wiring.Wiring` (no batch axes)."""
    layout = WiringLayout(config)
    weight, nmda = wiring.weight, wiring.nmda
    weight_scale = jnp.asarray(weight_scale, jnp.float32)
    density_scale = jnp.asarray(density_scale, jnp.float32)
    for pw in layout.pathways:
        if pw.pre not in config.spec.target_codes:
            continue
        n_post, k = config.size(pw.post), layout.in_degree[pw.name]
        scaled = jnp.floor(0.5 + pw.pmat * config.pmat_scale * config.size(pw.pre) * density_scale)
        kept = jnp.where(density_scale >= 1.0, k, scaled)
        factor = jnp.tile(jnp.where(jnp.arange(k) < kept, weight_scale, 0.0), n_post)
        synapses = layout.synapses(pw.name)
        weight = weight.at[synapses].multiply(factor)
        nmda = nmda.at[synapses].multiply(factor)
    return wiring._replace(weight=weight, nmda=nmda)


def min_interval_steps(config: NetworkConfig) -> int:
    """The shortest train interval of any generator, steps (bounds the spikes one train has in a window; a target
    code at its highest rate scale, :data:`MAX_CODE_RATE_SCALE`)."""
    rates = [config.p_rate_hz] + [config.spec.population(n).rate_hz * MAX_CODE_RATE_SCALE
                                  for n in config.spec.target_codes]
    return min(max(1, config.steps(1000.0 / r)) for r in rates)


def p_step(p: PState, step):
    """Spikes of the P cells at clock step ``step`` (the step just completed). Returns (state, (n_P,) bool)."""
    spiked = p.next_step == step
    following = jnp.where(p.interval_steps >= NEVER_STEPS, NEVER_STEPS, p.next_step + p.interval_steps)
    nxt = jnp.where(spiked, following, p.next_step)
    return PState(next_step=nxt, interval_steps=p.interval_steps), spiked
