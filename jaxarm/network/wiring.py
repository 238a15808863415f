"""Fixed in-degree wiring, drawn from a key and stored the way it is made: per postsynaptic cell ([model:
network](../model.md#network-inputs-and-delays)).

For every pathway pre -> post each postsynaptic cell draws exactly ``in_degree = int(0.5 + pmat * pmat_scale * N_pre)``
distinct presynaptic partners uniformly (``convwire``; with ``self_connections="code"`` a cell may draw itself, as
in the original). Delays are uniform in [3, 5] ms from E and LTS cells (distal), [1.8, 2.2] ms from FS cells
(somatic), and 1 ms from P; they are rounded to the clock step.

Layout (``Wiring``, every array may carry leading batch axes under ``vmap``):

* Synapses are numbered pathway by pathway in the spec's order (``NetworkSpec.pathways``), and inside a pathway post-cell major:
  synapse ``offset + i * in_degree + j`` is the j-th input of the i-th cell of the post population. So for any
  per-synapse array ``a`` of shape (n_syn,), ``layout.view(a, "ES->EM")`` is the (n_post, in_degree) per-post-cell
  block of that pathway (no copy semantics needed: a static slice and reshape). The eight plastic pathways come
  first, so plastic synapse k (0 <= k < n_plastic) is synapse k.
* ``pre``/``post``: global ids; ``delay_steps``; ``weight``: the AMPA (E presyn) or GABA (I presyn) base weight in mV,
  which ``wgain`` multiplies; ``nmda``: the NMDA base weight (0.1 x AMPA, not scaled by ``wgain``; 0 for GABA);
  ``target``: flat index ``channel * n_cells + post`` into one ring-buffer slot (channels: 0 AMPA-distal,
  1 NMDA-distal, 2 GABA-proximal, 3 GABA-distal); ``packed``: ``target << 10 | delay_steps`` (one gather fetches
  both on the hot path).
* Delivery tables, one :class:`GroupTables` per spike group (``NetworkSpec.spike_groups``; the paper's: ES; EM; the
  four inhibitory populations), row r = the r-th cell of the group, plus a last all-padding row for "no spike": ``out_syn`` the
  synapse ids the cell projects to (padded with the dummy synapse n_syn), and copies of what delivery needs per
  synapse in the same layout, ``out_packed`` (target << 10 | delay), ``out_weight``, ``out_nmda``, so the hot path
  reads whole rows (cheap) instead of single elements. ``in_plastic`` lists the plastic synapses onto the cell
  (padded with n_plastic) and ``in_plastic_pre`` their presynaptic ids (padded with n_all, a cell that never fires),
  for tagging. Synapses from the generator population (the paper's P -> ES) are in no table: its trains are known
  in advance and are delivered once per chunk of steps (:func:`jaxarm.network.synapses.deliver_p_window`). Grouping keeps each table as narrow as its cells need
  (EM cells project to ~46 cells, inhibitory ones to ~135; ES cells have 13 plastic inputs, inhibitory ones ~100).
* ``out_overflow``: synapses that did not fit ``out_capacity`` (must be 0; counted, never silent).

Weights are the spec's table (base wmat x pathway gain, [model: network](../model.md#network-inputs-and-delays)); NMDA =
``nmda_ampa_ratio`` (NMAMR, 0.1) x AMPA.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.config.network import NetworkConfig
from jaxarm.config.spec import Pathway
from jaxarm.config.validate import ConfigError
from jaxarm.network.populations import Populations

#: Receptor channels of the per-cell synaptic input rows.
AMPA, NMDA, GABA_PROX, GABA_DIST = 0, 1, 2, 3
N_CHANNELS = 4
#: The channel a presynaptic cell's output drives (``CellType.output``).
CHANNEL_OF_OUTPUT = {"excitatory": AMPA, "inhibitory_proximal": GABA_PROX, "inhibitory_distal": GABA_DIST}
DELAY_BITS = 10


class GroupTables(NamedTuple):
    """Delivery and tagging tables of one spike group (see module docstring). (n_group + 1, width) each."""

    out_syn: jnp.ndarray
    out_packed: jnp.ndarray
    out_weight: jnp.ndarray
    out_nmda: jnp.ndarray
    in_plastic: jnp.ndarray
    in_plastic_pre: jnp.ndarray


class Wiring(NamedTuple):
    """One network's synapses (see module docstring for the layout). Integer arrays are int32."""

    pre: jnp.ndarray            # (n_syn + 1,) global id of the presynaptic cell (dummy synapse: n_all)
    post: jnp.ndarray           # (n_syn + 1,) global id of the postsynaptic cell (dummy: 0)
    delay_steps: jnp.ndarray    # (n_syn + 1,) delay in clock steps (>= 1)
    weight: jnp.ndarray         # (n_syn + 1,) AMPA or GABA base weight, mV (dummy: 0)
    nmda: jnp.ndarray           # (n_syn + 1,) NMDA base weight, mV
    target: jnp.ndarray         # (n_syn + 1,) channel * n_cells + post
    packed: jnp.ndarray         # (n_syn + 1,) target << 10 | delay_steps
    groups: tuple               # GroupTables per spike group (NetworkSpec.spike_groups)
    out_overflow: jnp.ndarray   # () synapses left out of the delivery tables (must be 0)


