"""Training and testing on the centre-out task (:class:`jaxarm.task.centre_out.CentreOut`) through the one runner
(:class:`jaxarm.run.Runner`: every device, groups, checkpoints after every epoch, kill -9 resume, several processes):
epoch e trains toward target e % n (the task's :meth:`~jaxarm.task.centre_out.CentreOut.epoch`), every network is
tested on every target; its results (:func:`summary`, :func:`write_outputs`), and the comparison with a control
network without the target code (:func:`run_with_control`).

    task = CentreOut()                                    # the eight targets, 3 epochs each, cycled
    net = NetworkConfig(spec=with_target_code(NetworkSpec.dura_bernal_2015()))
    fns = make_centre_out_train(LoopConfig(network=net, task=task.task_config()), task)
    trained, history = fns.train(key, mp)                 # epoch e trains toward target e % 8
    results = fns.test(key, trained, mp)                  # TestResult with a leading (8,) target axis
"""
from __future__ import annotations

import dataclasses
import json
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import parallel
from jaxarm.config.validate import ConfigError
from jaxarm.run import Runner, learning_curve, stack_rows
from jaxarm.task.centre_out import CentreOut, ensure_target_code
from jaxarm.task.config import Target
from jaxarm.train import fresh_noise, make_train


class CentreOutFns(NamedTuple):
    """``train(key, mp) -> (Trained, EpochSummary history)``; ``test(key, trained, mp) -> TestResult`` with a
    leading target axis; ``fns``: the underlying :class:`jaxarm.train.TrainFns`."""

    train: Callable
    test: Callable
    fns: object


def make_centre_out_train(config, task: CentreOut = CentreOut(), record=None) -> CentreOutFns:
    """Pure train and test functions of the centre-out task for one static ``config`` (a LoopConfig whose task is
    ``task.task_config()``; it is replaced by that if it differs): the task's epoch and test
    (:mod:`jaxarm.task.interface`) over :func:`jaxarm.train.make_train`'s, all epochs under one ``lax.scan``."""
    if config.task != task.task_config():
        config = replace(config, task=task.task_config())
    fns = make_train(config, record)
    targets = jax.tree.map(jnp.asarray, task.network_target())
    epoch, test_all = task.epoch(fns.epoch), task.test(fns.test)

    def train(key, mp):
        carry, history = jax.lax.scan(lambda c, _: epoch(c, mp, targets), fns.init(key), None,
                                      length=config.task.epochs)
        return carry.trained, history

    def test(key, trained, mp):
        return test_all(key, trained, mp, targets)

    return CentreOutFns(train=train, test=test, fns=fns)


def batch(config, task: CentreOut, seeds, mp, out, mesh=None) -> Runner:
    """The runner's batch of one network per seed (key ``PRNGKey(seed)``), each trained with ``mp`` on ``task``
    into ``out`` (checkpoints in ``out/checkpoints``)."""
    seeds = [int(s) for s in seeds]
    n = len(seeds)
    target = task.network_target()
    return Runner(config, seeds, stack_rows([mp] * n), Target(*(np.stack([np.asarray(x, np.float32)] * n)
                                                              for x in target)), out,
                 {"arm": config.arm, "backend": config.backend, "task": task.identity(), "seeds": seeds,
                  "metaparams": mp.to_dict(), "label": f"{config.arm}/centre-out"}, mesh, task=task)


def _per_network(x) -> np.ndarray:
    """A history field (epochs, networks, ...) as (networks, epochs, ...), C-contiguous: the layout the means over
    networks were always taken in (so they round as they always did)."""
    return np.ascontiguousarray(np.swapaxes(np.asarray(x), 0, 1))


def _approach(task: CentreOut, result) -> dict:
    """Where each test's hand went, per target (medians over networks): how far from the start it was at its closest
    approach to the target (``median_travel_cm``) and the angle between that displacement and the target's
    direction (``median_direction_error_deg``, 0 = straight at it): a hand that moves little and one that moves the
    wrong way miss a target for different reasons."""
    hand = np.asarray(result.hand_m, np.float64)                              # (networks, targets, samples, 2)
    start = np.asarray(task.task_config().start_xy_m, np.float64)
    goal = np.asarray(task.stacked_targets().xy_m, np.float64) - start       # (targets, 2)
    closest = np.argmin(np.asarray(result.distance_m), axis=-1)              # (networks, targets)
    moved = np.take_along_axis(hand, closest[..., None, None], axis=2)[:, :, 0] - start   # (networks, targets, 2)
    travel = np.linalg.norm(moved, axis=-1)
    angle = np.degrees(np.abs(np.arctan2(moved[..., 1] * goal[:, 0] - moved[..., 0] * goal[:, 1],
                                         moved[..., 0] * goal[:, 0] + moved[..., 1] * goal[:, 1])))
    return {"median_travel_cm": {t: round(100 * float(np.median(travel[:, k])), 2) for k, t in enumerate(task.targets)},
            "median_direction_error_deg": {t: round(float(np.median(angle[:, k])), 1)
                                           for k, t in enumerate(task.targets)}}


