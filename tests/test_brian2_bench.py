"""The Brian2 C++-standalone port of the network (benchmarks/brian2_network.py), used by benchmarks/network.py.

The drive and noise helpers are checked against jaxarm without brian2; the build-and-run test needs the ``bench``
extra (``pip install -e '.[bench]'``) and a C++ compiler, and is skipped without brian2 (the default install,
``.[test]``, has none). Building the C++ project takes 20-40 s, so it is marked slow:
``pytest -m slow tests/test_brian2_bench.py``.
"""
import importlib.util
import math
import os
import sys

import jax.numpy as jnp
import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks"))
import brian2_network as B  # noqa: E402

from jaxarm.network import NetworkConfig  # noqa: E402
from jaxarm.network import proprio as P  # noqa: E402

LENGTHS_M = (0.1059, 0.1541, 0.1552, 0.1048)  # the simple arm's start posture


def test_p_drive_is_jaxarm_p_generators():
    """The Brian2 spike list equals jaxarm's P generators with the lengths set at the first 10 ms update."""
    config = NetworkConfig()
    n_steps = config.steps(100.0)
    p = P.init_p(config)
    got = []
    for m in range(1, n_steps + 1):
        p, s = P.p_step(p, m)
        got += [(int(i), m) for i in np.flatnonzero(np.asarray(s))]
        if m == config.steps_per_interface:
            p = P.set_lengths(config, p, jnp.asarray(LENGTHS_M), m)
    idx, steps = B.p_spike_train(config, LENGTHS_M, n_steps)
    assert sorted(zip(idx.tolist(), steps.tolist())) == sorted(got)
    assert len(set(idx[steps > config.steps(1.0)].tolist())) == 12   # 3 cells per muscle code the start posture


def test_noise_inversion_is_poisson():
    for lam in (0.025, 0.05, 0.1):
        cdf = B.poisson_cdf(lam)
        assert 1.0 - cdf[-1] < 1e-12
        pmf = np.diff(np.concatenate([[0.0], cdf]))
        np.testing.assert_allclose(pmf, [math.exp(-lam) * lam ** k / math.factorial(k) for k in range(len(cdf))],
                                   rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("e_rev", [65.0, 15.0])
def test_sequential_loads_give_the_one_by_one_jumps(e_rev):
    """One event: the load's jump equals the linear jump w (1 - V/E); k events: the original's k successive jumps."""
    v, w = 7.0, np.array([0.5, 3.0, 9.0])
    load = B.accumulated(w, e_rev, sequential=True)
    np.testing.assert_allclose((e_rev - v) * -np.expm1(-load / e_rev), w * (1 - v / e_rev), rtol=1e-12)
    x = v
    for _ in range(5):                                  # five events of 3 mV, one after the other
        x += 3.0 * (1 - x / e_rev)
    five = 5 * B.accumulated(3.0, e_rev, sequential=True)
    np.testing.assert_allclose(v + (e_rev - v) * -np.expm1(-five / e_rev), x, rtol=1e-12)
    np.testing.assert_array_equal(B.accumulated(w, e_rev, sequential=False), w)


def test_missing_brian2_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "brian2", None)   # import brian2 now fails as if it were not installed
    with pytest.raises(ImportError, match=r"pip install -e '\.\[bench\]'"):
        B.require_brian2()


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("brian2") is None,
                    reason="brian2 not installed: it comes with the bench extra, pip install -e '.[bench]'")
def test_brian2_network_builds_runs_and_fires_like_jaxarm(tmp_path):
    out = B.run_brian2(seconds=0.5, repeats=1, seed=0, lengths_m=LENGTHS_M, directory=str(tmp_path / "b2"))
    assert out["build_s"] > 0 and out["network_s_per_s"] > 0 and math.isfinite(out["network_s_per_s"])
    assert out["n_synapses"] == 50664
    rates = out["rates_hz"]
    assert all(math.isfinite(r) and 0.0 <= r < 100.0 for r in rates.values()), rates
    jax_rates = B.jaxarm_fixed_drive_rates(seconds=0.5, seed=0, n_noise=2, lengths_m=LENGTHS_M)["rates_hz"]
    sizes = NetworkConfig().sizes
    mean = lambda r: sum(r[p] * n for p, n in zip(B.NETWORK_POPULATIONS, sizes)) / sum(sizes[:6])  # noqa: E731
    # the same network: mean rate within a broad band of jaxarm's under the same drive (a 0.5 s run is noisy)
    assert 0.7 < mean(rates) / mean(jax_rates) < 1.4, (rates, jax_rates)
    assert 1.0 < mean(rates) < 30.0
