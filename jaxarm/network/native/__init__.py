"""Native CPU kernel for the network's hot loop: one XLA FFI call runs a whole chunk of steps of every network.

Why: on a CPU the clock-driven network is a few simple operations per cell and step plus a sparse delivery; XLA:CPU
spends most of its time between its kernels (a step is ~20 small fusions over (B, 512) arrays, and delivery is a
batch of scatters sized for the worst case). ``chunk_kernel.cc`` does the same work in one loop per network, with
branches where the model is sparse (most cells get no input in most steps), and delivers each spike where it lands,
so it has no spike-list capacity to overflow. The model, the state layout and the noise stream are the XLA path's
(:meth:`jaxarm.network.network.Network._chunk`); a state can be advanced by either path and continued by the other.
Results agree with the XLA path to float rounding (tests/test_native_kernel.py), not bit for bit: exp/expm1/log1p are the
kernel's own vectorisable ones (:func:`fast_math`, within 1.5 ulp), not XLA's, and spike trains of a chaotic network diverge after a while, as they would between
two machines.

Build: compiled on first use with the system C++ compiler (``$CXX`` or ``c++``; C++17) against the XLA FFI headers
that ship with jaxlib, into ``$JAXARM_CACHE_DIR`` (default ``~/.cache/jaxarm``), keyed by the source, jaxlib version,
compiler flags and CPU. No compiler, or a failed build: :func:`available` says why and ``NetworkConfig.kernel =
"auto"`` uses the XLA path.

Batching: ``vmap_method="expand_dims"``: unbatched inputs (shared wiring, constants) arrive with size-1 batch axes
and the kernel broadcasts them without copying, at any depth of nested ``vmap``.
"""
from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.network.wiring import DELAY_BITS

if TYPE_CHECKING:  # pragma: no cover
    from jaxarm.network.network import Network, NetworkParams, State
    from jaxarm.network.wiring import Wiring

TARGET = "jaxarm_network_chunk"
#: The spec's physics (``SynapsePhysics`` fields) the kernel takes as float32 attributes of the same names.
PHYSICS_ATTRIBUTES = ("e_ampa_mv", "e_nmda_mv", "e_gaba_mv", "mg_mm", "mg0_mm", "mg_slope_per_mv", "vm_min_mv",
                      "vm_max_mv", "max_jump_fraction")
SOURCE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "chunk_kernel.cc")
# -fno-math-errno and -fno-trapping-math change no result (no errno, no FP exception flags to keep) but let the
# compiler vectorise loops with selects (the fastmath calls); -ffp-contract=off keeps a*b+c two roundings
CXX_FLAGS = ("-O3", "-march=native", "-ffp-contract=off", "-fno-math-errno", "-fno-trapping-math", "-std=c++17",
             "-fPIC", "-shared", "-pthread")


def _cpu_signature() -> str:
    """CPU model and flags (the library is built with -march=native, so it is specific to the CPU)."""
    try:
        with open("/proc/cpuinfo") as f:
            lines = [ln for ln in f if ln.startswith(("model name", "flags"))][:2]
        return "".join(lines)
    except OSError:
        return platform.processor() + platform.machine()


def cache_dir() -> str:
    return os.environ.get("JAXARM_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "jaxarm")


def _compiler() -> str | None:
    for cand in (os.environ.get("CXX"), "c++", "g++", "clang++"):
        if cand and shutil.which(cand):
            return cand
    return None


@functools.lru_cache(maxsize=None)
def _build(profile: bool = False) -> tuple[str | None, str]:
    """(path of the shared library or None, reason). Builds once per source/jaxlib/CPU; atomic, so concurrent
    processes are safe. ``profile``: the library with phase timers (``-DJAXARM_PROFILE``), a file of its own."""
    cxx = _compiler()
    if cxx is None:
        return None, "no C++ compiler found (set $CXX)"
    import jaxlib

    flags = CXX_FLAGS + (("-DJAXARM_PROFILE",) if profile else ())
    with open(SOURCE, "rb") as f:
        src = f.read()
    key = hashlib.sha256(src + repr((jaxlib.__version__, flags, cxx, _cpu_signature())).encode()).hexdigest()[:16]
    folder = cache_dir()
    stem = "chunk_kernel_profile" if profile else "chunk_kernel"
    path = os.path.join(folder, f"{stem}-{key}.so")
    if os.path.exists(path):
        return path, "cached"
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=".so", dir=folder)
    except OSError:  # an unwritable home: build into the temporary folder instead
        folder = os.path.join(tempfile.gettempdir(), "jaxarm-native")
        os.makedirs(folder, exist_ok=True)
        path = os.path.join(folder, f"{stem}-{key}.so")
        if os.path.exists(path):
            return path, "cached"
        fd, tmp = tempfile.mkstemp(suffix=".so", dir=folder)
    os.close(fd)
    cmd = [cxx, *flags, "-w", "-I", jax.ffi.include_dir(), SOURCE, "-o", tmp]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.TimeoutExpired) as e:
        os.unlink(tmp)
        return None, f"compiler failed to run: {e}"
    if proc.returncode != 0:
        os.unlink(tmp)
        return None, f"build failed ({' '.join(cmd)}): {proc.stderr.strip()[-2000:]}"
    os.replace(tmp, path)
    return path, "built"


