"""A batch of networks trained together over every device, checkpointed after every epoch: the one runner of every
task (:mod:`jaxarm.task.interface`: reaching, centre-out).

Network i of a batch has the key ``PRNGKey(seeds[i])`` (its wiring, noise and babbling), metaparameter set ``mps[i]``
and target data ``targets[i]`` (the task's :meth:`~jaxarm.task.interface.TaskInterface.network_target`: reaching's
target, centre-out's schedule of targets); nothing else about the batch changes its results, so any network can be
reproduced alone, in any batch, on any number of devices or processes (:mod:`jaxarm.parallel`). The batch's leading
axis is split over the device mesh; one compiled ``epoch`` runs all of it, and an orbax checkpoint follows every epoch,
so a killed run started again with the same command resumes from its last completed epoch and ends with the same bits.

* :class:`Run`: one metaparameter set, one task (by default one target), networks ``seed .. seed + n - 1``
  (``jaxarm train``, ``--task`` reaching or centre-out-8).
* :class:`SetsRun`: network i trains with set i (the paper's statistic: its top 30 sets, one network each).
* :class:`Runner` (formerly ``Batch``, still a name of it): any list of (seed, set, target) rows and any task, e.g.
  every network of a reproduction in one program; :class:`Run` and :class:`SetsRun` are runners of given rows.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import sys
import time
from pathlib import Path
from typing import Callable, NamedTuple

import jax
import numpy as np

from jaxarm import parallel, runfolder
from jaxarm.config.network import RUNTIME_FIELDS, SPEC_KEYS
from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import NAMES, MetaParams, as_current
from jaxarm.learning.registry import learning_meta
from jaxarm.loop import LoopConfig
from jaxarm.network import Network, NetworkConfig
from jaxarm.task.config import Target, TaskConfig
from jaxarm.task.interface import TaskInterface
from jaxarm.train import EpochSummary, TestResult, Trained, fresh_noise, make_train

#: NetworkConfig fields the commands set from their options; recorded in a run's meta when not the default.
NETWORK_OPTIONS = ("dt_ms", "threshold_test", "crossing", "same_step_inhibition", "readout_clip")


@functools.lru_cache(maxsize=16)
def compiled(config: LoopConfig, mesh, record=None, at_once: int = 0, task: TaskInterface | None = None) -> tuple:
    """``make_train(config, record)`` and its init / epoch / test / epoch_recorded (None unless recording epochs),
    the epochs and the test the ``task``'s (default ``config.task``, reaching: the functions themselves; centre-out:
    the epoch toward the epoch's target of the schedule, the test on every target), mapped over networks (keys,
    metaparameters and target data all per network; ``at_once`` networks of a device together,
    :func:`jaxarm.parallel.map_networks`) and sharded over ``mesh``; shared by every batch of the same
    configuration."""
    fns = make_train(config, record)
    task = config.task if task is None else task
    b = parallel.BATCHED
    each = lambda fn: parallel.map_networks(fn, at_once)   # noqa: E731
    init = parallel.shard(each(fns.init), b, b, mesh)
    epoch = parallel.shard(each(task.epoch(fns.epoch)), (b, b, b), b, mesh)
    test = parallel.shard(each(task.test(fns.test)), (b, b, b, b), b, mesh)
    epoch_recorded = (None if fns.epoch_recorded is None else
                      parallel.shard(each(task.epoch(fns.epoch_recorded)), (b, b, b), b, mesh))
    return fns, init, epoch, test, epoch_recorded


def network_keys(seeds) -> np.ndarray:
    """(n, 2) uint32 keys ``PRNGKey(seed)`` of the given seeds."""
    return np.stack([np.asarray(jax.random.PRNGKey(int(s))) for s in seeds])


def stack_rows(rows: list[MetaParams]) -> MetaParams:
    """One MetaParams whose every field is the rows' values stacked (float32, leading axis = len(rows))."""
    return MetaParams(**{n: np.stack([np.asarray(getattr(m, n), np.float32) for m in rows]) for n in NAMES})


