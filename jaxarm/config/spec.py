"""The network as data: populations, cell types, pathways, background noise and synaptic physics ([model:
equations](../model.md#equations)).

A :class:`NetworkSpec` is a frozen, hashable, validated description, in the spirit of NetPyNE's network
parameters: everything the kernels need to know about *what* the network is (how it is computed lives in
:class:`jaxarm.config.network.NetworkConfig`, which holds a spec). Edit it in Python (``dataclasses.replace``,
:meth:`NetworkSpec.with_population`, :meth:`NetworkSpec.with_pathway`) or as a TOML/JSON file
(:meth:`NetworkSpec.save`, :meth:`NetworkSpec.load`)::

    spec = NetworkSpec.dura_bernal_2015()                  # the paper's network (the default of NetworkConfig)
    spec = spec.with_population(Population("EX", 64, "E", noise=((3.75, 200.0), (1.875, 100.0), (1.875, 100.0))))
    spec = spec.with_pathway(Pathway("ES", "EX", pmat=0.3, weight_mv=2.64, delay_ms=(3.0, 5.0), plastic=True))
    config = NetworkConfig(spec=spec)

Conventions the kernels rely on, checked here (a violation is a ConfigError naming the population or pathway):

* Network (INTF6) populations first, in global-id order; the generator populations (regular spike trains, known a
  chunk ahead) last: the proprioceptive code (``proprio``, trains set by the muscle lengths) and any number of
  target codes (``code="target"``: cell j belongs to direction group j % ``groups`` and fires at ``rate_hz`` while
  the current target lies in its direction, seen from the start hand position; silent otherwise).
* Pathways: the plastic ones first (plastic synapse k is synapse k; a target code's pathways may be plastic), then
  the fixed ones between network cells, then the fixed ones from generators (delivered once per chunk).
* Spike groups (which cells share one spike list and delivery table): each excitatory population alone, in order,
  then every inhibitory population together (the paper's: ES; EM; IS, ISL, IM, IML); at most 8 groups.
* The motor readout population (``readout``) and the generator population have multiples of 4 cells (four muscle
  groups, id % 4).

Units: mV, ms and Hz, as the names say.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from jaxarm.config.validate import ConfigError

#: The synaptic output of each cell type: which receptor channel its spikes drive on the postsynaptic cell.
OUTPUTS = ("excitatory", "inhibitory_proximal", "inhibitory_distal")
#: Background-noise receptor lanes, in the order of every (3, n_cells) noise array.
NOISE_RECEPTORS = ("ampa", "gaba_prox", "gaba_dist")
#: The cell type name of a generator population (a train of spikes, no membrane).
GENERATOR = "generator"
#: What sets a generator population's trains: the muscle lengths, or the direction of the current target.
GENERATOR_CODES = ("proprioceptive", "target")
#: Most spike groups the native kernel takes.
MAX_SPIKE_GROUPS = 8
MAX_POPULATION = 100_000


def _number(owner: str, name: str, value, lo: float, hi: float, lo_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or \
            not ((lo < value) if lo_open else (lo <= value)) or value > hi:
        raise ConfigError(f"{owner}.{name} = {value!r}: must be a number in {'(' if lo_open else '['}{lo}, {hi}]")
    return float(value)


@dataclass(frozen=True)
class CellType:
    """INTF6 parameters of one cell type (params.hoc, [model: cell](../model.md#cell-intf6-clock-driven)) and the
    receptor its spikes drive.

    ``rmp_mv`` resting potential; ``vth_mv`` resting threshold; ``vblock_mv`` depolarisation block (a cell above it
    does not fire); ``refrac_ms`` absolute refractory period; ``ahpwt_mv`` after-hyperpolarisation per spike;
    ``tauahp_ms`` its decay; ``taurr_ms`` decay of the post-spike threshold rise, ``rrwght`` its size as a fraction
    of Vblock - VTH; ``output``: one of :data:`OUTPUTS` (AMPA + NMDA distal, GABA proximal, GABA distal)."""

    name: str
    rmp_mv: float
    vth_mv: float
    vblock_mv: float
    refrac_ms: float
    ahpwt_mv: float
    tauahp_ms: float
    taurr_ms: float
    rrwght: float
    output: str

    def __post_init__(self):
        owner = f"CellType {self.name!r}"
        if not isinstance(self.name, str) or not self.name.isidentifier() or self.name == GENERATOR:
            raise ConfigError(f"CellType.name = {self.name!r}: an identifier other than {GENERATOR!r}")
        for f in ("rmp_mv", "vth_mv", "vblock_mv"):
            object.__setattr__(self, f, _number(owner, f, getattr(self, f), -100.0, 0.0))
        if not self.rmp_mv < self.vth_mv < self.vblock_mv:
            raise ConfigError(f"{owner}: needs rmp_mv < vth_mv < vblock_mv, got {self.rmp_mv}, {self.vth_mv}, "
                              f"{self.vblock_mv}")
        object.__setattr__(self, "refrac_ms", _number(owner, "refrac_ms", self.refrac_ms, 0.0, 1000.0, True))
        object.__setattr__(self, "ahpwt_mv", _number(owner, "ahpwt_mv", self.ahpwt_mv, 0.0, 100.0))
        for f in ("tauahp_ms", "taurr_ms"):
            object.__setattr__(self, f, _number(owner, f, getattr(self, f), 0.0, 1e6, True))
        object.__setattr__(self, "rrwght", _number(owner, "rrwght", self.rrwght, 0.0, 1.0))
        if self.output not in OUTPUTS:
            raise ConfigError(f"{owner}.output = {self.output!r}: one of {', '.join(OUTPUTS)}")

    @property
    def excitatory(self) -> bool:
        return self.output == "excitatory"


@dataclass(frozen=True)
class Population:
    """``size`` cells of one type (a :class:`CellType` name, or ``"generator"``). ``noise``: the background
    Poisson input of each cell, one (weight mV, rate Hz) per receptor of :data:`NOISE_RECEPTORS`; () for a
    generator population (it has no membrane). A generator population has a ``code`` (:data:`GENERATOR_CODES`);
    a target code also ``groups`` (directions, cell j codes direction j % groups, direction k at k x 360/groups
    degrees counterclockwise from +x) and ``rate_hz`` (its cells' rate while their direction is the target's)."""

    name: str
    size: int
    cell_type: str
    noise: tuple[tuple[float, float], ...] = ()
    code: str = ""
    groups: int = 0
    rate_hz: float = 0.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ConfigError(f"Population.name = {self.name!r}: must be an identifier (e.g. 'ES')")
        owner = f"Population {self.name!r}"
        if isinstance(self.size, bool) or not isinstance(self.size, int) or not 1 <= self.size <= MAX_POPULATION:
            raise ConfigError(f"{owner}.size = {self.size!r}: an integer in [1, {MAX_POPULATION}]")
        noise = tuple(tuple(x) if isinstance(x, (list, tuple)) else x for x in (self.noise or ()))
        if self.cell_type == GENERATOR:
            if noise:
                raise ConfigError(f"{owner}.noise: a generator population takes no background noise")
            if self.code not in GENERATOR_CODES:
                raise ConfigError(f"{owner}.code = {self.code!r}: a generator population's code is one of "
                                  f"{', '.join(GENERATOR_CODES)}")
            if self.code == "target":
                if isinstance(self.groups, bool) or not isinstance(self.groups, int) or not 1 <= self.groups <= 64 \
                        or self.size % self.groups:
                    raise ConfigError(f"{owner}.groups = {self.groups!r}: an integer in [1, 64] that divides its "
                                      f"size {self.size}")
                object.__setattr__(self, "rate_hz", _number(owner, "rate_hz", self.rate_hz, 0.0, 1000.0, True))
            elif self.groups or self.rate_hz:
                raise ConfigError(f"{owner}: groups and rate_hz belong to a target code (the proprioceptive code's "
                                  "rate is NetworkConfig.p_rate_hz)")
        elif self.code or self.groups or self.rate_hz:
            raise ConfigError(f"{owner}: code, groups and rate_hz belong to generator populations")
        elif len(noise) != len(NOISE_RECEPTORS) or not all(isinstance(x, tuple) and len(x) == 2 for x in noise):
            raise ConfigError(f"{owner}.noise = {self.noise!r}: one (weight mV, rate Hz) pair per receptor "
                              f"{', '.join(NOISE_RECEPTORS)}")
        noise = tuple((_number(owner, f"noise[{r}] weight_mv", w, 0.0, 100.0),
                       _number(owner, f"noise[{r}] rate_hz", hz, 0.0, 5000.0))
                      for r, (w, hz) in zip(NOISE_RECEPTORS, noise))
        object.__setattr__(self, "noise", noise)


@dataclass(frozen=True)
class Pathway:
    """Connections ``pre -> post``: every post cell draws ``int(0.5 + pmat * pmat_scale * N_pre)`` distinct
    presynaptic partners; base weight ``weight_mv`` (AMPA for an excitatory presynaptic type, with NMDA =
    ``nmda_ampa_ratio`` x AMPA; GABA for an inhibitory one); delays uniform in ``delay_ms`` (rounded to the clock
    step, at least one step); ``plastic``: reward-modulated STDP with soft bounds (plast_ee_maxw onto excitatory
    cells, plast_ei_maxw onto inhibitory ones)."""

    pre: str
    post: str
    pmat: float
    weight_mv: float
    delay_ms: tuple[float, float]
    plastic: bool = False

    def __post_init__(self):
        owner = f"Pathway {self.pre}->{self.post}"
        object.__setattr__(self, "pmat", _number(owner, "pmat", self.pmat, 0.0, 1.0, True))
        object.__setattr__(self, "weight_mv", _number(owner, "weight_mv", self.weight_mv, 0.0, 1000.0))
        d = tuple(self.delay_ms) if isinstance(self.delay_ms, (list, tuple)) else ()
        if len(d) != 2:
            raise ConfigError(f"{owner}.delay_ms = {self.delay_ms!r}: a (low, high) pair in ms")
        d = tuple(_number(owner, "delay_ms", x, 0.0, 1000.0, True) for x in d)
        if d[0] > d[1]:
            raise ConfigError(f"{owner}.delay_ms = {self.delay_ms!r}: low must not exceed high")
        object.__setattr__(self, "delay_ms", d)
        if not isinstance(self.plastic, bool):
            raise ConfigError(f"{owner}.plastic = {self.plastic!r}: must be true or false")

    @property
    def name(self) -> str:
        return f"{self.pre}->{self.post}"


@dataclass(frozen=True)
class SynapsePhysics:
    """Constants every cell shares (params.hoc, intf6.mod; [model: cell](../model.md#cell-intf6-clock-driven)): reversal
    potentials relative to rest, the NMDA Mg block B(v) = 1 / (1 + exp(-mg_slope_per_mv v) mg_mm / mg0_mm), the membrane
    clamp, the synaptic decay time constants, the NMDA/AMPA weight ratio (NMAMR) and the largest jump of the sequential
    event summation (w / E saturates there)."""

    e_ampa_mv: float = 65.0
    e_nmda_mv: float = 90.0
    e_gaba_mv: float = -15.0
    mg_mm: float = 1.6
    mg0_mm: float = 3.57
    mg_slope_per_mv: float = 0.062
    vm_min_mv: float = -90.0
    vm_max_mv: float = 0.0
    tau_ampa_ms: float = 20.0
    tau_nmda_ms: float = 300.0
    tau_gaba_prox_ms: float = 10.0
    tau_gaba_dist_ms: float = 20.0
    nmda_ampa_ratio: float = 0.1
    max_jump_fraction: float = 1.0 - 1e-6

    def __post_init__(self):
        o = "SynapsePhysics"
        for f, lo, hi, lo_open in (("e_ampa_mv", 0.0, 500.0, True), ("e_nmda_mv", 0.0, 500.0, True),
                                   ("e_gaba_mv", -500.0, -1e-9, False), ("mg_mm", 0.0, 100.0, False),
                                   ("mg0_mm", 0.0, 100.0, True), ("mg_slope_per_mv", 0.0, 10.0, False),
                                   ("vm_min_mv", -500.0, 0.0, False), ("vm_max_mv", -500.0, 500.0, False),
                                   ("tau_ampa_ms", 0.0, 1e6, True), ("tau_nmda_ms", 0.0, 1e6, True),
                                   ("tau_gaba_prox_ms", 0.0, 1e6, True), ("tau_gaba_dist_ms", 0.0, 1e6, True),
                                   ("nmda_ampa_ratio", 0.0, 100.0, False), ("max_jump_fraction", 0.0, 1.0, True)):
            object.__setattr__(self, f, _number(o, f, getattr(self, f), lo, hi, lo_open))
        if self.max_jump_fraction >= 1.0:
            raise ConfigError(f"{o}.max_jump_fraction = {self.max_jump_fraction!r}: must be below 1")
        if self.vm_min_mv >= self.vm_max_mv:
            raise ConfigError(f"{o}: vm_min_mv must be below vm_max_mv")


_E_NOISE = ((3.75, 200.0), (1.875, 100.0), (1.875, 100.0))
_DISTAL, _SOMA = (3.0, 5.0), (1.8, 2.2)


@dataclass(frozen=True)
class NetworkSpec:
    """What the network is (see the module docstring for the conventions checked). ``readout``: the population
    whose spikes, per muscle group (global id % 4), drive the muscles; ``proprio``: the generator population that
    codes the muscle lengths."""

    populations: tuple[Population, ...]
    pathways: tuple[Pathway, ...]
    cell_types: tuple[CellType, ...]
    physics: SynapsePhysics = SynapsePhysics()
    readout: str = "EM"
    proprio: str = "P"

    def __post_init__(self):
        for f, cls in (("populations", Population), ("pathways", Pathway), ("cell_types", CellType)):
            items = getattr(self, f)
            if not isinstance(items, (tuple, list)) or not all(isinstance(x, cls) for x in items):
                raise ConfigError(f"NetworkSpec.{f}: a sequence of {cls.__name__}")
            object.__setattr__(self, f, tuple(items))
        if not isinstance(self.physics, SynapsePhysics):
            raise ConfigError("NetworkSpec.physics: a SynapsePhysics")
        types = {t.name: t for t in self.cell_types}
        if len(types) != len(self.cell_types):
            raise ConfigError("NetworkSpec.cell_types: names must be unique")
        names = [p.name for p in self.populations]
        if len(set(names)) != len(names):
            raise ConfigError(f"NetworkSpec.populations: names must be unique, got {', '.join(names)}")
        for p in self.populations:
            if p.cell_type != GENERATOR and p.cell_type not in types:
                raise ConfigError(f"Population {p.name!r}.cell_type = {p.cell_type!r}: one of "
                                  f"{', '.join(list(types) + [GENERATOR])}")
        is_gen = [p.cell_type == GENERATOR for p in self.populations]
        if is_gen != sorted(is_gen) or not is_gen[-1]:
            raise ConfigError(f"NetworkSpec.populations: the generator populations come last; got "
                              f"{', '.join(f'{p.name} ({p.cell_type})' for p in self.populations)}")
        proprio = [p.name for p in self.populations if p.code == "proprioceptive"]
        if proprio != [self.proprio]:
            raise ConfigError(f"NetworkSpec.proprio = {self.proprio!r}: exactly one generator population with code "
                              f"'proprioceptive', named so; got {proprio}")
        if not any(not g for g in is_gen):
            raise ConfigError("NetworkSpec.populations: at least one network population")
        if self.readout not in self.network_populations:
            raise ConfigError(f"NetworkSpec.readout = {self.readout!r}: one of the network populations "
                              f"{', '.join(self.network_populations)}")
        for name in (self.readout, self.proprio):
            if self.population(name).size % 4:
                raise ConfigError(f"Population {name!r}.size = {self.population(name).size}: must be a multiple of "
                                  "4 (four muscle groups, id % 4)")
        seen = set()
        n_plastic = sum(pw.plastic for pw in self.pathways)
        for i, pw in enumerate(self.pathways):
            for end in (pw.pre, pw.post):
                if end not in names:
                    raise ConfigError(f"Pathway {pw.name}: no population {end!r}; known: {', '.join(names)}")
            if pw.post in self.generators:
                raise ConfigError(f"Pathway {pw.name}: the generator population {pw.post!r} takes no input")
            if pw.name in seen:
                raise ConfigError(f"Pathway {pw.name}: given twice")
            seen.add(pw.name)
            if pw.plastic != (i < n_plastic):
                raise ConfigError(f"Pathway {pw.name} (position {i}): the {n_plastic} plastic pathways must come "
                                  "first")
            if pw.plastic and pw.pre == self.proprio:
                raise ConfigError(f"Pathway {pw.name}: pathways from the proprioceptive code cannot be plastic "
                                  "(its trains are the arm's state)")
        fixed_from_gen = [pw.pre in self.generators for pw in self.pathways if not pw.plastic]
        if not any(pw.pre == self.proprio for pw in self.pathways) or fixed_from_gen != sorted(fixed_from_gen):
            raise ConfigError(f"NetworkSpec.pathways: the fixed pathways from generators ({', '.join(self.generators)})"
                              f" come last, with at least one from {self.proprio!r}; got "
                              f"{', '.join(pw.name for pw in self.pathways)}")
        if len(self.spike_groups) > MAX_SPIKE_GROUPS:
            raise ConfigError(f"NetworkSpec: {len(self.spike_groups)} spike groups (one per excitatory population "
                              f"plus one for the inhibitory ones); at most {MAX_SPIKE_GROUPS}")

    # ----- the paper's network -----
    @classmethod
    def dura_bernal_2015(cls) -> "NetworkSpec":
        """The network of Dura-Bernal et al. 2015 (the original's col.hoc at scale 4, [model:
        equations](../model.md#equations)): populations in the original's global-id order, its pathway table (EM ->
        IS/ISL absent: EMISFeedBack = 0), its background noise (stim.hoc setwmatex, EXGain 15 included) and INTF6
        parameters (params.hoc L71-136). One shared (immutable) object: every NetworkConfig() holds it without
        rebuilding and re-validating it."""
        return _paper_spec(cls)

    # ----- lookups -----
    @property
    def names(self) -> tuple[str, ...]:
        """Population names in global-id order."""
        return tuple(p.name for p in self.populations)

    @property
    def network_populations(self) -> tuple[str, ...]:
        """The INTF6 populations (all but the generators), in order."""
        return tuple(p.name for p in self.populations if p.cell_type != GENERATOR)

    @property
    def generators(self) -> tuple[str, ...]:
        """The generator populations (last in id order): the proprioceptive code and any target codes."""
        return tuple(p.name for p in self.populations if p.cell_type == GENERATOR)

    @property
    def target_codes(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.populations if p.code == "target")

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(p.size for p in self.populations)

    def population(self, name: str) -> Population:
        for p in self.populations:
            if p.name == name:
                return p
        raise KeyError(f"no population {name!r}; known: {', '.join(self.names)}")

    def cell_type(self, name: str) -> CellType:
        """The CellType of a network population (``name``), or of a cell-type name."""
        key = self.population(name).cell_type if name in self.names else name
        for t in self.cell_types:
            if t.name == key:
                return t
        raise KeyError(f"no cell type {key!r}")

    def output(self, population: str) -> str:
        """The receptor a population's spikes drive (a generator population's are excitatory)."""
        return "excitatory" if population in self.generators else self.cell_type(population).output

    def pathway(self, name: str) -> Pathway:
        for pw in self.pathways:
            if pw.name == name:
                return pw
        raise KeyError(f"no pathway {name!r}; known: {', '.join(p.name for p in self.pathways)}")

    @property
    def spike_groups(self) -> tuple[tuple[str, ...], ...]:
        """Network populations sharing one spike list and delivery table: each excitatory one alone, then the
        inhibitory ones together."""
        exc = tuple((p,) for p in self.network_populations if self.output(p) == "excitatory")
        inh = tuple(p for p in self.network_populations if self.output(p) != "excitatory")
        return exc + ((inh,) if inh else ())

    # ----- editing -----
    def with_sizes(self, sizes) -> "NetworkSpec":
        """This spec with the population sizes replaced (in population order)."""
        sizes = tuple(sizes)
        if len(sizes) != len(self.populations):
            raise ConfigError(f"sizes = {list(sizes)!r}: {len(self.populations)} integers, one per population "
                              f"{', '.join(self.names)}")
        return dataclasses.replace(self, populations=tuple(
            dataclasses.replace(p, size=n) for p, n in zip(self.populations, sizes)))

    def with_population(self, population: Population) -> "NetworkSpec":
        """This spec with a population added after the others of its kind (a network population before the
        generators, a generator last)."""
        pops = list(self.populations)
        i = len(pops) if population.cell_type == GENERATOR else len(self.network_populations)
        return dataclasses.replace(self, populations=tuple(pops[:i] + [population] + pops[i:]))

    def with_pathway(self, pathway: Pathway) -> "NetworkSpec":
        """This spec with a pathway added where the ordering rules put it: after the plastic ones if plastic, else
        last if from a generator, else before the fixed ones from generators."""
        pws = list(self.pathways)
        if pathway.plastic:
            i = sum(p.plastic for p in pws)
        elif pathway.pre in self.generators:
            i = len(pws)
        else:
            i = next((k for k, p in enumerate(pws) if not p.plastic and p.pre in self.generators), len(pws))
        return dataclasses.replace(self, pathways=tuple(pws[:i] + [pathway] + pws[i:]))

    def with_plastic(self, names) -> "NetworkSpec":
        """This spec with exactly the pathways ``names`` (e.g. ``"T->EM"``) plastic and the others fixed, reordered
        by the ordering rules (plastic first, the fixed ones from generators last)."""
        names = set(names)
        unknown = names - {pw.name for pw in self.pathways}
        if unknown:
            raise ConfigError(f"plastic pathways: no pathway {sorted(unknown)[0]!r}; known: "
                              f"{', '.join(pw.name for pw in self.pathways)}")
        pws = [dataclasses.replace(pw, plastic=pw.name in names) for pw in self.pathways]
        return dataclasses.replace(self, pathways=tuple(sorted(
            pws, key=lambda pw: 0 if pw.plastic else 2 if pw.pre in self.generators else 1)))   # sorted is stable

    def without_population(self, name: str) -> "NetworkSpec":
        """This spec without the population ``name`` and every pathway from or to it."""
        self.population(name)   # KeyError naming the known ones
        return dataclasses.replace(self, populations=tuple(p for p in self.populations if p.name != name),
                                   pathways=tuple(pw for pw in self.pathways if name not in (pw.pre, pw.post)))

    # ----- as data -----
    def to_dict(self) -> dict:
        """Plain JSON/TOML values (tuples as lists)."""
        def plain(x):
            if isinstance(x, tuple):
                return [plain(v) for v in x]
            return x

        return {"readout": self.readout, "proprio": self.proprio,
                "populations": [{k: plain(v) for k, v in dataclasses.asdict(p).items()
                                 if v or k in ("name", "size", "cell_type")} for p in self.populations],
                "pathways": [{k: plain(v) for k, v in dataclasses.asdict(pw).items()} for pw in self.pathways],
                "cell_types": [dataclasses.asdict(t) for t in self.cell_types],
                "physics": dataclasses.asdict(self.physics)}

    @classmethod
    def from_dict(cls, data: dict, base: "NetworkSpec | None" = None, what: str = "spec") -> "NetworkSpec":
        """``base`` (default: the paper's) with the parts ``data`` gives replaced (``populations``, ``pathways``,
        ``cell_types`` as whole lists; ``physics`` field by field; ``readout``, ``proprio``). Unknown keys are
        errors naming them."""
        base = base or cls.dura_bernal_2015()
        if not isinstance(data, dict):
            raise ConfigError(f"{what}: expected a table")
        known = {"populations": Population, "pathways": Pathway, "cell_types": CellType}
        unknown = sorted(set(data) - set(known) - {"physics", "readout", "proprio"})
        if unknown:
            raise ConfigError(f"{what}: unknown key(s) {', '.join(unknown)}; known: populations, pathways, "
                              "cell_types, physics, readout, proprio")
        parts = {}
        for key, item_cls in known.items():
            if key in data:
                if not isinstance(data[key], (list, tuple)):
                    raise ConfigError(f"{what} {key}: expected a list of tables, got {type(data[key]).__name__}")
                parts[key] = tuple(_build(item_cls, row, f"{what} {key}[{i}]") for i, row in enumerate(data[key]))
        if "physics" in data:
            parts["physics"] = _build(SynapsePhysics, {**dataclasses.asdict(base.physics), **data["physics"]},
                                      f"{what} physics")
        for key in ("readout", "proprio"):
            if key in data:
                parts[key] = data[key]
        return dataclasses.replace(base, **parts)

    @classmethod
    def load(cls, path) -> "NetworkSpec":
        """A spec from a TOML (``.toml``) or JSON file (see :meth:`from_dict`; :meth:`save` writes one)."""
        return cls.from_dict(read_table(path, "network spec"), what=str(path))

    def save(self, path) -> None:
        """Write the whole spec as TOML (``.toml``) or JSON."""
        path = Path(path)
        data = self.to_dict()
        path.write_text(to_toml(data, "jaxarm NetworkSpec") if path.suffix == ".toml"
                        else json.dumps(data, indent=1) + "\n")


@functools.lru_cache(maxsize=None)
def _paper_spec(cls) -> NetworkSpec:
    """NetworkSpec.dura_bernal_2015(), built once."""
    inh = ((1.875, 100.0), (1.875, 100.0))
    populations = (
        Population("ES", 192, "E", _E_NOISE),
        Population("IS", 44, "FS", ((4.125, 200.0),) + inh),
        Population("ISL", 20, "LTS", ((3.0, 200.0),) + inh),
        Population("EM", 192, "E", ((3.9375, 200.0),) + inh),
        Population("IM", 44, "FS", ((4.125, 200.0),) + inh),
        Population("IML", 20, "LTS", ((3.0, 200.0),) + inh),
        Population("P", 192, GENERATOR, code="proprioceptive"),
    )
    pathways = (
        Pathway("ES", "ES", 0.05, 1.98, _DISTAL, True),
        Pathway("ES", "IS", 0.43, 1.15, _DISTAL, True),
        Pathway("ES", "ISL", 0.51, 0.575, _DISTAL, True),
        Pathway("ES", "EM", 0.30, 2.64, _DISTAL, True),
        Pathway("EM", "EM", 0.05, 1.782, _DISTAL, True),
        Pathway("EM", "IM", 0.43, 1.15, _DISTAL, True),
        Pathway("EM", "IML", 0.51, 0.575, _DISTAL, True),
        Pathway("EM", "ES", 0.01, 0.72, _DISTAL, True),
        Pathway("ES", "IM", 0.05, 1.15, _DISTAL),
        Pathway("ES", "IML", 0.05, 0.575, _DISTAL),
        Pathway("IS", "ES", 0.44, 4.5, _SOMA),
        Pathway("IS", "IS", 0.62, 4.5, _SOMA),
        Pathway("IS", "ISL", 0.34, 4.5, _SOMA),
        Pathway("ISL", "ES", 0.35, 1.245, _DISTAL),
        Pathway("ISL", "IS", 0.53, 2.25, _DISTAL),
        Pathway("ISL", "ISL", 0.09, 4.5, _DISTAL),
        Pathway("IM", "EM", 0.44, 9.0, _SOMA),
        Pathway("IM", "IM", 0.62, 4.5, _SOMA),
        Pathway("IM", "IML", 0.34, 4.5, _SOMA),
        Pathway("IML", "EM", 0.35, 2.49, _DISTAL),
        Pathway("IML", "IM", 0.53, 2.25, _DISTAL),
        Pathway("IML", "IML", 0.09, 4.5, _DISTAL),
        Pathway("P", "ES", 0.1, 4.0, (1.0, 1.0)),
    )
    cell_types = (
        CellType("E", -65.0, -40.0, -25.0, 5.0, 1.0, 400.0, 8.0, 0.75, "excitatory"),
        CellType("FS", -63.0, -40.0, -10.0, 2.5, 0.5, 50.0, 1.5, 0.25, "inhibitory_proximal"),
        CellType("LTS", -65.0, -47.0, -10.0, 2.5, 0.5, 50.0, 1.5, 0.25, "inhibitory_distal"),
    )
    return cls(populations, pathways, cell_types)


def _build(cls, row, what: str):
    if not isinstance(row, dict):
        raise ConfigError(f"{what}: expected a table of {cls.__name__} fields")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(row) - names)
    missing = sorted(f.name for f in dataclasses.fields(cls) if f.name not in row
                     and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING)
    if unknown or missing:
        raise ConfigError(f"{what}: {'unknown field(s) ' + ', '.join(unknown) if unknown else ''}"
                          f"{'; ' if unknown and missing else ''}{'missing ' + ', '.join(missing) if missing else ''}"
                          f"; {cls.__name__} fields: {', '.join(sorted(names))}")
    try:
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in row.items()})
    except TypeError as e:
        raise ConfigError(f"{what}: {e}") from None


def read_table(path, what: str) -> dict:
    """The top-level table of a TOML (``.toml``) or JSON file; one-line ConfigErrors for unreadable or invalid
    files."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"{what} {path}: cannot read it ({e.strerror})") from None
    try:
        data = tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as e:
        raise ConfigError(f"{what} {path}: not valid {'TOML' if path.suffix == '.toml' else 'JSON'} "
                          f"({str(e).splitlines()[0]})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{what} {path}: expected a table")
    return data


def to_toml(data: dict, title: str) -> str:
    """TOML for a table of scalars, flat or nested arrays of numbers, sub-tables of those and arrays of such
    tables (what the configs here hold); read back with ``tomllib``."""
    def value(v):
        return json.dumps(v)   # numbers, strings, bools and (nested) arrays of them are the same in TOML

    lines = [f"# {title}"]
    scalars = {k: v for k, v in data.items() if not isinstance(v, dict) and not (
        isinstance(v, list) and v and all(isinstance(x, dict) for x in v))}
    lines += [f"{k} = {value(v)}" for k, v in scalars.items()]
    for k, v in data.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{kk} = {value(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for row in v:
                lines += ["", f"[[{k}]]"] + [f"{kk} = {value(vv)}" for kk, vv in row.items()]
    return "\n".join(lines) + "\n"
