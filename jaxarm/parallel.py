"""Every device of every machine as one batch axis: JAX's mesh, ``shard_map`` and ``jax.distributed``.

A batch of networks (a training run, a search's candidates x seeds, a reproduction) is split along its leading
axis over a 1-D :class:`jax.sharding.Mesh` of all devices of all processes (axis :data:`AXIS`). Each device runs the
``vmap``-ed function on its share (``jax.shard_map``): on a CPU the native C++ network kernel per device, on an
accelerator the pure-JAX kernel. Networks never talk to each other, so nothing crosses devices but what the caller
gathers (fitness for a search's ``tell``, results at the end). A network's result does not depend on which device or
process computes it, nor on how many share its device, so every layout gives the same bits.

Set-up, once per process and before JAX computes anything (:func:`start`; the command line's ``--devices``,
``--coordinator``, ``--num-processes``, ``--process-id``, see :mod:`jaxarm.parallel_cli`):

* CPU: ``devices`` host devices per process (default: the cores this process may use, :func:`usable_cores`: its
  affinity mask, at most its cgroup CPU quota), each running one network kernel thread, so a command uses the whole
  machine; a device may wait for the others at a gather for up to 6 h (:data:`COLLECTIVE_WAIT_S`; XLA's own default
  aborts after 40 s).
* Several processes (machines): ``jax.distributed.initialize`` with the coordinator's address, or with nothing under
  SLURM or Open MPI (JAX reads their environment); CPU collectives through gloo. A process that has not joined all
  the others within ``--coordinator-timeout`` (default 60 s) says so in one line naming the address and exits. Process 0 writes the outputs;
  checkpoints are orbax multi-process checkpoints on a file system all processes share.

Each device runs its share in groups of :func:`networks_at_once` networks (on CPUs one network at a time), one
group after the other, and a batch is padded to whole groups on every device (:func:`padded_size`): the extra members
are computed and dropped by the caller, never counted. With XLA's fused multiply-add off and the arm's small products
and the learning rule's long sums computed as in any batch (:mod:`jaxarm.cpu_arithmetic`), a network gets the same
bits at any place in its group and in a group of any size (docs/scaling.md, "A network in another batch").
"""
from __future__ import annotations

import itertools
import math
import os
import socket
import sys
import threading
from functools import lru_cache
from pathlib import Path
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import AxisType, Mesh, NamedSharding, PartitionSpec

from jaxarm import cpu_dispatch
from jaxarm.config.validate import ConfigError

#: The mesh axis the batch is split along.
AXIS = "batch"
BATCHED = PartitionSpec(AXIS)
REPLICATED = PartitionSpec()


def parse_cpu_max(text: str) -> float | None:
    """CPUs allowed by a cgroup v2 ``cpu.max`` ("QUOTA PERIOD", microseconds): "200000 100000" is 2.0, "max 100000"
    (no quota) and anything unreadable None."""
    parts = text.split()
    if len(parts) < 1 or parts[0] == "max":
        return None
    try:
        quota, period = int(parts[0]), int(parts[1]) if len(parts) > 1 else 100_000
    except ValueError:
        return None
    return quota / period if quota > 0 and period > 0 else None


def parse_cfs_quota(quota: str, period: str) -> float | None:
    """CPUs allowed by cgroup v1's ``cpu.cfs_quota_us`` and ``cpu.cfs_period_us`` ("-1": no quota), or None."""
    try:
        q, t = int(quota.strip()), int(period.strip())
    except ValueError:
        return None
    return q / t if q > 0 and t > 0 else None


def parse_cgroup_path(text: str, controller: str | None = None) -> str | None:
    """A ``/proc/self/cgroup``'s path of the cgroup v2 hierarchy (the line ``0::/PATH``), or with ``controller``
    (e.g. "cpu") the v1 hierarchy holding that controller; None if there is none."""
    for line in text.splitlines():
        num, _, rest = line.partition(":")
        names, _, path = rest.partition(":")
        if (controller is None and num == "0" and names == "") or \
                (controller is not None and controller in names.split(",")):
            return path.strip() or "/"
    return None


