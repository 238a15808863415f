"""A network's bits do not depend on its place in its group of 8 (jaxarm.cpu_arithmetic).

One group holds eight copies of one network (key 0, the authors' metaparameters, simple arm, left target) and
trains 4 epochs of 30 s: every copy must end with the same bits. With XLA's fused multiply-add kept
(``JAXARM_XLA_FMA=1``) the copy at place 0 drifts in the fourth epoch (a P cell on a window edge at the shoulder's
limit fires in it and not in the others), so the same run with FMA is the positive control: it shows the test can
see the fault it guards against. Each run is a fresh process, as XLA reads its flags when its backend starts.
"""
import json
import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import json, tempfile
    import jax, numpy as np
    from jaxarm import parallel
    parallel.start(devices=1, networks_at_once=8)   # one group of 8 (the default is one network at a time)
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.run import Batch, stack_rows
    from jaxarm.task.config import Target, TaskConfig

    config = LoopConfig(arm="simple", task=TaskConfig(target="left", epochs=4, epoch_duration_s=30.0,
                                                      test_duration_s=0.2))
    seeds = [0] * 8
    with tempfile.TemporaryDirectory() as d:
        batch = Batch(config, seeds, stack_rows([MetaParams.original()] * 8), Target.stack([config.task.target] * 8),
                      d, {"seeds": seeds})
        carry, history = batch.train(progress=False)[:2]
    # history is (epochs, networks, ...), the carry (networks, ...)
    rows = lambda x, axis: [np.take(x, r, axis=axis) for r in range(8)]
    carry_leaves = [np.asarray(x) for x in jax.tree.leaves(parallel.host(carry))]
    history_leaves = [np.asarray(x) for x in jax.tree.leaves(history)]
    differ = sorted({r for x in carry_leaves for r, row in enumerate(rows(x, 0)) if np.any(row != x[1])}
                    | {r for x in history_leaves for r, row in enumerate(rows(x, 1)) if np.any(row != x[:, 1])})
    print(json.dumps({"differ": differ, "flags": __import__("os").environ.get("XLA_FLAGS", "")}))
""")


def copies_that_differ(keep_fma: bool) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAXARM_XLA_FMA")}
    if keep_fma:
        env["JAXARM_XLA_FMA"] = "1"
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=1200)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_eight_copies_of_one_network_in_one_group_train_to_the_same_bits():
    pinned = copies_that_differ(keep_fma=False)
    assert "--xla_cpu_max_isa=AVX" in pinned["flags"]
    assert pinned["differ"] == []
    with_fma = copies_that_differ(keep_fma=True)   # positive control: the fault this guards against
    assert "xla_cpu_max_isa" not in with_fma["flags"]
    assert with_fma["differ"] != []
