"""Static configuration of the cortical spiking network ([model: equations](../model.md#equations)). Times in ms,
lengths in m.

Everything here is hashable and fixed at trace time (sizes, the time step, capacities, which variant of the
original to run). Values the authors tuned by evolution are traced arrays and live in
:class:`jaxarm.network.network.NetworkParams`.
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field

from jaxarm.config.spec import NetworkSpec, read_table, to_toml
from jaxarm.config.validate import ConfigError, check_choice, check_interval, check_range

#: Keys of a NetworkSpec in NetworkConfig's flat table form (:meth:`NetworkConfig.to_dict`).
SPEC_KEYS = ("populations", "pathways", "cell_types", "physics", "readout", "proprio")
#: NetworkConfig fields that choose how the network is computed, not what it is (never part of a run's identity).
RUNTIME_FIELDS = ("kernel", "native_threads", "spike_gradient", "surrogate_width_mv", "surrogate_scale")


def _is_multiple(x: float, step: float) -> bool:
    n = round(x / step)
    return n >= 1 and abs(n * step - x) <= 1e-9 * max(1.0, x)


#: The rules of NetworkConfig.same_step_inhibition, the default first.
SAME_STEP_INHIBITION = ("end_of_step", "random_order")


@dataclass(frozen=True)
class NetworkConfig:
    """Static structure of one network.

    Attributes:
        dt_ms: clock step, ms. Must divide 1 ms and ``interface_ms`` exactly. The default, 0.25 ms, is the largest
            tested step whose per-population rates under the training drive are all within 10 % of a dt = 0.1 ms run
            of the same networks and seed (8 networks x 20 s: worst population -9.1 % at 0.25 ms, -21.9 % at
            0.5 ms; ``experiments/network_rates.py --compare-dt 0.1,0.2,0.25,0.5,1 --networks 8 --seconds 20``).
        interface_ms: period of the closed loop (readout, arm step, P update), ms (the original's aDT = 10).
        spec: what the network is: populations and their sizes, cell types, pathways, background noise and the
            synaptic physics (:class:`jaxarm.config.spec.NetworkSpec`; default the paper's,
            ``NetworkSpec.dura_bernal_2015()``). ``sizes`` is a shortcut to its population sizes.
        pmat_scale: in-degree = int(0.5 + pmat * pmat_scale * N_pre) (the original's 0.75 * 6 / scale = 1.125).
        self_connections: "code" lets a cell draw itself as presynaptic partner, as the original did by accident
            (uninitialised ``prid``, [model: network](../model.md#network-inputs-and-delays)); "exclude" forbids it
            (ModelDB 150245's fix).
        p_tuning: "code": each P cell fires for lengths in a window 3 steps wide (12.5 mm); "paper": 2 steps (8.33 mm),
            same centres. Step = (max - min) / cells per group = 4.17 mm either way.
        p_length_range_m: (min, max) muscle length covered by the P code, m.
        p_positions: positions per muscle group along the length axis (0: one per P cell of the group, n_P / 4, the
            original's 48). P cell j codes position (j // 4) * p_positions // (n_P / 4): with more cells than
            positions, each position is coded by n_P / (4 p_positions) cells, and the code's step and window widths
            (mm) do not change with the population's size.
        p_rate_hz: rate of an active P cell (regular train), Hz.
        p_start_ms: every P cell fires once at this time (NSLOC ``start``), ms.
        readout_em_reference: the EM population size the readout's ``v_em_max`` refers to (0: the actual size, no
            normalisation). With it the EM counts are multiplied by reference / n_EM, so a larger EM population
            drives the muscles as the reference one does (the readout's gain normalised per EM cell).
        readout_clip: clip the motor excitation to [0, 1] (the paper's "thresholded linear" readout). The hoc
            code does not clip ([model: every deviation](../model.md#every-deviation-from-the-original)); False
            reproduces it.
        readout_bins: length of the EM spike-count history, in interface periods; must cover the longest readout
            window the metaparameters allow plus its lag (200 + 50 ms: 26 bins; the loop checks it).
        spike_capacity: spike-list length per delivery block (lax.top_k) of each spike group (ES, EM, inhibitory)
            for one network, and the shortest list of a batch. Spikes beyond it in one block are delivered by
            further passes in that block (exact); each extra pass is counted in ``State.counters.extra_passes`` and
            ``max_passes`` bounds the work.
        batch_spike_capacity: under ``vmap`` one list serves the whole batch of B networks, of length
            ``max(spike_capacity, ceil(B * batch_spike_capacity))`` per group: entries per network, sized for the
            mean spikes per block (~1 ES, ~0.3 EM, ~0.3 inhibitory at the original's rates and dt 0.25 ms) with
            room to spare; a batch's total is far steadier than one network's, so the list can be short.
            Both give one entry per spike group of the spec (``NetworkSpec.spike_groups``), or three that stand for
            (the first excitatory group, every other excitatory group, the inhibitory group).
        block_steps: upper limit on the steps per delivery block (0 = as long as exactness allows, see
            ``Network.block_steps``; 1 = deliver after every step). Changes speed, not results.
        max_passes: most spike-list passes per block and group; spikes still left after them are lost and counted
            in ``State.counters.lost_spikes`` (a test fails if any are). 0 = enough passes for every cell of every
            network to fire in one block, so nothing can be lost.
        out_capacity: out-degree capacity of the per-presynaptic-cell delivery rows; 0 = derive one per spike group
            from the sizes (mean + 6 sd). Synapses beyond it are counted in ``Wiring.out_overflow``.
        noise_max_rate_hz: highest background rate the Poisson noise tables must represent, Hz (sets how many
            events per step per receptor are representable, see ``noise_kmax``).
        event_summation: how several events of one channel (AMPA, GABA) arriving in the same step combine.
            "sequential" (default): as the original's one-event-at-a-time jumps, each moving V toward the reversal by
            w/E of the remaining distance (exact for any number of same-channel events; see
            ``jaxarm.network.cell.event_load``); "linear": summed weights times one driving force (the first-order
            form, which overshoots for volleys, e.g. the 22 simultaneous P inputs of every ES cell at t = 2 ms:
            88 mV vs the original's 49 mV). One event per step gives the same jump either way.
        threshold_test: when a cell's threshold is tested. "every_step" (default): at the end of every step, so a
            cell above threshold fires as soon as its refractory period ends; "on_event": only in steps in which at
            least one event (synaptic or noise, excitatory or inhibitory) arrives at the cell, as the event-driven
            original tests it (intf6.mod: on every arriving event; the end of the refractory period does not test),
            so a cell held above threshold waits for its next input.
        crossing: what a step whose input lifts a cell from below threshold to above Vblock (depolarisation block)
            does. "after_step" (default): the step's summed input is tested once, so the cell is blocked and fires
            only when it decays back below Vblock; "per_event": it fires, as in the event-driven original, which tests
            the threshold after every event and so fires at the event that crossed it (intf6.mod). The difference
            shows in volleys, e.g. the start-of-run volley: the 22 simultaneous P inputs of an ES cell lift it from
            rest to about -17 mV, past Vblock (-25 mV); the original fires every ES cell at t = 2 ms, "after_step"
            spreads those spikes over 2-10 ms. One event per step is tested the same way by both.
        same_step_inhibition: what a step whose excitation lifts a cell above threshold and whose inhibition brings
            it back below does. The event-driven original tests the threshold after every event, so it fires the
            cell if the excitatory event came first. "end_of_step" (default): the summed step is tested once, so the
            cell never fires, as if the inhibition always came first; the loss grows with dt (at 0.5 ms the M
            populations fire 10-20 % less than at 0.05 ms, experiments/dt_ablation.py). "random_order": the
            excitation comes first with probability 1/2, a coin per cell and step drawn from the noise hash
            (``jaxarm.network.noise.excitation_first``), and then the cell fires, as the original would have at the
            excitatory event. A model change: another random stream and other spikes than "end_of_step".
        plasticity_bookkeeping: keep each cell's last spike time and tag plastic synapses on postsynaptic spikes
            (``pdope``), for reward-modulated STDP.
        kernel: what runs a chunk of steps. "native": one compiled C++ call per chunk for the whole batch
            (``jaxarm.network.native``; CPU only, built on first use with the system C++ compiler); "xla": pure
            JAX (any backend; the spike-list fields above apply to it only); "auto" (default): native on a CPU
            backend when it builds, else xla. Same model and state layout; results agree to float rounding.
        native_threads: threads the native kernel splits a batch of networks over (default: $JAXARM_NATIVE_THREADS,
            else 1 = the calling thread only). Changes speed, never results (each network is computed by one thread).
        spike_gradient: "none" (default): spikes have no derivative and delivery uses spike lists; "fast_sigmoid":
            the same spikes on the forward pass, a surrogate derivative of the threshold on the backward pass
            (``jaxarm.network.surrogate``) and dense delivery (every cell's row, scaled by its spike), so gradients
            of anything the network drives reach its weights. XLA kernel only; it changes how, not what: forward
            spikes are bit for bit those of ``kernel="xla"``.
        surrogate_width_mv: width w of the surrogate derivative, mV (only with ``spike_gradient``).
        surrogate_scale: its dampening factor g (the derivative integrates to g over the margin); the default,
            0.05, is the largest whose gradient stays steady over noise streams; from about 0.2 this network's
            gradients explode (``jaxarm.network.surrogate``).
    """

    dt_ms: float = 0.25
    interface_ms: float = 10.0
    spec: NetworkSpec = field(default_factory=NetworkSpec.dura_bernal_2015)
    pmat_scale: float = 1.125
    self_connections: str = "code"
    p_tuning: str = "code"
    p_length_range_m: tuple[float, float] = (0.03, 0.23)
    p_rate_hz: float = 100.0
    p_start_ms: float = 1.0
    p_positions: int = 0
    readout_em_reference: int = 0
    readout_clip: bool = True
    readout_bins: int = 26
    spike_capacity: tuple[int, int, int] = (16, 8, 8)
    batch_spike_capacity: tuple[float, float, float] = (2.0, 1.0, 1.0)
    block_steps: int = 0
    max_passes: int = 0
    out_capacity: int = 0
    noise_max_rate_hz: float = 250.0
    event_summation: str = "sequential"
    threshold_test: str = "every_step"
    crossing: str = "after_step"
    same_step_inhibition: str = "end_of_step"
    plasticity_bookkeeping: bool = True
    kernel: str = "auto"
    native_threads: int = field(default_factory=lambda: int(os.environ.get("JAXARM_NATIVE_THREADS", "1")))
    spike_gradient: str = "none"
    surrogate_width_mv: float = 2.0
    surrogate_scale: float = 0.05

    def __post_init__(self):
        check_range(self, "dt_ms", 0.01, 1.0)
        if not _is_multiple(1.0, self.dt_ms):
            raise ConfigError(f"NetworkConfig.dt_ms = {self.dt_ms!r}: must divide 1 ms exactly (e.g. 0.1, 0.25, 0.5, 1)")
        check_range(self, "interface_ms", 1.0, 1000.0)
        if not _is_multiple(self.interface_ms, 1.0):
            raise ConfigError(f"NetworkConfig.interface_ms = {self.interface_ms!r}: must be a whole number of ms")
        if not isinstance(self.spec, NetworkSpec):
            raise ConfigError(f"NetworkConfig.spec: a NetworkSpec, got {type(self.spec).__name__}")
        check_range(self, "pmat_scale", 0.0, 100.0, lo_open=True)
        check_choice(self, "self_connections", ("code", "exclude"))
        check_choice(self, "p_tuning", ("code", "paper"))
        check_interval(self, "p_length_range_m", 0.0, 10.0)
        check_range(self, "p_rate_hz", 1.0, 1000.0)
        check_range(self, "p_start_ms", 0.0, 1000.0)
        if not _is_multiple(self.p_start_ms, self.dt_ms) and self.p_start_ms != 0.0:
            raise ConfigError(f"NetworkConfig.p_start_ms = {self.p_start_ms!r}: must be a multiple of dt_ms = {self.dt_ms}")
        per_group = self.n_p // 4
        check_range(self, "p_positions", 0, per_group, integer=True)
        if self.p_positions and per_group % self.p_positions:
            raise ConfigError(f"NetworkConfig.p_positions = {self.p_positions!r}: must divide the P cells per muscle "
                              f"group ({per_group}; 0 = one position per cell)")
        check_range(self, "readout_em_reference", 0, 100_000, integer=True)
        if not isinstance(self.readout_clip, bool):
            raise ConfigError(f"NetworkConfig.readout_clip = {self.readout_clip!r}: must be True or False")
        check_range(self, "readout_bins", 2, 1000, integer=True)
        n_groups = len(self.spec.spike_groups)
        if (not isinstance(self.spike_capacity, tuple) or len(self.spike_capacity) not in (3, n_groups)
                or not all(isinstance(k, int) and not isinstance(k, bool) and 1 <= k <= 4096
                           for k in self.spike_capacity)):
            raise ConfigError(f"NetworkConfig.spike_capacity = {self.spike_capacity!r}: a tuple of 3 or "
                              f"{n_groups} (one per spike group) integers in [1, 4096]")
        if (not isinstance(self.batch_spike_capacity, tuple) or len(self.batch_spike_capacity) not in (3, n_groups)
                or not all(isinstance(k, (int, float)) and not isinstance(k, bool) and 0.01 <= k <= 4096
                           for k in self.batch_spike_capacity)):
            raise ConfigError(f"NetworkConfig.batch_spike_capacity = {self.batch_spike_capacity!r}: a tuple of 3 or "
                              f"{n_groups} (one per spike group) numbers in [0.01, 4096]")
        check_range(self, "block_steps", 0, 10_000, integer=True)
        check_range(self, "max_passes", 0, 100_000, integer=True)
        check_range(self, "out_capacity", 0, 1_000_000, integer=True)
        check_range(self, "noise_max_rate_hz", 0.0, 5000.0, lo_open=True)
        check_choice(self, "event_summation", ("sequential", "linear"))
        check_choice(self, "threshold_test", ("every_step", "on_event"))
        check_choice(self, "crossing", ("after_step", "per_event"))
        check_choice(self, "same_step_inhibition", SAME_STEP_INHIBITION)
        if not isinstance(self.plasticity_bookkeeping, bool):
            raise ConfigError(f"NetworkConfig.plasticity_bookkeeping = {self.plasticity_bookkeeping!r}: "
                              "must be True or False")
        check_choice(self, "kernel", ("auto", "native", "xla"))
        check_range(self, "native_threads", 1, 256, integer=True)
        check_choice(self, "spike_gradient", ("none", "fast_sigmoid"))
        check_range(self, "surrogate_width_mv", 0.01, 100.0)
        check_range(self, "surrogate_scale", 0.0, 1.0, lo_open=True)
        if self.spike_gradient != "none" and self.kernel == "native":
            raise ConfigError(f"NetworkConfig.spike_gradient = {self.spike_gradient!r} needs kernel 'xla' or 'auto' "
                              "(the native kernel has no derivative), not 'native'")

    def scaled(self, factor: int) -> "NetworkConfig":
        """This network with every population ``factor`` times larger, by the original's scaling rules: in-degrees
        kept (``pmat_scale / factor``, the original's 0.75 * 6 / scale), the P code kept (its positions; more
        cells per position) and the readout normalised per EM cell (``readout_em_reference``), so each cell sees
        the inputs, and the arm the drive, of the network it was scaled from."""
        if isinstance(factor, bool) or not isinstance(factor, int) or not 1 <= factor <= 100:
            raise ConfigError(f"NetworkConfig.scaled factor = {factor!r}: an integer in [1, 100]")
        return dataclasses.replace(
            self, spec=self.spec.with_sizes(n * factor for n in self.sizes), pmat_scale=self.pmat_scale / factor,
            p_positions=self.p_positions_per_group,
            readout_em_reference=self.readout_em_reference or self.size(self.spec.readout))

    def with_sizes(self, sizes) -> "NetworkConfig":
        """This configuration with the spec's population sizes replaced (in population order)."""
        return dataclasses.replace(self, spec=self.spec.with_sizes(sizes))

    def group_capacities(self) -> tuple[tuple[int, ...], tuple[float, ...]]:
        """(spike_capacity, batch_spike_capacity) with one entry per spike group (a 3-entry setting stands for
        the first excitatory group, every other excitatory group, the inhibitory group)."""
        groups = self.spec.spike_groups
        exc = [self.spec.output(g[0]) == "excitatory" for g in groups]

        def per_group(values):
            if len(values) == len(groups) and (len(groups) != 3 or exc == [True, True, False]):
                return tuple(values)
            first = exc.index(True) if True in exc else -1
            return tuple(values[0] if i == first else values[1] if e else values[2] for i, e in enumerate(exc))

        return per_group(self.spike_capacity), per_group(self.batch_spike_capacity)

    # ----- as data -----
    def to_dict(self, changed_only: bool = False) -> dict:
        """The fields as plain JSON/TOML values (tuples as lists), one flat table: the spec's population sizes as
        ``sizes`` and, when the spec differs from the paper's in more than its sizes, the whole spec's parts
        (``populations``, ``pathways``, ``cell_types``, ``physics``, ``readout``, ``proprio``; see
        :class:`~jaxarm.config.spec.NetworkSpec`) instead. ``changed_only``: only what differs from NetworkConfig's
        defaults. The :data:`RUNTIME_FIELDS` (how to compute, not what) are left out."""
        default = NetworkConfig()
        out = {}
        paper = default.spec
        try:
            only_sizes = len(self.sizes) == len(paper.sizes) and self.spec == paper.with_sizes(self.sizes)
        except ConfigError:          # sizes the paper's populations cannot take: another network
            only_sizes = False
        if not only_sizes:
            out.update(self.spec.to_dict())
        elif not (changed_only and self.sizes == paper.sizes):
            out["sizes"] = list(self.sizes)
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "spec" or f.name in RUNTIME_FIELDS or (changed_only and v == getattr(default, f.name)):
                continue
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    @classmethod
    def from_dict(cls, data: dict, base: "NetworkConfig | None" = None, what: str = "network") -> "NetworkConfig":
        """``base`` (default: NetworkConfig()) with the fields of ``data`` set, in :meth:`to_dict`'s flat form:
        NetworkConfig fields, ``sizes`` (the spec's population sizes) and any part of a NetworkSpec (replacing
        that part of ``base``'s spec). An unknown key is an error naming it and the known ones, and every value is
        validated as the constructors do."""
        base = base or cls()
        names = {f.name for f in dataclasses.fields(cls)} - {"spec"}
        unknown = sorted(set(data) - names - set(SPEC_KEYS) - {"sizes"})
        if unknown:
            raise ConfigError(f"{what}: unknown NetworkConfig field(s) {', '.join(unknown)}; known: "
                              f"{', '.join(sorted(names | {'sizes'}))} and the spec's {', '.join(SPEC_KEYS)}")
        spec = base.spec
        spec_part = {k: v for k, v in data.items() if k in SPEC_KEYS}
        if spec_part:
            spec = NetworkSpec.from_dict(spec_part, base=spec, what=what)
        if "sizes" in data:
            sizes = data["sizes"]
            if not isinstance(sizes, (list, tuple)) or not all(
                    isinstance(n, int) and not isinstance(n, bool) for n in sizes):
                raise ConfigError(f"NetworkConfig.sizes = {sizes!r}: a list of {len(spec.populations)} integers in "
                                  f"[1, 100000], one per population {', '.join(spec.names)}")
            if len(sizes) != len(spec.populations):
                raise ConfigError(f"NetworkConfig.sizes = {list(sizes)!r}: {len(spec.populations)} integers, one per "
                                  f"population {', '.join(spec.names)}")
            spec = spec.with_sizes(sizes)
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items() if k in names}
        return dataclasses.replace(base, spec=spec, **values)

    @classmethod
    def load(cls, path) -> "NetworkConfig":
        """A NetworkConfig from a TOML (``.toml``) or JSON file in :meth:`to_dict`'s form (what it does not give
        keeps its default), e.g. ``sizes = [384, 88, 40, 384, 88, 40, 384]`` and ``pmat_scale = 0.5625``, or a
        whole network (``[[populations]]``, ``[[pathways]]``, ... as :meth:`save` writes them)."""
        return cls.from_dict(read_table(path, "--network"), what=f"--network {path}")

    def save(self, path, changed_only: bool = True) -> None:
        """Write the fields (by default only those that differ from the defaults) as TOML (``.toml``) or JSON."""
        import json
        from pathlib import Path

        path = Path(path)
        data = self.to_dict(changed_only)
        if path.suffix == ".toml":
            path.write_text(to_toml(data, "jaxarm NetworkConfig (what is not listed keeps its default)"))
        else:
            path.write_text(json.dumps(data, indent=1) + "\n")

    # ----- derived static quantities -----
    @property
    def p_positions_per_group(self) -> int:
        """Positions of the P code per muscle group (``p_positions``, or n_P / 4)."""
        return self.p_positions or self.n_p // 4

    @property
    def sizes(self) -> tuple[int, ...]:
        """Population sizes in the spec's order (the paper's: ES, IS, ISL, EM, IM, IML, P)."""
        return self.spec.sizes

    @property
    def populations(self) -> tuple[str, ...]:
        """Population names in global-id order (network populations, then the generator)."""
        return self.spec.names

    def size(self, pop: str) -> int:
        return self.spec.population(pop).size

    @property
    def n_cells(self) -> int:
        """Network (INTF6) cells: every population but the generators (ids 0 .. n_cells - 1)."""
        return sum(self.size(p) for p in self.spec.network_populations)

    @property
    def n_p(self) -> int:
        """Cells of the proprioceptive (P) code."""
        return self.size(self.spec.proprio)

    @property
    def n_generators(self) -> int:
        """Generator cells, every generator population (ids n_cells .. n_all - 1; the paper's: the 192 P cells)."""
        return self.n_all - self.n_cells

    @property
    def n_all(self) -> int:
        """All cells with a global id (network cells, then P generators)."""
        return sum(self.sizes)

    def steps(self, ms: float) -> int:
        """Whole steps in ``ms`` (rounded to the nearest step)."""
        return int(round(ms / self.dt_ms))

    @property
    def steps_per_interface(self) -> int:
        return self.steps(self.interface_ms)

    @property
    def noise_kmax(self) -> int:
        """Most Poisson noise events per step per receptor that the noise tables represent: the smallest k with
        P(N > k) < 2**-24 (the resolution of the 32-bit uniform draws, compared in float32) at the highest rate."""
        lam = self.noise_max_rate_hz * self.dt_ms / 1000.0
        term, cdf, k = math.exp(-lam), math.exp(-lam), 0
        while 1.0 - cdf >= 2.0 ** -24 and k < 64:
            k += 1
            term *= lam / k
            cdf += term
        return max(k, 1)
