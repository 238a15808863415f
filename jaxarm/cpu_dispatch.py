"""How XLA:CPU runs jaxarm's small programs: fewer thunks, and no idle threads beside the devices' own.

XLA:CPU runs a compiled program as a sequence of thunks (one per fusion, copy, loop iteration, custom call), each
with a fixed dispatch cost, and keeps a pool of threads for the work it spreads. A closed-loop interval of one
network is small, so both show:

* **Threefry unrolled.** JAX lowers its threefry hash (every ``jax.random`` draw: the interval's key splits and
  babbling draws) on CPU as a loop over its 5 rounds, and each iteration runs a dozen thunks (its copies and
  fusions), about 270 of a simple-arm interval's 316. Unrolled, as JAX lowers it on every other platform, the same
  integer operations in the same order fuse into a few thunks: the same numbers (``tests/test_cpu_dispatch.py``:
  Random123's known answers, and JAX's rolled lowering in a second process) and the same training bits.
  ``benchmarks/thunks.py`` counts an interval's thunks both ways. :func:`unroll_threefry` registers the unrolled
  lowering for CPU (``import jaxarm`` calls it): it changes how JAX compiles every threefry draw on CPU in this
  process, also outside jaxarm (the same numbers, fewer thunks, more operations to compile: JAX rolls the loop on
  CPU to keep compile times short; jaxarm's epochs compile no slower, ``benchmarks/train.py`` reports their compile
  times). ``JAXARM_ROLLED_THREEFRY=1`` keeps JAX's rolled loop.
* **One pool thread per device.** XLA:CPU's pool has a thread per core by default. jaxarm's programs have nothing
  to spread (each device runs its networks one at a time; the network kernel has threads of its own,
  ``NetworkConfig.native_threads``), and the pool's threads woke and spun on the other cores at every hand-off: one
  device on a 2-core machine ran the network alone 1.06-1.24x and the closed loop 1.3x as fast with a pool of one
  thread, on one core instead of 1.3 (``benchmarks/pool_threads.py``, ``docs/results/pool_threads.json``); with
  a device on every core both sizes are the same. :func:`pool_threads` sets the pool to one
  thread per device of this process (``import jaxarm``: one; :func:`jaxarm.parallel.start`: its device count)
  through ``PJRT_NPROC``, which XLA reads when its CPU backend starts; a ``PJRT_NPROC`` or ``NPROC`` of the user's
  own is kept.
"""
from __future__ import annotations

import os
import warnings
from functools import partial

#: Set this environment variable to 1 to keep JAX's rolled threefry loop on CPU.
KEEP_ROLLED_ENV = "JAXARM_ROLLED_THREEFRY"

_registered = False


def unroll_threefry() -> bool:
    """Lower ``threefry2x32`` on CPU as straight-line code (JAX's lowering for other platforms). Returns whether the
    unrolled lowering is now registered; ``False`` (with a warning) where this JAX has no such lowering to reuse, or
    when ``$JAXARM_ROLLED_THREEFRY`` is 1. Programs compiled before the call keep the rolled loop."""
    global _registered
    if _registered:
        return True
    if os.environ.get(KEEP_ROLLED_ENV) == "1":
        return False
    try:   # JAX's own lowering function, with its switch for the rolled loop (jax/_src/random/threefry2x32.py)
        from jax._src.random import threefry2x32 as threefry
        from jax.interpreters import mlir

        lowering = threefry._threefry2x32_lowering
        primitive = threefry.threefry2x32_p
    except (ImportError, AttributeError) as err:
        warnings.warn(f"jaxarm: this JAX has no threefry lowering to unroll ({err}); random draws keep JAX's rolled "
                      "loop on CPU (the same numbers, slower)", stacklevel=2)
        return False
    mlir.register_lowering(primitive, mlir.lower_fun(partial(lowering, use_rolled_loops=False),
                                                     multiple_results=True), platform="cpu")
    _registered = True
    return True


#: The environment variables XLA:CPU sizes its thread pool from (the first one set wins).
POOL_ENV = ("PJRT_NPROC", "NPROC")
#: The value jaxarm wrote into ``PJRT_NPROC``, so that a process started from this one (which inherits both) can
#: tell jaxarm's size from the user's own and set its own device count.
POOL_SET_BY_JAXARM_ENV = "JAXARM_SET_PJRT_NPROC"


def _pool_set_by_jaxarm() -> bool:
    """Whether the pool size in the environment is jaxarm's (this process's or a parent's), not the user's: jaxarm's
    marker equals ``PJRT_NPROC`` (a user's ``NPROC`` alone, or a changed ``PJRT_NPROC``, leaves them apart)."""
    marker = os.environ.get(POOL_SET_BY_JAXARM_ENV)
    return marker is not None and marker == os.environ.get(POOL_ENV[0])


def pool_threads(threads: int) -> bool:
    """Size XLA:CPU's thread pool to ``threads`` (one per device of this process) unless the user set
    ``PJRT_NPROC`` or ``NPROC``. Read when JAX's CPU backend starts: a later call changes nothing. Returns whether
    jaxarm sets the size. A size that jaxarm set (here or in the process that started this one: both variables are
    inherited) is not the user's and is set again."""
    if threads < 1:
        raise ValueError(f"pool_threads: threads = {threads}: must be >= 1")
    if any(name in os.environ for name in POOL_ENV) and not _pool_set_by_jaxarm():
        return False
    os.environ[POOL_ENV[0]] = os.environ[POOL_SET_BY_JAXARM_ENV] = str(threads)
    return True