def summary(task: CentreOut, spec, seeds, history, res, naive, held_out=None) -> dict:
    """The task's results from host arrays (``history`` (epochs, networks, ...) as :meth:`jaxarm.run.Runner.train`
    returns it; ``res``, ``naive``: TestResults (networks, targets, ...)): success per (network, target), counts per
    target (trained and naive), the distribution and median of targets reached per network, median closest approach
    per target (cm), hand paths (m) under ``trained["hand_m"]`` and ``naive["hand_m"]``; with ``held_out`` (the
    trained networks tested on noise streams no training used), the same under ``held_out``."""
    n_t = len(task.targets)
    hist = {"rates_last10s_hz": {p: _per_network(history.rates_last10s_hz)[:, :, j].mean(axis=0).round(3).tolist()
                                 for j, p in enumerate(spec.network_populations)},
            "mean_wgain": {pw.name: _per_network(history.mean_wgain)[:, :, j].mean(axis=0).round(4).tolist()
                           for j, pw in enumerate(spec.pathways) if pw.plastic},
            "rewards": _per_network(history.rewards).mean(axis=0).round(1).tolist(),
            "punishments": _per_network(history.punishments).mean(axis=0).round(1).tolist(),
            "min_distance_cm": (100 * _per_network(history.min_distance_m).mean(axis=0)).round(2).tolist()}
    out = {"targets": list(task.targets), "directions_deg": [round(d, 1) for d in task.directions_deg()],
           "seeds": [int(s) for s in seeds], "history_mean_over_networks_by_epoch": hist,
           "test_rates_hz": {p: np.asarray(res.rates_hz)[..., j].mean().round(3).item()
                             for j, p in enumerate(spec.network_populations)},
           "naive_test_rates_hz": {p: np.asarray(naive.rates_hz)[..., j].mean().round(3).item()
                                   for j, p in enumerate(spec.network_populations)},
           "lost_spikes": int(np.asarray(history.lost_spikes).sum() + np.asarray(res.lost_spikes).sum())}
    tests = (("trained", res), ("naive", naive)) + ((("held_out", held_out),) if held_out is not None else ())
    for name, r in tests:
        ok = np.asarray(r.success)                                                # (networks, targets)
        out[name] = {"success": ok.astype(int).tolist(),
                     "per_target": {t: int(ok[:, k].sum()) for k, t in enumerate(task.targets)},
                     "targets_reached_per_network": np.bincount(ok.sum(axis=1), minlength=n_t + 1).tolist(),
                     "median_targets_reached": float(np.median(ok.sum(axis=1))),
                     "median_min_distance_cm": {t: round(100 * float(np.median(np.asarray(r.min_distance_m)[:, k])), 2)
                                                for k, t in enumerate(task.targets)},
                     **_approach(task, r),
                     "hand_m": np.asarray(r.hand_m)}
    return out


def train_and_test(config, task: CentreOut, seeds, mp, out=None, progress: bool = False) -> dict:
    """Train one network per seed (key ``PRNGKey(seed)``) in one batch of the runner, test each, and each untrained
    network, on every target; returns :func:`summary`. ``out``: the batch's folder (its checkpoints: a rerun resumes;
    default a temporary folder, one process only)."""
    with tempfile.TemporaryDirectory() as tmp:
        b = batch(config, task, seeds, mp, Path(tmp) if out is None else out)
        carry, history, *_ = b.train(progress=progress)
        return summary(task, b.config.network.spec, b.seeds, history, b.test(carry.trained),
                       b.test(b.naive(), "naive test"), b.test(fresh_noise(carry.trained, 0), "held-out test"))


