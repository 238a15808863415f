"""Tests of the compiled evolutionary search (jaxarm.evolve) on small sizes, with benchmark fitness functions."""
from __future__ import annotations

import dataclasses
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config.validate import ConfigError
from jaxarm.evolve import fitness as fit
from jaxarm.evolve.checkpoint import SearchCheckpointer
from jaxarm.evolve.cli import evolve_main
from jaxarm.evolve.runner import HISTORY_FILE, PLOT_FILE, REEVALUATION_FILE, TOP_K_FILE, run_search
from jaxarm.evolve.search import (RERANK_STREAM, STRATEGIES, EvolveConfig, make_reevaluate, make_search,
                                  rank_failures_last)
from jaxarm.evolve.space import SearchSpace
from jaxarm.learning.metaparams import BOUNDS, NAMES, ORIGINAL

KEY = jax.random.PRNGKey(0)
SMALL = SearchSpace.make(search=["learn_rate", "v_em_max", "rl_dt_ms", "explore_tot"])
#: A strategy that compiles fast (CMA-ES's own update takes most of its compile time), for tests of the loop itself.
CHEAP = "HillClimbing"


def leaves_equal(a, b) -> bool:
    la, lb = jax.tree.leaves(a), jax.tree.leaves(b)
    return len(la) == len(lb) and all(
        np.asarray(x).dtype == np.asarray(y).dtype and np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True)
        for x, y in zip(la, lb))


# --------------------------------------------------------------------------------------------- space
def test_space_maps_unit_cube_to_bounds_and_back():
    space = SearchSpace()
    assert space.names == NAMES and space.n_dims == len(NAMES)
    u = jax.random.uniform(KEY, (64, space.n_dims), minval=-1.0, maxval=2.0)   # most entries outside the cube
    mp = space.to_metaparams(u)
    for name in NAMES:
        v = np.asarray(getattr(mp, name))
        assert v.shape == (64,)
        assert np.all(v >= np.float32(BOUNDS[name].lo)) and np.all(v <= np.float32(BOUNDS[name].hi)), name
    inside = jax.random.uniform(KEY, (64, space.n_dims))
    np.testing.assert_allclose(space.to_unit(space.to_metaparams(inside)), inside, atol=2e-5)
    # the start point is the published model
    start = space.to_metaparams(space.start_unit())
    for name in NAMES:
        assert float(getattr(start, name)) == pytest.approx(ORIGINAL[name], rel=1e-5), name
    # log scale: the middle of the cube is the geometric mean of the range
    b = BOUNDS["learn_rate"]
    mid = SearchSpace.make(search=["learn_rate"]).to_metaparams(jnp.array([0.5]))
    assert float(mid.learn_rate) == pytest.approx(math.sqrt(b.lo * b.hi), rel=1e-5)


def test_space_frozen_fields_and_overrides():
    space = SearchSpace.make(freeze={"learn_rate": 0.05, "explore_tot": 3.0}, bounds={"v_em_max": (50.0, 200.0, "linear")},
                             start={"rl_dt_ms": 100.0})
    assert "learn_rate" not in space.names and "explore_tot" not in space.names and space.n_dims == len(NAMES) - 2
    mp = space.to_metaparams(jnp.zeros((5, space.n_dims)))
    assert np.all(np.asarray(mp.learn_rate) == np.float32(0.05)) and np.all(np.asarray(mp.explore_tot) == 3.0)
    assert np.all(np.asarray(mp.v_em_max) == 50.0)
    assert float(space.to_metaparams(space.start_unit()).rl_dt_ms) == pytest.approx(100.0, rel=1e-6)
    only = SearchSpace.make(search=["learn_rate"])
    assert only.names == ("learn_rate",) and dict(only.frozen)["explore_tot"] == ORIGINAL["explore_tot"]
    assert hash(space) == hash(SearchSpace.make(freeze={"explore_tot": 3.0, "learn_rate": 0.05},
                                                bounds={"v_em_max": (50.0, 200.0, "linear")},
                                                start={"rl_dt_ms": 100.0}))


@pytest.mark.parametrize("kwargs, names", [
    (dict(freeze=["learning_rate"]), "learning_rate"),
    (dict(freeze={"learn_rate": float("nan")}), "learn_rate"),
    (dict(bounds={"v_em_max": (10.0, 5.0, "linear")}), "v_em_max"),
    (dict(bounds={"v_em_max": (0.0, 5.0, "log")}), "v_em_max"),
    (dict(bounds={"v_em_max": (1.0, 5.0, "cubic")}), "cubic"),
    (dict(bounds={"v_em_max": (1.0, 5.0, "linear")}), "v_em_max"),        # excludes the published start 117.92
    (dict(start={"rl_dt_ms": 1000.0}), "rl_dt_ms"),
    (dict(freeze=["explore_tot"], start={"explore_tot": 3.0}), "explore_tot"),
    (dict(search=["explore_tot"], freeze=["explore_tot"]), "explore_tot"),
    (dict(freeze=list(NAMES)), "frozen"),
])
def test_space_errors_name_the_field(kwargs, names):
    with pytest.raises(ConfigError, match=names):
        SearchSpace.make(**kwargs)


