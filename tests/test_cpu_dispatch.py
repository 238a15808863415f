"""jaxarm.cpu_dispatch: JAX's threefry hash lowered as straight-line code on CPU gives the same numbers, in fewer
XLA:CPU thunks; XLA's CPU pool has one thread per device.

References: the Random123 known-answer vectors of threefry2x32 (20 rounds), and JAX's own rolled lowering in a
second process (``JAXARM_ROLLED_THREEFRY=1``), whose compiled program is the positive control (it has the loop);
the pool's threads counted by name in fresh processes.
"""
import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxarm  # noqa: F401  (registers the unrolled lowering)
from jaxarm import cpu_dispatch
from jaxarm.cpu_arithmetic import ordered_dot

#: Random123's known-answer tests for threefry2x32_20: (key, counter) -> output, as uint32 pairs.
KNOWN_ANSWERS = [
    ((0x00000000, 0x00000000), (0x00000000, 0x00000000), (0x6B200159, 0x99BA4EFE)),
    ((0xFFFFFFFF, 0xFFFFFFFF), (0xFFFFFFFF, 0xFFFFFFFF), (0x1CB996FC, 0xBB002BE7)),
    ((0x13198A2E, 0x03707344), (0x243F6A88, 0x85A308D3), (0xC4923A9C, 0x483DF7A0)),
]

# The draws compared across the two lowerings: a network's interval uses splits, uniforms and normals, under jit
# and under vmap.
DRAWS = """
import json, sys
import jax, jax.numpy as jnp
import jaxarm
keys = jax.random.split(jax.random.PRNGKey(7), 5)
def draws(k):
    a, b = jax.random.split(k)
    return (jax.random.key_data(jax.random.split(a, 3)), jax.random.uniform(b, (4,)), jax.random.normal(a, (3,)),
            jax.random.randint(b, (2,), 0, 1000))
f = jax.jit(jax.vmap(draws))
out = [x.tolist() for x in jax.tree.leaves(f(keys))]
hlo = f.lower(keys).compile().as_text()
print(json.dumps({"draws": out, "while_loops": hlo.count(" while(")}))
"""


def _draws(env_extra):
    env = dict(os.environ, **env_extra)
    run = subprocess.run([sys.executable, "-c", DRAWS], capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_threefry_matches_random123_known_answers():
    assert cpu_dispatch.unroll_threefry()
    from jax.extend.random import threefry_2x32

    for key, counter, expect in KNOWN_ANSWERS:
        out = jax.jit(threefry_2x32)(jnp.asarray(key, jnp.uint32), jnp.asarray(counter, jnp.uint32))
        assert [int(x) for x in out] == list(expect)


def test_unrolled_draws_equal_jaxs_rolled_loop_and_compile_without_it():
    unrolled = _draws({cpu_dispatch.KEEP_ROLLED_ENV: "0"})
    rolled = _draws({cpu_dispatch.KEEP_ROLLED_ENV: "1"})
    assert rolled["while_loops"] > 0        # positive control: JAX's CPU lowering loops over the rounds
    assert unrolled["while_loops"] == 0
    assert unrolled["draws"] == rolled["draws"]


def test_ordered_dot_takes_its_columns_as_a_list():
    """The arm's geometry passes its monomials one by one: bit-equal to the stacked array."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(7, 19)).astype(np.float32)
    y = rng.normal(size=(19, 66)).astype(np.float32)
    stacked = np.asarray(jax.jit(ordered_dot)(x, y))
    columns = np.asarray(jax.jit(lambda x, y: ordered_dot([x[:, k] for k in range(19)], y))(x, y))
    np.testing.assert_array_equal(columns, stacked)


POOL = """
import collections, os, sys
import jaxarm
from jaxarm import parallel
if sys.argv[1] != "import":
    parallel.start(devices=int(sys.argv[1]))
import jax.numpy as jnp
jnp.zeros(3).block_until_ready()
names = [open(f"/proc/self/task/{t}/comm").read().strip() for t in os.listdir("/proc/self/task")]
print(collections.Counter(names)["tf_XLAEigen"])
"""


def _pool_threads(how: str, **env_extra) -> int:
    ours = (*cpu_dispatch.POOL_ENV, cpu_dispatch.POOL_SET_BY_JAXARM_ENV)
    env = {k: v for k, v in os.environ.items() if k not in ours} | env_extra
    run = subprocess.run([sys.executable, "-c", POOL, how], capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    return int(run.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts XLA's pool threads by name in /proc (Linux)")
def test_xla_pool_has_one_thread_per_device_unless_the_user_sized_it():
    """XLA names its CPU pool's threads tf_XLAEigen; by default it starts one per core (positive control: the
    user's PJRT_NPROC=3 gives 3 on any machine)."""
    assert _pool_threads("import") == 1
    assert _pool_threads("2") == 2
    assert _pool_threads("2", PJRT_NPROC="3") == 3
    assert _pool_threads("import", NPROC="3") == 3
    # started from a process that imported jaxarm (it inherits jaxarm's size and its marker): its own device count
    assert _pool_threads("2", PJRT_NPROC="1", JAXARM_SET_PJRT_NPROC="1") == 2
    # the user changed the inherited size: theirs
    assert _pool_threads("2", PJRT_NPROC="3", JAXARM_SET_PJRT_NPROC="1") == 3


def test_pool_threads_rejects_a_size_below_one():
    with pytest.raises(ValueError, match="threads = 0: must be >= 1"):
        cpu_dispatch.pool_threads(0)