def _learning_curve(curve: dict, naive_success, epoch_s: float) -> dict:
    """:func:`jaxarm.run.learning_curve` of tests after every epoch (``--test-each-epoch``) on every target: each
    (network, target) test counted as reaching's one test per network, so ``success_count`` (per epoch) counts the
    tests that reached of networks x targets, and ``criterion_s`` is (networks, targets): the training time after
    which that network's test on that target first succeeded."""
    n, k = np.shape(naive_success)
    flat = {e: {name: np.asarray(v).reshape(-1).tolist() for name, v in c.items()} for e, c in curve.items()}
    out = learning_curve(flat, np.asarray(naive_success).reshape(-1), epoch_s)
    for name in [m for m in out if m.endswith("criterion_s")]:
        out[name] = [out[name][i * k:(i + 1) * k] for i in range(n)]
    return out


def write_outputs(run: Runner, trained_res, naive_res, history, wall_s, epochs_run, compile_s=None) -> dict:
    """``jaxarm train --task centre-out-8``'s results.json (:func:`summary`, the configuration, the timing) and
    trajectories.npz (hand paths (networks, targets, samples, 2), trained and naive; the targets; the seeds), written
    by process 0; every process returns the results. ``run``: a :class:`~jaxarm.run.Runner` of a CentreOut task."""
    task = run.task
    r = summary(task, run.config.network.spec, run.seeds, history, trained_res, naive_res)
    hands = {k: r[k].pop("hand_m") for k in ("trained", "naive")}
    results = {"task": "centre-out-8", **r, "n_networks": run.n,
               "network_seconds": run.n * task.task_config().epochs * task.epoch_duration_s,
               "timing": {"train_wall_s_this_invocation": round(wall_s, 2), "epochs_run_this_invocation": epochs_run,
                          "compile_s": None if compile_s is None else round(compile_s, 2),
                          "device": jax.default_backend(), "layout": parallel.describe()},
               "config": run.config_record()}
    if run.learning_curve:
        results["learning_curve"] = _learning_curve(run.learning_curve, naive_res.success, task.epoch_duration_s)
    if run.record is not None:   # a window per target: test_right, ..., naive_test_right, ...
        from jaxarm.recordfile import write_run_records

        results["record"] = write_run_records(run, trained_res, naive_res)
    if parallel.is_main_process():
        run.out.mkdir(parents=True, exist_ok=True)
        (run.out / "results.json").write_text(json.dumps(results, indent=1))
        np.savez_compressed(run.out / "trajectories.npz", hand=hands["trained"], naive_hand=hands["naive"],
                            target=np.asarray(task.stacked_targets().xy_m), seeds=np.asarray(run.seeds))
    return results


def said(run: Runner, res: dict) -> str:
    """The line ``jaxarm train`` and ``jaxarm test`` print for a centre-out run's results (:func:`write_outputs`)."""
    return (f"{run.config.arm} arm, {len(res['targets'])} centre-out targets, {run.n} networks: "
            + ", ".join(f"{t} {n}/{run.n}" for t, n in res["trained"]["per_target"].items())
            + f" (naive: {sum(res['naive']['per_target'].values())} reaches in all); networks by targets reached "
            f"(0..{len(res['targets'])}): {res['trained']['targets_reached_per_network']} -> "
            f"{run.out / 'results.json'}")


#: The two conditions of the centre-out comparison: the network with a target code, and without (the control)
CONDITIONS = ("target-code", "control")


