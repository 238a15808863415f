"""Helpers shared by the tests, and the test process's devices.

The whole suite runs on two CPU devices (as `jaxarm` commands do on a 2-core machine): every batch command splits
its networks over both, and tests can compare a one-device mesh with the two-device one in one process.
"""
from __future__ import annotations

from pathlib import Path

import jax

jax.config.update("jax_num_cpu_devices", 2)


def truncate_newest_checkpoint(checkpoints: Path) -> Path:
    """Truncate the largest file of the newest step folder in ``checkpoints`` to half its size, as a full disk leaves
    a write. Returns the damaged step folder."""
    steps = sorted((p for p in Path(checkpoints).iterdir() if p.name.isdigit()), key=lambda p: int(p.name))
    newest = steps[-1]
    largest = max((f for f in newest.rglob("*") if f.is_file()), key=lambda f: f.stat().st_size)
    with open(largest, "r+b") as f:
        f.truncate(largest.stat().st_size // 2)
    return newest