def _smallest_up(root: str, path: str, read) -> float | None:
    """The smallest limit ``read(folder)`` of ``root + path`` and its parents up to ``root``."""
    limits, folder, top = [], Path(root + path.rstrip("/")), Path(root)
    while True:
        try:
            limit = read(folder)
        except OSError:
            limit = None
        if limit is not None:
            limits.append(limit)
        if folder == top or top not in folder.parents:
            break
        folder = folder.parent
    return min(limits) if limits else None


def cgroup_cpu_limit(root: str = "/sys/fs/cgroup", proc_cgroup: str = "/proc/self/cgroup") -> float | None:
    """CPUs allowed by this process's cgroup CPU quota (the smallest of its cgroup and its parents; a container sees
    its own as the root): cgroup v2's ``cpu.max``, or v1's ``cpu.cfs_quota_us``; None without one."""
    try:
        text = Path(proc_cgroup).read_text()
    except OSError:
        text = ""
    limits = [_smallest_up(root, parse_cgroup_path(text) or "/",
                           lambda f: parse_cpu_max((f / "cpu.max").read_text()))]
    v1 = parse_cgroup_path(text, "cpu")
    if v1 is not None:
        limits.append(_smallest_up(f"{root}/cpu", v1, lambda f: parse_cfs_quota(
            (f / "cpu.cfs_quota_us").read_text(), (f / "cpu.cfs_period_us").read_text())))
    limits = [x for x in limits if x is not None]
    return min(limits) if limits else None


def cores_from(affinity: int, quota: float | None) -> int:
    """Usable cores: the affinity mask's count, at most the CPU quota's whole CPUs (at least 1)."""
    return affinity if quota is None else max(1, min(affinity, math.floor(quota + 1e-9)))


def _affinity_count() -> int:
    """Cores in this process's affinity mask (the OS's CPU count where there is no mask)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:   # pragma: no cover - not Linux
        return os.cpu_count() or 1


def usable_cores() -> int:
    """CPU cores this process may run on: its affinity mask (where the OS has one), at most the whole CPUs of its
    cgroup v2 CPU quota (``cpu.max``: a ``docker run --cpus 2`` container on a 64-core host has 2)."""
    return cores_from(_affinity_count(), cgroup_cpu_limit())


def _cluster_detected() -> bool:
    """Whether JAX can find its processes by itself: a SLURM job step or an Open MPI launch of several tasks."""
    slurm = int(os.environ.get("SLURM_NTASKS", os.environ.get("SLURM_NPROCS", "1")) or 1) > 1 \
        and "SLURM_PROCID" in os.environ
    ompi = int(os.environ.get("OMPI_COMM_WORLD_SIZE", "1") or 1) > 1
    return slurm or ompi


#: XLA:CPU's limits on how long one device waits at a collective for the others: by default it warns after 20 s and
#: aborts the process after 40 s ("to ensure a consistent program state"). A batch's shares can differ by minutes
#: (networks firing at different rates, a shared machine), so a search's gather of fitness would abort a healthy run;
#: :func:`start` raises both unless ``XLA_FLAGS`` already sets them.
COLLECTIVE_WAIT_S = {"xla_cpu_collective_call_warn_stuck_timeout_seconds": 600,
                     "xla_cpu_collective_call_terminate_timeout_seconds": 6 * 3600}


def _relax_collective_waits() -> None:
    flags = os.environ.get("XLA_FLAGS", "")
    extra = [f"--{name}={seconds}" for name, seconds in COLLECTIVE_WAIT_S.items() if name not in flags]
    if extra:
        os.environ["XLA_FLAGS"] = " ".join([flags, *extra]).strip()


_started = False


#: Networks a CPU device steps together by default: one, the share's networks one after the other (``lax.map``).
#: A network's ring buffer and wiring (about 2 MB) then stay in the core's caches through its epoch; in groups of 8
#: they leave them at every 10 ms exchange, and ``jaxarm train`` trained 1.2x (simple arm) and 1.1x
#: (musculoskeletal) slower (docs/scaling.md, docs/results/group_size.json). No padding beyond the device count.
CPU_NETWORKS_AT_ONCE = 1
_networks_at_once: int | None = None


def networks_at_once() -> int:
    """Networks each device steps together (0: its whole share). ``--networks-at-once`` sets it; by default
    :data:`CPU_NETWORKS_AT_ONCE` on CPUs and the whole share on accelerators, whose parallelism is across networks.
    Any value gives the networks the same bits (``tests/test_batch_invariance.py``); 0 (one ``vmap``) too, but for
    the epoch summaries' hand distances, about 1e-6 m off the grouped ones (docs/scaling.md)."""
    if _networks_at_once is not None:
        return _networks_at_once
    return CPU_NETWORKS_AT_ONCE if jax.default_backend() == "cpu" else 0