@pytest.mark.parametrize("kwargs, field", [
    (dict(strategy="CMAES"), "EvolveConfig.strategy"),
    (dict(population_size=1), "EvolveConfig.population_size"),
    (dict(generations=0), "EvolveConfig.generations"),
    (dict(chunk_size=2.5), "EvolveConfig.chunk_size"),
    (dict(seeds_per_candidate=0), "EvolveConfig.seeds_per_candidate"),
    (dict(sigma_init=-0.1), "EvolveConfig.sigma_init"),
    (dict(seed_mode="shared"), "EvolveConfig.seed_mode"),
    (dict(population_size=8, eval_batch_size=9), "EvolveConfig.eval_batch_size"),
    (dict(strategy="SimpleGA", strategy_params={"mutation_rate": 0.1}), "mutation_rate"),
    (dict(strategy="Open_ES", population_size=7), "EvolveConfig.population_size"),   # evosax needs an even one
])
def test_config_errors_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        EvolveConfig(**kwargs)


def test_rank_failures_last():
    f = jnp.array([1.0, jnp.nan, 3.0, jnp.inf, -jnp.inf, 2.0])
    told = np.asarray(rank_failures_last(f))
    assert np.all(np.isfinite(told))
    assert np.all(told[[1, 3, 4]] > 3.0) and np.array_equal(told[[0, 2, 5]], [1.0, 3.0, 2.0])
    assert np.all(np.asarray(rank_failures_last(jnp.full(4, jnp.nan))) == 0.0)


# --------------------------------------------------------------------------------------------- the compiled loop
def test_loop_compiles_once_and_counts_traces():
    traces = []

    def counting(key, mp):
        traces.append(1)   # runs at trace time only
        return fit.make_quadratic(0.01)(key, mp)

    search = make_search(counting, SMALL, EvolveConfig(strategy=CHEAP, population_size=6, generations=7,
                                                       chunk_size=3))
    state = search.init(KEY)
    state = search.run_chunk(state)
    after_first = len(traces)
    for _ in range(3):   # the last two chunks run past `generations`: nothing more runs
        state = search.run_chunk(state)
    assert len(traces) == after_first
    assert [f._cache_size() for f in (search.ask, search.evaluate, search.tell)] == [1, 1, 1]
    assert int(state.generation) == 7
    h = state.history
    assert np.all(np.isfinite(np.asarray(h.best))) and np.all(np.asarray(h.nonfinite_evals) == 0)
    # best so far is the running minimum of the generation bests
    np.testing.assert_array_equal(h.best_so_far, np.minimum.accumulate(np.asarray(h.best)))
    assert float(state.archive.fitness[0]) == float(np.min(h.best))


@pytest.mark.parametrize("strategy", ["CMA_ES", pytest.param("SimpleGA", marks=pytest.mark.slow)])  # GA: slow suite (8-min budget)
def test_candidates_respect_bounds(strategy):
    """A huge initial width makes the strategy propose points far outside the cube; every evaluated metaparameter
    set must still be inside BOUNDS (the fitness reports how many fields were outside)."""

    def out_of_bounds(key, mp):
        n = sum(((getattr(mp, k) < BOUNDS[k].lo) | (getattr(mp, k) > BOUNDS[k].hi)).astype(jnp.float32)
                for k in NAMES)
        return fit.make_quadratic(0.0)(key, mp)[0], {"outside": n}

    config = EvolveConfig(strategy=strategy, population_size=8, generations=4, chunk_size=4, sigma_init=5.0)
    search = make_search(out_of_bounds, SearchSpace(), config)
    state = search.run_chunk(search.init(KEY))
    assert np.all(np.asarray(state.history.metrics_mean["outside"]) == 0.0)
    assert np.all(np.asarray(state.history.metrics_best["outside"]) == 0.0)
    unit = np.asarray(state.archive.unit)
    assert np.all((unit >= 0.0) & (unit <= 1.0))


