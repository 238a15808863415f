"""The spike record's files: ``spikes.npz`` (every recorded window's spikes, decoded, with the arm) and
``muscles.npz`` (the musculoskeletal arm's muscles in the tests), written after a recording run and read back
(:class:`SpikeFile`). The jittable buffer they are decoded from is :mod:`jaxarm.record`."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from jaxarm.record import BYTES_PER_SLOT, RecordConfig, decode
from jaxarm.runfolder import read_npz

SPIKES_FILE = "spikes.npz"
MUSCLES_FILE = "muscles.npz"


def earlier_windows(path: Path, now, *, seeds, networks) -> dict[str, dict[str, np.ndarray]]:
    """The training-epoch windows of an existing ``spikes.npz`` of the same networks that are not in ``now`` (names),
    as name -> {key: array}: a run resumed or rerun after a recorded epoch cannot record that epoch again, and
    rewriting the file must not drop it. Empty when there is no such file or it holds other networks."""
    path = Path(path)
    if not path.is_file():
        return {}
    f = SpikeFile(path)
    if (f.data["networks"].tolist() != list(networks)
            or f.seeds.tolist() != np.asarray(seeds)[list(networks)].tolist()):
        return {}
    return {w: {k[len(w) + 1:]: v for k, v in f.data.items() if k.startswith(w + ".")}
            for w in f.windows if w.startswith("epoch_") and w not in now}


def save_spikes(path: Path, windows: dict[str, dict], *, seeds, networks, dt_ms: float, interval_ms: float,
                populations, pop_start, pop_stop, group, capacity: dict[str, int], config: RecordConfig,
                arm: str, earlier: dict[str, dict[str, np.ndarray]] | None = None, target_group=None) -> Path:
    """Write ``spikes.npz``. ``windows``: name -> {"recording": a host Recording batch (networks first),
    "start_step": int, "stop_step": int}; only the networks ``networks`` (indices) are written. ``earlier``
    (:func:`earlier_windows`): windows of an earlier write kept as they were, after these.

    Keys: ``windows`` (names), ``seeds``, ``networks``, ``dt_ms``, ``interval_ms``, ``n_all``, ``populations``,
    ``pop_start``/``pop_stop`` (global id ranges), ``group`` (n_all,: the muscle group, 0..3 in
    :data:`jaxarm.arm.GROUPS` order, an EM cell drives or a P cell senses; -1 for the other cells), with a target
    code (``target_group`` given) ``target_group`` (n_all,: a target-code cell's direction group; -1 elsewhere), ``max_rate_hz``,
    ``arm``; per window W: ``W.step`` (int32 clock
    steps since the run's start), ``W.cell`` (int16 global ids), ``W.offsets`` (network r's spikes are
    offsets[r]:offsets[r+1]), ``W.t_start_ms``/``W.t_stop_ms``, ``W.counts`` (networks, n_all: the network's own
    spike count per cell over the window), ``W.capacity``, ``W.t_ms`` (the arm samples' times), ``W.q_rad``,
    ``W.hand_m``, ``W.u``.
    """
    n_all = int(pop_stop[-1])
    steps_per_interval = round(interval_ms / dt_ms)
    earlier = earlier or {}
    out: dict[str, Any] = {"windows": np.asarray(list(windows) + list(earlier)),
                           "seeds": np.asarray(seeds)[list(networks)],
                           "networks": np.asarray(networks, np.int32), "dt_ms": np.float64(dt_ms),
                           "interval_ms": np.float64(interval_ms), "n_all": np.int32(n_all),
                           "populations": np.asarray(populations), "pop_start": np.asarray(pop_start, np.int32),
                           "pop_stop": np.asarray(pop_stop, np.int32), "group": np.asarray(group, np.int8),
                           "max_rate_hz": np.float64(config.max_rate_hz),
                           "bytes_per_slot": np.int32(BYTES_PER_SLOT), "arm": np.asarray(arm)}
    if target_group is not None:
        out["target_group"] = np.asarray(target_group, np.int8)
    for name, w in windows.items():
        rec, start = w["recording"], int(w["start_step"])
        steps, cells, offsets = [], [], [0]
        for k in networks:
            s, c = decode(rec.spikes.word[k], rec.spikes.bits[k], rec.spikes.used[k], n_all, start,
                          steps_per_interval)
            steps.append(s)
            cells.append(c)
            offsets.append(offsets[-1] + len(s))
        rows = len(np.asarray(rec.q_rad)[0])
        out |= {f"{name}.step": np.concatenate(steps) if steps else np.zeros(0, np.int32),
                f"{name}.cell": np.concatenate(cells) if cells else np.zeros(0, np.int16),
                f"{name}.offsets": np.asarray(offsets, np.int64),
                f"{name}.t_start_ms": np.float64(start * dt_ms),
                f"{name}.t_stop_ms": np.float64(w["stop_step"] * dt_ms),
                f"{name}.counts": np.asarray(rec.counts)[list(networks)].astype(np.int32),
                f"{name}.capacity": np.int64(capacity[name]),
                f"{name}.t_ms": start * dt_ms + interval_ms * np.arange(1, rows + 1),
                f"{name}.q_rad": np.asarray(rec.q_rad)[list(networks)],
                f"{name}.hand_m": np.asarray(rec.hand_m)[list(networks)],
                f"{name}.u": np.asarray(rec.u)[list(networks)]}
    out |= {f"{name}.{key}": value for name, arrays in earlier.items() for key, value in arrays.items()}
    path = Path(path)
    np.savez_compressed(path, **out)
    return path


def save_muscles(path: Path, recordings: dict[str, Any], *, seeds, networks, muscle_names, groups,
                 interval_ms: float) -> Path | None:
    """Write ``muscles.npz`` (musculoskeletal arm): per window W (e.g. test, naive_test) ``W.activation``,
    ``W.force_n``, ``W.active_force_n``, ``W.passive_force_n``, ``W.fiber_length_m``, ``W.mtu_length_m``, each
    (networks, intervals, 22), at ``W.t_ms``; ``muscle_names``, ``group`` (the excitation group driving each muscle,
    -1 passive), ``seeds``, ``networks``. Returns None when no window has muscles (the simple arm)."""
    out: dict[str, Any] = {}
    for name, rec in recordings.items():
        if rec.muscles is None:
            continue
        m = rec.muscles
        rows = np.asarray(m.activation).shape[1]
        out[f"{name}.t_ms"] = interval_ms * np.arange(1, rows + 1)
        for field in m._fields:
            out[f"{name}.{field}"] = np.asarray(getattr(m, field))[list(networks)]
    if not out:
        return None
    out |= {"windows": np.asarray([n for n, r in recordings.items() if r.muscles is not None]),
            "muscle_names": np.asarray(muscle_names), "group": np.asarray(groups, np.int32),
            "seeds": np.asarray(seeds)[list(networks)], "networks": np.asarray(networks, np.int32)}
    path = Path(path)
    np.savez_compressed(path, **out)
    return path


class SpikeFile:
    """A ``spikes.npz`` read back: ``spikes(window, r)`` gives network r's (t_ms, cell) arrays."""

    def __init__(self, path: Path):
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path}: no spike record there; make one with `jaxarm test --from RUN "
                                    "--record-spikes` (or `jaxarm train ... --record-spikes`)")
        self.data = read_npz(self.path, ("windows", "seeds", "dt_ms", "populations", "pop_start", "pop_stop",
                                         "n_all", "group", "arm", "networks"))
        self.windows = [str(w) for w in self.data["windows"]]
        self.seeds = self.data["seeds"]
        self.dt_ms = float(self.data["dt_ms"])
        self.populations = [str(p) for p in self.data["populations"]]
        self.pop_start = dict(zip(self.populations, self.data["pop_start"].tolist()))
        self.pop_stop = dict(zip(self.populations, self.data["pop_stop"].tolist()))
        self.n_all = int(self.data["n_all"])
        self.group = self.data["group"].astype(np.int64)
        #: a target-code cell's direction group, -1 elsewhere (None: a file of a network without a target code)
        self.target_group = self.data["target_group"].astype(np.int64) if "target_group" in self.data else None
        self.arm = str(self.data["arm"])

    def __len__(self):
        return len(self.seeds)

    def window(self, name: str) -> str:
        if name not in self.windows:
            raise KeyError(f"{self.path}: no window {name!r}; it holds {', '.join(self.windows)}")
        return name

    def spikes(self, window: str, r: int) -> tuple[np.ndarray, np.ndarray]:
        """(t_ms float64, cell int) of recorded network r (0-based row of this file) in ``window``."""
        w = self.window(window)
        a, b = self.data[f"{w}.offsets"][r: r + 2]
        return self.data[f"{w}.step"][a:b] * self.dt_ms, self.data[f"{w}.cell"][a:b].astype(np.int64)

    def get(self, window: str, key: str) -> np.ndarray:
        return self.data[f"{self.window(window)}.{key}"]

    def span_ms(self, window: str) -> tuple[float, float]:
        return float(self.get(window, "t_start_ms")), float(self.get(window, "t_stop_ms"))

    def row_of(self, network: int) -> int:
        """This file's row of the run's network index ``network`` (``--network``)."""
        nets = self.data["networks"].tolist()
        if network not in nets:
            raise KeyError(f"{self.path}: network {network} was not recorded (recorded: {nets})")
        return nets.index(network)


def write_run_records(run, trained_res, naive_res) -> dict:
    """``spikes.npz`` (the tests' and recorded epochs' spikes) and, for the musculoskeletal arm, ``muscles.npz``
    (the tests' muscles) of a recording run (a :class:`jaxarm.run.Runner`) and its trained and naive test results:
    windows ``test`` and ``naive_test``, or one per target of a task of several
    (:meth:`~jaxarm.run.Runner.test_recordings`). Returns what results.json says about the files."""
    from jaxarm.network.populations import Populations

    tests = run.test_recordings(trained_res) | run.test_recordings(naive_res, "naive_test")
    net, task = run.config.network, run.config.task
    steps = net.steps_per_interface
    windows = {name: {"recording": rec, "start_step": 0, "stop_step": task.test_steps * steps}
               for name, rec in tests.items() if rec is not None}
    for e, rec in sorted(run.epoch_records.items()):
        n_rec = round(run.record.train_last_s / task.update_interval_s)
        windows[f"epoch_{e}"] = {"recording": rec, "start_step": (task.epoch_steps - n_rec) * steps,
                                 "stop_step": task.epoch_steps * steps}
    pops = Populations(net)
    group = np.full(net.n_all, -1, np.int8)
    group[pops.slice(net.spec.readout)] = pops.em_groups()
    group[pops.slice(net.spec.proprio)] = pops.p_groups()
    target_group = None
    if net.spec.target_codes:
        target_group = np.full(net.n_all, -1, np.int8)
        for name in net.spec.target_codes:
            target_group[pops.slice(name)] = pops.target_groups(name)
    networks = run.recorded_networks()
    earlier = earlier_windows(run.out / SPIKES_FILE, windows, seeds=run.seeds, networks=networks)
    save_spikes(run.out / SPIKES_FILE, windows, seeds=run.seeds, networks=networks, dt_ms=net.dt_ms,
                interval_ms=net.interface_ms, populations=net.populations,
                pop_start=[pops.start[p] for p in net.populations], pop_stop=[pops.stop[p] for p in net.populations],
                group=group, capacity=run.record_capacity, config=run.record, arm=run.config.arm, earlier=earlier,
                target_group=target_group)
    files = [SPIKES_FILE]
    if run.config.arm == "musculoskeletal":
        from jaxarm.arm.musculoskeletal import GROUP_MUSCLES

        arm = run.fns.loop.arm
        groups = [next((g for g, names in enumerate(GROUP_MUSCLES) if m in names), -1) for m in arm.muscle_names]
        if save_muscles(run.out / MUSCLES_FILE, {n: w["recording"] for n, w in windows.items() if n in tests},
                        seeds=run.seeds, networks=networks, muscle_names=arm.muscle_names, groups=groups,
                        interval_ms=net.interface_ms):
            files.append(MUSCLES_FILE)
    spikes = {name: [int(c) for c in np.asarray(w["recording"].spikes.count)[networks]]
              for name, w in windows.items()}
    spikes |= {name: [int(c) for c in w["counts"].sum(axis=1)] for name, w in earlier.items()}
    capacity = run.record_capacity | {name: int(w["capacity"]) for name, w in earlier.items()}
    return {"files": files, "windows": list(windows) + list(earlier), "networks": networks,
            "capacity_spikes": capacity, "max_rate_hz": run.record.max_rate_hz,
            "memory_bound": run.record_memory, "spikes": spikes}
