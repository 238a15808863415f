"""XLA:CPU without fused multiply-add, so that a network's bits do not depend on its place in its group.

XLA:CPU lets LLVM fuse ``a * b + c`` into one FMA instruction (one rounding instead of two) wherever its code
generator sees fit, and the code it generates for a group of networks is not the same for every row: in the
closed loop's P-cell window test the first network's ``x = (q - q_min) / (q_max - q_min)`` was hoisted out of the
unrolled rows and rounded on its own, so its ``1 - x`` took two roundings where the other seven networks' took one
(``vfnmadd``). At a joint limit the muscle length then sits on a window edge, one P cell fired in some networks of
a group and not in others, and a network's training drifted with its place in the group (found with eight copies
of one network in one group: ``experiments/group_place.py --compare copies``). Without FMA every multiply and add
rounds on its own, whatever code LLVM generates, so the rows of a group compute the same numbers.

:func:`pin` caps XLA:CPU's instruction set at AVX (``--xla_cpu_max_isa=AVX``: no FMA, no AVX2 or AVX-512 in XLA's
code; the native network kernel is compiled apart and keeps them). It must run before JAX starts its CPU backend;
``import jaxarm`` calls it. Measured cost on the closed loop: none beyond noise (``docs/scaling.md``).
"""
from __future__ import annotations

import os
import warnings

#: The flag :func:`pin` adds to ``XLA_FLAGS``.
NO_FMA_FLAG = "--xla_cpu_max_isa=AVX"
#: Set this environment variable to 1 to keep XLA's FMA (a network's bits may then depend on its place).
KEEP_FMA_ENV = "JAXARM_XLA_FMA"


def pin() -> bool:
    """Add :data:`NO_FMA_FLAG` to ``XLA_FLAGS`` unless ``XLA_FLAGS`` already sets ``xla_cpu_max_isa`` or
    ``$JAXARM_XLA_FMA`` is 1. Returns whether XLA:CPU will run without FMA. Warns (once per process) when JAX's
    backend started before this call, too late for the flag."""
    flags = os.environ.get("XLA_FLAGS", "")
    if os.environ.get(KEEP_FMA_ENV) == "1":
        return False
    if "xla_cpu_max_isa" in flags:
        return NO_FMA_FLAG in flags.split()
    from jax._src import xla_bridge

    if xla_bridge.backends_are_initialized():
        warnings.warn("jaxarm: JAX computed before jaxarm was imported, so XLA:CPU keeps fused multiply-add and a "
                      "network's bits may depend on its place in its batch; import jaxarm first (or set "
                      f"XLA_FLAGS={NO_FMA_FLAG})", stacklevel=3)
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {NO_FMA_FLAG}".strip()
    return True
