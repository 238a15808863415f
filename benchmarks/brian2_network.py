"""The jaxarm network in Brian2's C++ standalone mode, for the throughput comparison of benchmarks/network.py.

    python benchmarks/brian2_network.py --json                      # 1 network, default dt, 10 s, 3 timed runs
    python benchmarks/brian2_network.py --seconds 2 --repeats 1 --jaxarm-rates 0   # quick, no jaxarm comparison

Needs the ``bench`` extra (``pip install -e '.[bench]'``: brian2) and a C++ compiler.

What is simulated: one jaxarm network under a fixed drive, no plasticity — the same 512 INTF6 cells, the same
synapses (taken from ``Network(config).make_wiring(jax.random.key(seed))``: pre, post, delay, weight, NMDA weight
of every synapse), Poisson background per cell and receptor at the rates and weights of
the spec (``NetworkSpec.dura_bernal_2015()``, ``Population.noise``; EM AMPA at its default 200 Hz), and the 192 P generators for the muscle
lengths of the simple arm's start posture: every P cell fires at 1 ms (``p_start_ms``), the cells coding those
lengths (12 of 192) then fire regular 100 Hz trains from 20 ms on (their lengths are set at 10 ms, the first
interface update, as in jaxarm's closed loop). The time step is ``NetworkConfig().dt_ms`` (or ``--dt``).

How the model maps onto Brian2 (the step is :func:`jaxarm.network.cell.cell_step`, line for line):

* all cell state is plain (non-ODE) variables, advanced by one ``run_regularly`` operation every step in the
  ``groups`` slot: exact exponential decays, the threshold excess decaying with tauRR once the absolute refractory
  period (an integer step counter, as in jaxarm) is over, V = clamped sum of components, then the driving-force
  jumps with the Mg block from the *summed* input of the step, and the input accumulators reset. Same-step events
  of one channel combine as ``NetworkConfig.event_summation`` says: summed loads -E log(1 - w/E) with the jump
  (E - V)(1 - exp(-L/E)) ("sequential", the default: the original's one-by-one jumps), or summed weights times one
  driving force ("linear");
* the Poisson background is drawn in that same operation: the number of events of every receptor and cell in the
  step, by inverting the Poisson(rate dt) CDF with one ``rand()`` (the method of jaxarm's noise, truncated where the
  tail is below 1e-12). Brian2's own ways give the same distribution no faster (``--noise``; 10 s at dt 0.25 ms,
  linear summation, network-seconds per CPU-second of the binary on the 2-core development machine: 12.7 this way,
  12.1 with three ``PoissonInput``s, 6.9 with ``poisson()`` in the update);
* the threshold (``thresholds`` slot, after the cell update) is the same test every step: not refractory, Vm above
  the dynamic threshold and not above Vblock (depolarisation block); the reset lowers AHP, raises the threshold and
  restarts the refractory counter;
* synapses (one ``Synapses`` object per receptor: excitatory AMPA+NMDA, FS proximal GABA, LTS distal GABA, and P->ES)
  only add their weights to the postsynaptic input accumulators (``on_pre``); Brian2 propagates spikes in the
  ``synapses`` slot, after the threshold, and the cell update of the next step applies them, so a synapse of d steps
  in jaxarm gets a Brian2 delay of (d - 1) steps and every input arrives in exactly the same step as in jaxarm.

Differences from jaxarm's step (none changes the model; they change the random numbers): Brian2 computes in float64
(jaxarm float32) and draws the noise from its own RNG (same Poisson distribution, other samples). So rates agree
statistically, not spike by spike: :func:`jaxarm_fixed_drive_rates` runs jaxarm under the same fixed drive and
:func:`compare_rates` compares. ``python benchmarks/brian2_network.py --repeats 16 --jaxarm-rates 16`` (10 s, 16
Brian2 runs against 16 jaxarm noise realisations, same wiring; sequential summation): every population within
2.1 %, each difference within 1.4 standard errors (Brian2 was the higher in all six, by 0.3-2.1 %; the populations
are coupled, so these are not six independent signs). With linear summation, 8 against 8: within 1.5 %. Brian2's
RNG is seeded afresh by each run of the binary (``--noise-seed`` fixes it), so every timed repeat is also another
noise realisation.

What benchmarks/network.py compares this with is heavier for jaxarm: its throughput is measured under the closed-loop
training drive (arm, readout, babbling) with plasticity bookkeeping on; Brian2 runs the network alone.

Timing: build (Brian2 objects, code generation, C++ compilation; excluded from the throughput and reported as
``build_s``), then the compiled binary is run ``repeats`` times; the throughput is the simulated seconds over the
run time of the network loop measured inside the binary (Brian2's ``device._last_run_time``), median over repeats.
The wall time and the CPU time of the whole binary (start-up, loading arrays, writing results) are reported too.
Brian2 runs single-threaded unless ``--threads`` is given (OpenMP; on the shared 2-core machine 2 threads were
slower). Everything is built in a temporary directory that is removed afterwards.
"""
from __future__ import annotations