@dataclass(frozen=True)
class WiringLayout:
    """Static shape of the wiring for a configuration (Python ints only; hashable).

    The spec has checked the pathway order (plastic first, the generator's last); construction checks that every
    index the kernels form fits int32: ``target << DELAY_BITS`` (4 n_cells << 10 < 2**31, so at most 524,287 network cells), the synapse ids,
    and a delay of 5 ms in DELAY_BITS bits."""

    config: NetworkConfig

    def __post_init__(self):
        c = self.config
        if (N_CHANNELS * c.n_cells) << DELAY_BITS >= 2 ** 31:
            raise ConfigError(f"NetworkConfig.sizes = {c.sizes}: {c.n_cells} network cells; at most "
                              f"{(2 ** 31 >> DELAY_BITS) // N_CHANNELS - 1} fit the int32 packed (target << "
                              f"{DELAY_BITS} | delay) synapse words")
        if self.n_syn + 1 >= 2 ** 31:
            raise ConfigError(f"NetworkConfig.sizes = {c.sizes}: {self.n_syn} synapses do not fit int32 ids")
        if c.steps(max(pw.delay_ms[1] for pw in self.pathways)) >= 1 << DELAY_BITS:
            raise ConfigError(f"NetworkConfig.dt_ms = {c.dt_ms}: the longest delay does not fit {DELAY_BITS} bits "
                              "of steps")

    @cached_property
    def pops(self) -> Populations:
        return Populations(self.config)

    @property
    def pathways(self) -> tuple[Pathway, ...]:
        return self.config.spec.pathways

    @property
    def spike_groups(self) -> tuple[tuple[str, ...], ...]:
        return self.config.spec.spike_groups

    def channel(self, pw: Pathway) -> int:
        """The receptor channel pathway ``pw`` drives (from its presynaptic population's output)."""
        return CHANNEL_OF_OUTPUT[self.config.spec.output(pw.pre)]

    def nmda_weight_mv(self, pw: Pathway) -> float:
        """NMDA base weight of pathway ``pw``, mV: nmda_ampa_ratio x AMPA for an excitatory presynaptic type, else 0."""
        if self.channel(pw) != AMPA:
            return 0.0
        return self.config.spec.physics.nmda_ampa_ratio * pw.weight_mv

    @cached_property
    def generator_pathways(self) -> tuple[Pathway, ...]:
        """The pathways from generator populations (the plastic ones among the first, the fixed ones last)."""
        return tuple(pw for pw in self.pathways if pw.pre in self.config.spec.generators)

    @cached_property
    def generator_synapses(self) -> "slice | np.ndarray":
        """The synapse indices of every pathway from a generator, delivered once per chunk: a slice when they are
        one block (the paper's P -> ES, last), else an int32 index array (plastic ones from a target code)."""
        ids = np.concatenate([np.arange(self.synapses(pw.name).start, self.synapses(pw.name).stop)
                              for pw in self.generator_pathways]).astype(np.int32)
        if np.all(np.diff(ids) == 1):
            return slice(int(ids[0]), int(ids[-1]) + 1)
        return ids

    @cached_property
    def in_degree(self) -> dict[str, int]:
        c = self.config
        return {pw.name: int(0.5 + pw.pmat * c.pmat_scale * c.size(pw.pre)) for pw in self.pathways}

    @cached_property
    def offset(self) -> dict[str, int]:
        out, s = {}, 0
        for pw in self.pathways:
            out[pw.name] = s
            s += self.config.size(pw.post) * self.in_degree[pw.name]
        return out

    @cached_property
    def n_syn(self) -> int:
        return self.synapses(self.pathways[-1].name).stop

    @cached_property
    def n_plastic(self) -> int:
        return sum(self.config.size(pw.post) * self.in_degree[pw.name] for pw in self.pathways if pw.plastic)

    @cached_property
    def n_network_syn(self) -> int:
        """Synapses between network cells (everything but the generators' pathways)."""
        return sum(self.config.size(pw.post) * self.in_degree[pw.name] for pw in self.pathways
                   if pw.pre not in self.config.spec.generators)

    def pathway(self, name: str) -> Pathway:
        return self.config.spec.pathway(name)

    def synapses(self, name: str) -> slice:
        """The synapse indices of pathway ``name`` (its contiguous block of the per-synapse arrays)."""
        start = self.offset[name]
        return slice(start, start + self.config.size(self.pathway(name).post) * self.in_degree[name])

    def view(self, per_synapse, name: str):
        """The (..., n_post, in_degree) block of pathway ``name`` of a per-synapse array (..., n_syn[+1])."""
        a = per_synapse[..., self.synapses(name)]
        return a.reshape(a.shape[:-1] + (self.config.size(self.pathway(name).post), self.in_degree[name]))

    def pathway_of_synapse(self) -> np.ndarray:
        """(n_syn,) index into the spec's pathways of every synapse."""
        return np.repeat(np.arange(len(self.pathways)),
                         [self.config.size(pw.post) * self.in_degree[pw.name] for pw in self.pathways])

    @cached_property
    def group_cells(self) -> tuple[np.ndarray, ...]:
        """Global ids of the cells of each spike group (ascending)."""
        return tuple(np.concatenate([self.pops.ids(p) for p in g]) for g in self.spike_groups)

    @cached_property
    def group_is_excitatory(self) -> tuple[bool, ...]:
        return tuple(all(self.config.spec.output(p) == "excitatory" for p in g) for g in self.spike_groups)

    def mean_out_degree(self, pre: str) -> float:
        return sum(self.config.size(pw.post) * self.in_degree[pw.name] / self.config.size(pre)
                   for pw in self.pathways if pw.pre == pre)

    @cached_property
    def out_capacity(self) -> tuple[int, ...]:
        """Delivery-row width of each spike group: ``config.out_capacity`` or mean + 6 sd of the largest expected
        out-degree in the group (out-degrees are sums of independent draws, so exceeding this has probability
        ~1e-9 per cell; it would be counted in ``Wiring.out_overflow``)."""
        if self.config.out_capacity:
            return (self.config.out_capacity,) * len(self.spike_groups)
        return tuple(int(math.ceil(max(m + 6.0 * math.sqrt(max(m, 1.0)) for m in map(self.mean_out_degree, g))))
                     for g in self.spike_groups)

    @cached_property
    def plastic_inputs(self) -> tuple[np.ndarray, ...]:
        """Per spike group, the static (n_group + 1, width) table of plastic synapse ids onto each cell, padded
        with n_plastic (the draw only decides which presynaptic cell each one has)."""
        rows: dict[int, list[int]] = {}
        for pw in self.pathways:
            if not pw.plastic:
                continue
            k, start = self.in_degree[pw.name], self.pops.start[pw.post]
            for i in range(self.config.size(pw.post)):
                base = self.offset[pw.name] + i * k
                rows.setdefault(start + i, []).extend(range(base, base + k))
        tables = []
        for cells in self.group_cells:
            width = max(1, max(len(rows.get(int(c), [])) for c in cells))
            table = np.full((len(cells) + 1, width), self.n_plastic, dtype=np.int32)
            for r, c in enumerate(cells):
                ids = rows.get(int(c), [])
                table[r, :len(ids)] = ids
            tables.append(table)
        return tuple(tables)


