"""The network as data (jaxarm.config.spec.NetworkSpec): the paper's spec gives the model as it was before the spec
existed, bit for bit on both kernels; a spec round-trips through TOML and JSON; bad specs are one-line errors naming
the part; an edited network (a population and a plastic pathway added) builds, runs on both kernels alike and
learns on its new synapses."""
import dataclasses
import hashlib
import json
import os
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config import ConfigError
from jaxarm.config.spec import CellType, NetworkSpec, Pathway, Population
from jaxarm.network import Network, NetworkConfig, NetworkParams, WiringLayout, native

PRE_SPEC = Path(__file__).parent / "data" / "pre_spec_outputs.json"
needs_native = pytest.mark.skipif(not native.available(), reason=f"native kernel unavailable: {native.status()}")
E_NOISE = ((3.75, 200.0), (1.875, 100.0), (1.875, 100.0))


def training_outputs(kernel: str) -> dict:
    """SHA-256 (first 16 hex digits) of every array one training epoch (1 s) and one test (0.3 s) return, 2 networks
    of the simple arm, seed 3, authors' metaparameters. Uses only APIs that predate the spec, so the same function
    ran at commit 0d3c267 (before the spec) wrote tests/data/pre_spec_outputs.json."""
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    config = LoopConfig(arm="simple", network=NetworkConfig(kernel=kernel),
                        task=TaskConfig(epochs=1, epoch_duration_s=1.0, test_duration_s=0.3))
    fns = make_train(config)
    mp = MetaParams.original()
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    carry = jax.jit(jax.vmap(fns.init))(keys)
    carry, history = jax.jit(jax.vmap(fns.epoch, in_axes=(0, None)))(carry, mp)
    result = jax.jit(jax.vmap(fns.test, in_axes=(0, 0, None)))(keys, carry.trained, mp)
    out = {}
    for path, leaf in jax.tree_util.tree_flatten_with_path((carry, history, result))[0]:
        a = np.ascontiguousarray(np.asarray(leaf))
        if a.dtype.kind in "fiub":
            out[jax.tree_util.keystr(path)] = hashlib.sha256(a.tobytes() + str(a.shape).encode()).hexdigest()[:16]
    return out


@pytest.mark.parametrize("kernel", [pytest.param("native", marks=needs_native),
                                    pytest.param("xla", marks=pytest.mark.slow)])   # slow: the 8-minute budget
def test_the_papers_spec_trains_bit_for_bit_as_before_the_spec(kernel):
    ref = json.loads(PRE_SPEC.read_text())
    if ref["jax"] != jax.__version__:
        pytest.skip(f"the reference was recorded with jax {ref['jax']}, this is {jax.__version__}: floating-point "
                    "results may differ between versions")
    if "--xla_cpu_max_isa=AVX" in os.environ.get("XLA_FLAGS", ""):
        pytest.skip("the reference was recorded with XLA's fused multiply-add, which jaxarm.cpu_arithmetic turns off; "
                    "run with JAXARM_XLA_FMA=1 to compare")
    flags = Path("/proc/cpuinfo").read_text().split() if Path("/proc/cpuinfo").exists() else []
    if {f: f in flags for f in ref["cpu_features"]} != ref["cpu_features"]:
        pytest.skip(f"the reference was recorded on a CPU with {ref['cpu_features']}: exp/log and vector code may "
                    "round differently on this one")
    now = training_outputs(kernel)
    assert now.keys() == ref[kernel].keys()
    differ = [k for k in now if now[k] != ref[kernel][k]]
    assert not differ, f"{len(differ)} of {len(now)} arrays differ from the pre-spec model, e.g. {differ[:5]}"


