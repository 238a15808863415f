"""Same seed, same result, in two fresh processes with different thread counts (not a jitted call against itself).

Each process runs a small script: both arms under fixed excitations and a short closed-loop training and test of
two networks on each arm, and prints SHA-256 digests of the raw bytes. The second process splits the native
kernel's batch over 2 threads and lets XLA use its default thread pool, the first runs single-threaded.
"""
import json
import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import hashlib, json
    import jax, jax.numpy as jnp, numpy as np
    from jaxarm import make_arm
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.network import NetworkConfig
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    def digest(tree):
        h = hashlib.sha256()
        for leaf in jax.tree.leaves(tree):
            h.update(np.asarray(leaf).tobytes())
        return h.hexdigest()

    out = {}
    us = jax.random.uniform(jax.random.PRNGKey(0), (300, 4))
    for kind in ("simple", "musculoskeletal"):
        arm = make_arm(kind)
        def body(s, u, arm=arm):
            s = arm.step(s, u)
            return s, arm.observe(s).q
        out[kind + "_arm"] = digest(jax.jit(lambda us: jax.lax.scan(body, arm.init(), us)[1])(us))
        cfg = LoopConfig(arm=kind, network=NetworkConfig(),
                         task=TaskConfig(epochs=2, epoch_duration_s=0.3, test_duration_s=0.2))
        fns = make_train(cfg)
        keys = jnp.stack([jax.random.PRNGKey(i) for i in range(2)])
        mp = MetaParams.original()
        trained, history = jax.jit(jax.vmap(fns.train, in_axes=(0, None)))(keys, mp)
        result = jax.jit(jax.vmap(fns.test, in_axes=(0, 0, None)))(keys, trained, mp)
        out[kind + "_training"] = digest((trained.wgain, history, result))
        out[kind + "_kernel_threads"] = cfg.network.native_threads
    print(json.dumps(out))
""")


def run(threads: int, xla_single_thread: bool) -> dict:
    env = dict(os.environ, JAXARM_NATIVE_THREADS=str(threads))
    if xla_single_thread:
        env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " --xla_cpu_multi_thread_eigen=false").strip()
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_two_fresh_processes_with_different_thread_counts_agree_bit_for_bit():
    one, two = run(1, True), run(2, False)
    assert (one.pop("simple_kernel_threads"), two.pop("simple_kernel_threads")) == (1, 2)
    assert (one.pop("musculoskeletal_kernel_threads"), two.pop("musculoskeletal_kernel_threads")) == (1, 2)
    assert one == two