import argparse
import importlib.machinery
import importlib.util
import json
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

INSTALL_HINT = "brian2 is not installed: install the benchmark extra with `pip install -e '.[bench]'`"
NETWORK_POPULATIONS = ("ES", "IS", "ISL", "EM", "IM", "IML")
NOISE_MODES = ("poisson", "poisson_builtin", "poisson_input")
POISSON_INPUT_N = 1000


def require_brian2():
    """Import brian2, or raise ImportError naming the extra that provides it."""
    if "brian2" not in sys.modules:
        _numpy_24_shim()
    try:
        import brian2
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(INSTALL_HINT) from e
    return brian2


_UNIT_MODULE = "brian2.units.fundamentalunits"


def _numpy_24_shim() -> None:
    """Let brian2 <= 2.9.0 import under numpy >= 2.4.

    Its unit class wraps the method ``ndarray.ptp``, which numpy 2.4 removed (numpy 2.0 deprecated it; brian2
    fixed this after 2.9.0, the newest release when this was written: brian-team/brian2 pull request 1705).
    Without a fix brian2 fails at import with ``AttributeError: ... has no attribute 'ptp'``. This installs an import hook that loads that one brian2 module
    with ``np.ndarray.ptp`` read as ``np.ptp`` (same result for arrays); it does nothing when numpy still has the
    method or the installed brian2 no longer uses it.
    """
    if hasattr(np.ndarray, "ptp") or any(isinstance(f, _PtpFinder) for f in sys.meta_path):
        return
    if importlib.util.find_spec("brian2") is None:
        return
    sys.meta_path.insert(0, _PtpFinder())


class _PtpFinder:
    """Meta-path finder for :func:`_numpy_24_shim` (only ever answers for brian2's unit module)."""

    def find_spec(self, name, path=None, target=None):
        if name != _UNIT_MODULE:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None or not isinstance(spec.loader, importlib.machinery.SourceFileLoader):
            return spec
        spec.loader = _PtpLoader(spec.loader.name, spec.loader.path)
        return spec


class _PtpLoader(importlib.machinery.SourceFileLoader):
    def get_data(self, path):
        data = super().get_data(path)
        if path.endswith(".py"):
            data = data.replace(b"np.ndarray.ptp)", b"np.ptp)")
        return data

    def get_code(self, fullname):  # no bytecode cache: the source is patched
        return compile(self.get_data(self.path), self.path, "exec")


def start_lengths_m() -> np.ndarray:
    """Muscle lengths (4,) of the simple arm at its start posture, m."""
    from jaxarm import make_arm

    arm = make_arm("simple")
    return np.asarray(arm.observe(arm.init()).proprio, dtype=np.float64)