_PROFILE = {"on": False}
_LIBS: dict = {}   # profile build? -> the loaded library
#: Phases of the profiling build's timers (chunk_kernel.cc, namespace prof), in its order.
PROFILE_PHASES = ("copy_in", "p_window", "noise", "cells", "spike_bookkeeping", "delivery", "tags")
PROFILE_COUNTERS = ("spikes", "synapse_events", "tag_checks", "steps", "cell_blocks", "blocks_ampa", "blocks_nmda",
                    "blocks_gaba_prox", "blocks_gaba_dist")


@functools.lru_cache(maxsize=None)
def _register(profile: bool = False) -> tuple[bool, str]:
    path, why = _build(profile)
    if path is None:
        return False, why
    try:
        lib = ctypes.cdll.LoadLibrary(path)
        jax.ffi.register_ffi_target(TARGET + ("_profile" if profile else ""),
                                    jax.ffi.pycapsule(lib.JaxarmNetworkChunk), platform="cpu")
        lib.JaxarmFastMath.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64]
        _LIBS[profile] = lib
    except Exception as e:  # noqa: BLE001 - any loading problem means "not available", with the reason
        return False, f"loading {path} failed: {e}"
    return True, f"{why}: {path}"


FAST_MATH = ("exp", "expm1", "log1p")


def fast_math(name: str, x, lanes: bool = False) -> np.ndarray:
    """The kernel's own float32 ``exp``, ``expm1`` or ``log1p`` (the vectorisable ones it uses instead of the C
    library's) of the array ``x``, for tests: one float at a time, or with ``lanes`` in the kernel's blocks of
    eight lanes."""
    ok, why = _register()
    if not ok:
        raise RuntimeError(f"jaxarm native network kernel unavailable: {why}")
    x = np.ascontiguousarray(np.ravel(x), np.float32)
    n = x.size
    if lanes:
        x = np.concatenate([x, np.zeros(-n % 8, np.float32)])
    out = np.empty_like(x)
    _LIBS[False].JaxarmFastMath(x.ctypes.data, out.ctypes.data, x.size, FAST_MATH.index(name) + 3 * lanes)
    return out[:n]


def enable_profiling(on: bool = True) -> None:
    """Programs traced from now on call the kernel built with phase timers (one kernel thread only; for
    ``benchmarks/profile.py``). Read them with :func:`profile_counters`."""
    if on:
        ok, why = _register(True)
        if not ok:
            raise RuntimeError(f"the profiling build of the native kernel failed: {why}")
    _PROFILE["on"] = on


def profile_counters(reset: bool = True) -> dict:
    """Seconds per kernel phase and event counts since the last reset (:data:`PROFILE_PHASES`,
    :data:`PROFILE_COUNTERS`)."""
    lib = _LIBS.get(True)
    if lib is None:
        raise RuntimeError("enable_profiling() first")
    buf = (ctypes.c_int64 * (len(PROFILE_PHASES) + len(PROFILE_COUNTERS)))()
    lib.JaxarmProfileRead(buf)
    if reset:
        lib.JaxarmProfileReset()
    values = list(buf)
    return {**{p: values[k] * 1e-9 for k, p in enumerate(PROFILE_PHASES)},
            **{c: values[len(PROFILE_PHASES) + k] for k, c in enumerate(PROFILE_COUNTERS)}}


def available() -> bool:
    """Whether the native kernel can be used here (CPU backend, library built and registered)."""
    return jax.default_backend() == "cpu" and _register()[0]


def status() -> str:
    """Why the native kernel is or is not available (for error messages and benchmarks)."""
    if jax.default_backend() != "cpu":
        return f"JAX backend is {jax.default_backend()!r}; the native kernel is CPU-only"
    return _register()[1]


#: Input -> output aliases: the state is updated in place (no copy of the ring per chunk).
ALIASES = {0: 0, 1: 1, 2: 2, 3: 3, 4: 4, 5: 5, 6: 6, 7: 7, 8: 8, 13: 9, 15: 10, 16: 11, 17: 12, 18: 13, 30: 14}