def test_the_papers_spec_is_the_papers_table():
    """Independent of the spec module's own table: counts and sums of spec §2 and §1."""
    spec = NetworkSpec.dura_bernal_2015()
    assert spec.names == ("ES", "IS", "ISL", "EM", "IM", "IML", "P") and spec.sizes == (192, 44, 20, 192, 44, 20, 192)
    assert len(spec.pathways) == 23 and sum(pw.plastic for pw in spec.pathways) == 8
    assert spec.spike_groups == (("ES",), ("EM",), ("IS", "ISL", "IM", "IML"))
    assert [spec.cell_type(p).name for p in spec.network_populations] == ["E", "FS", "LTS", "E", "FS", "LTS"]
    assert spec.cell_type("LTS").vth_mv == -47.0 and spec.cell_type("E").refrac_ms == 5.0
    assert spec.population("EM").noise[0] == (3.9375, 200.0)
    assert (spec.physics.e_ampa_mv, spec.physics.e_nmda_mv, spec.physics.e_gaba_mv) == (65.0, 90.0, -15.0)
    assert hash(spec) == hash(NetworkSpec.dura_bernal_2015())          # hashable: a static argument of jit


def test_a_spec_round_trips_through_toml_and_json(tmp_path):
    spec = NetworkSpec.dura_bernal_2015().with_population(Population("EX", 32, "E", E_NOISE))
    spec = spec.with_pathway(Pathway("ES", "EX", 0.3, 2.64, (3.0, 5.0), plastic=True))
    for suffix in (".toml", ".json"):
        spec.save(tmp_path / f"s{suffix}")
        assert NetworkSpec.load(tmp_path / f"s{suffix}") == spec
    # a NetworkConfig with that spec: one flat file (the spec's tables beside the config's fields), and a run's
    # meta (its changed fields) rebuilds it, as `jaxarm test --from` does
    from jaxarm.run import network_config

    config = NetworkConfig(spec=spec, dt_ms=0.5)
    config.save(tmp_path / "n.toml")
    text = (tmp_path / "n.toml").read_text()
    assert "[[pathways]]" in text and 'name = "EX"' in text and "dt_ms = 0.5" in text
    assert NetworkConfig.load(tmp_path / "n.toml") == config
    assert network_config(config.to_dict(changed_only=True) | {"kernel": "xla"}) == config
    # sizes alone stay a one-line file; only a part of a spec in a file replaces that part
    assert NetworkConfig().with_sizes((384, 88, 40, 384, 88, 40, 384)).to_dict(changed_only=True) == {
        "sizes": [384, 88, 40, 384, 88, 40, 384]}
    (tmp_path / "p.toml").write_text('[physics]\ne_gaba_mv = -20.0\n')
    assert NetworkConfig.load(tmp_path / "p.toml").spec.physics.e_gaba_mv == -20.0


@pytest.mark.parametrize("edit, message", [
    (lambda s: s.with_pathway(Pathway("ES", "XX", 0.1, 1.0, (1.0, 2.0))), r"Pathway ES->XX: no population 'XX'"),
    (lambda s: s.with_pathway(Pathway("ES", "P", 0.1, 1.0, (1.0, 2.0))), r"'P' takes no input"),
    (lambda s: s.with_pathway(Pathway("P", "EM", 0.1, 1.0, (1.0, 2.0), plastic=True)), r"P->EM: pathways from the "
                                                                                        "proprioceptive code cannot"),
    (lambda s: dataclasses.replace(s, pathways=s.pathways[1:] + s.pathways[:1]), r"plastic pathways must come first"),
    (lambda s: s.with_pathway(Pathway("ES", "ES", 0.1, 1.0, (1.0, 2.0), plastic=True)), r"ES->ES: given twice"),
    (lambda s: s.with_sizes((192, 44, 20, 190, 44, 20, 192)), r"Population 'EM'.size = 190: must be a multiple of 4"),
    (lambda s: s.with_population(Population("EX", 8, "XX", E_NOISE)), r"Population 'EX'.cell_type = 'XX': one of"),
    (lambda s: dataclasses.replace(s, populations=s.populations[-1:] + s.populations[:-1]), r"generator populations "
                                                                                              "come last"),
    (lambda s: s.with_population(Population("T", 8, "generator")), r"Population 'T'.code = '': a generator"),
    (lambda s: s.with_population(Population("T", 12, "generator", code="target", groups=8, rate_hz=50.0)),
     r"Population 'T'.groups = 8: an integer in \[1, 64\] that divides its size 12"),
    (lambda s: s.with_population(Population("T", 8, "generator", code="proprioceptive")), r"exactly one generator"),
    (lambda s: Population("EX", 0, "E", E_NOISE), r"Population 'EX'.size = 0: an integer in \[1, 100000\]"),
    (lambda s: Population("EX", 8, "E", E_NOISE[:2]), r"Population 'EX'.noise .*one \(weight mV, rate Hz\) pair"),
    (lambda s: Pathway("ES", "EM", 0.3, 2.6, (5.0, 3.0)), r"Pathway ES->EM.delay_ms .*low must not exceed high"),
    (lambda s: Pathway("ES", "EM", 0.0, 2.6, (3.0, 5.0)), r"Pathway ES->EM.pmat = 0.0: must be a number in \(0.0"),
    (lambda s: CellType("X", -65.0, -30.0, -40.0, 5.0, 1.0, 400.0, 8.0, 0.75, "excitatory"), r"rmp_mv < vth_mv <"),
    (lambda s: CellType("X", -65.0, -40.0, -25.0, 5.0, 1.0, 400.0, 8.0, 0.75, "gap"), r"output = 'gap': one of"),
])
def test_bad_specs_are_one_line_errors_naming_the_part(edit, message):
    with pytest.raises(ConfigError, match=message) as e:
        edit(NetworkSpec.dura_bernal_2015())
    assert "\n" not in str(e.value)