def map_networks(fn: Callable, at_once: int = 0) -> Callable:
    """``fn`` over the leading (network) axis of its arguments: one ``vmap``, or with ``at_once`` groups of that
    many networks one after the other (``lax.map``; a last, smaller group takes the rest)."""
    if not at_once:
        return jax.vmap(fn)

    def grouped(*args):
        return jax.lax.map(lambda a: fn(*a), args, batch_size=at_once)

    return grouped


#: Seconds a process waits for all processes to join through the coordinator by default (``--coordinator-timeout``;
#: JAX's own default is 300 s, after which it aborts the process with a C++ stack).
COORDINATOR_TIMEOUT_S = 60.0
_warned_devices = False


def _quota_text() -> str:
    quota = cgroup_cpu_limit()
    return f"affinity mask {_affinity_count()}" + (f", cgroup CPU quota {quota:g}" if quota is not None else "")


def _warn_devices(devices: int) -> None:
    global _warned_devices
    cores = usable_cores()
    if devices > cores and not _warned_devices:
        _warned_devices = True
        print(f"jaxarm: warning: --devices {devices} is more than the {cores} core(s) this process may use "
              f"({_quota_text()}): the devices share cores, which is slower than one device per core and takes "
              "more memory; leave --devices out for one device per usable core", file=sys.stderr, flush=True)


def _check_port(coordinator: str) -> None:
    """Process 0 serves the coordinator on the address's port: refuse at once when it cannot listen there."""
    port = coordinator.rsplit(":", 1)[1]
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError(f"--coordinator = {coordinator!r}: the port must be a number in [1, 65535]")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("", int(port)))
        except OSError as e:
            raise ConfigError(f"--coordinator {coordinator}: process 0 cannot listen on port {port} "
                              f"({e.strerror or e}); give a free port") from None


def _join(timeout_s: float, coordinator: str | None = None, num_processes: int | None = None,
          process_id: int | None = None) -> None:
    """``jax.distributed.initialize``, bounded: if not every process has joined after ``timeout_s``, one line
    naming the address and this process's part, then exit status 2 (JAX's own timeout, set a little later, aborts
    the process with a C++ stack)."""
    where = coordinator or os.environ.get("JAX_COORDINATOR_ADDRESS") or "(from the SLURM / Open MPI environment)"
    if coordinator is not None and process_id == 0:
        _check_port(coordinator)

    def give_up():
        if process_id == 0:
            why = (f"process 0 waited {timeout_s:g} s and not all {num_processes} processes joined; start each with "
                   "the same command and its own --process-id")
        else:
            who = "this process" if process_id is None else f"process {process_id} of {num_processes}"
            why = (f"{who} could not join within {timeout_s:g} s: is process 0 running there and the port "
                   "reachable from here?")
        print(f"jaxarm: error: --coordinator {where}: {why} (--coordinator-timeout S to wait longer)",
              file=sys.stderr, flush=True)
        os._exit(2)

    watchdog = threading.Timer(timeout_s, give_up)
    watchdog.daemon = True
    watchdog.start()
    kwargs = {} if coordinator is None else {"coordinator_address": coordinator, "num_processes": num_processes,
                                             "process_id": process_id}
    try:
        jax.distributed.initialize(initialization_timeout=math.ceil(timeout_s) + 15, **kwargs)
    except Exception as e:  # noqa: BLE001 - what JAX raises (a bad address, ...) becomes one line
        text = str(e).strip().splitlines()[0][:200] if str(e).strip() else type(e).__name__
        raise ConfigError(f"--coordinator {where}: cannot join the other processes ({text})") from None
    finally:
        watchdog.cancel()