def unstack(mps: MetaParams) -> list[MetaParams]:
    """The sets of a stacked MetaParams (leading axis), in order."""
    n = int(np.shape(mps.learn_rate)[0])
    return [MetaParams(**{k: np.asarray(getattr(mps, k))[i] for k in NAMES}) for i in range(n)]


def network_config(source, default: NetworkConfig | None = None) -> NetworkConfig:
    """The NetworkConfig of a run: ``source`` is a run's meta dict (every NetworkConfig field it records) or a
    command's parsed options (``--network FILE``, then ``--network-scale F``, then the :data:`NETWORK_OPTIONS`); an
    option that is absent or None keeps the default: ``default`` (a preset's network) or NetworkConfig's."""
    if isinstance(source, dict):
        fields = ({f.name for f in dataclasses.fields(NetworkConfig)} | {"sizes", *SPEC_KEYS}) - set(RUNTIME_FIELDS)
        return NetworkConfig.from_dict({k: v for k, v in source.items() if k in fields and v is not None})
    if getattr(source, "network", None):
        base = NetworkConfig.load(source.network)
    else:
        base = default or NetworkConfig()
    scale = getattr(source, "network_scale", None)
    if scale is not None:
        try:
            base = base.scaled(scale)
        except ConfigError:
            raise ConfigError(f"--network-scale {scale}: must be an integer in [1, 100]") from None
    options = {k: getattr(source, k, None) for k in NETWORK_OPTIONS}
    return dataclasses.replace(base, **{k: v for k, v in options.items() if v is not None})


def add_network_arguments(ap, note: str = "") -> None:
    """``--network FILE`` and ``--network-scale F`` (read by :func:`network_config`); ``note`` ends the first's
    help."""
    ap.add_argument("--network", type=Path, default=None, metavar="FILE",
                    help="the network as data: a TOML or JSON file of NetworkConfig fields (sizes, pmat_scale, "
                         "p_positions, ...) and of a NetworkSpec (populations, pathways, cell_types, physics: a "
                         "whole network; NetworkSpec.save writes the paper's); what it does not give keeps its "
                         "default" + note)
    ap.add_argument("--network-scale", type=int, default=None, metavar="F",
                    help="every population F times larger by the original's scaling rules (NetworkConfig.scaled: "
                         "in-degrees, P code and readout drive kept; docs/model.md)")


def _short(value, width: int = 60) -> str:
    text = "(absent)" if value is _ABSENT else json.dumps(value, default=str)
    return text if len(text) <= width else text[: width - 3] + "..."


_ABSENT = object()


def differences(saved, now, prefix: str = "") -> list[tuple[str, object, object]]:
    """(dotted field, saved value, value now) of every field that differs between two run descriptions, nested
    dicts (metaparams, a network's sizes) field by field, lists element by element when their lengths agree."""
    if isinstance(saved, dict) and isinstance(now, dict):
        out = []
        for k in list(saved) + [k for k in now if k not in saved]:
            out += differences(saved.get(k, _ABSENT), now.get(k, _ABSENT), f"{prefix}{k}.")
        return out
    if isinstance(saved, list) and isinstance(now, list) and len(saved) == len(now):
        return [d for i, (a, b) in enumerate(zip(saved, now)) for d in differences(a, b, f"{prefix}{i}.")]
    return [] if saved == now else [(prefix.rstrip("."), saved, now)]


def describe_differences(saved: dict, now: dict, most: int = 4) -> str:
    """One line naming the fields that differ: ``epochs saved 6, now 3; metaparams.learn_rate saved 0.1, now 0.2``
    (the first ``most`` of them, then how many more)."""
    diff = differences(saved, now)
    text = "; ".join(f"{k or 'the description'} saved {_short(a)}, now {_short(b)}" for k, a, b in diff[:most])
    return text + (f"; and {len(diff) - most} more field(s)" if len(diff) > most else "")


