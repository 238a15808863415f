"""Fewer XLA:CPU thunks per 10 ms interval: JAX's threefry hash as straight-line code.

XLA:CPU runs a compiled program as a sequence of thunks (one per fusion, copy, loop iteration, custom call), each
with a fixed dispatch cost. A closed-loop interval of one network is small, so that cost shows: JAX lowers its
threefry hash (every ``jax.random`` draw: the interval's key splits and babbling draws) on CPU as a loop over its 5
rounds, and each iteration runs a dozen thunks (its copies and fusions), about 270 of a simple-arm interval's 316.
Unrolled, as JAX lowers it on every other platform, the same integer operations in the same order fuse into a few
thunks: the same numbers (``tests/test_cpu_dispatch.py``: Random123's known answers, and JAX's rolled lowering in
a second process) and the same training bits. ``benchmarks/thunks.py`` counts an interval's thunks both ways.

:func:`unroll_threefry` registers the unrolled lowering for CPU (``import jaxarm`` calls it). It changes how JAX
compiles every threefry draw on CPU in this process, also outside jaxarm: the same numbers, fewer thunks, more
operations to compile (JAX rolls the loop on CPU to keep compile times short; jaxarm's epochs compile no slower,
``benchmarks/train.py`` reports their compile times). ``JAXARM_ROLLED_THREEFRY=1`` keeps JAX's rolled loop.
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