def make_wiring(config: NetworkConfig, key) -> Wiring:
    """Draw one network's wiring from ``key`` (pure; ``vmap`` over keys gives one wiring per network)."""
    return _make_wiring_jit(config, key)


@partial(jax.jit, static_argnums=0)
def _make_wiring_jit(config: NetworkConfig, key) -> Wiring:
    pre, delay_ms = _draw_synapses(config, key)
    return _build_wiring(config, pre, delay_ms)


def _draw_synapses(config: NetworkConfig, key):
    """(n_syn,) presynaptic global ids and delays (ms) in the layout's synapse order, drawn from ``key``."""
    layout = WiringLayout(config)
    pops = layout.pops
    # Two draws and one top_k for everything (threefry and sorts compile slowly on CPU, so not one per pathway):
    # every (pathway, post cell) row gets uniform keys for its candidate partners and keeps the k largest, which is
    # k distinct partners drawn uniformly; every synapse gets a uniform delay.
    pathways = layout.pathways
    pools = [config.size(pw.pre) - (pw.pre == pw.post and config.self_connections == "exclude") for pw in pathways]
    for pw, pool in zip(pathways, pools):
        if layout.in_degree[pw.name] > pool:
            raise ValueError(f"pathway {pw.name}: in-degree {layout.in_degree[pw.name]} exceeds the {pool} "
                             "available presynaptic cells")
    width, k_max = max(pools), max(layout.in_degree.values())
    rows = np.concatenate([[0], np.cumsum([config.size(pw.post) for pw in pathways])])
    valid = np.zeros((rows[-1], width), bool)
    for index, pool in enumerate(pools):
        valid[rows[index]:rows[index + 1], :pool] = True
    k_pre, k_delay = jax.random.split(key)
    keys = jnp.where(valid, jax.random.uniform(k_pre, valid.shape), -1.0)
    chosen = jax.lax.top_k(keys, k_max)[1]
    delay_u = jax.random.uniform(k_delay, (layout.n_syn,))
    pres, delays = [], []
    for index, (pw, pool) in enumerate(zip(pathways, pools)):
        n_post, k = config.size(pw.post), layout.in_degree[pw.name]
        local = chosen[rows[index]:rows[index + 1], :k]
        if pool < config.size(pw.pre):  # self excluded: candidate c >= own index stands for c + 1
            local = local + (local >= jnp.arange(n_post)[:, None])
        pres.append((local + pops.start[pw.pre]).astype(jnp.int32).reshape(-1))
        lo, hi = pw.delay_ms
        off = layout.offset[pw.name]
        delays.append(lo + (hi - lo) * delay_u[off:off + n_post * k])
    return jnp.concatenate(pres), jnp.concatenate(delays)