def curve_entry(result: TestResult, held_out: TestResult | None = None) -> dict:
    """What :meth:`Runner.train` keeps of the tests after an epoch by default: per network, success and closest
    approach (m) on the network's own noise stream (the one R-STDP trains on, as the original tests) and, with
    ``held_out``, the same on a stream no rule trains on (:func:`jaxarm.train.fresh_noise` with ``j = 0``)."""
    entry = {"success": np.asarray(result.success).tolist(),
             "min_distance_m": np.asarray(result.min_distance_m).round(5).tolist()}
    if held_out is not None:
        entry |= {"fresh_noise_success": np.asarray(held_out.success).tolist(),
                  "fresh_noise_min_distance_m": np.asarray(held_out.min_distance_m).round(5).tolist()}
    return entry


def learning_curve(curve: dict, naive_success, epoch_s: float) -> dict:
    """results.json's ``learning_curve`` from per-epoch tests (``Runner.learning_curve``: 1-based epoch ->
    {"success", "min_distance_m"} per network, and "fresh_noise_success", "fresh_noise_min_distance_m" where the
    epochs were also tested on held-out noise) and the naive test's successes (epoch 0).

    ``criterion_s`` per network: the training time (network-seconds) after which its test first succeeded: 0 if the
    naive network already reaches, None if no tested epoch reached or if an epoch before the first success was not
    tested (a run resumed with ``--test-each-epoch`` after training without it). ``fresh_noise_*``: the same on
    held-out noise, where every tested epoch has it."""
    epochs = sorted(curve)
    complete = epochs == list(range(1, len(epochs) + 1))

    def curve_of(prefix: str) -> dict:
        success = np.asarray([curve[e][prefix + "success"] for e in epochs], bool)      # (epochs, networks)
        closest = np.asarray([curve[e][prefix + "min_distance_m"] for e in epochs], float)
        criterion = []
        for i, naive in enumerate(np.asarray(naive_success, bool)):
            hits = np.nonzero(success[:, i])[0]
            # sorted epochs from 1: epochs[j] == j + 1 means every epoch up to the first success was tested
            first = 0 if naive else (epochs[hits[0]] if hits.size and epochs[hits[0]] == hits[0] + 1 else None)
            criterion.append(None if first is None else round(first * epoch_s, 3))
        return {prefix + "success_count": success.sum(axis=1).tolist(),
                prefix + "median_min_distance_m": np.median(closest, axis=1).round(5).tolist(),
                prefix + "criterion_s": criterion}

    out = {"epochs": epochs, "epoch_s": epoch_s, "complete": complete} | curve_of("")
    if all("fresh_noise_success" in curve[e] for e in epochs):
        out |= curve_of("fresh_noise_")
    return out