def test_frozen_fields_stay_at_their_values():
    space = SearchSpace.make(freeze={"learn_rate": 0.05, "explore_tot": 3.0, "v_em_max": 117.92})

    def report(key, mp):
        return fit.make_quadratic(0.01)(key, mp)[0], {"learn_rate": mp.learn_rate, "explore_tot": mp.explore_tot,
                                                       "v_em_max": mp.v_em_max}

    search = make_search(report, space, EvolveConfig(strategy=CHEAP, population_size=6, generations=3,
                                                     chunk_size=3, sigma_init=2.0))
    state = search.run_chunk(search.init(KEY))
    for name, value in (("learn_rate", 0.05), ("explore_tot", 3.0), ("v_em_max", 117.92)):
        for table in (state.history.metrics_best, state.archive.metrics):   # per candidate: exact
            v = np.asarray(table[name])
            assert np.all(v[np.isfinite(v)] == np.float32(value)), name
        np.testing.assert_allclose(state.history.metrics_mean[name], value, rtol=1e-6)   # a float32 mean


@pytest.mark.parametrize("strategy", ["CMA_ES", pytest.param("SimpleGA", marks=pytest.mark.slow)])  # GA: slow suite (8-min budget)
def test_nan_fitness_is_ranked_worst_counted_and_reported(strategy, tmp_path):
    """The 'quadratic-diverging' benchmark is NaN where learn_rate's unit coordinate > 0.6; a fitness that is also
    -inf/+inf on other seeds is a failure too. Failures never enter the archive, are counted per generation, and
    the search goes on."""
    space = SearchSpace.make(search=["learn_rate", "v_em_max"])
    i_lr = space.names.index("learn_rate")
    base = fit.make_quadratic(0.01, diverge_above=0.6)

    def diverging(key, mp):
        f, m = base(key, mp)
        u = (jnp.log(mp.learn_rate) - math.log(BOUNDS["learn_rate"].lo)) / \
            (math.log(BOUNDS["learn_rate"].hi) - math.log(BOUNDS["learn_rate"].lo))
        return f, {**m, "diverged": (u > 0.6).astype(jnp.float32)}

    config = EvolveConfig(strategy=strategy, population_size=12, generations=6, chunk_size=3, sigma_init=0.5,
                          seeds_per_candidate=2, top_k=50)
    lines = []
    result = run_search(diverging, space, config, tmp_path, log=lines.append)
    h = jax.device_get(result.state.history)
    failed = np.asarray(h.nonfinite_candidates)
    assert failed.sum() > 0 and np.all(failed <= config.population_size)
    # every failed candidate failed on both seeds; the reported diverged fraction matches the count
    np.testing.assert_array_equal(h.nonfinite_evals, 2 * failed)
    np.testing.assert_allclose(h.metrics_mean["diverged"] * config.population_size, failed, atol=1e-4)
    assert np.all(np.isfinite(h.best)) and np.all(np.isfinite(h.median))
    arc = jax.device_get(result.state.archive)
    kept = np.isfinite(arc.fitness)
    assert np.all(arc.unit[kept, i_lr] <= 0.6) and np.all(arc.metrics["diverged"][kept] == 0.0)
    assert kept.sum() == min(config.top_k, config.generations * config.population_size - failed.sum())
    # reported: progress lines and history.json
    assert any(f"(total {failed.sum()})" in line for line in lines)
    saved = json.loads((tmp_path / HISTORY_FILE).read_text())
    assert sum(saved["history"]["nonfinite_candidates"]) == failed.sum()


def test_all_failed_generation_does_not_crash():
    search = make_search(lambda key, mp: jnp.float32(jnp.nan), SMALL,
                         EvolveConfig(strategy=CHEAP, population_size=4, generations=2, chunk_size=2,
                                      seeds_per_candidate=3))
    state = search.run_chunk(search.init(KEY))
    assert np.all(np.asarray(state.history.nonfinite_candidates) == 4)
    assert np.all(np.asarray(state.history.nonfinite_evals) == 12)
    assert np.all(np.isnan(np.asarray(state.history.best))) and np.all(np.isinf(np.asarray(state.archive.fitness)))
    assert np.all(np.isfinite(np.asarray(state.strategy.mean)))


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_common_and_independent_seeds():
    """Common seeds give every candidate of a generation the same keys (pure-noise fitness: all equal)."""

    def noise(key, mp):
        return jax.random.normal(key, ())

    def spread(mode):
        s = make_search(noise, SMALL, EvolveConfig(strategy=CHEAP, population_size=6, generations=2, chunk_size=2,
                                                   seed_mode=mode))
        h = s.run_chunk(s.init(KEY)).history
        return np.asarray(h.median) - np.asarray(h.best)

    assert np.all(spread("common") == 0.0)
    assert np.all(spread("independent") > 0.0)
    s = make_search(noise, SMALL, EvolveConfig(strategy=CHEAP, population_size=6, generations=3, chunk_size=3,
                                               seed_mode="fixed"))
    h = s.run_chunk(s.init(KEY)).history
    assert np.all(np.asarray(h.median) == np.asarray(h.best)) and len(set(np.asarray(h.best).tolist())) == 1


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_batched_evaluation_equals_one_vmap():
    """eval_batch_size runs the population in sequential batches (less memory) with the same result."""
    fitness = fit.make_quadratic(0.01)
    states = []
    for batch in (0, 3):   # 3 does not divide the population of 8: a remainder batch
        s = make_search(fitness, SMALL, EvolveConfig(strategy=CHEAP, population_size=8, generations=2, chunk_size=2,
                                                     seeds_per_candidate=2, seed_mode="independent",
                                                     eval_batch_size=batch))
        states.append(s.run_chunk(s.init(KEY)))
    a, b = states
    np.testing.assert_allclose(a.archive.fitness, b.archive.fitness, rtol=1e-6)
    np.testing.assert_array_equal(a.archive.unit, b.archive.unit)


