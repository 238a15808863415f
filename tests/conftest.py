"""Helpers shared by the tests, and the test process's devices.

The whole suite runs on two CPU devices (as `jaxarm` commands do on a 2-core machine): every batch command splits
its networks over both, and tests can compare a one-device mesh with the two-device one in one process.

`make test` and `make test-slow` spread the test files over worker processes (pytest-xdist, one per CPU, at most four;
a file's tests stay in one worker, so a module's fixtures are built once); each worker is such a process.

Every test, and every process a test or a worker starts, shares one persistent XLA compilation cache
(``.pytest_cache/jax-xla`` in the checkout, git-ignored; ``pytest --cache-clear`` empties it): about half of the
suite's time is compiling, and the slow suite, the CLI processes and the notebooks compile many of the programs the
default suite already did. A cached program is the same executable, so no result changes. Set
``JAX_COMPILATION_CACHE_DIR`` to use another folder.
"""
from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("JAX_COMPILATION_CACHE_DIR",
                      str(Path(__file__).resolve().parents[1] / ".pytest_cache" / "jax-xla"))
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")

import jax  # noqa: E402  (reads the cache settings above when imported)

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