def test_bad_spec_files_name_the_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[populations]]\nname = "ES"\nsize = 10\n')
    with pytest.raises(ConfigError, match=r"populations\[0\]: missing cell_type"):
        NetworkConfig.load(bad)
    bad.write_text('[physics]\ne_gaba = -20.0\n')
    with pytest.raises(ConfigError, match="physics: unknown field.*e_gaba"):
        NetworkConfig.load(bad)
    bad.write_text('[[pathways]]\npre = "ES"\npost = "EM"\npmat = 0.3\nweight_mv = 2.6\ndelay_ms = [3, 5]\n')
    with pytest.raises(ConfigError, match=r"with at least one from 'P'; got ES->EM"):   # a list replaces the list
        NetworkConfig.load(bad)


def _extended(kernel: str) -> NetworkConfig:
    """The paper's network plus an excitatory population EX (32 cells) driven by ES through a plastic pathway and
    inhibited by IS; EX makes its own spike group."""
    spec = NetworkSpec.dura_bernal_2015().with_population(Population("EX", 32, "E", E_NOISE))
    spec = spec.with_pathway(Pathway("ES", "EX", 0.3, 2.64, (3.0, 5.0), plastic=True))
    spec = spec.with_pathway(Pathway("IS", "EX", 0.44, 4.5, (1.8, 2.2)))
    return NetworkConfig(spec=spec, kernel=kernel)


def test_an_added_population_and_pathway_are_wired_as_the_spec_says():
    config = _extended("xla")
    layout = WiringLayout(config)
    assert config.n_cells == 512 + 32 and config.populations[-2:] == ("EX", "P")
    assert layout.spike_groups == (("ES",), ("EM",), ("EX",), ("IS", "ISL", "IM", "IML"))
    assert config.group_capacities() == ((16, 8, 8, 8), (2.0, 1.0, 1.0, 1.0))
    assert layout.in_degree["ES->EX"] == int(0.5 + 0.3 * 1.125 * 192) == 65
    assert layout.in_degree["IS->EX"] == int(0.5 + 0.44 * 1.125 * 44) == 22
    w = Network(config).make_wiring(jax.random.key(0))
    pre = np.asarray(layout.view(w.pre, "ES->EX"))
    assert pre.shape == (32, 65) and pre.min() >= 0 and pre.max() < 192
    assert np.all(np.asarray(layout.view(w.post, "ES->EX")) == np.arange(512, 544)[:, None])
    np.testing.assert_allclose(np.asarray(layout.view(w.nmda, "ES->EX")), 0.264, rtol=1e-6)
    # ES->EX is the ninth plastic pathway: its synapses are plastic synapses, right after the paper's eight
    assert layout.synapses("ES->EX").stop == layout.n_plastic


