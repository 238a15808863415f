"""Where a coarser clock loses firing rate: each population's rate at a coarse dt against a fine one, for the full
network and for variants that remove one suspect at a time.

    python experiments/dt_ablation.py --seeds 0,1,2 --json-out docs/results/dt_ablation.json   # 16 networks x 20 s each, ~10 min

At dt = 0.5 ms the M populations fire 10-20 % less than at 0.05 ms under the training drive ([model: time
step](../docs/model.md#the-spiking-network-in-detail)), which keeps the default step at 0.25 ms and the kernel at
4,000 steps per network-second. A variant that brings its coarse-dt rates back to the fine ones names the cause; one
that leaves the loss in place rules its suspect out. Every variant runs the same networks (wiring and noise keys
from each of ``--seeds``) at both steps under the training drive of ``network_rates.py``:

* ``full``: the model as it is;
* ``isolated``: every pathway's weight 0 (P -> ES included): each cell alone under its background noise, so the
  cell's clock-driven update and the Poisson noise per step are tested without the network;
* ``isolated_no_inhibitory_noise`` / ``no_inhibitory_noise``: ``isolated`` / ``full`` with the GABA noise lanes'
  weights 0 (the AMPA noise kept): whether same-step inhibition plays a part (the end-of-step threshold test
  misses a crossing made by an excitatory event when an inhibitory event of the same step undoes it, where the
  event-driven original fires if the excitatory event comes first);
* ``no_inhibition`` / ``no_excitatory_recurrence``: the weights of the pathways from the inhibitory populations /
  from ES and EM set to 0 (P -> ES kept);
* ``delays_on_grid``: every delay fixed at a multiple of both steps (3-5 ms -> 4 ms, 1.8-2.2 ms -> 2 ms), so delay
  rounding plays no part;
* ``no_nmda``: the NMDA/AMPA ratio 0;
* ``linear_summation``, ``crossing_per_event``, ``threshold_on_event``: the NetworkConfig options of the same names
  ([model: deviations](../docs/model.md#every-deviation-from-the-original));
* ``random_order`` (and with ``delays_on_grid``): ``NetworkConfig.same_step_inhibition = "random_order"``, the
  remedy for the same-step inhibition above (a crossing by excitation fires when a coin says the excitation came
  first), at both steps.

The relative differences of the coarse step from the fine one per population are printed and written, with the
standard error that Poisson counting alone would give; the networks' own variability adds to it, which is why
the result is given per seed (each seed: other wirings and noise) and as the mean over seeds. An absolute
rate in a variant is not the model's (the variants are not the model), only the dt effect within one is compared.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from network_rates import ORIGINAL_RATES_HZ, measure_rates  # noqa: E402

from jaxarm.network import NetworkConfig  # noqa: E402

INHIBITORY = {"IS", "ISL", "IM", "IML"}
EXCITATORY_RECURRENT = {"ES", "EM"}


def _zero_from(spec, pres):
    return dataclasses.replace(spec, pathways=tuple(dataclasses.replace(pw, weight_mv=0.0) if pw.pre in pres else pw
                                                    for pw in spec.pathways))


def _delays_on_grid(spec, grid_ms: float):
    def snap(pw):
        mid = 0.5 * (pw.delay_ms[0] + pw.delay_ms[1])
        d = max(grid_ms, round(mid / grid_ms) * grid_ms)
        return dataclasses.replace(pw, delay_ms=(d, d))
    return dataclasses.replace(spec, pathways=tuple(snap(pw) for pw in spec.pathways))


def _no_inhibitory_noise(spec):
    """Every population's GABA noise lanes (proximal, distal) at weight 0; the AMPA lane unchanged."""
    def strip(pop):
        if not pop.noise:
            return pop
        return dataclasses.replace(pop, noise=(pop.noise[0],) + tuple((0.0, hz) for _, hz in pop.noise[1:]))
    return dataclasses.replace(spec, populations=tuple(strip(p) for p in spec.populations))