def test_reevaluation_ranks_the_top_k_again(tmp_path):
    """The quadratic's noise is shared by all candidates evaluated with the same key, so re-evaluating the top-k with
    common fresh seeds ranks them by their noiseless value: the first row is the closest to the optimum."""
    config = EvolveConfig(strategy=CHEAP, population_size=8, generations=6, chunk_size=6, top_k=10)
    result = run_search(fit.make_quadratic(0.05), SMALL, config, tmp_path, reevaluate_seeds=3, log=lambda _: None)
    top = json.loads((tmp_path / TOP_K_FILE).read_text())
    rows = top["top_k"]
    assert top["reevaluated"] and len(rows) == 10 and [r["rank"] for r in rows] == list(range(1, 11))
    assert sorted(r["search_rank"] for r in rows) == list(range(1, 11))
    again = [r["reevaluation"]["fitness"] for r in rows]
    assert again == sorted(again) and all(len(r["reevaluation"]["fitness_per_seed"]) == 3 for r in rows)
    distances = [r["metrics"]["distance"] for r in rows]
    assert distances[0] == min(distances)
    assert int(result.state.generation) == 6


def test_candidates_per_call_fill_whole_groups():
    from jaxarm import parallel
    from jaxarm.evolve.search import candidates_per_call

    group = parallel.networks_at_once()
    for seeds in (1, 3, 4, 16, 24):
        k = candidates_per_call(seeds)
        assert (k * seeds) % max(1, group) == 0                                   # whole groups ...
        assert all((j * seeds) % max(1, group) for j in range(1, k))             # ... with the fewest candidates


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_killed_reevaluation_resumes_where_it_stopped(tmp_path):
    """Re-evaluation saves each call's results: with the file cut back to 4 of 10 (a kill after the 4th), a rerun
    evaluates only the other 6 and writes the same top_k.json; the saved results equal one batched call over all
    candidates (to float32 rounding: the two compile separately), and a candidate's result is the same whatever
    else its call holds."""
    config = EvolveConfig(strategy=CHEAP, population_size=8, generations=3, chunk_size=3, top_k=10)
    fitness = fit.make_quadratic(0.05)
    result = run_search(fitness, SMALL, config, tmp_path, reevaluate_seeds=3, log=lambda _: None)
    first = json.loads((tmp_path / TOP_K_FILE).read_text())
    saved = json.loads((tmp_path / REEVALUATION_FILE).read_text())
    assert len(saved["candidates"]) == 10
    arc = result.state.archive
    units = np.asarray(arc.unit)[np.isfinite(np.asarray(arc.fitness))]
    key = jax.random.fold_in(jax.random.PRNGKey(config.seed), RERANK_STREAM)
    batched = make_reevaluate(fitness, SMALL, 3)(key, units)
    np.testing.assert_allclose([c["fitness"] for c in saved["candidates"]], batched.fitness, rtol=1e-5, atol=1e-7)
    # a candidate's result does not depend on the others evaluated in the same call
    for rows in (slice(0, 1), slice(3, 5)):
        part = make_reevaluate(fitness, SMALL, 3)(key, units[rows])
        np.testing.assert_array_equal(part.fitness_per_seed, np.asarray(batched.fitness_per_seed)[rows])

    # cut back in the format of files written before each result carried its unit (matched by position in "units")
    old_format = [{k: v for k, v in c.items() if k != "unit"} for c in saved["candidates"][:4]]
    (tmp_path / REEVALUATION_FILE).write_text(json.dumps({**saved, "candidates": old_format}))
    lines = []
    run_search(fitness, SMALL, config, tmp_path, reevaluate_seeds=3, log=lines.append)
    assert any("resuming the re-evaluation: 4/10" in ln for ln in lines)
    assert sum(ln.startswith("re-evaluated ") and "/10:" in ln for ln in lines) == 6
    assert json.loads((tmp_path / TOP_K_FILE).read_text()) == first
    # other seeds: the saved results do not apply, all 10 are evaluated again
    lines = []
    run_search(fitness, SMALL, config, tmp_path, reevaluate_seeds=2, log=lines.append)
    assert not any("resuming the re-evaluation" in ln for ln in lines)
    assert sum(ln.startswith("re-evaluated ") and "/10:" in ln for ln in lines) == 10


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_extended_search_reevaluates_only_new_archive_members(tmp_path):
    """Every candidate is re-evaluated with the same keys, so its result depends on it alone: after the search is
    extended, saved results are reused for the members still in the archive and only the new ones are evaluated,
    and top_k.json equals a re-evaluation of the extended archive from scratch."""
    fitness = fit.make_quadratic(0.05)
    short = EvolveConfig(strategy=CHEAP, population_size=8, generations=1, chunk_size=1, top_k=10)
    run_search(fitness, SMALL, short, tmp_path / "a", reevaluate_seeds=2, log=lambda _: None)
    before = {tuple(c["unit"]) for c in json.loads((tmp_path / "a" / REEVALUATION_FILE).read_text())["candidates"]}
    longer = dataclasses.replace(short, generations=2)
    lines = []
    result = run_search(fitness, SMALL, longer, tmp_path / "a", reevaluate_seeds=2, log=lines.append)
    arc = result.state.archive
    units = [tuple(float(x) for x in u) for u in np.asarray(arc.unit, np.float32)[np.isfinite(np.asarray(arc.fitness))]]
    kept = sum(u in before for u in units)
    assert 0 < kept < len(units), kept   # the extension both kept and replaced archive members
    assert any(f"resuming the re-evaluation: {kept}/{len(units)}" in ln for ln in lines)
    assert sum(ln.startswith("re-evaluated ") and f"/{len(units)}:" in ln for ln in lines) == len(units) - kept
    run_search(fitness, SMALL, longer, tmp_path / "b", reevaluate_seeds=2, log=lambda _: None)
    assert (json.loads((tmp_path / "a" / TOP_K_FILE).read_text())["top_k"]
            == json.loads((tmp_path / "b" / TOP_K_FILE).read_text())["top_k"])