def start(devices: int | None = None, coordinator: str | None = None, num_processes: int | None = None,
          process_id: int | None = None, networks_at_once: int | None = None,
          coordinator_timeout_s: float | None = None) -> None:
    """Configure this process before JAX computes anything: ``devices`` CPU host devices (default
    :func:`usable_cores`), and, with a coordinator (or a detected SLURM / Open MPI job, or ``JAX_COORDINATOR_ADDRESS``),
    join the other processes through ``jax.distributed`` with gloo CPU collectives.

    Called after JAX has already computed (a notebook, a test calling a command's ``main``), or a second time, the
    device count cannot change any more: the devices JAX has are used and ``devices`` is ignored.
    """
    from jax._src import xla_bridge

    if devices is not None and devices < 1:
        raise ConfigError(f"--devices = {devices}: must be >= 1")
    if coordinator_timeout_s is not None and not 0 < coordinator_timeout_s <= 86_400:
        raise ConfigError(f"--coordinator-timeout = {coordinator_timeout_s:g}: must be in (0, 86400] s")
    if networks_at_once is not None:
        if networks_at_once < 0:
            raise ConfigError(f"--networks-at-once = {networks_at_once}: must be >= 0 (0: a device's whole share)")
        global _networks_at_once
        _networks_at_once = networks_at_once
    explicit = [v is not None for v in (coordinator, num_processes, process_id)]
    if any(explicit) and not all(explicit):
        raise ConfigError("--coordinator, --num-processes and --process-id go together (or none of them, under "
                          "SLURM or Open MPI)")
    if all(explicit):
        if num_processes < 1:
            raise ConfigError(f"--num-processes = {num_processes}: must be >= 1")
        if not 0 <= process_id < num_processes:
            raise ConfigError(f"--process-id = {process_id}: must be in [0, {num_processes - 1}]")
        if ":" not in coordinator:
            raise ConfigError(f"--coordinator = {coordinator!r}: expected HOST:PORT")
    if devices is not None:
        _warn_devices(devices)
    global _started
    if _started or xla_bridge.backends_are_initialized():
        return
    _started = True
    _relax_collective_waits()      # read by XLA when the backend starts, just below
    jax.config.update("jax_num_cpu_devices", devices or usable_cores())
    cpu_dispatch.pool_threads(devices or usable_cores())   # likewise: one XLA:CPU pool thread per device
    distributed = all(explicit) and num_processes > 1
    if distributed or _cluster_detected() or os.environ.get("JAX_COORDINATOR_ADDRESS"):
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
        timeout = COORDINATOR_TIMEOUT_S if coordinator_timeout_s is None else coordinator_timeout_s
        global _wait_s
        _wait_s = timeout
        if distributed:
            _join(timeout, coordinator, num_processes, process_id)
        else:
            _join(timeout)


@lru_cache(maxsize=None)
def _mesh(devices: tuple) -> Mesh:
    return Mesh(np.asarray(devices), (AXIS,), axis_types=(AxisType.Auto,))


def mesh() -> Mesh:
    """The 1-D mesh of every device of every process (the same object for the same devices)."""
    return _mesh(tuple(jax.devices()))