class Runner:
    """The one runner of every task: networks ``seeds[i]`` with metaparameters ``mps[i]`` (stacked) and target data
    ``targets[i]`` (stacked: each network's ``task.network_target()``, or another target of the same shape), trained
    with one configuration into ``out`` (checkpoints in ``out/checkpoints``). ``description``: the JSON identity of
    the batch (what a checkpoint must match to be resumed). ``mesh``: the devices (default: all of them). ``task``:
    what the epochs train toward and what the test tests (:mod:`jaxarm.task.interface`; default ``config.task``,
    reaching); ``config.task`` is taken as ``task.task_config()``."""

    def __init__(self, config: LoopConfig, seeds, mps: MetaParams, targets: Target, out: Path, description: dict,
                 mesh=None, record=None, task: TaskInterface | None = None):
        if task is not None and config.task != task.task_config():
            config = dataclasses.replace(config, task=task.task_config())
        self.task = config.task if task is None else task
        self.config, self.out = config, Path(out)
        self.seeds = [int(s) for s in seeds]
        self.n = len(self.seeds)
        if self.n < 1:
            raise ValueError("a batch needs at least one network")
        self.mps, self.targets, self.description = mps, targets, description
        self.mesh = parallel.mesh() if mesh is None else mesh
        self.at_once = parallel.networks_at_once()
        self.n_padded = parallel.padded_size(self.n, self.mesh, self.at_once)
        #: the RecordConfig (jaxarm.record) or None; its windows' capacities and memory bound; the epochs recorded
        #: by this invocation of :meth:`train` (1-based epoch -> host Recording of the real networks)
        self.record, self.record_capacity, self.record_memory, self.epoch_records = record, {}, None, {}
        #: epoch (1-based) -> {"success", "min_distance_m"}: per-network tests after that epoch (train's
        #: test_each_epoch; kept in the checkpoints' meta, so a resumed run keeps the epochs tested before)
        self.learning_curve: dict[int, dict] = {}
        if record is not None:
            self._check_record()
        self.fns, self.init_fn, self.epoch_fn, self.test_fn, self.epoch_rec_fn = compiled(
            config, self.mesh, record, self.at_once, None if self.task == config.task else self.task)

    def _check_record(self) -> None:
        """The windows' buffer capacities (spikes per network) and the memory bound, refused above the limit."""
        from jaxarm import record as rec_mod

        rec, task, net = self.record, self.config.task, self.config.network
        bad = [k for k in rec.networks if k >= self.n]
        if bad:
            raise ConfigError(f"--record-networks {' '.join(map(str, bad))}: the run has {self.n} networks (0.."
                              f"{self.n - 1})")
        test = rec.capacity(net.n_all, task.test_steps * net.interface_ms)
        self.record_capacity = {name: test for what in ("test", "naive_test") for name in self.test_windows(what)}
        for e in rec.recorded_epochs(task.epochs):
            self.record_capacity[f"epoch_{e}"] = rec.capacity(net.n_all, rec.train_last_s * 1000.0)
        self.record_memory = rec_mod.check_memory(rec, self.n_padded, self.record_capacity)

    def test_windows(self, what: str = "test") -> list[str]:
        """The recorded windows of a test (``what``: test, naive_test): ``what`` itself for a task of one target,
        ``what_TARGET`` for each target of a task that tests several (its test's leading target axis)."""
        targets = getattr(self.task, "targets", None)   # reaching's TaskConfig has one target, no `targets`
        return [what] if targets is None else [f"{what}_{t}" for t in targets]

    def test_recordings(self, result: TestResult, what: str = "test") -> dict:
        """{window: the host Recording of the real networks} of a test's result (:meth:`test_windows`)."""
        names = self.test_windows(what)
        if names == [what]:
            return {what: result.record}
        return {name: jax.tree.map(lambda x, k=k: np.asarray(x)[:, k], result.record) for k, name in enumerate(names)}

    def recorded_networks(self) -> list[int]:
        """Indices of the networks whose records are written."""
        return sorted(set(self.record.networks)) if self.record and self.record.networks else list(range(self.n))

    # -- identity -------------------------------------------------------------------------------------------------
    def meta(self) -> dict:
        learning = learning_meta(self.config.learning, self.config.rule_config)
        return self.description | self.network_meta() | learning

    def config_record(self) -> dict:
        """results.json's ``config``: the whole LoopConfig as JSON and the run's :meth:`meta` (what ``jaxarm
        reproduce`` compares to reuse a finished folder)."""
        return json.loads(json.dumps({"loop": dataclasses.asdict(self.config), **self.meta()}, default=_json_default))

    def network_meta(self) -> dict:
        """The run's NetworkConfig fields that differ from the defaults (only those are recorded, so folders
        written before a field existed still resume; ``jaxarm test --from`` rebuilds the network from them), and
        the kernel that runs the network: the native and XLA kernels agree to float rounding, not bit for bit, so a
        run resumes only on the kernel it began on."""
        net = self.config.network
        kernel = "native" if Network(net).uses_native_kernel else "xla"
        return net.to_dict(changed_only=True) | {"kernel": kernel}

    def layout(self) -> dict:
        """How the batch is laid out over devices (not part of its identity: with one group size, results do not
        depend on it)."""
        return {"padded_networks": self.n_padded, "devices": self.mesh.size, "processes": jax.process_count(),
                "networks_at_once": self.at_once}

    def check_resumable(self, saved: dict) -> None:
        """Refuse to resume a checkpoint written by a different run (a folder from before the kernel was recorded
        resumes on either kernel). The layout (devices, processes) may differ: results do not depend on it."""
        saved = {k: v for k, v in saved.items() if k not in ("layout", "learning_curve")}
        recorded = saved.get("metaparams")   # a folder from before RETIRED names left or ADDED ones came: as today
        if isinstance(recorded, dict):
            saved["metaparams"] = as_current(recorded)
        elif isinstance(recorded, list):
            saved["metaparams"] = [as_current(m) if isinstance(m, dict) else m for m in recorded]
        mine = self.meta()
        if "kernel" not in saved:
            mine.pop("kernel")
        if saved.get("kernel", mine.get("kernel")) != mine.get("kernel"):
            from jaxarm.network import native
            raise SystemExit(f"{self.out / 'checkpoints'} was trained with the {saved['kernel']} network kernel and "
                             f"this machine would continue with the {mine['kernel']} one ({native.status()}); the "
                             "kernels agree to float rounding, not bit for bit: resume where the same kernel runs")
        if saved != mine:
            raise SystemExit(f"{self.out / 'checkpoints'} holds a different run: {describe_differences(saved, mine)}; "
                             "give the same options to resume it, or another --out (or delete the folder)")

    def _restore(self, ckpt, carry, history, saved: dict):
        """(carry on the mesh, host history) from ``ckpt``'s newest step. A checkpoint written on another layout
        (the batch padded for another device count) is read whole, its padding dropped and the batch re-split."""
        padded = saved.get("layout", {}).get("padded_networks", self.n)
        hist_like = parallel.put(history, parallel.REPLICATED, self.mesh)
        if padded == self.n_padded:
            (carry, hist), _ = ckpt.restore((carry, hist_like))
            return carry, jax.tree.map(np.array, parallel.host(hist))      # writable copies
        whole = jax.sharding.NamedSharding(self.mesh, parallel.REPLICATED)
        like = jax.tree.map(lambda x: jax.ShapeDtypeStruct((padded,) + x.shape[1:], x.dtype, sharding=whole), carry)
        (old, hist), _ = ckpt.restore((like, hist_like))
        old = jax.tree.map(lambda x: x[: self.n], parallel.host(old))
        return self._padded(old), jax.tree.map(np.array, parallel.host(hist))

    def check_capacity(self, lost_spikes, what: str, overflow=None) -> None:
        """Fail with the counts if any network lost a spike (a full spike list) or a synapse (a full delivery row):
        a fixed-capacity overflow is an error, never a rounding. ``lost_spikes``, ``overflow``: (networks,), or
        (networks, ...) summed per network (a test on several targets)."""
        for counts, kind, fix in ((lost_spikes, "lost spikes", "raise NetworkConfig.max_passes or spike_capacity"),
                                  (overflow, "synapses left out of the delivery tables",
                                   "raise NetworkConfig.out_capacity")):
            if counts is None:
                continue
            counts = np.asarray(counts)
            counts = (counts.reshape(counts.shape[0], -1).sum(axis=1) if counts.ndim > 1 else counts.reshape(-1))
            counts = counts[: self.n]
            bad = np.nonzero(counts)[0]
            if bad.size:
                nets = ", ".join(f"{self.seeds[i]} ({int(counts[i])})" for i in bad[:10])
                raise RuntimeError(f"{what}: {int(counts.sum())} {kind} in network(s) of seed {nets}"
                                   f"{' ...' if bad.size > 10 else ''}; {fix} (or use the native kernel)")

    def override(self, values: dict[str, float]) -> None:
        """Change these metaparameters in every network's set (e.g. a re-test with another readout gain); the
        recorded metaparameters follow."""
        self.mps = self.mps.replace(**{k: np.full(np.shape(getattr(self.mps, k)), v, np.float32)
                                       for k, v in values.items()})
        recorded = self.description.get("metaparams")
        if isinstance(recorded, list):
            self.description["metaparams"] = [m | {k: float(v) for k, v in values.items()} for m in recorded]
        elif isinstance(recorded, dict):
            self.description["metaparams"] = recorded | {k: float(v) for k, v in values.items()}

    # -- the batch on the devices ----------------------------------------------------------------------------------
    def _padded(self, tree):
        """Host rows (n, ...) padded to the device multiple and split over the mesh."""
        return parallel.put(jax.tree.map(lambda x: parallel.pad_rows(x, self.n_padded), tree), parallel.BATCHED,
                            self.mesh)

    def keys(self, fold: int | None = None):
        """The networks' keys on the mesh; the padding rows are further seeds (computed, then dropped)."""
        extra = max(self.seeds) + 1
        seeds = self.seeds + list(range(extra, extra + self.n_padded - self.n))
        keys = network_keys(seeds)
        if fold is not None:
            keys = np.asarray(jax.vmap(lambda k: jax.random.fold_in(k, fold))(keys))
        return parallel.put(keys, parallel.BATCHED, self.mesh)

    def batched_inputs(self):
        """(metaparameters, targets) on the mesh, one row per network."""
        return self._padded(self.mps), self._padded(Target(*(np.asarray(x, np.float32) for x in self.targets)))

    def _empty_history(self, carry, mps, targets) -> EpochSummary:
        one = jax.eval_shape(lambda c, m, t: self.epoch_fn(c, m, t)[1], carry, mps, targets)
        return jax.tree.map(lambda s: np.zeros((self.config.task.epochs, self.n) + s.shape[1:], s.dtype), one)

    def train(self, progress: bool = True, stop_after: int | None = None,
              test_each_epoch: bool | Callable[[TestResult], dict] = False):
        """Train all networks (resuming from ``out/checkpoints``). ``stop_after``: return after that many epochs of
        this invocation, as a kill would (tests use it). ``test_each_epoch``: also run the 1 s test after every
        epoch and keep ``summarise(result)`` (a JSON-able dict) in :attr:`learning_curve`; True: :func:`curve_entry`
        of that test and of a second one on held-out noise (:func:`jaxarm.train.fresh_noise`, ``j = 0``); the tests'
        time is not counted in ``wall_s``. Returns (carry, history, wall_s, epochs_run,
        compile_s): ``carry`` on the mesh (padded), ``history`` host arrays (epochs, networks, ...)."""
        from jaxarm.checkpoint import Checkpointer

        epochs = self.config.task.epochs
        mps, targets = self.batched_inputs()
        carry = self.init_fn(self.keys())
        self.check_capacity(parallel.host(carry.trained.wiring.out_overflow), "wiring")
        history = self._empty_history(carry, mps, targets)
        done = 0
        with Checkpointer(self.out / "checkpoints") as ckpt:
            saved = ckpt.read_meta()
            if saved is not None:
                self.check_resumable(saved)
                carry, history = self._restore(ckpt, carry, history, saved)
                done = int(ckpt.latest_step())
                self.learning_curve = {int(e): v for e, v in saved.get("learning_curve", {}).items()
                                       if int(e) <= done}
            last = epochs if stop_after is None else min(epochs, done + stop_after)
            if done < last:   # a full disk is refused here, before compiling, not after the first epoch
                runfolder.check_space(self.out, ckpt.step_bytes() or sum(x.nbytes for x in
                                                                         jax.tree.leaves((carry, history))))
            recorded = self.record.recorded_epochs(epochs) if self.record is not None else ()
            skipped = [e for e in recorded if e <= done]
            if skipped and parallel.is_main_process():
                print(f"note: epoch(s) {', '.join(map(str, skipped))} finished before this invocation and are not "
                      "recorded again; spikes.npz keeps them if an earlier invocation wrote it (one killed before "
                      "its end did not: train into a new --out to record them)", file=sys.stderr)
            t0 = time.perf_counter()
            epoch_fn = (self.epoch_fn.lower(carry, mps, targets).compile()
                        if any(e + 1 not in recorded for e in range(done, last)) else None)
            epoch_rec_fn = (self.epoch_rec_fn.lower(carry, mps, targets).compile()
                            if any(done < e <= last for e in recorded) else None)
            compile_s = time.perf_counter() - t0
            bar = _progress(epochs, done, progress and parallel.is_main_process(), self.description.get("label", ""))
            wall = 0.0
            for e in range(done, last):
                t0 = time.perf_counter()
                if e + 1 in recorded:
                    carry, summary, recording = epoch_rec_fn(carry, mps, targets)
                    self.epoch_records[e + 1] = self._host_recording(recording, f"epoch {e + 1}",
                                                                     self.record_capacity[f"epoch_{e + 1}"])
                else:
                    carry, summary = epoch_fn(carry, mps, targets)
                summary = jax.tree.map(lambda x: x[: self.n], parallel.host(summary))
                wall += time.perf_counter() - t0
                self.check_capacity(summary.lost_spikes, f"training epoch {e + 1}")
                jax.tree.map(lambda h, s: h.__setitem__(e, s), history, summary)
                if callable(test_each_epoch):
                    self.learning_curve[e + 1] = test_each_epoch(self.test(carry.trained, f"test after epoch {e + 1}"))
                elif test_each_epoch:
                    what = f"test after epoch {e + 1}"
                    self.learning_curve[e + 1] = curve_entry(
                        self.test(carry.trained, what),
                        self.test(fresh_noise(carry.trained, 0), what + " on held-out noise"))
                ckpt.save(e + 1, (carry, parallel.put(history, parallel.REPLICATED, self.mesh)),
                          self.meta() | {"layout": self.layout(),
                                         "learning_curve": {str(k): v for k, v in self.learning_curve.items()}})
                if bar is not None:
                    sim_s = (e + 1 - done) * self.config.task.epoch_duration_s
                    bar.set_postfix(sim_s=f"{(e + 1) * self.config.task.epoch_duration_s:.0f}",
                                    net_s_per_s=f"{sim_s * self.n / wall:.1f}")
                    bar.update(1)
            if bar is not None:
                bar.close()
        return carry, history, wall, last - done, compile_s

    def test(self, trained: Trained, what: str = "test") -> TestResult:
        """The 1 s test of every network (host arrays, padding dropped); with recording, ``result.record`` holds
        its spikes (checked for overflow; ``what`` names the window in errors)."""
        mps, targets = self.batched_inputs()
        result = self.test_fn(self.keys(self.task.test_key_fold), trained, mps, targets)
        result = jax.tree.map(lambda x: x[: self.n], parallel.host(result))
        self.check_capacity(result.lost_spikes, "test")
        if result.record is not None:
            from jaxarm import record as rec_mod

            for name, rec in self.test_recordings(result).items():
                rec_mod.check_overflow(rec.spikes, self.record_capacity[name], self.seeds,
                                       what + name.removeprefix("test").replace("_", " ", 1), self.record.max_rate_hz)
        return result

    def _host_recording(self, recording, what: str, capacity: int):
        """A Recording on the host, real networks only, checked for buffer overflow."""
        from jaxarm import record as rec_mod

        recording = jax.tree.map(lambda x: np.asarray(x)[: self.n], parallel.host(recording))
        rec_mod.check_overflow(recording.spikes, capacity, self.seeds, what, self.record.max_rate_hz)
        return recording

    def naive(self) -> Trained:
        """The untrained networks (on the mesh, padded), for the naive test."""
        return self.init_fn(self.keys()).trained

    def restore_trained(self, checkpoints: Path) -> tuple:
        """(carry, history) of the last checkpoint in ``checkpoints`` (a finished run's), for a re-test."""
        from jaxarm.checkpoint import Checkpointer

        mps, targets = self.batched_inputs()
        carry = self.init_fn(self.keys())
        history = self._empty_history(carry, mps, targets)
        with Checkpointer(checkpoints) as ckpt:
            return self._restore(ckpt, carry, history, ckpt.read_meta())