def test_cma_es_finds_the_benchmark_optimum():
    """CMA-ES on the noisy 15-d quadratic (noise std 0.01 against a start-point fitness of ~0.03): the distribution
    mean ends within 0.05 of the known optimum in every unit-cube coordinate."""
    search = make_search(fit.make_quadratic(0.01), SearchSpace(),
                         EvolveConfig(population_size=16, generations=80, chunk_size=40, seed=3))
    state = search.init(KEY)
    state = search.run_chunk(search.run_chunk(state))
    err0 = np.abs(SearchSpace().start_unit() - fit.QUADRATIC_OPTIMUM_UNIT).max()
    err = np.abs(np.asarray(state.strategy.mean) - fit.QUADRATIC_OPTIMUM_UNIT).max()
    assert err0 > 0.3 and err < 0.05, (err0, err)
    best = SearchSpace().to_metaparams(state.archive.unit[0])
    opt = fit.quadratic_optimum()
    for name in ("learn_rate", "v_em_max", "explore_tot"):
        b = BOUNDS[name]
        scale = math.log(b.hi / b.lo) if b.scale == "log" else b.hi - b.lo
        diff = (math.log(float(getattr(best, name)) / float(getattr(opt, name))) if b.scale == "log"
                else float(getattr(best, name)) - float(getattr(opt, name)))
        assert abs(diff) / scale < 0.1, name


def test_genetic_algorithm_improves():
    config = EvolveConfig(strategy="SimpleGA", population_size=16, generations=30, chunk_size=30, seed=1,
                          strategy_params={"crossover_rate": 0.2})
    search = make_search(fit.make_quadratic(0.0), SearchSpace(), config)
    h = search.run_chunk(search.init(KEY)).history
    # the best fitness found so far (a GA's generation best wanders: no elite is kept); 0.32-0.67 of the first
    # generation's over keys 0-4 on the 16-field space (0.39-0.51 on the 13 fields before the target code's three)
    best = np.asarray(h.best_so_far)
    assert best[-1] < 0.75 * best[0]


