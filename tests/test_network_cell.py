"""The clock-driven INTF6 cell against the event-driven INTF6 equations of spec §1, computed by hand (in Python floats).

With exactly one input event per clock step the original tests the threshold at every step too, so the two must
agree: same spike times, same state at every step.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config import ConfigError
from jaxarm.network import NetworkConfig, Populations
from jaxarm.network import cell as C

TAUS = {"ampa": 20.0, "nmda": 300.0, "gaba_prox": 10.0, "gaba_dist": 20.0}
#: INTF6 parameters per type, as params.hoc L71-136 give them (spec §1), written out here independently of the
#: spec module: RMP, VTH, Vblock (mV), refrac (ms), ahpwt (mV), tauahp, tauRR (ms), RRWght.
PAPER_CELL_PARAMS = {
    "E": dict(rmp=-65.0, vth=-40.0, vblock=-25.0, refrac=5.0, ahpwt=1.0, tauahp=400.0, taurr=8.0, rrwght=0.75),
    "FS": dict(rmp=-63.0, vth=-40.0, vblock=-10.0, refrac=2.5, ahpwt=0.5, tauahp=50.0, taurr=1.5, rrwght=0.25),
    "LTS": dict(rmp=-65.0, vth=-47.0, vblock=-10.0, refrac=2.5, ahpwt=0.5, tauahp=50.0, taurr=1.5, rrwght=0.25),
}


def reference_intf6(events, p, dt):
    """Event-driven INTF6 (spec §1). ``events``: list of (t, kind, w) with kind in {"E", "FS", "LTS"}.

    Returns (spike times, [(t, Vm, VTHC)] after each event, spike included)."""
    x = dict(ampa=0.0, nmda=0.0, gaba_prox=0.0, gaba_dist=0.0, ahp=0.0)
    vthc, vthr, t0, trrs, refractory, refr_end = p["vth"], p["vth"], 0.0, 0.0, False, None
    spikes, trace = [], []
    for t, kind, w in events:
        if refractory and refr_end is not None and refr_end <= t + 1e-9:   # flag-3 event first (same time: first)
            refractory, trrs = False, refr_end
        for k, tau in TAUS.items():
            x[k] *= math.exp(-(t - t0) / tau)
        x["ahp"] *= math.exp(-(t - t0) / p["tauahp"])
        if not refractory and vthc > p["vth"]:
            vthc = p["vth"] + (vthr - p["vth"]) * math.exp(-(t - trrs) / p["taurr"])
        t0 = t
        v = min(max(sum(x.values()), p["rmp"]), -p["rmp"])
        if kind == "E":   # an AMPA + NMDA pair sees the same V
            x["ampa"] = max(x["ampa"] + w * (1 - v / 65.0), 0.0)
            if x["nmda"] < 90.0:
                block = 1.0 / (1.0 + math.exp(-0.062 * (p["rmp"] + v)) * (1.6 / 3.57))
                x["nmda"] += 0.1 * w * block * (1 - v / 90.0)
        else:
            key = "gaba_prox" if kind == "FS" else "gaba_dist"
            if x[key] > -15.0:
                x[key] = min(x[key] - w * (1 - v / -15.0), 0.0)
        vm = min(max(p["rmp"] + sum(x.values()), -90.0), 0.0)
        if not refractory and vm > vthc and vm <= p["vblock"]:
            spikes.append(t)
            x["ahp"] -= p["ahpwt"]
            vthc = vthr = p["vth"] + p["rrwght"] * (p["vblock"] - p["vth"])
            refractory, refr_end = True, t + p["refrac"]
        trace.append((t, min(max(p["rmp"] + sum(x.values()), -90.0), 0.0), vthc))  # after the spike's AHP
    return spikes, trace


def _one_cell_constants(config, index):
    return C.CellConstants(*(np.asarray(a)[index:index + 1] for a in C.cell_constants(config)))


@pytest.mark.parametrize("pop, cell_type", [("ES", "E"), ("IM", "FS"), ("IML", "LTS")])
def test_clock_driven_cell_matches_event_driven_intf6(pop, cell_type):
    config = NetworkConfig(dt_ms=0.5)
    dt = config.dt_ms
    index = Populations(config).start[pop]
    const = _one_cell_constants(config, index)
    rng = np.random.default_rng(7)
    n = 1200  # 600 ms, one event per step
    kinds = rng.choice(["E", "FS", "LTS"], size=n, p=[0.7, 0.15, 0.15])
    weights = np.where(kinds == "E", rng.uniform(0.5, 4.5, n), rng.uniform(0.5, 3.0, n))
    events = [((k + 1) * dt, kinds[k], float(weights[k])) for k in range(n)]
    ampa = np.where(kinds == "E", weights, 0.0)
    inputs = np.stack([ampa, 0.1 * ampa, np.where(kinds == "FS", weights, 0.0),
                       np.where(kinds == "LTS", weights, 0.0)], axis=1).astype(np.float32)

    @jax.jit
    def simulate(inputs):
        def body(s, x):
            s, spiked = C.cell_step(s, x[0:1], x[1:2], x[2:3], x[3:4], const)
            return s, (spiked[0], C.membrane_potential(s, const)[0], const.vth[0] + s.vthc_excess[0])
        return jax.lax.scan(body, C.init_cells(1), jnp.asarray(inputs))[1]

    spiked, vm, vthc = (np.asarray(a) for a in simulate(inputs))
    ref_spikes, trace = reference_intf6(events, PAPER_CELL_PARAMS[cell_type], dt)
    ours = [(k + 1) * dt for k in np.flatnonzero(spiked)]
    assert len(ref_spikes) >= 5, "the input train should make the cell fire"
    np.testing.assert_allclose(ours, ref_spikes, atol=1e-6)
    np.testing.assert_allclose(vm, [v for _, v, _ in trace], atol=2e-3)
    np.testing.assert_allclose(vthc, [th for _, _, th in trace], atol=2e-3)


def test_depolarisation_block_prevents_spikes():
    config = NetworkConfig(dt_ms=0.5)
    const = _one_cell_constants(config, 0)  # an E cell: Vblock = -25 mV
    s = C.init_cells(1)
    big = jnp.array([60.0])                 # AMPA jump of 60 mV -> Vm = -5 mV > Vblock
    s, spiked = C.cell_step(s, big, big * 0, big * 0, big * 0, const)
    assert not bool(spiked[0]) and float(C.membrane_potential(s, const)[0]) > -25.0
    # as AMPA decays (tau 20 ms) Vm falls through (VTH, Vblock] = (-40, -25] and the cell fires there, once
    zero = jnp.zeros(1)
    fired = []
    for k in range(200):
        s, spiked = C.cell_step(s, zero, zero, zero, zero, const)
        if bool(spiked[0]):
            fired.append(float(C.membrane_potential(s, const)[0]) + 1.0)  # + ahpwt: Vm at the crossing
    assert fired and all(-40.0 < v <= -25.0 + 1e-4 for v in fired[:1])


def test_on_event_threshold_test_waits_for_the_next_input():
    """The original tests the threshold only when an event arrives: a cell depolarised into block that then decays
    through (VTH, Vblock] fires at once with every-step tests, and only at its next input with on-event tests."""
    config = NetworkConfig(dt_ms=0.5)
    const = _one_cell_constants(config, 0)  # an E cell
    zero, big, tiny = jnp.zeros(1), jnp.array([60.0]), jnp.array([1e-3])

    def first_spike(on_event, input_at):
        s, _ = C.cell_step(C.init_cells(1), big, zero, zero, zero, const, on_event=on_event)   # into block
        for k in range(200):
            gaba = tiny if k == input_at else zero      # a negligible inhibitory event: it only triggers the test
            s, spiked = C.cell_step(s, zero, zero, gaba, zero, const, on_event=on_event)
            if bool(spiked[0]):
                return k
        return None

    # Vm decays from -5 mV through Vblock = -25 (t = 8 ms) to VTH = -40 (t = 17.5 ms); step 25 is t = 13 ms
    every = first_spike(False, input_at=25)
    assert every is not None and every < 25
    assert first_spike(True, input_at=25) == 25        # silent until the event, then fires at it
    assert first_spike(True, input_at=10_000) is None  # no event, no test, no spike
    with pytest.raises(ConfigError, match="threshold_test"):
        NetworkConfig(threshold_test="sometimes")


def test_per_event_crossing_fires_a_volley_that_jumps_past_vblock():
    """22 simultaneous P inputs (4 mV each, one step) lift an ES cell from rest past Vblock (-25 mV). The original
    tests after every event and fires at the one that crosses VTH; testing the step's sum once blocks it until it
    decays back below Vblock ("after_step"); "per_event" fires it in the step of the volley, as the original."""
    config = NetworkConfig(dt_ms=0.25)
    const = _one_cell_constants(config, 0)   # an E cell: VTH -40, Vblock -25 mV
    zero = jnp.zeros(1)
    volley = C.event_load(jnp.full((1,), 4.0), 65.0) * 22     # the summed load of 22 events of 4 mV
    s, after = C.cell_step(C.init_cells(1), volley, zero, zero, zero, const, sequential=True)
    assert float(C.membrane_potential(s, const)[0]) > -25.0 and not bool(after[0])       # into block: no spike
    _, per = C.cell_step(C.init_cells(1), volley, zero, zero, zero, const, sequential=True, per_event_crossing=True)
    assert bool(per[0])
    # a cell already above Vblock before the step stays blocked either way (the original's events find it blocked)
    _, again = C.cell_step(s, jnp.array([0.5]), zero, zero, zero, const, sequential=True, per_event_crossing=True)
    assert not bool(again[0])
    # input that stays within (VTH, Vblock] fires the same way under both rules; below VTH neither fires
    small = jnp.array([30.0])
    for rule in (False, True):
        assert bool(C.cell_step(C.init_cells(1), small, zero, zero, zero, const, per_event_crossing=rule)[1][0])
        assert not bool(C.cell_step(C.init_cells(1), jnp.array([5.0]), zero, zero, zero, const,
                                    per_event_crossing=rule)[1][0])
    with pytest.raises(ConfigError, match="crossing"):
        NetworkConfig(crossing="sometimes")


@pytest.mark.parametrize("sequential", [False, True])
def test_random_order_fires_where_the_excitation_came_first(sequential):
    """One step brings an E cell at rest an excitatory event that alone crosses VTH and an inhibitory (FS) event that
    brings the sum back below. The event-driven original (reference_intf6) fires if the excitatory event comes
    first and not otherwise; the end-of-step test never fires; "random_order" fires exactly where its coin says the
    excitation came first, and a coin never fires a cell without inhibition in the step (the end-of-step test
    decides that alone) or within its refractory period."""
    config = NetworkConfig(dt_ms=0.5)
    const = _one_cell_constants(config, 0)   # an E cell: RMP -65, VTH -40, Vblock -25 mV
    w_e, w_i = 27.0, 5.0
    t = config.dt_ms
    first_e, _ = reference_intf6([(t, "E", w_e), (t, "FS", w_i)], PAPER_CELL_PARAMS["E"], t)
    first_i, _ = reference_intf6([(t, "FS", w_i), (t, "E", w_e)], PAPER_CELL_PARAMS["E"], t)
    assert first_e == [t] and first_i == []
    e_load = C.event_load(jnp.array([w_e]), 65.0) if sequential else jnp.array([w_e])
    i_load = C.event_load(jnp.array([w_i]), 15.0) if sequential else jnp.array([w_i])
    zero = jnp.zeros(1)

    def fires(cells, order, gaba=i_load):
        return bool(C.cell_step(cells, e_load, 0.1 * jnp.array([w_e]), gaba, zero, const, sequential=sequential,
                                excitation_first=order)[1][0])

    rest = C.init_cells(1)
    assert not fires(rest, None)
    assert fires(rest, jnp.array([True])) and not fires(rest, jnp.array([False]))
    # without inhibition the step's end decides, whatever the coin; a refractory cell never fires
    assert fires(rest, jnp.array([False]), gaba=zero)
    refractory = rest._replace(steps_since_spike=jnp.array([1], jnp.int32))
    assert not fires(refractory, jnp.array([True]))
    with pytest.raises(ConfigError, match="same_step_inhibition"):
        NetworkConfig(same_step_inhibition="sometimes")


def test_refractory_periods_in_steps():
    for dt, expected in [(0.1, (50, 25, 25)), (0.5, (10, 5, 5)), (1.0, (5, 3, 3))]:
        const = C.cell_constants(NetworkConfig(dt_ms=dt))
        pops = Populations(NetworkConfig(dt_ms=dt))
        got = tuple(int(const.n_refractory[pops.start[p]]) for p in ("ES", "IS", "ISL"))
        assert got == expected


@pytest.mark.parametrize("pop, cell_type", [("ES", "E"), ("IM", "FS")])
def test_sequential_summation_one_event_per_step_equals_intf6(pop, cell_type):
    """With loads instead of weights (event_summation="sequential"), one event per step still gives INTF6 exactly."""
    config = NetworkConfig(dt_ms=0.5)
    const = _one_cell_constants(config, Populations(config).start[pop])
    rng = np.random.default_rng(3)
    n = 600
    kinds = rng.choice(["E", "FS", "LTS"], size=n, p=[0.7, 0.15, 0.15])
    weights = np.where(kinds == "E", rng.uniform(0.5, 4.5, n), rng.uniform(0.5, 3.0, n))
    events = [((k + 1) * 0.5, kinds[k], float(weights[k])) for k in range(n)]
    ampa = np.where(kinds == "E", weights, 0.0)
    loads = np.stack([C.event_load(ampa, 65.0), 0.1 * ampa, C.event_load(np.where(kinds == "FS", weights, 0.0), 15.0),
                      C.event_load(np.where(kinds == "LTS", weights, 0.0), 15.0)], axis=1).astype(np.float32)

    @jax.jit
    def simulate(inputs):
        def body(s, x):
            s, spiked = C.cell_step(s, x[0:1], x[1:2], x[2:3], x[3:4], const, sequential=True)
            return s, (spiked[0], C.membrane_potential(s, const)[0])
        return jax.lax.scan(body, C.init_cells(1), jnp.asarray(loads))[1]

    spiked, vm = (np.asarray(a) for a in simulate(loads))
    ref_spikes, trace = reference_intf6(events, PAPER_CELL_PARAMS[cell_type], 0.5)
    assert len(ref_spikes) >= 3
    np.testing.assert_allclose([(k + 1) * 0.5 for k in np.flatnonzero(spiked)], ref_spikes, atol=1e-6)
    np.testing.assert_allclose(vm, [v for _, v, _ in trace], atol=5e-3)


def test_sequential_summation_of_a_volley_equals_one_by_one_jumps():
    """22 AMPA events of 4 mV in one step (the P volley onto an ES cell): the original's one-by-one jumps leave
    65 (1 - (1 - 4/65)^22) = 48.9 mV; the linear form gives 88 mV. Same for GABA toward -15 mV."""
    config = NetworkConfig(dt_ms=0.5)
    const = _one_cell_constants(config, 0)
    zero = jnp.zeros(1)
    one_by_one = 65.0 * (1.0 - (1.0 - 4.0 / 65.0) ** 22)
    load = jnp.asarray([22 * float(C.event_load(np.float32(4.0), 65.0))], jnp.float32)
    s, _ = C.cell_step(C.init_cells(1), load, zero, zero, zero, const, sequential=True)
    assert float(s.ampa[0]) == pytest.approx(one_by_one * math.exp(0.0), rel=1e-5)
    s_lin, _ = C.cell_step(C.init_cells(1), jnp.asarray([88.0]), zero, zero, zero, const)
    assert float(s_lin.ampa[0]) == pytest.approx(88.0)
    # GABA: three 9 mV events from rest: V -> -15 + 15 (1 - 9/15)^3 ... i.e. -15 (1 - 0.4^3)
    g = jnp.asarray([3 * float(C.event_load(np.float32(9.0), 15.0))], jnp.float32)
    s, _ = C.cell_step(C.init_cells(1), zero, zero, g, zero, const, sequential=True)
    assert float(s.gaba_prox[0]) == pytest.approx(-15.0 * (1.0 - 0.4 ** 3), rel=1e-5)