class Run(Runner):
    """One task: networks ``seed .. seed + n - 1`` trained with one metaparameter set ``mp``. ``task``: default
    ``config.task`` (reaching, one target); another (:class:`jaxarm.task.centre_out.CentreOut`) is recorded in the
    description as ``task``: its :meth:`~jaxarm.task.interface.TaskInterface.identity`."""

    def __init__(self, config: LoopConfig, n_networks: int, seed: int, out: Path, mp: MetaParams, mesh=None,
                 record=None, task: TaskInterface | None = None):
        self.mp, self.seed = mp, seed
        if task is None or isinstance(task, TaskConfig):   # reaching: the description every run folder has had
            task = task or config.task
            what = {"target": task.target}
            label = f"{config.arm}/{task.target}"
        else:
            what = {"task": task.identity()}
            label = f"{config.arm}/{task.identity().get('name', type(task).__name__)}"
        tc = task.task_config()
        target = task.network_target()
        super().__init__(config, range(seed, seed + n_networks), stack_rows([mp] * n_networks),
                         Target(*(np.stack([np.asarray(x, np.float32)] * n_networks) for x in target)), out,
                         {"arm": config.arm, "backend": config.backend, **what,
                          "networks": n_networks, "seed": seed, "epochs": tc.epochs,
                          "epoch_s": tc.epoch_duration_s, "metaparams": mp.to_dict(),
                          "label": label}, mesh, record, task)

    def meta(self) -> dict:
        return {k: v for k, v in super().meta().items() if k != "label"}