# --------------------------------------------------------------------------------------------- checkpoints / resume
@pytest.mark.parametrize("strategy", ["CMA_ES", pytest.param("SimpleGA", marks=pytest.mark.slow)])  # GA: slow suite (8-min budget)
def test_resumed_search_equals_uninterrupted_bit_for_bit(strategy, tmp_path):
    space = SearchSpace.make(freeze=["explore_tot", "syn_scaling_dt_ms"])
    config = EvolveConfig(strategy=strategy, population_size=6, generations=7, chunk_size=3, seeds_per_candidate=2,
                          top_k=5)
    fitness = fit.Fitness(fit.make_quadratic(0.01))
    meta = {"name": "quadratic"}
    quiet = lambda line: None   # noqa: E731
    full = run_search(fitness, space, config, tmp_path / "full", fitness_meta=meta, log=quiet)
    part = run_search(fitness, space, config, tmp_path / "killed", fitness_meta=meta, max_chunks=1, log=quiet)
    assert not part.finished and int(part.state.generation) == 3
    assert SearchCheckpointer(tmp_path / "killed" / "checkpoints").latest_generation() == 3
    lines = []
    resumed = run_search(fitness, space, config, tmp_path / "killed", fitness_meta=meta, log=lines.append)
    assert resumed.finished and full.finished and int(resumed.state.generation) == 7
    assert any("resuming from the checkpoint at generation 3" in line for line in lines)
    assert leaves_equal(full.state, resumed.state)
    for name in (HISTORY_FILE, TOP_K_FILE):
        a = json.loads((tmp_path / "full" / name).read_text())
        b = json.loads((tmp_path / "killed" / name).read_text())
        if name == HISTORY_FILE:
            a, b = a["history"], b["history"]
        assert a == b
    assert (tmp_path / "full" / PLOT_FILE).stat().st_size > 1000
    # a different search refuses the folder
    with pytest.raises(ConfigError, match="different search"):
        run_search(fitness, space, EvolveConfig(strategy=strategy, population_size=8, generations=7, chunk_size=3),
                   tmp_path / "killed", fitness_meta=meta, log=quiet)


def test_search_resumes_past_a_damaged_checkpoint(tmp_path, capsys):
    from conftest import truncate_newest_checkpoint

    space = SearchSpace.make(freeze=["explore_tot", "syn_scaling_dt_ms"])
    config = EvolveConfig(strategy=CHEAP, population_size=4, generations=6, chunk_size=2, top_k=3)
    fitness, meta, quiet = fit.Fitness(fit.make_quadratic(0.01)), {"name": "quadratic"}, (lambda line: None)
    full = run_search(fitness, space, config, tmp_path / "full", fitness_meta=meta, log=quiet)
    run_search(fitness, space, config, tmp_path / "killed", fitness_meta=meta, max_chunks=2, log=quiet)
    truncate_newest_checkpoint(tmp_path / "killed" / "checkpoints")     # generation 4 damaged
    lines = []
    resumed = run_search(fitness, space, config, tmp_path / "killed", fitness_meta=meta, log=lines.append)
    assert "unreadable" in capsys.readouterr().err
    assert any("resuming from the checkpoint at generation 2/6" in line for line in lines)
    assert leaves_equal(full.state, resumed.state)


def test_checkpoint_restores_exact_state(tmp_path):
    search = make_search(fit.make_quadratic(0.01), SMALL, EvolveConfig(strategy=CHEAP, population_size=4,
                                                                      generations=4, chunk_size=2))
    state = search.run_chunk(search.init(KEY))
    with SearchCheckpointer(tmp_path) as ckpt:
        ckpt.save(state, {"note": "x"})
        restored, meta = ckpt.restore(jax.eval_shape(search.init, KEY))
    assert meta == {"note": "x"} and leaves_equal(state, restored)
    assert restored.key.dtype == jnp.uint32
    # continuing from the restored state is the same program and gives the same bits
    assert leaves_equal(search.run_chunk(state), search.run_chunk(restored))
    assert [f._cache_size() for f in (search.ask, search.evaluate, search.tell)] == [1, 1, 1]