def p_spike_train(config, lengths_m, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(P index, step) of every P spike in steps 1..n_steps of the fixed drive: all P cells at ``p_start_ms``;
    the cells coding ``lengths_m`` from 10 ms (first interface update) on, every 1000/p_rate_hz ms (jaxarm's
    :mod:`jaxarm.network.proprio` semantics: the first spike one interval after the update)."""
    from jaxarm.network.proprio import active_cells

    start = config.steps(config.p_start_ms)
    interval = config.steps(1000.0 / config.p_rate_hz)
    update = config.steps_per_interface
    idx = [np.arange(config.n_p)] if 1 <= start <= n_steps else []
    steps = [np.full(config.n_p, start)] if idx else []
    on = np.nonzero(np.asarray(active_cells(config, lengths_m)))[0]
    train = np.arange(update + interval, n_steps + 1, interval)
    if len(on) and len(train):
        idx.append(np.repeat(on, len(train)))
        steps.append(np.tile(train, len(on)))
    if not idx:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(idx), np.concatenate(steps)


def poisson_cdf(lam: float, tail: float = 1e-12) -> list[float]:
    """CDF(0), CDF(1), ... of Poisson(lam) up to the first k with P(N > k) < ``tail``: N = #{k : u >= CDF(k)} for a
    uniform u is then Poisson(lam) except with probability < ``tail`` per draw (the inversion jaxarm's noise uses)."""
    term = cdf = math.exp(-lam)
    out = [cdf]
    k = 0
    while 1.0 - cdf >= tail and k < 64:
        k += 1
        term *= lam / k
        cdf += term
        out.append(cdf)
    return out


def _one_rate(per_cell: np.ndarray) -> float:
    rates = np.unique(per_cell)
    if len(rates) != 1:
        raise ValueError("the Brian2 port draws one background rate per receptor (jaxarm's defaults: AMPA 200 Hz, "
                         f"GABA 100 Hz in every population); got {rates}")
    return float(rates[0])


#: Jumps of the AMPA and GABA components from a step's summed input, per ``NetworkConfig.event_summation``
#: (jaxarm.network.cell.cell_step). "linear": summed weights times one driving force.
_LINEAR_JUMPS = """
        ampa_jump = ampa_in * (1.0 - v / E_AMPA)
        gp_jump = gp_in * (1.0 - v / E_GABA)
        gd_jump = gd_in * (1.0 - v / E_GABA)
"""
#: "sequential": summed loads L (:func:`accumulated`); the jump (E - V)(1 - exp(-L/E)) is what one-by-one jumps give.
#: ``saturation(L, E)`` = 1 - exp(-L/E) is a small C++ function (see :func:`_saturation_function`).
_SEQUENTIAL_JUMPS = """
        ampa_jump = (E_AMPA - v) * saturation(ampa_in, E_AMPA)
        gp_jump = (v - E_GABA) * saturation(gp_in, -E_GABA)
        gd_jump = (v - E_GABA) * saturation(gd_in, -E_GABA)
"""
MAX_JUMP_FRACTION = 1.0 - 1e-6


def _saturation_function(b2):
    """Brian2 function ``saturation(L, E)`` = 1 - exp(-L/E) = -expm1(-L/E), in C++ with a shortcut for L = 0 (most
    cells get no event of a given channel in a step; the shortcut skips their exp, and is exact)."""

    @b2.implementation("cpp", """
    double saturation(double load, double e_rev) { return load == 0.0 ? 0.0 : -expm1(-load / e_rev); }
    """)
    @b2.check_units(load=1, e_rev=1, result=1)
    def saturation(load, e_rev):
        return -np.expm1(-np.asarray(load) / e_rev)

    return saturation


def accumulated(w, e_rev: float, sequential: bool) -> np.ndarray:
    """What one event of weight ``w`` (mV) adds to its cell's input accumulator, float64: the weight itself
    ("linear"), or its load ``-e_rev log(1 - w/e_rev)`` ("sequential"; ``e_rev`` = 65 AMPA, 15 GABA; loads add, and
    the step's jump is (E - V)(1 - exp(-L/E)), as in jaxarm.network.cell)."""
    w = np.asarray(w, np.float64)
    if not sequential:
        return w
    return -e_rev * np.log1p(-np.minimum(w / e_rev, MAX_JUMP_FRACTION))


def wiring_arrays(config, seed: int) -> dict:
    """Per-synapse numpy arrays of the jaxarm wiring drawn from ``jax.random.key(seed)`` (dummy synapse dropped)."""
    import jax

    from jaxarm.network import Network

    w = Network(config).make_wiring(jax.random.key(seed))
    return {k: np.asarray(getattr(w, k))[:-1] for k in ("pre", "post", "delay_steps", "weight", "nmda")}


def run_brian2(dt_ms: float | None = None, seconds: float = 10.0, seed: int = 0, repeats: int = 3,
               openmp_threads: int = 0, lengths_m=None, profile: bool = False, directory: str | None = None,
               noise: str = "poisson", noise_seed: int | None = None) -> dict:
    """Build the network in Brian2 C++ standalone, run the compiled binary ``repeats`` times, return timings/rates.

    ``seed`` draws the wiring (jaxarm key). Brian2's RNG is seeded afresh by every run of the binary, so each
    repeat is another noise realisation (rates are reported per repeat and as their mean), unless ``noise_seed``
    fixes it (then every repeat is the same run). ``directory``: where to build (default: a new
    temporary directory, removed afterwards; a given directory is left in place). ``noise``: how the background
    count of each receptor and cell is drawn every step: "poisson" (in the cell update, by inverting the Poisson
    CDF with one ``rand()``, as jaxarm does), "poisson_builtin" (Brian2's ``poisson()`` function there) or
    "poisson_input" (three Brian2 ``PoissonInput``s with N = 1000 sources each at rate/1000: a binomial count,
    Poisson to within 0.1 %). All are the same distribution; they differ in speed only.
    """
    if noise not in NOISE_MODES:
        raise ValueError(f"noise = {noise!r}: one of {NOISE_MODES}")
    b2 = require_brian2()
    from jaxarm.network import NetworkConfig
    from jaxarm.network import cell as cell_mod
    from jaxarm.network import noise as noise_mod
    from jaxarm.network.populations import Populations
    from jaxarm.network.wiring import AMPA, GABA_DIST, GABA_PROX, WiringLayout

    config = NetworkConfig() if dt_ms is None else NetworkConfig(dt_ms=dt_ms)
    ph = config.spec.physics
    dt = config.dt_ms
    n_steps = int(round(seconds * 1000.0 / dt))
    lengths = start_lengths_m() if lengths_m is None else np.asarray(lengths_m, np.float64)
    syn = wiring_arrays(config, seed)
    t_build0 = time.perf_counter()   # build = Brian2 objects + code generation + C++ compilation
    c = cell_mod.cell_constants(config)
    sequential = config.event_summation == "sequential"
    raw_noise_w = np.concatenate([np.repeat(np.array([[w for w, _ in config.spec.population(p).noise]]).T,
                                            config.size(p), 1) for p in NETWORK_POPULATIONS], axis=1)
    noise_w = np.stack([accumulated(raw_noise_w[0], ph.e_ampa_mv, sequential),
                        accumulated(raw_noise_w[1], -ph.e_gaba_mv, sequential),
                        accumulated(raw_noise_w[2], -ph.e_gaba_mv, sequential)])
    noise_lam = noise_mod.base_rates_hz(config).astype(np.float64) * dt / 1000.0

    own_dir = directory is None
    build_dir = tempfile.mkdtemp(prefix="jaxarm_brian2_") if own_dir else directory
    b2.prefs.devices.cpp_standalone.openmp_threads = int(openmp_threads)
    b2.set_device("cpp_standalone", directory=build_dir, build_on_run=False)
    try:
        b2.device.reinit()
        b2.device.activate(directory=build_dir, build_on_run=False)
        b2.prefs.devices.cpp_standalone.openmp_threads = int(openmp_threads)
        b2.defaultclock.dt = dt * b2.ms
        if noise_seed is not None:
            b2.seed(noise_seed)
        n = config.n_cells
        eqs = """
        ampa : 1
        nmda : 1
        gaba_prox : 1
        gaba_dist : 1
        ahp : 1
        excess : 1
        since : integer
        ampa_in : 1
        nmda_in : 1
        gp_in : 1
        gd_in : 1
        rmp : 1 (constant)
        vth : 1 (constant)
        vblock : 1 (constant)
        ahpwt : 1 (constant)
        post_excess : 1 (constant)
        n_ref : integer (constant)
        decay_ahp : 1 (constant)
        decay_rr : 1 (constant)
        decay_rr_first : 1 (constant)
        w_noise_ampa : 1 (constant)
        w_noise_gp : 1 (constant)
        w_noise_gd : 1 (constant)
        lam_ampa : 1 (constant)
        lam_gp : 1 (constant)
        lam_gd : 1 (constant)
        vm = clip(rmp + ampa + nmda + gaba_prox + gaba_dist + ahp, VM_MIN, VM_MAX) : 1
        """
        namespace = dict(
            VM_MIN=ph.vm_min_mv, VM_MAX=ph.vm_max_mv, E_AMPA=ph.e_ampa_mv, E_NMDA=ph.e_nmda_mv,
            E_GABA=ph.e_gaba_mv, MG_RATIO=ph.mg_mm / ph.mg0_mm, MG_SLOPE=ph.mg_slope_per_mv,
            D_AMPA=float(c.decay_ampa[0]), D_NMDA=float(c.decay_nmda[0]), D_GP=float(c.decay_gaba_prox[0]),
            D_GD=float(c.decay_gaba_dist[0]), SINCE_MAX=cell_mod._SINCE_MAX - 1, saturation=_saturation_function(b2))
        # jaxarm.network.cell.cell_step, in its order: noise counts of this step, decays, V, jumps, clear inputs
        step_code = ""
        if noise == "poisson":
            for r, (var, wname) in enumerate((("ampa_in", "w_noise_ampa"), ("gp_in", "w_noise_gp"),
                                               ("gd_in", "w_noise_gd"))):
                cdf = poisson_cdf(_one_rate(noise_lam[r]))
                for k, value in enumerate(cdf):
                    namespace[f"CDF_{r}_{k}"] = value
                count = " + ".join(f"int(u_{r} >= CDF_{r}_{k})" for k in range(len(cdf)))
                step_code += f"u_{r} = rand()\n{var} += {wname} * ({count})\n"
        elif noise == "poisson_builtin":
            step_code = ("ampa_in += w_noise_ampa * poisson(lam_ampa)\ngp_in += w_noise_gp * poisson(lam_gp)\n"
                         "gd_in += w_noise_gd * poisson(lam_gd)\n")
        g = b2.NeuronGroup(n, eqs, threshold="since >= n_ref and vm > vth + excess and vm <= vblock",
                           reset="ahp -= ahpwt\nexcess = post_excess\nsince = 0", namespace=namespace, name="cells")
        g.run_regularly(step_code + """
        ampa *= D_AMPA
        nmda *= D_NMDA
        gaba_prox *= D_GP
        gaba_dist *= D_GD
        ahp *= decay_ahp
        since += int(since < SINCE_MAX)
        excess *= decay_rr * int(since > n_ref) + decay_rr_first * int(since == n_ref) + 1.0 * int(since < n_ref)
        v = clip(ampa + nmda + gaba_prox + gaba_dist + ahp, rmp, -rmp)
        """ + (_SEQUENTIAL_JUMPS if sequential else _LINEAR_JUMPS) + """
        ampa = clip(ampa + ampa_jump, 0.0, inf)
        nmda += int(nmda < E_NMDA) * nmda_in * (1.0 - v / E_NMDA) / (1.0 + exp(-MG_SLOPE * (rmp + v)) * MG_RATIO)
        gaba_prox += int(gaba_prox > E_GABA) * (clip(gaba_prox - gp_jump, -inf, 0.0) - gaba_prox)
        gaba_dist += int(gaba_dist > E_GABA) * (clip(gaba_dist - gd_jump, -inf, 0.0) - gaba_dist)
        ampa_in = 0.0
        nmda_in = 0.0
        gp_in = 0.0
        gd_in = 0.0
        """, when="groups", name="cell_step")
        g.since = cell_mod._SINCE_MAX - 1
        for name, values in (("rmp", c.rmp), ("vth", c.vth), ("vblock", c.vblock), ("ahpwt", c.ahpwt),
                             ("post_excess", c.post_spike_excess), ("decay_ahp", c.decay_ahp),
                             ("decay_rr", c.decay_rr), ("decay_rr_first", c.decay_rr_first)):
            setattr(g, name, np.asarray(values, np.float64))
        g.n_ref = np.asarray(c.n_refractory, np.int32)
        g.w_noise_ampa, g.w_noise_gp, g.w_noise_gd = noise_w
        g.lam_ampa, g.lam_gp, g.lam_gd = noise_lam

        # synapses by receptor; P -> ES separately (its presynaptic group is the spike generator)
        n_cells = config.n_cells
        pre, post, delay = syn["pre"], syn["post"], syn["delay_steps"]
        layout = WiringLayout(config)
        channel = np.array([layout.channel(pw) for pw in layout.pathways])[layout.pathway_of_synapse()]
        objects = []
        from_p = pre >= n_cells
        for chan, on_pre, name in ((AMPA, "ampa_in_post += w\nnmda_in_post += wn", "exc"),
                                   (GABA_PROX, "gp_in_post += w", "fs"),
                                   (GABA_DIST, "gd_in_post += w", "lts")):
            sel = (channel == chan) & ~from_p
            model = "w : 1 (constant)\nwn : 1 (constant)" if chan == AMPA else "w : 1 (constant)"
            s = b2.Synapses(g, g, model=model, on_pre=on_pre, name=f"syn_{name}")
            s.connect(i=pre[sel].astype(np.int32), j=post[sel].astype(np.int32))
            s.w = accumulated(syn["weight"][sel], ph.e_ampa_mv if chan == AMPA else -ph.e_gaba_mv, sequential)
            if chan == AMPA:
                s.wn = syn["nmda"][sel].astype(np.float64)
            s.delay = (delay[sel] - 1) * dt * b2.ms   # applied by the next step's cell update: d steps in all
            objects.append(s)
        pops = Populations(config)
        p_idx, p_steps = p_spike_train(config, lengths, n_steps - 1)
        gen = b2.SpikeGeneratorGroup(config.n_p, p_idx, p_steps * dt * b2.ms, name="P")
        sp = b2.Synapses(gen, g, model="w : 1 (constant)\nwn : 1 (constant)",
                         on_pre="ampa_in_post += w\nnmda_in_post += wn", name="syn_p")
        sp.connect(i=(pre[from_p] - pops.start["P"]).astype(np.int32), j=post[from_p].astype(np.int32))
        sp.w = accumulated(syn["weight"][from_p], ph.e_ampa_mv, sequential)
        sp.wn = syn["nmda"][from_p].astype(np.float64)
        sp.delay = (delay[from_p] - 1) * dt * b2.ms
        if noise == "poisson_input":
            for r, (var, wname) in enumerate((("ampa_in", "w_noise_ampa"), ("gp_in", "w_noise_gp"),
                                               ("gd_in", "w_noise_gd"))):
                objects.append(b2.PoissonInput(g, var, N=POISSON_INPUT_N,
                                               rate=_one_rate(noise_lam[r]) * 1000.0 / dt / POISSON_INPUT_N * b2.Hz,
                                               weight=wname))
        mon = b2.SpikeMonitor(g, record=False, name="counts")
        net = b2.Network(g, gen, sp, mon, *objects)
        net.run(n_steps * dt * b2.ms, profile=profile)
        b2.device.build(directory=build_dir, compile=True, run=False, with_output=False)
        build_s = time.perf_counter() - t_build0

        loop_s, binary_s, cpu_s, counts = [], [], [], []
        for _ in range(max(1, repeats)):
            t0, c0 = time.perf_counter(), _children_cpu_s()
            b2.device.run(directory=build_dir, with_output=False)
            binary_s.append(time.perf_counter() - t0)
            cpu_s.append(_children_cpu_s() - c0)
            loop_s.append(float(b2.device._last_run_time))
            counts.append(np.asarray(mon.count[:], dtype=np.float64))
        prof = None
        if profile:
            prof = {str(name): float(t / b2.second) for name, t in net.profiling_info}
        n_syn = int(len(pre))
    finally:
        b2.device.reinit()
        b2.device.activate()
        b2.set_device("runtime")
        if own_dir:
            shutil.rmtree(build_dir, ignore_errors=True)
    duration_s = n_steps * dt / 1000.0
    per_repeat = [{p: float(c[pops.slice(p)].mean() / duration_s) for p in NETWORK_POPULATIONS} for c in counts]
    rates = {p: float(np.mean([r[p] for r in per_repeat])) for p in NETWORK_POPULATIONS}
    rates_sd = {p: float(np.std([r[p] for r in per_repeat])) for p in NETWORK_POPULATIONS}
    loop = float(np.median(loop_s))
    out = {
        "network_s_per_s": duration_s / loop,
        "network_s_per_s_binary_wall": duration_s / float(np.median(binary_s)),
        "network_s_per_cpu_s_binary": duration_s / float(np.median(cpu_s)),
        "build_s": build_s, "loop_s": loop_s, "binary_wall_s": binary_s, "binary_cpu_s": cpu_s,
        "repeats": len(loop_s),
        "simulated_s": duration_s, "dt_ms": dt, "seed": seed, "openmp_threads": int(openmp_threads), "noise": noise,
        "rates_hz": rates, "rates_sd_across_repeats_hz": rates_sd, "rates_per_repeat_hz": per_repeat,
        "noise_seed": noise_seed, "event_summation": config.event_summation,
        "lengths_m": [float(x) for x in lengths], "n_synapses": n_syn,
        "brian2_version": b2.__version__,
    }
    if prof is not None:
        out["profile_s"] = prof
    return out


def _children_cpu_s() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def jaxarm_fixed_drive_rates(dt_ms: float | None = None, seconds: float = 10.0, seed: int = 0, n_noise: int = 4,
                             lengths_m=None) -> dict:
    """Population rates (Hz) of jaxarm's network under the same fixed drive as :func:`run_brian2`: the wiring of
    ``jax.random.key(seed)``, ``n_noise`` background-noise realisations (vmapped), P lengths set at 10 ms."""
    import jax
    import jax.numpy as jnp

    from jaxarm.network import Network, NetworkConfig, NetworkParams

    config = NetworkConfig() if dt_ms is None else NetworkConfig(dt_ms=dt_ms)
    net = Network(config)
    wiring = net.make_wiring(jax.random.key(seed))
    lengths = jnp.asarray(start_lengths_m() if lengths_m is None else lengths_m, jnp.float32)
    n_steps = int(round(seconds * 1000.0 / config.dt_ms))
    first = min(config.steps_per_interface, n_steps)
    params = NetworkParams.original()

    def simulate(key):
        s = net.init(key)
        s, _ = net.run(wiring, s, params, first, collect=False)
        s = net.set_lengths(s, lengths)
        if n_steps > first:
            s, _ = net.run(wiring, s, params, n_steps - first, collect=False)
        return s.spike_count

    keys = jax.random.split(jax.random.key(seed + 1000), n_noise)
    t0 = time.perf_counter()
    counts = np.asarray(jax.jit(jax.vmap(simulate))(keys), dtype=np.float64)
    wall = time.perf_counter() - t0
    duration_s = n_steps * config.dt_ms / 1000.0
    per = [net.pops.population_rates_hz(counts[i], duration_s * 1000.0) for i in range(n_noise)]
    return {"rates_hz": {p: float(np.mean([r[p] for r in per])) for p in NETWORK_POPULATIONS},
            "rates_sd_across_noise_hz": {p: float(np.std([r[p] for r in per])) for p in NETWORK_POPULATIONS},
            "noise_realisations": n_noise, "simulated_s": duration_s, "dt_ms": config.dt_ms, "seed": seed,
            "wall_s_including_compile": wall}


def compare_rates(brian2: dict, jaxarm: dict) -> dict:
    """Per population: Brian2's and jaxarm's mean rates (Hz) over their noise realisations, the relative difference
    (Brian2 / jaxarm - 1) and ``z``, the difference over its standard error (from the spread across realisations of
    each; a rough yardstick with a few realisations)."""
    out = {}
    n_b, n_j = brian2["repeats"], jaxarm["noise_realisations"]
    for p in NETWORK_POPULATIONS:
        b, j = brian2["rates_hz"][p], jaxarm["rates_hz"][p]
        se = math.sqrt(brian2["rates_sd_across_repeats_hz"][p] ** 2 / max(n_b - 1, 1)
                       + jaxarm["rates_sd_across_noise_hz"][p] ** 2 / max(n_j - 1, 1))
        out[p] = {"brian2_hz": b, "jaxarm_hz": j, "relative": (b / j - 1.0) if j else float("nan"),
                  "z": (b - j) / se if se else float("nan")}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dt", type=float, default=None, help="clock step, ms (default: NetworkConfig's)")
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per timed run")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs of the compiled binary (median)")
    ap.add_argument("--seed", type=int, default=0, help="wiring key (jaxarm)")
    ap.add_argument("--noise-seed", type=int, default=None,
                    help="fix Brian2's RNG seed (default: a fresh seed, i.e. a new noise realisation, every repeat)")
    ap.add_argument("--threads", type=int, default=0, help="Brian2 OpenMP threads (0: single-threaded)")
    ap.add_argument("--jaxarm-rates", type=int, default=4, metavar="N",
                    help="also run jaxarm under the same fixed drive with N noise realisations (0: skip)")
    ap.add_argument("--profile", action="store_true", help="Brian2 per-object profile of one run")
    ap.add_argument("--noise", choices=NOISE_MODES, default="poisson", help="how Brian2 draws the background")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    result = {"brian2": run_brian2(args.dt, args.seconds, args.seed, args.repeats, args.threads,
                                   profile=args.profile, noise=args.noise, noise_seed=args.noise_seed)}
    if args.jaxarm_rates:
        j = jaxarm_fixed_drive_rates(args.dt, args.seconds, args.seed, args.jaxarm_rates)
        result["jaxarm_fixed_drive"] = j
        result["rates_brian2_vs_jaxarm"] = compare_rates(result["brian2"], j)
    if args.json:
        print(json.dumps(result, indent=1))
        return 0
    b = result["brian2"]
    print(f"Brian2 {b['brian2_version']} C++ standalone, dt {b['dt_ms']} ms, {b['simulated_s']:g} s simulated: "
          f"{b['network_s_per_s']:.2f} network-s/s (run loop, median of {b['repeats']}), "
          f"{b['network_s_per_s_binary_wall']:.2f} incl. binary start-up, {b['network_s_per_cpu_s_binary']:.2f} per "
          f"CPU-s of the binary; build {b['build_s']:.1f} s")
    print("rates Hz  " + "  ".join(f"{p} {r:.2f}" for p, r in b["rates_hz"].items()))
    if "rates_brian2_vs_jaxarm" in result:
        print("jaxarm    " + "  ".join(f"{p} {r:.2f}" for p, r in result["jaxarm_fixed_drive"]["rates_hz"].items())
              + f"  (mean of {args.jaxarm_rates} noise realisations)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