class SetsRun(Runner):
    """N networks, network i (key ``PRNGKey(seed + i)``) trained and tested with metaparameter set i.

    ``mps`` is a :class:`MetaParams` stacked along a leading axis of length N
    (:func:`jaxarm.learning.metaparams.stack`); the paper's statistic (its top 30 configurations, one network each)
    is such a run. ``meta()["metaparams"]`` is the list of the N sets.
    """

    def __init__(self, config: LoopConfig, seed: int, out: Path, mps: MetaParams, mesh=None, record=None):
        n = int(np.shape(mps.learn_rate)[0])
        self.mp, self.seed = mps, seed
        super().__init__(config, range(seed, seed + n), mps, Target.stack([config.task.target] * n), out,
                         {"arm": config.arm, "backend": config.backend, "target": config.task.target,
                          "networks": n, "seed": seed, "epochs": config.task.epochs,
                          "epoch_s": config.task.epoch_duration_s, "metaparams": [m.to_dict() for m in unstack(mps)],
                          "label": f"{config.arm}/{config.task.target}"}, mesh, record)

    def meta(self) -> dict:
        return {k: v for k, v in super().meta().items() if k != "label"}


def _json_default(x):
    """numpy scalars in a configuration, as Python numbers."""
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


#: The runner's former name (callers written before it ran any task).
Batch = Runner


def _progress(total, initial, enabled, desc):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit="epoch")


class Rows(NamedTuple):
    """Selected networks of a batch's results (host arrays), for writing one group's outputs."""

    trained: TestResult
    naive: TestResult
    history: EpochSummary


def select(rows: slice, trained: TestResult, naive: TestResult, history: EpochSummary) -> Rows:
    """The networks ``rows`` of a batch's test results and history (history is (epochs, networks, ...))."""
    return Rows(jax.tree.map(lambda x: x[rows], trained), jax.tree.map(lambda x: x[rows], naive),
                jax.tree.map(lambda x: x[:, rows], history))


__all__ = ["Runner", "Batch", "Run", "SetsRun", "learning_curve", "compiled", "network_keys", "network_config",
           "stack_rows", "unstack", "NETWORK_OPTIONS", "select", "Rows"]