# --------------------------------------------------------------------------------------------- registry and CLI
def test_registry_builds_and_lists():
    fit.register("test-constant", lambda options: (lambda key, mp: jnp.float32(len(options.targets))), "a test")
    built = fit.build("test-constant", fit.FitnessOptions(arm="simple", targets=("left",)))
    assert isinstance(built, fit.Fitness) and float(built.fn(KEY, None)) == 1.0
    assert {"quadratic", "quadratic-diverging", "test-constant"} <= set(fit.available())
    with pytest.raises(ConfigError, match="not registered.*quadratic"):
        fit.build("nope", fit.FitnessOptions())
    with pytest.raises(ConfigError, match="FitnessOptions.targets"):
        fit.FitnessOptions(targets=("middle",))
    with pytest.raises(ConfigError, match="FitnessOptions.train_s"):
        fit.FitnessOptions(train_s=0.0)
    with pytest.raises(ConfigError, match="dt_ms = 0.3: must divide 1 ms"):
        fit.FitnessOptions(dt_ms=0.3)
    opt = fit.quadratic_optimum()
    assert float(fit.make_quadratic(0.0)(KEY, opt)[0]) == pytest.approx(0.0, abs=1e-10)


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_extended_search_equals_one_planned_that_long(tmp_path):
    """Asking a finished (or stopped) search for more generations continues it; the result equals a search
    planned that long from the start, bit for bit. Fewer generations than done is refused."""
    space = SearchSpace.make(freeze=["explore_tot", "syn_scaling_dt_ms"])
    make = lambda g: EvolveConfig(strategy="CMA_ES", population_size=6, generations=g, chunk_size=3,   # noqa: E731
                                  seeds_per_candidate=2, top_k=5)
    fitness = fit.Fitness(fit.make_quadratic(0.01))
    meta = {"name": "quadratic"}
    quiet = lambda line: None   # noqa: E731
    full = run_search(fitness, space, make(7), tmp_path / "full", fitness_meta=meta, log=quiet)
    short = run_search(fitness, space, make(4), tmp_path / "ext", fitness_meta=meta, log=quiet)
    assert short.finished and int(short.state.generation) == 4
    assert short.state.history.best.shape == (4,)
    lines = []
    extended = run_search(fitness, space, make(7), tmp_path / "ext", fitness_meta=meta, log=lines.append)
    assert any("generation 4/7 (extended from 4 generations)" in line for line in lines)
    assert extended.finished and int(extended.state.generation) == 7
    assert leaves_equal(full.state, extended.state)
    assert (json.loads((tmp_path / "full" / HISTORY_FILE).read_text())["history"]
            == json.loads((tmp_path / "ext" / HISTORY_FILE).read_text())["history"])
    with pytest.raises(ConfigError, match="generations = 5 is fewer than the 7"):
        run_search(fitness, space, make(5), tmp_path / "ext", fitness_meta=meta, log=quiet)


def test_cli_runs_resumes_and_reports_errors(tmp_path, capsys):
    args = ["--fitness", "quadratic-diverging", "--strategy", "SimpleGA", "--population", "6", "--generations", "4",
            "--chunk", "2", "--seeds-per-candidate", "2", "--search", "learn_rate,v_em_max", "--sigma", "0.4",
            "--top-k", "5", "--strategy-param", "crossover_rate=0.2", "--out", str(tmp_path / "run")]
    assert evolve_main(args + ["--max-chunks", "1"]) == 0
    assert evolve_main(args + ["--reevaluate-seeds", "2"]) == 0
    out = capsys.readouterr().out
    assert "resuming from the checkpoint at generation 2" in out and "gen 4/4" in out and "eval/s" in out
    assert "re-evaluated the top" in out
    # the layout line: 6 candidates x 2 seeds on the suite's 2 devices, one network at a time (padding_note)
    assert ("jaxarm evolve: a generation's 12 evaluations (6 candidates x 2 seed(s)): on 2 devices one network at a "
            "time, no padding") in out
    top = json.loads((tmp_path / "run" / TOP_K_FILE).read_text())
    assert 1 <= len(top["top_k"]) <= 5 and top["reevaluated"]
    first = top["top_k"][0]["metaparams"]
    assert set(first) == set(NAMES) and first["explore_tot"] == ORIGINAL["explore_tot"]
    saved = json.loads((tmp_path / "run" / HISTORY_FILE).read_text())
    assert saved["config"]["strategy_params"] == {"crossover_rate": 0.2} and saved["generations_done"] == 4

    assert evolve_main(["--fitness", "quadratic", "--freeze", "learning_rate", "--out", str(tmp_path / "x")]) == 2
    assert "learning_rate" in capsys.readouterr().err
    assert evolve_main(["--fitness", "quadratic", "--population", "1", "--out", str(tmp_path / "x")]) == 2
    assert "EvolveConfig.population_size" in capsys.readouterr().err
    assert evolve_main(["--fitness", "no-such-fitness", "--out", str(tmp_path / "x")]) == 2
    assert "quadratic" in capsys.readouterr().err
    fit.register("test-ignores", lambda options: fit.Fitness(fit.make_quadratic(0.0), ignores=("explore_tot",)), "test")
    assert evolve_main(["--fitness", "test-ignores", "--population", "4", "--generations", "1", "--chunk", "1",
                        "--search", "explore_tot,learn_rate", "--out", str(tmp_path / "ign")]) == 0
    assert "does not use explore_tot" in capsys.readouterr().out
    saved = json.loads((tmp_path / "ign" / HISTORY_FILE).read_text())
    assert list(saved["space"]["searched"]) == ["learn_rate"] and saved["space"]["frozen"]["explore_tot"] == 16.0
    # a command recorded before max_w_scaling and epochs left the metaparameters runs, without them
    assert evolve_main(["--fitness", "quadratic", "--population", "4", "--generations", "1", "--chunk", "1",
                        "--freeze", "max_w_scaling=0.7,epochs=4,explore_tot", "--out", str(tmp_path / "old")]) == 0
    err = capsys.readouterr().err
    assert "--freeze max_w_scaling: no longer a metaparameter" in err and "--freeze epochs" in err
    saved = json.loads((tmp_path / "old" / HISTORY_FILE).read_text())
    assert saved["space"]["frozen"] == {"explore_tot": 16.0} and len(saved["space"]["searched"]) == len(NAMES) - 1
    assert evolve_main(["--list-strategies"]) == 0
    listed = capsys.readouterr().out.split()
    assert "CMA_ES" in listed and "SimpleGA" in listed