def variants(coarse_dt_ms: float) -> dict[str, dict]:
    """NetworkConfig keyword arguments of each variant (``spec`` where the network itself changes)."""
    spec = NetworkConfig().spec
    isolated = _zero_from(spec, set(spec.names) | {"P"})
    return {
        "full": {},
        "isolated": {"spec": isolated},
        "isolated_no_inhibitory_noise": {"spec": _no_inhibitory_noise(isolated)},
        "no_inhibitory_noise": {"spec": _no_inhibitory_noise(spec)},
        "no_inhibition": {"spec": _zero_from(spec, INHIBITORY)},
        "no_excitatory_recurrence": {"spec": _zero_from(spec, EXCITATORY_RECURRENT)},
        "delays_on_grid": {"spec": _delays_on_grid(spec, coarse_dt_ms)},
        "no_nmda": {"spec": dataclasses.replace(spec, physics=dataclasses.replace(spec.physics, nmda_ampa_ratio=0.0))},
        "linear_summation": {"event_summation": "linear"},
        "crossing_per_event": {"crossing": "per_event"},
        "threshold_on_event": {"threshold_test": "on_event"},
        "random_order": {"same_step_inhibition": "random_order"},
        "random_order_delays_on_grid": {"same_step_inhibition": "random_order",
                                        "spec": _delays_on_grid(spec, coarse_dt_ms)},
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--networks", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--fine-dt", type=float, default=0.05, help="reference step, ms")
    ap.add_argument("--coarse-dt", type=float, default=0.5, help="step under test, ms")
    ap.add_argument("--seeds", default="0", help="comma-separated seeds, each a separate set of networks")
    ap.add_argument("--only", default=None, help="comma-separated variant names (default: all)")
    ap.add_argument("--json-out", default=None, help="write the result here")
    args = ap.parse_args(argv)
    table = variants(args.coarse_dt)
    names = args.only.split(",") if args.only else list(table)
    unknown = [n for n in names if n not in table]
    if unknown:
        ap.error(f"--only: unknown variant(s) {', '.join(unknown)}; known: {', '.join(table)}")
    t0 = time.perf_counter()
    out = {}
    seeds = [int(x) for x in args.seeds.split(",")]
    print(f"{args.networks} networks x {args.seconds:g} s, seeds {args.seeds}: rate at dt {args.coarse_dt} ms "
          f"relative to dt {args.fine_dt} ms (mean over seeds)")
    print(f"{'variant':26s} " + " ".join(f"{p:>7}" for p in ORIGINAL_RATES_HZ))
    for name in names:
        per_seed = {}
        for seed in seeds:
            runs = {dt: measure_rates(NetworkConfig(dt_ms=dt, **table[name]), args.networks, args.seconds, seed)
                    for dt in (args.fine_dt, args.coarse_dt)}
            fine, coarse = runs[args.fine_dt]["rates_hz"], runs[args.coarse_dt]["rates_hz"]
            counts = {dt: {p: r["spike_counts"][p] for p in fine} for dt, r in runs.items()}
            rel = {p: (coarse[p] / fine[p] - 1.0) if fine[p] > 0 else None for p in fine}
            # counting noise alone (Poisson counts): the relative difference's standard error
            se = {p: (1.0 / counts[args.fine_dt][p] + 1.0 / counts[args.coarse_dt][p]) ** 0.5
                  if counts[args.fine_dt][p] and counts[args.coarse_dt][p] else None for p in fine}
            per_seed[str(seed)] = {"fine_hz": fine, "coarse_hz": coarse, "relative_difference": rel,
                                   "poisson_se": se, "spike_counts": {str(dt): c for dt, c in counts.items()}}
        mean = {p: (sum(r["relative_difference"][p] for r in per_seed.values()) / len(per_seed)
                    if all(r["relative_difference"][p] is not None for r in per_seed.values()) else None)
                for p in ORIGINAL_RATES_HZ}
        out[name] = {"mean_relative_difference": mean,
                     "worst_mean": min((v for v in mean.values() if v is not None), default=None),
                     "by_seed": per_seed}
        print(f"{name:26s} " + " ".join(f"{100 * v:+6.1f}%" if v is not None else "    n/a" for v in mean.values()),
              flush=True)
    result = {
        "command": "python experiments/dt_ablation.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {len(os.sched_getaffinity(0))} CPUs",
        "networks": args.networks, "seconds": args.seconds, "seeds": seeds,
        "fine_dt_ms": args.fine_dt, "coarse_dt_ms": args.coarse_dt, "variants": out,
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