def _round_up(n: int, devices: int, at_once: int) -> int:
    d = devices * max(1, at_once)
    return -(-n // d) * d


def padded_size(n: int, m: Mesh | None = None, at_once: int = 0) -> int:
    """``n`` rounded up to a multiple of the mesh's device count, times ``at_once`` when that is given: every
    device then runs whole groups of ``at_once`` networks (:func:`map_networks`), the same program whatever the
    layout."""
    return _round_up(n, (m or mesh()).size, at_once)


def group_span(devices: int, at_once: int) -> int:
    """Networks a batch must be a multiple of to fill whole groups: ``devices`` x ``at_once`` (x 1 for 0, a
    device's whole share: then only a multiple of the devices)."""
    return max(1, devices) * max(1, at_once)


def padding_note(n: int, what: str, devices: int, at_once: int, processes: int = 1,
                 fill: tuple[str, Callable[[int], int], int] | None = None, unit: str = "networks") -> str:
    """One line on how a batch of ``n`` rows (``unit``; ``what``: e.g. "a generation's 512 evaluations (256
    candidates x 2 seeds)") runs on ``devices`` devices of ``processes`` processes in groups of ``at_once``: whole
    groups, or the padded size, the fraction of what runs that is padding and, with ``fill`` = (option, the batch's
    size for a value of it, its value now), the option's smallest value at or above the current one whose batch
    fills the groups (or the batch size that would, when no value of the option does)."""
    span = group_span(devices, at_once)
    padded = -(-n // span) * span
    where = f"on {devices} device{'s' if devices != 1 else ''}"
    where += f" of {processes} processes" if processes > 1 else ""
    where += (" one network at a time" if at_once == 1 else f" in groups of {at_once}") if at_once else ""
    if padded == n:
        return f"{what}: {where}, " + ("whole groups (no padding)" if at_once > 1 else "no padding")
    text = (f"{what}: {where}, padded to {padded}: {100 * (padded - n) / padded:.3g} % of what runs is padding "
            "(computed and dropped)")
    if fill is not None:
        option, size, now = fill
        value = next((v for v in range(max(1, now), max(1, now) + span + 1) if size(v) % span == 0), None)
        if value is not None:
            return text + f"; {option} {value} fills the groups ({size(value)} {unit})"
    return text + f"; a batch of {padded} {unit} (a multiple of {span}) fills the groups"


def sharded_map(fn: Callable, m: Mesh | None = None, at_once: int | None = None) -> Callable:
    """``fn`` mapped over the leading axis of its arguments (inside a ``jit``), split over the mesh ``m`` when one
    is given (else on the default device), each device's share in groups of ``at_once`` networks (default
    :func:`networks_at_once`; 0: one ``vmap``). Rows are padded to whole groups on every device (with copies of the
    last row) and the padding dropped from the result, so a row's result is the same bits whatever the batch size
    and layout (docs/scaling.md, "A network in another batch"). The result is whole (replicated)
    on every device of ``m``."""
    at_once = networks_at_once() if at_once is None else at_once
    local = map_networks(fn, at_once)

    def mapped(*args):
        n = jax.tree.leaves(args)[0].shape[0]
        n_pad = _round_up(n, 1 if m is None else m.size, at_once)
        pad = lambda x: jnp.concatenate([x, jnp.repeat(x[-1:], n_pad - n, axis=0)]) if n_pad > n else x  # noqa: E731
        args = jax.tree.map(pad, args)
        if m is None:
            return jax.tree.map(lambda x: x[:n], local(*args))
        everywhere = NamedSharding(m, REPLICATED)
        out = jax.shard_map(local, mesh=m, in_specs=BATCHED, out_specs=BATCHED, check_vma=False)(*args)
        # gathered whole onto every device: what follows (means over seeds, ...) is computed whole, not in parts
        return jax.tree.map(lambda x: jax.lax.with_sharding_constraint(x, everywhere)[:n], out)

    return mapped


def is_main_process() -> bool:
    """Process 0 writes results, figures and logs."""
    return jax.process_index() == 0


_agreements = itertools.count()
#: Seconds :func:`agree` waits for the other processes (the ``--coordinator-timeout`` the processes joined with).
_wait_s = COORDINATOR_TIMEOUT_S


def agree(refusal: str | None) -> str | None:
    """Share a step's outcome across processes: each process gives its refusal (one line) or None, and every process
    gets the first refusal of any process (naming it when it is another's), or None.

    Without it a refusal on one process (process 0's folder lock) ends that process, and the others wait in their
    first collective until gloo's 30 s timeout ends them with a traceback. Through the coordinator's key-value store
    each process publishes its outcome and reads every other's, then all meet at a barrier, so process 0 (which holds
    the store) leaves only after every process has read it. Every process must call it the same number of times, in
    the same order. One process: ``refusal`` itself."""
    n = jax.process_count()
    if n == 1:
        return refusal
    from jax._src import distributed

    client, me = distributed.global_state.client, jax.process_index()
    key, wait_ms = f"jaxarm/agree/{next(_agreements)}", int(_wait_s * 1000)
    client.key_value_set(f"{key}/{me}", refusal or "")
    try:
        said = [client.blocking_key_value_get(f"{key}/{i}", wait_ms) for i in range(n)]
        client.wait_at_barrier(f"{key}/read", wait_ms)
    except Exception:  # noqa: BLE001 - a process that never got here (it died, or hangs before this step)
        return refusal or (f"process {me} of {n} waited {_wait_s:g} s for the others to reach the same step; one of "
                           "them has ended or hangs (see its own output)")
    for i, text in enumerate(said):
        if text:
            return text if i == me else f"{text} [process {i} of {n}; process {me} stops with it]"
    return None


def barrier(name: str) -> None:
    """Wait for every process (no-op with one)."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)


def shard(fn: Callable, in_specs, out_specs, m: Mesh | None = None) -> Callable:
    """``jit(shard_map(fn))`` over the batch mesh: ``fn`` (already ``vmap``-ed) runs on each device's share of every
    argument with spec :data:`BATCHED`; :data:`REPLICATED` arguments reach every device whole."""
    m = m or mesh()
    return jax.jit(jax.shard_map(fn, mesh=m, in_specs=in_specs, out_specs=out_specs, check_vma=False))


def put(tree, spec: PartitionSpec, m: Mesh | None = None):
    """Host values (numpy or JAX, the same on every process) as global arrays with ``spec`` on the mesh."""
    m = m or mesh()
    sharding = NamedSharding(m, spec)

    def one(x):
        x = np.asarray(x)
        return jax.make_array_from_callback(x.shape, sharding, lambda index: x[index])

    return jax.tree.map(one, tree)


def host(tree) -> Any:
    """Global arrays as numpy arrays on every process (gathered across processes where they are split)."""
    def one(x):
        if not isinstance(x, jax.Array) or x.is_fully_addressable:
            return np.asarray(x)
        if x.is_fully_replicated:
            return np.asarray(x.addressable_data(0))
        from jax.experimental import multihost_utils

        return np.asarray(multihost_utils.process_allgather(x, tiled=True))

    return jax.tree.map(one, tree)


def abstract(tree) -> Any:
    """Shapes, dtypes and shardings of a pytree of arrays (what orbax restores into)."""
    return jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=getattr(x, "sharding", None)),
                        tree)


def pad_rows(x, n: int):
    """``x`` (n0, ...) extended to n rows by repeating its last row (host arrays)."""
    x = np.asarray(x)
    if x.shape[0] == n:
        return x
    return np.concatenate([x, np.repeat(x[-1:], n - x.shape[0], axis=0)])


def describe() -> dict:
    """What this process computes on, for results and logs."""
    return {"backend": jax.default_backend(), "devices": jax.device_count(), "local_devices": jax.local_device_count(),
            "processes": jax.process_count(), "device_kind": jax.devices()[0].device_kind}


__all__ = ["AXIS", "BATCHED", "REPLICATED", "start", "mesh", "padded_size",
           "sharded_map", "is_main_process", "agree", "barrier", "shard", "put", "host", "abstract", "pad_rows", "describe",
           "usable_cores", "cgroup_cpu_limit", "parse_cpu_max", "COORDINATOR_TIMEOUT_S", "group_span", "padding_note"]