def test_with_plastic_makes_exactly_the_named_pathways_plastic_and_orders_them():
    """Only ES->EM plastic: its synapses become the layout's plastic block (ES->EM's in-degree by hand, pmat 0.5 x
    1.125 x 192 rounded), the seven others fixed; unknown names are one-line errors."""
    spec = NetworkSpec.dura_bernal_2015().with_plastic({"ES->EM"})
    assert [pw.name for pw in spec.pathways if pw.plastic] == ["ES->EM"]
    assert spec.pathways[0].name == "ES->EM" and spec.pathways[-1].name == "P->ES"
    assert sorted(pw.name for pw in spec.pathways) == sorted(pw.name for pw in NetworkSpec.dura_bernal_2015().pathways)
    layout = WiringLayout(NetworkConfig(spec=spec))
    assert layout.synapses("ES->EM") == slice(0, layout.n_plastic)
    assert layout.n_plastic == 192 * int(0.5 + spec.pathway("ES->EM").pmat * 1.125 * 192)
    with pytest.raises(ConfigError, match="plastic pathways: no pathway 'EM->XX'"):
        spec.with_plastic({"EM->XX"})


def _run_on_both_kernels(config_of, direction_rad=None):
    """Two networks of ``config_of(kernel)`` from rest, 250 ms on the XLA and the native kernel (the same wiring,
    noise and muscle lengths; target codes pointed at ``direction_rad``): [(states, spikes) xla, (...) native]."""
    nets = [Network(config_of(k)) for k in ("xla", "native")]
    keys = jax.random.split(jax.random.key(3), 2)
    wirings = jax.vmap(nets[0].make_wiring)(keys)

    def start(net, key):
        s = net.set_em_rates(net.init(key), jnp.asarray((152.76, 50.0, 50.0, 50.0), jnp.float32))
        s = s if direction_rad is None else net.set_target(s, direction_rad)
        return net.set_lengths(s, jnp.array([0.10, 0.16, 0.12, 0.14]))

    s0 = jax.vmap(lambda k: start(nets[0], k))(jax.random.split(jax.random.key(4), 2))
    return [jax.jit(jax.vmap(lambda w, s, net=net: net.run(w, s, NetworkParams.original(), 1000)))(wirings, s0)
            for net in nets]


@needs_native
@pytest.mark.slow
def test_an_extended_network_runs_alike_on_both_kernels():
    """Like tests/test_native_kernel.py for the paper's network: the same spikes over 250 ms from rest."""
    spikes = [np.asarray(out[1]) for out in _run_on_both_kernels(_extended)]
    np.testing.assert_array_equal(spikes[0], spikes[1])
    ex = spikes[0][:, :, 512:544].sum() / (2 * 32 * 0.25)
    assert 1.0 < ex < 200.0, f"EX should fire at a cortical rate, got {ex:.1f} Hz"


@pytest.mark.slow   # the default suite's 8-minute budget
def test_an_extended_network_learns_on_its_new_synapses():
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    config = LoopConfig(arm="simple", network=_extended("auto"),
                        task=TaskConfig(epochs=1, epoch_duration_s=1.0, test_duration_s=0.2))
    fns = make_train(config)
    carry = jax.jit(fns.init)(jax.random.PRNGKey(0))
    carry, history = jax.jit(fns.epoch)(carry, MetaParams.original())
    layout = fns.loop.net.layout
    gains = np.asarray(layout.view(carry.trained.wgain, "ES->EX"))
    fixed = np.asarray(layout.view(carry.trained.wgain, "IS->EX"))
    assert np.any(gains != 1.0), "reward-modulated STDP should change some ES->EX gains"
    assert np.all(np.ptp(fixed, axis=1) < 1e-6), "IS->EX is fixed (synaptic scaling moves a cell's inputs alike)"
    assert int(np.asarray(history.lost_spikes).sum()) == 0