def run_with_control(config, task: CentreOut, seeds, mp, out, *, conditions=CONDITIONS, code: dict | None = None,
                     plastic=None, meta: dict | None = None, log=print, progress: bool = False) -> dict:
    """Train and test one network per seed on every target of ``task`` under each condition: ``target-code``
    (``config``'s network with ``with_target_code(spec, task, **code)`` unless it has one) and ``control`` (the
    network without any target code and its pathways; when ``config``'s only plastic pathways were the code's,
    nothing in the control learns and its trained networks are its naive ones). ``plastic``: names of the only
    plastic pathways of the target-code network (e.g. ``("T->EM",)``; default: as built). Results go to
    ``out/centre_out.json`` after each condition; a rerun with the same description skips the conditions already
    there, and a condition killed mid-training resumes from its checkpoints (``out/CONDITION/checkpoints``).
    ``progress``: the runner's progress bar. Returns that file's content."""
    import time

    out = Path(out)
    base = config.network.spec
    for name in base.target_codes:        # the control: the network without its target code(s) and their pathways
        base = base.without_population(name)
    coded = ensure_target_code(config.network.spec, task, **(code or {}))
    if plastic is not None:
        coded = coded.with_plastic(plastic)
    specs = {"target-code": coded, "control": base}
    unknown = [c for c in conditions if c not in specs]
    if unknown:
        raise ConfigError(f"conditions: {unknown[0]!r} is not one of {', '.join(CONDITIONS)}")
    description = {"arm": config.arm, "task": dataclasses.asdict(task), "seeds": [int(s) for s in seeds],
                   "metaparams": mp.to_dict(), "code": code or {}, "plastic": None if plastic is None else
                   sorted(plastic), "dt_ms": config.network.dt_ms}
    path = out / "centre_out.json"
    done = json.loads(path.read_text()) if path.exists() else {}
    if done.get("description") != json.loads(json.dumps(description)):
        done = {}
    result = {**(meta or {}), "description": description, "conditions": done.get("conditions", {})}
    main = parallel.is_main_process()        # with several processes (--coordinator) process 0 writes and says
    log = log if main else (lambda *a, **k: None)
    parallel.barrier("centre-out-read")      # every process has read the file before process 0 writes it
    out.mkdir(parents=True, exist_ok=True)
    for name in conditions:
        if name in result["conditions"]:
            log(f"{name}: already in {path}")
            continue
        t0 = time.perf_counter()
        cfg = dataclasses.replace(config, network=dataclasses.replace(config.network, spec=specs[name]))
        r = train_and_test(cfg, task, seeds, mp, out / name, progress=progress)
        for k in ("trained", "naive", "held_out"):
            r[k].pop("hand_m")
        r.update(condition=name, populations=list(specs[name].names),
                 network_seconds=len(r["seeds"]) * task.task_config().epochs * task.epoch_duration_s,
                 wall_s=round(time.perf_counter() - t0, 1))
        result["conditions"][name] = r
        if main:
            path.write_text(json.dumps(result, indent=1))
        log(f"{name}: trained and tested in {r['wall_s']} s ({r['network_seconds']:g} network-s); lost spikes "
            f"{r['lost_spikes']}")
    return result


def table_markdown(result: dict) -> str:
    """The per-target table of :func:`run_with_control`'s result: per condition, the trained networks' counts on
    held-out noise (when measured), on their training noise and the naive networks'; the first condition's median
    closest approach per target; then the networks by number of targets reached, and the median number per
    network."""
    conds = list(result["conditions"].values())
    n = len(conds[0]["seeds"])
    header, columns = [], []
    for c in conds:
        if "held_out" in c:
            header.append(f"{c['condition']}: held-out noise")
            columns.append((c, "held_out"))
        header.append(f"{c['condition']}: trained (naive)")
        columns.append((c, "trained"))
    header.append(f"{conds[0]['condition']}: median closest approach, cm, trained (naive)")
    header.append(f"{conds[0]['condition']}: median travel, cm, and direction error, deg, at the closest approach, "
                  "trained")
    lines = ["| target (direction) | " + " | ".join(header) + " |", "|---|" + "---|" * len(header)]
    first = conds[0]
    for k, t in enumerate(first["targets"]):
        cells = [f"{c[what]['per_target'][t]}/{n}" + (f" ({c['naive']['per_target'][t]}/{n})" if what == "trained"
                                                      else "") for c, what in columns]
        cells.append(f"{first['trained']['median_min_distance_cm'][t]:.1f} "
                     f"({first['naive']['median_min_distance_cm'][t]:.1f})")
        cells.append(f"{first['trained']['median_travel_cm'][t]:.1f}, "
                     f"{first['trained']['median_direction_error_deg'][t]:.0f}"
                     if "median_travel_cm" in first["trained"] else "")
        lines.append(f"| {t} ({first['directions_deg'][k]:g} deg) | " + " | ".join(cells) + " |")
    for c, what in columns:
        r = c[what]
        median = r.get("median_targets_reached")
        lines.append(f"\n{c['condition']}, {what.replace('_', '-')}: networks by number of targets reached "
                     f"(0..{len(c['targets'])}): {r['targets_reached_per_network']}"
                     + (f" (naive {c['naive']['targets_reached_per_network']})" if what == "trained" else "")
                     + ("" if median is None else f"; median {median:g} of {len(c['targets'])} per network"))
    return "\n".join(lines)