@pytest.mark.slow
@pytest.mark.parametrize("strategy", STRATEGIES)
def test_every_strategy_runs(strategy):
    config = EvolveConfig(strategy=strategy, population_size=8, generations=4, chunk_size=2)
    search = make_search(fit.make_quadratic(0.01, diverge_above=0.6), SMALL, config)
    state = search.run_chunk(search.run_chunk(search.init(KEY)))
    h = state.history
    assert int(state.generation) == 4 and np.isfinite(float(h.best_so_far[-1]))
    unit = np.asarray(state.archive.unit)[np.isfinite(np.asarray(state.archive.fitness))]
    assert np.all((unit >= 0) & (unit <= 1))


_SLOW_CLI = """
import sys
import jax.numpy as jnp
from jax import lax
from jaxarm.evolve import fitness as fit
from jaxarm.evolve.cli import evolve_main

def make_slow(options):   # the quadratic plus ~0.1 s of busy work per generation, so a kill lands mid-search
    base = fit.make_quadratic(0.01)
    def fn(key, mp):
        f, m = base(key, mp)
        x = lax.fori_loop(0, 100000, lambda i, x: jnp.sin(x) + f * 1e-9, jnp.zeros(64))
        return f + 0.0 * x.sum(), m
    return fit.Fitness(fn)

fit.register("slow-quadratic", make_slow, "test")
raise SystemExit(evolve_main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_killed_process_resumes_bit_for_bit(tmp_path):
    """A real kill (SIGKILL) of a `jaxarm evolve` process after its first checkpoint; the rerun resumes and ends with
    the same history and top-k as an uninterrupted run."""
    import os
    import signal
    import subprocess
    import sys
    import time

    script = tmp_path / "slow_cli.py"
    script.write_text(_SLOW_CLI)
    args = ["--fitness", "slow-quadratic", "--population", "8", "--generations", "40", "--chunk", "1",
            "--seeds-per-candidate", "2", "--top-k", "10"]
    run = lambda out: subprocess.run([sys.executable, str(script), *args, "--out", str(out)],   # noqa: E731
                                     capture_output=True, text=True, timeout=600)
    full = run(tmp_path / "full")
    assert full.returncode == 0, full.stderr

    killed_dir = tmp_path / "killed"
    # killed mid-run: kept off the suite's shared compilation cache (JAX writes its entries in place, not atomically)
    proc = subprocess.Popen([sys.executable, str(script), *args, "--out", str(killed_dir)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            env=dict(os.environ, JAX_ENABLE_COMPILATION_CACHE="false"))
    deadline = time.time() + 300
    while not (killed_dir / "checkpoints" / "2").exists():
        assert proc.poll() is None and time.time() < deadline, "the search ended before it could be killed"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    stopped_at = SearchCheckpointer(killed_dir / "checkpoints").latest_generation()
    assert 2 <= stopped_at < 40
    resumed = run(killed_dir)
    assert resumed.returncode == 0, resumed.stderr
    assert f"resuming from the checkpoint at generation {stopped_at}/40" in resumed.stdout
    a = json.loads((tmp_path / "full" / HISTORY_FILE).read_text())["history"]
    b = json.loads((killed_dir / HISTORY_FILE).read_text())["history"]
    assert a == b and len(a["best"]) == 40
    assert json.loads((tmp_path / "full" / TOP_K_FILE).read_text()) == json.loads((killed_dir / TOP_K_FILE).read_text())