# ------------------------------------------------------------------------------------------------ target codes
def _with_target_code(kernel: str, plastic: bool = True) -> NetworkConfig:
    """The paper's network plus T, a target code of 16 cells in 8 direction groups firing at 50 Hz, projecting to
    EM (plastic) and IM (fixed)."""
    spec = NetworkSpec.dura_bernal_2015().with_population(
        Population("T", 16, "generator", code="target", groups=8, rate_hz=50.0))
    spec = spec.with_pathway(Pathway("T", "EM", 0.5, 2.0, (3.0, 5.0), plastic=plastic))
    spec = spec.with_pathway(Pathway("T", "IM", 0.5, 1.0, (3.0, 5.0)))
    return NetworkConfig(spec=spec, kernel=kernel)


@pytest.mark.slow   # the default suite's 8-minute budget
def test_a_target_code_fires_its_directions_train_and_nothing_else():
    """Direction 90 degrees is group 2 of 8: T cells 2 and 10 fire at 50 Hz (one interval, 20 ms, after the
    switch at step 0, then every 20 ms: 10 spikes in 200 ms), the 14 others never; P and the network as before."""
    config = _with_target_code("xla")
    assert config.populations[-2:] == ("P", "T") and config.n_generators == 192 + 16
    net = Network(config)
    layout = net.layout
    assert isinstance(layout.generator_synapses, np.ndarray)       # T->EM is among the plastic synapses
    assert layout.synapses("T->EM").stop == layout.n_plastic
    state = net.set_lengths(net.set_target(net.init(jax.random.key(1)), np.pi / 2), jnp.array([0.1, 0.16, 0.12, 0.14]))
    wiring = net.make_wiring(jax.random.key(0))
    state, spikes = jax.jit(lambda w, s: net.run(w, s, NetworkParams.original(), 800))(wiring, state)
    t = np.asarray(spikes)[:, 704:720]
    expected = np.zeros(16, int)
    expected[[2, 10]] = 10
    np.testing.assert_array_equal(t.sum(axis=0), expected)
    np.testing.assert_array_equal(np.flatnonzero(t[:, 2]) + 1, np.arange(80, 801, 80))      # steps of 0.25 ms
    # the delivery tables list every synapse between network cells once, and no generator synapse
    ids = np.concatenate([np.asarray(g.out_syn)[:-1].ravel() for g in wiring.groups])
    ids = np.sort(ids[ids < layout.n_syn])
    gen = np.arange(layout.n_syn)[layout.generator_synapses]
    np.testing.assert_array_equal(ids, np.setdiff1d(np.arange(layout.n_syn), gen))


@needs_native
@pytest.mark.slow
def test_a_target_code_runs_alike_on_both_kernels():
    out = _run_on_both_kernels(_with_target_code, np.pi)
    np.testing.assert_array_equal(np.asarray(out[0][1]), np.asarray(out[1][1]))
    np.testing.assert_array_equal(np.asarray(out[0][0].pdope_ms), np.asarray(out[1][0].pdope_ms))
    assert np.asarray(out[0][1])[:, :, 704:].sum() == 2 * 2 * 12     # group 4 (180 deg): 2 cells x 12 spikes


@pytest.mark.slow   # the default suite's 8-minute budget
def test_a_plastic_target_code_learns_only_from_its_active_direction():
    """Training toward the left target (180 degrees from the start hand position: group 4 of 8): the T->EM synapses
    from group 4's cells are tagged and change under reward-modulated STDP; those from silent cells only move with
    their post cell's synaptic scaling (equal within a post cell)."""
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    config = LoopConfig(arm="simple", network=_with_target_code("auto"),
                        task=TaskConfig(target="left", epochs=1, epoch_duration_s=2.0, test_duration_s=0.2))
    fns = make_train(config)
    carry = jax.jit(fns.init)(jax.random.PRNGKey(0))
    carry, _ = jax.jit(fns.epoch)(carry, MetaParams.original())
    layout = fns.loop.net.layout
    gains = np.asarray(layout.view(carry.trained.wgain, "T->EM"))
    pre = np.asarray(layout.view(carry.trained.wiring.pre, "T->EM")) - 704
    active = pre % 8 == 4
    assert active.any() and (~active).any()
    assert np.any(gains[active] != 1.0), "synapses from the active direction should learn"
    silent = np.where(active, np.nan, gains)
    assert np.all(np.nan_to_num(np.nanmax(silent, axis=1) - np.nanmin(silent, axis=1)) < 1e-6)
