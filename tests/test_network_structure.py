"""Network structure: populations, ids, groups, fixed in-degree wiring and its per-post layout (spec §2)."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config.validate import ConfigError
from jaxarm.config.spec import NetworkSpec
from jaxarm.network import NetworkConfig, Populations, WiringLayout, in_degree_table, make_wiring

PATHWAYS = NetworkSpec.dura_bernal_2015().pathways

#: In-degrees of the spec §2 table (verified there by dumping the original's built network).
SPEC_IN_DEGREE = {
    "P->ES": 22, "ES->ES": 11, "ES->IS": 93, "ES->ISL": 110, "ES->EM": 65, "ES->IM": 11, "ES->IML": 11,
    "EM->EM": 11, "EM->ES": 2, "EM->IM": 93, "EM->IML": 110,
    "IS->ES": 22, "IS->IS": 31, "IS->ISL": 17, "ISL->ES": 8, "ISL->IS": 12, "ISL->ISL": 2,
    "IM->EM": 22, "IM->IM": 31, "IM->IML": 17, "IML->EM": 8, "IML->IM": 12, "IML->IML": 2,
}
#: Weights of the spec §2 table: AMPA (E presyn, NMDA = 0.1 x) or GABA (I presyn), mV.
SPEC_WEIGHT = {
    "P->ES": 4.0, "ES->ES": 1.98, "ES->IS": 1.15, "ES->ISL": 0.575, "ES->EM": 2.64, "ES->IM": 1.15, "ES->IML": 0.575,
    "EM->EM": 1.782, "EM->ES": 0.72, "EM->IM": 1.15, "EM->IML": 0.575,
    "IS->ES": 4.5, "IS->IS": 4.5, "IS->ISL": 4.5, "ISL->ES": 1.245, "ISL->IS": 2.25, "ISL->ISL": 4.5,
    "IM->EM": 9.0, "IM->IM": 4.5, "IM->IML": 4.5, "IML->EM": 2.49, "IML->IM": 2.25, "IML->IML": 4.5,
}
PLASTIC = {"ES->ES", "ES->IS", "ES->ISL", "ES->EM", "EM->EM", "EM->IM", "EM->IML", "EM->ES"}


@pytest.fixture(scope="module")
def wiring():
    return make_wiring(NetworkConfig(), jax.random.key(398115))


def test_population_sizes_and_id_ranges():
    pops = Populations(NetworkConfig())
    expected = {"ES": (0, 192), "IS": (192, 236), "ISL": (236, 256), "EM": (256, 448), "IM": (448, 492),
                "IML": (492, 512), "P": (512, 704)}
    assert {p: (pops.start[p], pops.stop[p]) for p in expected} == expected
    assert NetworkConfig().n_cells == 512 and NetworkConfig().n_all == 704


def test_muscle_groups_are_id_mod_4_and_interleaved():
    pops = Populations(NetworkConfig())
    np.testing.assert_array_equal(pops.em_groups(), np.arange(256, 448) % 4)
    np.testing.assert_array_equal(pops.p_groups(), np.arange(192) % 4)
    np.testing.assert_array_equal(pops.p_tuning_index(), np.arange(192) // 4)
    assert all(np.sum(pops.em_groups() == g) == 48 for g in range(4))


def test_in_degrees_weights_and_totals_match_spec_table():
    assert in_degree_table() == SPEC_IN_DEGREE
    assert {pw.name: pw.weight_mv for pw in PATHWAYS} == SPEC_WEIGHT
    assert {pw.name for pw in PATHWAYS if pw.plastic} == PLASTIC
    layout = WiringLayout(NetworkConfig())
    assert layout.n_network_syn == 46_440       # spec §2: intra-network synapses
    assert layout.n_syn == 46_440 + 4_224       # + P -> ES
    assert layout.n_plastic == sum(NetworkConfig().size(pw.post) * SPEC_IN_DEGREE[pw.name]
                                   for pw in PATHWAYS if pw.plastic)


def test_wiring_is_fixed_in_degree_without_multi_edges_and_with_spec_delays(wiring):
    layout = WiringLayout(NetworkConfig())
    pops = layout.pops
    for pw in PATHWAYS:
        pre = np.asarray(layout.view(wiring.pre, pw.name))
        post = np.asarray(layout.view(wiring.post, pw.name))
        delay = np.asarray(layout.view(wiring.delay_steps, pw.name)) * NetworkConfig().dt_ms
        n_post, k = pre.shape
        assert (n_post, k) == (NetworkConfig().size(pw.post), SPEC_IN_DEGREE[pw.name])
        np.testing.assert_array_equal(post, np.repeat(pops.ids(pw.post)[:, None], k, axis=1))
        assert pre.min() >= pops.start[pw.pre] and pre.max() < pops.stop[pw.pre]
        assert all(len(set(row)) == k for row in pre), f"{pw.name}: duplicate presynaptic partner"
        lo, hi = pw.delay_ms
        assert delay.min() >= lo - 0.25 and delay.max() <= hi + 0.25  # rounded to dt = 0.5 ms
        w = np.asarray(layout.view(wiring.weight, pw.name))
        np.testing.assert_allclose(w, SPEC_WEIGHT[pw.name])
        nmda = np.asarray(layout.view(wiring.nmda, pw.name))
        np.testing.assert_allclose(nmda, 0.1 * SPEC_WEIGHT[pw.name] if pw.pre in ("P", "ES", "EM") else 0.0,
                                   rtol=1e-6)
    assert int(wiring.out_overflow) == 0


def test_self_connections_follow_the_variant(wiring):
    layout = WiringLayout(NetworkConfig())
    selfs = sum(int(np.sum(np.asarray(layout.view(wiring.pre, n)) == np.asarray(layout.view(wiring.post, n))))
                for n in ("ES->ES", "IS->IS", "EM->EM", "IM->IM"))
    assert selfs > 0   # the original's accidental self-connections (spec §2: 12 + 30 + 7 + 23 there)
    cfg = NetworkConfig(self_connections="exclude")
    w = make_wiring(cfg, jax.random.key(398115))
    lay = WiringLayout(cfg)
    for pw in PATHWAYS:
        assert not np.any(np.asarray(lay.view(w.pre, pw.name)) == np.asarray(lay.view(w.post, pw.name)))


def test_delivery_tables_list_every_network_synapse_once(wiring):
    layout = WiringLayout(NetworkConfig())
    seen = []
    for cells, tables in zip(layout.group_cells, wiring.groups):
        out = np.asarray(tables.out_syn)
        assert np.all(out[-1] == layout.n_syn)          # the "no spike" row is all padding
        for r, c in enumerate(cells):
            ids = out[r][out[r] < layout.n_syn]
            assert np.all(np.asarray(wiring.pre)[ids] == c)
            seen.append(ids)
        np.testing.assert_allclose(np.asarray(tables.out_weight), np.asarray(wiring.weight)[out])
    seen = np.sort(np.concatenate(seen))
    np.testing.assert_array_equal(seen, np.arange(layout.n_network_syn))
    assert layout.spike_groups == (("ES",), ("EM",), ("IS", "ISL", "IM", "IML"))


def test_plastic_input_tables_list_each_cells_plastic_synapses(wiring):
    layout = WiringLayout(NetworkConfig())
    plastic_post = np.asarray(wiring.post)[:layout.n_plastic]
    for cells, tables in zip(layout.group_cells, wiring.groups):
        table = np.asarray(tables.in_plastic)
        pre = np.asarray(tables.in_plastic_pre)
        for r, c in enumerate(cells[::17]):
            row = table[r * 17]
            ids = row[row < layout.n_plastic]
            np.testing.assert_array_equal(np.sort(ids), np.flatnonzero(plastic_post == c))
            np.testing.assert_array_equal(pre[r * 17][row < layout.n_plastic], np.asarray(wiring.pre)[ids])


def test_wiring_is_deterministic_and_key_dependent():
    cfg = NetworkConfig()
    a, b = make_wiring(cfg, jax.random.key(1)), make_wiring(cfg, jax.random.key(1))
    c = make_wiring(cfg, jax.random.key(2))
    np.testing.assert_array_equal(a.pre, b.pre)
    np.testing.assert_array_equal(a.delay_steps, b.delay_steps)
    assert np.mean(np.asarray(a.pre) != np.asarray(c.pre)) > 0.5


@pytest.mark.parametrize("field, value", [
    ("dt_ms", 0.3), ("dt_ms", 0.0), ("dt_ms", 2.0),
    ("self_connections", "none"), ("p_tuning", "wide"), ("spike_capacity", (4, 2)), ("spike_capacity", 8),
    ("readout_bins", 1), ("interface_ms", 10.5), ("noise_max_rate_hz", -1.0), ("readout_clip", 1),
])
def test_config_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        NetworkConfig(**{field: value})


def test_sizes_are_checked_against_the_spec():
    with pytest.raises(ConfigError, match=r"Population 'EM'.size = 190: must be a multiple of 4"):
        NetworkConfig().with_sizes((192, 44, 20, 190, 44, 20, 192))
    with pytest.raises(ConfigError, match=r"7 integers, one per population ES, IS, ISL, EM, IM, IML, P"):
        NetworkConfig.from_dict({"sizes": [1, 2]})


def test_wiring_from_edges_rebuilds_a_drawn_wiring_and_maps_per_edge_arrays(wiring):
    # An edge list in any order (e.g. a network exported from the original NEURON model) becomes the same network:
    # the drawn wiring's own edges, shuffled, give back every array; `order` carries per-edge values along.
    from jaxarm.network.wiring import wiring_from_edges

    config = NetworkConfig()
    n = WiringLayout(config).n_syn
    pre, post = np.asarray(wiring.pre[:n]), np.asarray(wiring.post[:n])
    delay_ms = np.asarray(wiring.delay_steps[:n]) * config.dt_ms
    perm = np.random.default_rng(0).permutation(n)
    rebuilt, order = wiring_from_edges(config, pre[perm], post[perm], delay_ms[perm])
    # per (post cell, pathway row) the presynaptic multiset and the delays are those of the original wiring
    key = lambda w: np.lexsort((np.asarray(w.delay_steps), np.asarray(w.pre), np.asarray(w.post)))  # noqa: E731
    for field in ("pre", "post", "delay_steps", "weight", "nmda", "target"):
        np.testing.assert_array_equal(np.asarray(getattr(rebuilt, field))[key(rebuilt)],
                                      np.asarray(getattr(wiring, field))[key(wiring)])
    assert int(rebuilt.out_overflow) == 0
    # a per-edge value (here: the drawn synapse each edge came from) lands on the synapse that edge became
    source = perm[order]
    np.testing.assert_array_equal(np.asarray(rebuilt.pre[:n]), pre[source])
    np.testing.assert_array_equal(np.asarray(rebuilt.post[:n]), post[source])
    np.testing.assert_array_equal(np.asarray(rebuilt.delay_steps[:n]), np.asarray(wiring.delay_steps)[source])
    # in the drawn order, the rebuild is exact
    same, order = wiring_from_edges(config, pre, post, delay_ms)
    np.testing.assert_array_equal(order, np.arange(n))
    for a, b in zip(jax.tree.leaves(same), jax.tree.leaves(wiring)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_wiring_from_edges_names_what_does_not_fit(wiring):
    from jaxarm.network.wiring import wiring_from_edges

    config = NetworkConfig()
    n = WiringLayout(config).n_syn
    pre, post = np.asarray(wiring.pre[:n]), np.asarray(wiring.post[:n])
    delay = np.ones(n)
    with pytest.raises(ValueError, match=r"pathway ES->ES: post cell 0 has 10 inputs, the in-degree is 11"):
        wiring_from_edges(config, pre[1:], post[1:], delay[1:])
    bad_post = post.copy()
    bad_post[0] = 300                                           # an ES -> ES edge moved onto an EM cell
    with pytest.raises(ValueError, match="in-degree"):
        wiring_from_edges(config, pre, bad_post, delay)
    iml_to_es = np.append(pre, 500), np.append(post, 0)         # IML -> ES is not a pathway of the model
    with pytest.raises(ValueError, match="IML -> ES is not a pathway"):
        wiring_from_edges(config, *iml_to_es, np.ones(n + 1))
    with pytest.raises(ValueError, match=r"pre ids must be in \[0, 704\)"):
        wiring_from_edges(config, np.append(pre, 704), np.append(post, 0), np.ones(n + 1))


def test_pathway_order_and_int32_limits_are_checked():
    spec = NetworkSpec.dura_bernal_2015()
    with pytest.raises(ConfigError, match="plastic pathways must come first"):
        dataclasses.replace(spec, pathways=PATHWAYS[1:] + PATHWAYS[:1])
    with pytest.raises(ConfigError, match=r"fixed pathways from generators \(P\) come last"):
        dataclasses.replace(spec, pathways=PATHWAYS[:-2] + PATHWAYS[-1:] + PATHWAYS[-2:-1])
    # 4 channels x n_cells << 10 must fit int32: 524,287 network cells at most
    with pytest.raises(ConfigError, match="at most 524287"):
        WiringLayout(NetworkConfig().with_sizes((100_000,) * 6 + (192,)))
    WiringLayout(NetworkConfig(pmat_scale=0.001).with_sizes((87_000,) * 6 + (192,)))   # 522,000 cells: fits
    with pytest.raises(ConfigError, match="synapses do not fit int32"):
        WiringLayout(NetworkConfig().with_sizes((87_000,) * 6 + (192,)))


def test_loop_checks_run_length_and_readout_history():
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig

    # float32 spike times keep a quarter step up to 2**22 steps: 41.9 s at dt 0.01 ms
    with pytest.raises(ConfigError, match=r"epoch_duration_s = 60 s: at NetworkConfig.dt_ms = 0.01 .* at most 41.9"):
        LoopConfig(network=NetworkConfig(dt_ms=0.01), task=TaskConfig(epoch_duration_s=60.0))
    LoopConfig(network=NetworkConfig(dt_ms=0.01), task=TaskConfig(epoch_duration_s=30.0))
    # the readout must see back 200 + 50 ms, the longest window the metaparameters allow
    with pytest.raises(ConfigError, match="readout_bins = 16: .* at least 26 bins"):
        LoopConfig(network=NetworkConfig(readout_bins=16))


def test_readout_sums_the_whole_window_up_to_its_bound():
    from jaxarm.network import readout as ro

    cfg = NetworkConfig()
    state = ro.init_readout(cfg)
    for _ in range(cfg.readout_bins):
        state = ro.push(state, jnp.ones(4))
    for window in (10.0, 76.08, 100.0, 150.0, 200.0):
        # rows ending 60, 70, ... ms back up to window + 50 ms: floor(window / 10) + (1 if not a multiple) rows
        expected = np.floor((window + 50.0) / 10.0) - 5     # 7 rows for the original 76.08 ms, 20 for 200 ms
        u = ro.excitation(dataclasses.replace(cfg, readout_clip=False), state, v_em_max=1.0, window_ms=window)
        np.testing.assert_allclose(np.asarray(u), np.full(4, expected))


# ------------------------------------------------------------------------------------------------ scaled networks
def test_scaled_network_keeps_in_degrees_the_p_code_and_the_readout_drive():
    """NetworkConfig.scaled(f): every population f times larger, every in-degree of the spec table kept, the P code
    coded by f cells per position with the same windows (m), and f times the EM spikes giving the same excitation."""
    from jaxarm.network import proprio, readout

    base = NetworkConfig()
    for f in (2, 4):
        big = base.scaled(f)
        assert big.sizes == tuple(f * n for n in base.sizes)
        assert WiringLayout(big).in_degree == SPEC_IN_DEGREE
        lo, hi = proprio.tuning_windows(big)
        lo1, hi1 = proprio.tuning_windows(base)
        np.testing.assert_array_equal(np.unique(lo), np.unique(lo1))   # the same windows, f cells each
        np.testing.assert_array_equal(np.unique(hi), np.unique(hi1))
        lengths = np.array([0.101, 0.157, 0.119, 0.188])
        n1 = np.asarray(proprio.active_cells(base, lengths)).sum()
        assert np.asarray(proprio.active_cells(big, lengths)).sum() == f * n1 > 0
        counts = np.array([3.0, 1.0, 0.0, 7.0], np.float32)
        state1, state_f = readout.init_readout(base), readout.init_readout(big)
        for _ in range(20):
            state1, state_f = readout.push(state1, counts), readout.push(state_f, f * counts)
        np.testing.assert_allclose(readout.excitation(big, state_f), readout.excitation(base, state1), rtol=1e-6)
    # the original numbering is unchanged: position = index // 4, no normalisation
    np.testing.assert_array_equal(Populations(base).p_tuning_index(), np.arange(192) // 4)
    for bad, field in ((lambda: base.scaled(0), "scaled factor"), (lambda: base.scaled(1.5), "scaled factor"),
                       (lambda: NetworkConfig(p_positions=7), "p_positions")):
        with pytest.raises(ConfigError, match=field):
            bad()


@pytest.mark.slow
def test_scaled_network_fires_at_the_rates_of_the_original():
    """The paper's network and its 2x scaling (8 networks, one 10 s epoch of closed-loop training and a 1 s test,
    published metaparameters, seeds 0-7): every population's mean rate within 15 % of the original's in training
    and 20 % in the test (measured: experiments/network_scaling.py, docs/model.md)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent.parent / "experiments"))
    from network_scaling import RATE_POPS, measure

    from jaxarm.network import Network, NetworkParams, native

    counts = {}
    for kernel in ("xla", "native") if native.available() else ("xla", "xla"):               # 100 ms of the 2x network, open loop: the same spikes
        net = Network(NetworkConfig(kernel=kernel).scaled(2))
        state = net.set_lengths(net.init(jax.random.key(1)), np.array([0.10, 0.16, 0.12, 0.14]))
        state, _ = jax.jit(lambda s: net.run(net.make_wiring(jax.random.key(0)), s, NetworkParams.original(),
                                             400))(state)
        counts[kernel] = np.asarray(state.spike_count)
    np.testing.assert_array_equal(counts["xla"], counts["native"])
    assert counts["xla"].sum() > 1000
    one, two = measure(1, 8, 10.0, "simple"), measure(2, 8, 10.0, "simple")
    assert one["lost_spikes"] == two["lost_spikes"] == 0
    for phase, tol in (("train_hz", 0.15), ("test_hz", 0.20)):
        for p in RATE_POPS:
            assert abs(two[phase][p] / one[phase][p] - 1) < tol, (phase, p, one[phase][p], two[phase][p])


