"""Firing rates of the network under the training drive, compared with the original (spec §10).

Training drive = what the first 10 s of the original's training did, without plasticity: the simple arm in closed
loop (readout every 10 ms -> arm step -> muscle lengths -> P code), motor babbling as the code did it (spec §5:
EM AMPA noise 152.76 Hz to the babbled group(s), 50 Hz to the others, re-chosen at every 60 ms critic update, 200 Hz
before the first one). The original's rates over its first 10 s of training: ES 3.9, IS 2.4, ISL 1.7, EM 1.0,
IM 1.3, IML 0.8 Hz.

    python experiments/network_rates.py --json                  # 8 networks x 10 s, default dt
    python experiments/network_rates.py --networks 1 --seconds 10 --dt 0.1
    python experiments/network_rates.py --compare-dt 0.1,0.25,0.5,1 --seconds 20 --json   # choosing the default dt
    python experiments/network_rates.py --seconds 30 --window-s 5     # how the rates settle after the start

``--compare-dt``: the same networks (wiring and noise keys) at each dt; every dt is compared with the first
(the reference) by per-population rate and spike count. The default dt is the largest one whose every population
is within 10 % of the dt = 0.1 ms reference.

Each network has its own wiring and noise (keys from --seed); rates are means over networks, with the spread.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import make_arm
from jaxarm.learning.babbling import BabblingState, babble, init_babbling
from jaxarm.learning.metaparams import MetaParams
from jaxarm.network import Network, NetworkConfig, NetworkParams
from jaxarm.network import readout as readout_mod
from jaxarm.config.spec import NetworkSpec

POPULATIONS = NetworkSpec.dura_bernal_2015().names

#: Rates of the original over the first 10 s of training, Hz (spec §10, spkstats2).
ORIGINAL_RATES_HZ = {"ES": 3.9, "IS": 2.4, "ISL": 1.7, "EM": 1.0, "IM": 1.3, "IML": 0.8}
#: The original's rates over the last 10 s of training epoch 1 (t = 20-30 s; spec §10 table, first row), Hz. The
#: original had plasticity on (its gains moved 0-5 % by then); ours here has none.
ORIGINAL_EPOCH1_LAST10S_HZ = {"ES": 3.46, "IS": 2.07, "ISL": 1.65, "EM": 0.78, "IM": 0.80, "IML": 0.68}
#: The original's critic period on the 10 ms loop (rlDT = 55.55 ms -> every 60 ms).
RL_PERIOD_MS = 60.0


class LoopState(NamedTuple):
    net: object
    arm: object
    readout: readout_mod.ReadoutState
    babble: BabblingState


def make_training_drive(net: Network, seconds: float, mp: MetaParams | None = None, arm_kind: str = "simple",
                        from_state: bool = False):
    """A pure ``simulate(wiring, key) -> (final LoopState, hand (n_intervals, 2) m)`` of one network under the
    training drive for ``seconds`` from rest (no plasticity). With ``from_state=True`` it is
    ``simulate(wiring, key, state)``, continuing a :class:`LoopState` (time keeps running). ``vmap`` it over networks."""
    mp = MetaParams.original() if mp is None else mp
    arm = make_arm(arm_kind)
    cfg = net.config
    period = cfg.interface_ms
    n_intervals = int(round(seconds * 1000.0 / period))
    rl_every = int(round(RL_PERIOD_MS / period))
    params = NetworkParams(max_plast_t_ms=mp.max_plast_t_ms)
    em = net.pops.slice("EM")

    def interval(wiring, k_babble, s: LoopState):
        before = s.net.spike_count[em]
        net_state, _ = net.run(wiring, s.net, params, cfg.steps_per_interface, collect=False)
        i = s.readout.pushes                      # intervals completed so far in this run
        t_ms = (i + 1).astype(jnp.float32) * period
        em_counts = readout_mod.em_group_counts(cfg, jnp.zeros((cfg.n_all,), jnp.int32).at[em].set(
            net_state.spike_count[em] - before))
        ro = readout_mod.push(s.readout, em_counts)
        u = readout_mod.excitation(cfg, ro, mp.v_em_max, mp.mcmd_spk_wd_ms)
        arm_state = arm.step(s.arm, u)
        obs = arm.observe(arm_state)
        net_state = net.set_lengths(net_state, obs.proprio)
        rl = (i + 1) % rl_every == 0
        new_babble, rates = babble(jax.random.fold_in(k_babble, i), s.babble, t_ms, mp)
        babble_state = jax.tree_util.tree_map(lambda a, b: jnp.where(rl, a, b), new_babble, s.babble)
        net_state = jax.lax.cond(rl, lambda ns: net.set_em_rates(ns, rates), lambda ns: ns, net_state)
        return LoopState(net_state, arm_state, ro, babble_state), obs.hand

    def run(wiring, key, state):
        k_babble = jax.random.fold_in(key, 1)
        return jax.lax.scan(lambda s, _: interval(wiring, k_babble, s), state, None, length=n_intervals)

    def initial(key):
        return LoopState(net=net.init(jax.random.fold_in(key, 0)), arm=arm.init(),
                         readout=readout_mod.init_readout(cfg), babble=init_babbling())

    if from_state:
        return run
    return lambda wiring, key: run(wiring, key, initial(key))


def measure_rates(config: NetworkConfig, n_networks: int, seconds: float, seed: int):
    """Run ``n_networks`` networks (own wiring and noise each) under the training drive.

    Returns a dict with per-network rates (Hz), means, counters and wall times."""
    net = Network(config)
    keys = jax.random.split(jax.random.key(seed), 2 * n_networks)
    wirings = jax.vmap(net.make_wiring)(keys[:n_networks])
    simulate = jax.jit(jax.vmap(make_training_drive(net, seconds)))
    t0 = time.perf_counter()
    final, hand = simulate(wirings, keys[n_networks:])
    jax.block_until_ready(final)
    wall = time.perf_counter() - t0
    counts = np.asarray(final.net.spike_count)
    duration_ms = seconds * 1000.0
    per_net = [net.pops.population_rates_hz(counts[i], duration_ms) for i in range(n_networks)]
    means = {p: float(np.mean([r[p] for r in per_net])) for p in POPULATIONS}
    sds = {p: float(np.std([r[p] for r in per_net])) for p in POPULATIONS}
    return {
        "rates_hz": {p: means[p] for p in ORIGINAL_RATES_HZ},
        "rates_sd_across_networks_hz": {p: sds[p] for p in ORIGINAL_RATES_HZ},
        "p_rate_hz": means["P"],
        "spike_counts": {p: int(counts[:, net.pops.slice(p)].sum()) for p in POPULATIONS},
        "per_network_rates_hz": per_net,
        "original_rates_hz": ORIGINAL_RATES_HZ,
        "ratio_to_original": {p: means[p] / ORIGINAL_RATES_HZ[p] for p in ORIGINAL_RATES_HZ},
        "extra_passes": int(np.asarray(final.net.counters.extra_passes).sum()),
        "lost_spikes": int(np.asarray(final.net.counters.lost_spikes).sum()),
        "wiring_out_overflow": int(np.asarray(wirings.out_overflow).sum()),
        "hand_final_m": np.asarray(hand[:, -1]).tolist(),
        "config": {"dt_ms": config.dt_ms, "networks": n_networks, "seconds": seconds, "seed": seed,
                   "spike_capacity": list(config.spike_capacity), "p_tuning": config.p_tuning,
                   "self_connections": config.self_connections},
        "wall_s_including_compile": wall,
    }


def measure_windows(config: NetworkConfig, n_networks: int, seconds: float, window_s: float, seed: int):
    """Rates in consecutive windows of ``window_s`` under the training drive (one continuing run): how the rates
    settle after the start. Returns per-window mean rates (Hz) per population, P included."""
    net = Network(config)
    keys = jax.random.split(jax.random.key(seed), 2 * n_networks)
    wirings = jax.vmap(net.make_wiring)(keys[:n_networks])
    first = jax.jit(jax.vmap(make_training_drive(net, window_s)))
    more = jax.jit(jax.vmap(make_training_drive(net, window_s, from_state=True)))
    n_windows = max(1, int(round(seconds / window_s)))
    windows, prev, state = [], None, None
    for w in range(n_windows):
        state, _ = first(wirings, keys[n_networks:]) if w == 0 else more(wirings, keys[n_networks:], state)
        counts = np.asarray(state.net.spike_count)
        diff = counts if prev is None else counts - prev
        prev = counts
        rates = {p: float(diff[:, net.pops.slice(p)].sum() / (n_networks * config.size(p) * window_s))
                 for p in POPULATIONS}
        windows.append({"start_s": w * window_s, "end_s": (w + 1) * window_s, "rates_hz": rates})
    return {"windows": windows, "original_first_10s_hz": ORIGINAL_RATES_HZ,
            "original_epoch1_last_10s_hz": ORIGINAL_EPOCH1_LAST10S_HZ,
            "config": {"dt_ms": config.dt_ms, "networks": n_networks, "seconds": n_windows * window_s,
                       "window_s": window_s, "seed": seed},
            "lost_spikes": int(np.asarray(state.net.counters.lost_spikes).sum())}


def compare_dt(dts, n_networks: int, seconds: float, seed: int):
    """Rates at each dt for the same networks; relative difference of each population from the first dt."""
    runs = {dt: measure_rates(NetworkConfig(dt_ms=dt), n_networks, seconds, seed) for dt in dts}
    ref = runs[dts[0]]
    table = {}
    for dt, r in runs.items():
        rel = {p: r["rates_hz"][p] / ref["rates_hz"][p] - 1.0 for p in ORIGINAL_RATES_HZ}
        # the spread of the reference's mean over networks, as a yardstick for the differences
        sem = {p: ref["rates_sd_across_networks_hz"][p] / np.sqrt(n_networks) / ref["rates_hz"][p]
               for p in ORIGINAL_RATES_HZ}
        table[str(dt)] = {"rates_hz": r["rates_hz"], "relative_difference": rel,
                          "max_abs_relative_difference": max(abs(v) for v in rel.values()),
                          "within_10_percent": all(abs(v) <= 0.10 for v in rel.values()),
                          "reference_sem_relative": sem,
                          "spike_counts": r["spike_counts"], "wall_s_including_compile": r["wall_s_including_compile"]}
    ok = [dt for dt in dts if table[str(dt)]["within_10_percent"]]
    return {"reference_dt_ms": dts[0], "networks": n_networks, "seconds": seconds, "seed": seed, "by_dt": table,
            "largest_dt_within_10_percent": max(ok) if ok else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", type=int, default=8, help="networks (own wiring and noise each)")
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds (original: first 10 s)")
    ap.add_argument("--dt", type=float, default=None, help="clock step, ms (default: NetworkConfig's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    ap.add_argument("--compare-dt", default=None, metavar="DT,DT,...",
                    help="compare rates across time steps (the first is the reference), e.g. 0.1,0.25,0.5,1")
    ap.add_argument("--window-s", type=float, default=None,
                    help="report rates in consecutive windows of this many seconds (e.g. --seconds 30 --window-s 5)")
    args = ap.parse_args(argv)
    if args.window_s:
        config = NetworkConfig() if args.dt is None else NetworkConfig(dt_ms=args.dt)
        result = measure_windows(config, args.networks, args.seconds, args.window_s, args.seed)
        if args.json:
            print(json.dumps(result, indent=1))
            return 0
        print(f"{args.networks} networks, dt = {config.dt_ms} ms, seed {args.seed}; rates (Hz) per window")
        print(f"{'window s':>10} " + " ".join(f"{p:>6}" for p in POPULATIONS))
        for w in result["windows"]:
            print(f"{w['start_s']:4g}-{w['end_s']:<5g} " + " ".join(f"{w['rates_hz'][p]:6.2f}" for p in POPULATIONS))
        print(f"{'orig 0-10':>10} " + " ".join(f"{ORIGINAL_RATES_HZ[p]:6.2f}" for p in ORIGINAL_RATES_HZ))
        print(f"{'orig 20-30':>10} " + " ".join(f"{ORIGINAL_EPOCH1_LAST10S_HZ[p]:6.2f}" for p in ORIGINAL_RATES_HZ)
              + "   (training epoch 1, plasticity on)")
        return 0
    if args.compare_dt:
        dts = [float(x) for x in args.compare_dt.split(",")]
        result = compare_dt(dts, args.networks, args.seconds, args.seed)
        if args.json:
            print(json.dumps(result, indent=1))
            return 0
        print(f"{args.networks} networks x {args.seconds:g} s, seed {args.seed}; difference from dt = {dts[0]} ms")
        print(f"{'dt':>6} " + " ".join(f"{p:>7}" for p in ORIGINAL_RATES_HZ) + "  within 10 %")
        for dt in dts:
            row = result["by_dt"][str(dt)]
            print(f"{dt:6g} " + " ".join(f"{100 * row['relative_difference'][p]:+6.1f}%" for p in ORIGINAL_RATES_HZ)
                  + f"  {row['within_10_percent']}")
        print(f"largest dt within 10 %: {result['largest_dt_within_10_percent']}")
        return 0
    config = NetworkConfig() if args.dt is None else NetworkConfig(dt_ms=args.dt)
    result = measure_rates(config, args.networks, args.seconds, args.seed)
    if args.json:
        print(json.dumps(result, indent=1))
        return 0
    print(f"{args.networks} networks x {args.seconds:g} s, dt = {config.dt_ms} ms, seed {args.seed} "
          f"(wall {result['wall_s_including_compile']:.1f} s incl. compile)")
    print(f"{'pop':5} {'ours Hz':>9} {'sd':>6} {'original':>9} {'ratio':>6}")
    for p, ref in ORIGINAL_RATES_HZ.items():
        r = result["rates_hz"][p]
        flag = "" if 1 / 1.5 <= r / ref <= 1.5 else "  (outside x1.5)"
        print(f"{p:5} {r:9.2f} {result['rates_sd_across_networks_hz'][p]:6.2f} {ref:9.2f} {r / ref:6.2f}{flag}")
    print(f"P rate {result['p_rate_hz']:.2f} Hz; extra spike-list passes {result['extra_passes']}, "
          f"lost spikes {result['lost_spikes']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