def _build_wiring(config: NetworkConfig, pre_syn, delay_ms) -> Wiring:
    """The Wiring of given synapses: ``pre_syn`` (n_syn,) presynaptic global ids and ``delay_ms`` (n_syn,) in the
    layout's order (pathway by pathway, post-cell major); posts, weights and channels follow from the layout."""
    layout = WiringLayout(config)
    pops = layout.pops
    dt = config.dt_ms
    posts, weights, nmdas, targets = [], [], [], []
    for pw in layout.pathways:
        n_post, k = config.size(pw.post), layout.in_degree[pw.name]
        post = jnp.asarray(np.repeat(np.arange(n_post, dtype=np.int32) + pops.start[pw.post], k))
        posts.append(post)
        weights.append(jnp.full((n_post * k,), pw.weight_mv, jnp.float32))
        nmdas.append(jnp.full((n_post * k,), layout.nmda_weight_mv(pw), jnp.float32))
        targets.append(post + layout.channel(pw) * config.n_cells)
    delays = [jnp.maximum(jnp.round(jnp.asarray(delay_ms, jnp.float32) / dt), 1).astype(jnp.int32)]
    pres = [jnp.asarray(pre_syn, jnp.int32)]
    n_all = config.n_all
    # the dummy synapse n_syn: zero weight onto cell 0, presynaptic id n_all
    pre = jnp.concatenate(pres + [jnp.array([n_all], jnp.int32)])
    post = jnp.concatenate(posts + [jnp.zeros(1, jnp.int32)])
    delay = jnp.concatenate(delays + [jnp.ones(1, jnp.int32)])
    weight = jnp.concatenate(weights + [jnp.zeros(1, jnp.float32)])
    nmda = jnp.concatenate(nmdas + [jnp.zeros(1, jnp.float32)])
    target = jnp.concatenate(targets + [jnp.zeros(1, jnp.int32)])
    packed = (target << DELAY_BITS) | delay
    gen = layout.generator_synapses   # delivered separately (the P window): in no delivery table
    if isinstance(gen, slice) and gen.stop == layout.n_syn:     # the paper's: P -> ES, the last block
        by_pre, overflow = _delivery_lists(pre[:gen.start], config.n_cells, max(layout.out_capacity), layout.n_syn)
    else:
        net_ids = np.setdiff1d(np.arange(layout.n_syn), np.arange(layout.n_syn)[gen]).astype(np.int32)
        local, overflow = _delivery_lists(pre[net_ids], config.n_cells, max(layout.out_capacity), len(net_ids))
        by_pre = jnp.asarray(np.append(net_ids, layout.n_syn).astype(np.int32))[local]
    groups = []
    for cells, width, in_plastic_np in zip(layout.group_cells, layout.out_capacity, layout.plastic_inputs):
        rows = np.append(cells, config.n_cells)  # + the "no spike" row (all padding)
        out_syn = by_pre[rows, :width]
        overflow = overflow + jnp.sum(by_pre[rows, width:] < layout.n_syn)
        in_plastic = jnp.asarray(in_plastic_np)
        in_pre = jnp.where(in_plastic < layout.n_plastic, pre[jnp.minimum(in_plastic, layout.n_syn)], n_all)
        groups.append(GroupTables(out_syn=out_syn, out_packed=packed[out_syn], out_weight=weight[out_syn],
                                  out_nmda=nmda[out_syn], in_plastic=in_plastic,
                                  in_plastic_pre=in_pre.astype(jnp.int32)))
    return Wiring(pre=pre, post=post, delay_steps=delay, weight=weight, nmda=nmda, target=target, packed=packed,
                  groups=tuple(groups), out_overflow=overflow.astype(jnp.int32))