# ------------------------------------------------------------------------------------------------ the network as data
def test_network_config_round_trips_through_toml_and_json_and_names_bad_fields(tmp_path):
    import argparse

    from jaxarm.run import network_config

    big = NetworkConfig(dt_ms=0.5, crossing="per_event").scaled(2)
    for suffix in (".toml", ".json"):
        path = tmp_path / f"net{suffix}"
        big.save(path)
        assert NetworkConfig.load(path) == big
    text = (tmp_path / "net.toml").read_text()
    assert "sizes = [384, 88, 40, 384, 88, 40, 384]" in text and "kernel" not in text
    # a run's meta (the changed fields) rebuilds the network, as `jaxarm test --from` does
    assert network_config(big.to_dict(changed_only=True) | {"kernel": "native", "target": "left"}) == big
    # command options: the file, then --network-scale, then the single options
    args = argparse.Namespace(network=tmp_path / "net.json", network_scale=2, dt_ms=None, threshold_test="on_event",
                              crossing=None, readout_clip=None)
    assert network_config(args) == dataclasses.replace(big.scaled(2), threshold_test="on_event")
    (tmp_path / "bad.toml").write_text("sizes = [1, 2]\nfoo = 3\n")
    with pytest.raises(ConfigError, match="unknown NetworkConfig field.*foo"):
        NetworkConfig.load(tmp_path / "bad.toml")
    (tmp_path / "bad.toml").write_text("sizes = [1, 2]\n")
    with pytest.raises(ConfigError, match="NetworkConfig.sizes = \\[1, 2\\]: 7 integers"):
        NetworkConfig.load(tmp_path / "bad.toml")
    (tmp_path / "bad.toml").write_text("sizes = [1, 2\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        NetworkConfig.load(tmp_path / "bad.toml")
    with pytest.raises(ConfigError, match="--network-scale 0: must be an integer in"):
        network_config(argparse.Namespace(network=None, network_scale=0))
    # `jaxarm evolve --network FILE --dt-ms 0.5`: the fitness builds its networks from the file, at that step
    from jaxarm.evolve.cli import _network
    from jaxarm.evolve.fitness import FitnessOptions

    net = _network(argparse.Namespace(network=tmp_path / "net.toml", network_scale=None))
    assert net == big and _network(argparse.Namespace(network=None, network_scale=None)) is None
    options = FitnessOptions(arm="simple", targets=("left",), network=net, dt_ms=0.25)
    assert options.network_config() == dataclasses.replace(big, dt_ms=0.25)


@pytest.mark.slow
def test_train_with_a_network_file_equals_network_scale_and_test_rebuilds_it(tmp_path):
    """`jaxarm train --network FILE` (the 2x network as TOML) and `--network-scale 2` train the same networks; `jaxarm
    test --from` rebuilds the network from the run's meta and re-tests them identically."""
    import json

    from jaxarm.cli import main

    NetworkConfig().scaled(2).save(tmp_path / "big.toml")
    common = ["train", "--networks", "2", "--epochs", "1", "--epoch-s", "0.3", "--test-s", "0.3", "--no-progress"]
    assert main([*common, "--network", str(tmp_path / "big.toml"), "--out", str(tmp_path / "file")]) == 0
    assert main([*common, "--network-scale", "2", "--out", str(tmp_path / "scale")]) == 0
    a, b = (json.loads((tmp_path / d / "results.json").read_text()) for d in ("file", "scale"))
    assert a["networks"] == b["networks"] and a["config"]["loop"]["network"]["spec"]["populations"][0]["size"] == 384
    assert main(["test", "--from", str(tmp_path / "file"), "--test-s", "0.3"]) == 0
    again = json.loads((tmp_path / "file" / "test" / "results.json").read_text())
    assert again["networks"] == a["networks"]