def _as(x, dtype):
    return jnp.asarray(x).astype(dtype)


def chunk(net: "Network", wiring: "Wiring", state: "State", params: "NetworkParams", n_steps: int):
    """``n_steps`` steps of one network (``vmap`` for many) with the native kernel. Returns (state, spikes
    (n_steps, n_all) bool). Same contract as the XLA path's chunk."""
    profile = _PROFILE["on"]
    ok, why = _register(profile)
    if not ok:
        raise RuntimeError(f"jaxarm native network kernel unavailable: {why}")
    c = net.config
    lay = net.layout
    ph = c.spec.physics
    ps = net.p_synapses
    s = state
    cells = s.cells
    groups = []
    for g in wiring.groups:
        groups += [_as(g.out_syn, jnp.int32), _as(g.out_packed, jnp.int32), _as(g.out_weight, jnp.float32),
                   _as(g.out_nmda, jnp.float32), _as(g.in_plastic, jnp.int32), _as(g.in_plastic_pre, jnp.int32)]
    args = [
        _as(s.step, jnp.int32), cells.ampa, cells.nmda, cells.gaba_prox, cells.gaba_dist, cells.ahp,
        cells.vthc_excess, _as(cells.steps_since_spike, jnp.int32), _as(s.p.next_step, jnp.int32),
        _as(s.p.interval_steps, jnp.int32), _as(s.noise.step_seed, jnp.uint32), _as(s.noise.lane_key, jnp.uint32),
        _as(s.noise.thresholds, jnp.uint32), s.ring, s.wgain, s.pdope_ms, s.last_spike_ms, s.prev_spike_ms,
        _as(s.spike_count, jnp.int32), _as(params.max_plast_t_ms, jnp.float32),
        _as(wiring.pre[ps] - c.n_cells, jnp.int32), _as(wiring.delay_steps[ps], jnp.int32),
        _as(wiring.target[ps], jnp.int32), _as(wiring.weight[ps], jnp.float32), _as(wiring.nmda[ps], jnp.float32),
        jnp.asarray(net.native_cell_floats), jnp.asarray(net.cell_constants.n_refractory, jnp.int32),
        jnp.asarray(net.noise_weights), jnp.asarray(net.native_cell_group), jnp.asarray(net.native_cell_row),
        _as(s.noise.events_left, jnp.int32), jnp.asarray(net.p_synapse_ids), *groups,
    ]
    n, n_all = c.n_cells, c.n_all
    f32, i32 = jnp.float32, jnp.int32
    sds = jax.ShapeDtypeStruct
    out_types = [sds((), i32)] + [sds((n,), f32)] * 6 + [sds((n,), i32), sds((c.n_generators,), i32), sds(s.ring.shape, f32),
                                                      sds(s.pdope_ms.shape, f32), sds((n_all,), f32),
                                                      sds((n_all,), f32), sds((n_all,), i32),
                                                      sds((3, n), i32), sds((n_steps, n_all), jnp.bool_)]
    call = jax.ffi.ffi_call(TARGET + ("_profile" if profile else ""), out_types, vmap_method="expand_dims", input_output_aliases=ALIASES)
    outs = call(*args, n_steps=np.int64(n_steps), n_slots=np.int64(net.n_slots),
                sequential=np.int64(c.event_summation == "sequential"),
                on_event=np.int64(c.threshold_test == "on_event"), per_event=np.int64(c.crossing == "per_event"),
                random_order=np.int64(c.same_step_inhibition == "random_order"),
                dt_ms=np.float32(c.dt_ms), excitatory=np.asarray(lay.group_is_excitatory, np.int64),
                n_threads=np.int64(c.native_threads), delay_bits=np.int64(DELAY_BITS),
                **{name: np.float32(getattr(ph, name)) for name in PHYSICS_ATTRIBUTES})
    (step, ampa, nmda, gprox, gdist, ahp, excess, since, p_next, ring, pdope, last, prev, count, events_left,
     spikes) = outs
    cells = cells._replace(ampa=ampa, nmda=nmda, gaba_prox=gprox, gaba_dist=gdist, ahp=ahp, vthc_excess=excess,
                           steps_since_spike=since)
    state = s._replace(step=step, cells=cells, p=s.p._replace(next_step=p_next), ring=ring, pdope_ms=pdope,
                       last_spike_ms=last, prev_spike_ms=prev, spike_count=count,
                       noise=s.noise._replace(events_left=events_left))
    return state, spikes