def wiring_from_edges(config: NetworkConfig, pre, post, delay_ms) -> tuple[Wiring, np.ndarray]:
    """A Wiring from an explicit edge list, e.g. a network built by the original NEURON model (experiments/
    transplant.py). ``pre``, ``post``: (n_edges,) global ids (:mod:`jaxarm.network.populations` numbering, which is
    the original's); ``delay_ms``: (n_edges,) delays, ms (rounded to the clock step, as drawn ones are). The edges
    must be exactly this configuration's synapses: every (pathway, post cell) with the pathway's in-degree, P -> ES
    included, and no edge of a pathway the model does not have.

    Returns (wiring, order): ``order[s]`` is the edge index of synapse ``s``, so a per-edge array ``a`` (e.g. the
    original's plastic gains) is ``a[order]`` in the wiring's synapse order. Raises ValueError naming the pathway
    and cell that do not fit."""
    layout = WiringLayout(config)
    pops = layout.pops
    pre, post = np.asarray(pre, np.int64), np.asarray(post, np.int64)
    delay_ms = np.asarray(delay_ms, np.float64)
    if not (pre.shape == post.shape == delay_ms.shape and pre.ndim == 1):
        raise ValueError(f"pre, post, delay_ms must be 1-d arrays of one length, got {pre.shape}, {post.shape}, "
                         f"{delay_ms.shape}")
    for name, ids in (("pre", pre), ("post", post)):
        if ids.size and (ids.min() < 0 or ids.max() >= config.n_all):
            raise ValueError(f"{name} ids must be in [0, {config.n_all}), got [{ids.min()}, {ids.max()}]")
    pop_names = np.asarray(config.populations)
    pop_of = pops.population_of()
    index = {(pw.pre, pw.post): i for i, pw in enumerate(layout.pathways)}
    pathway = np.array([index.get((pop_names[a], pop_names[b]), -1) for a, b in zip(pop_of[pre], pop_of[post])],
                       np.int64)
    if np.any(pathway < 0):
        bad = int(np.argmax(pathway < 0))
        raise ValueError(f"edge {bad}: {pop_names[pop_of[pre[bad]]]} -> {pop_names[pop_of[post[bad]]]} is not a "
                         "pathway of this network")
    # our order: pathway, then post cell; edges of one row keep their given order (stable sort)
    order = np.lexsort((post, pathway))
    for i, pw in enumerate(layout.pathways):
        k = layout.in_degree[pw.name]
        counts = np.bincount(post[pathway == i] - pops.start[pw.post], minlength=config.size(pw.post))
        if np.any(counts != k):
            cell = int(np.argmax(counts != k))
            raise ValueError(f"pathway {pw.name}: post cell {pops.start[pw.post] + cell} has {counts[cell]} inputs, "
                             f"the in-degree is {k}")
    if order.size != layout.n_syn:
        raise ValueError(f"{order.size} edges, this network has {layout.n_syn} synapses")
    wiring = jax.jit(_build_wiring, static_argnums=0)(config, jnp.asarray(pre[order], jnp.int32),
                                                      jnp.asarray(delay_ms[order], jnp.float32))
    return wiring, order


def _delivery_lists(pre, n_pre: int, capacity: int, n_syn: int):
    """Group synapse ids by presynaptic cell: (n_pre + 1, capacity) padded with n_syn, and the overflow count."""
    order = jnp.argsort(pre, stable=True).astype(jnp.int32)
    sorted_pre = pre[order]
    first = jnp.searchsorted(sorted_pre, jnp.arange(n_pre + 1, dtype=jnp.int32), side="left")
    rank = jnp.arange(pre.shape[0], dtype=jnp.int32) - first[sorted_pre]
    table = jnp.full((n_pre + 1, capacity), n_syn, jnp.int32)
    table = table.at[sorted_pre, rank].set(order, mode="drop")
    return table, jnp.sum(rank >= capacity).astype(jnp.int32)


def in_degree_table(config: NetworkConfig = NetworkConfig()) -> dict[str, int]:
    """In-degree of every pathway, e.g. {"ES->EM": 65, ...}."""
    return dict(WiringLayout(config).in_degree)
