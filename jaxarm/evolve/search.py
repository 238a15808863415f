"""The compiled search: evosax ask -> ``vmap`` of the fitness over candidates x seeds -> tell, in ``lax.scan``.

:func:`make_search` returns two pure functions, each one ``jit``:

* ``init(key) -> SearchState``: the strategy's state, the PRNG key, an empty history and an empty top-k archive.
* ``run_chunk(state) -> SearchState``: ``config.chunk_size`` generations. Generations past ``config.generations``
  leave the state unchanged (``lax.cond``), so every chunk has the same shape and the loop compiles once.

Everything the search needs to continue is in :class:`SearchState` (arrays only, PRNG key as raw ``uint32[2]``), so a
search restored from a checkpoint of it continues exactly as the uninterrupted one.

One generation:

1. ``ask``: the strategy proposes ``population_size`` points of the unit cube; they are clipped to [0, 1] (the
   *repaired* candidates are what is evaluated, told, and archived, so a population-based strategy never leaves
   the bounds).
2. Each candidate is evaluated with ``seeds_per_candidate`` keys ("common": the same keys for every candidate of the
   generation, which makes their comparison less noisy; "independent": a key per evaluation; "fixed": the same
   keys in every generation) and the seeds combine by their mean (or their maximum, the worst case). A candidate
   with any non-finite evaluation fails. All candidates x seeds run in one ``vmap``, or ``eval_batch_size``
   candidates at a time (``lax.map``) when memory is short.
3. ``tell``: failed candidates are told a fitness strictly worse than the generation's worst finite one (the
   generation's worst plus its spread, :func:`rank_failures_last`), so they rank last, whatever the strategy does
   with NaN. Their count is recorded in the history.
4. The history (best / median fitness, failures, metrics) and the top-k archive are updated.

evosax initialises population-based strategies (GAs, DE, PSO) from an evaluated population: for them, generation 0
evaluates a first population (uniform in the cube, with the start point as its first member) and initialises the
strategy with it, instead of ask/tell. Distribution-based strategies (CMA-ES, ...) start from a mean at the start point
with width ``sigma_init``.

evosax minimises; so does this search (lower fitness is better).
"""
from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import time
from dataclasses import dataclass
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct
from jax import lax

from jaxarm.config.validate import ConfigError, check_choice, check_range
from jaxarm.evolve.space import SearchSpace


#: evosax strategies left out: they search several populations at once (a ``num_populations`` argument).
EXCLUDED_STRATEGIES = ("SV_CMA_ES", "SV_Open_ES")


@functools.lru_cache(maxsize=None)
def _strategies() -> dict:
    # Imported on first use, not with this module: evosax creates arrays when its algorithms are imported, which
    # starts JAX's backends and fixes the device count before `jaxarm.parallel.start` can choose it.
    from evosax.algorithms import algorithms
    return {k: v for k, v in algorithms.items() if k not in EXCLUDED_STRATEGIES}


def strategies() -> tuple[str, ...]:
    """evosax 0.3.2 strategy names (``evosax.algorithms.algorithms`` but :data:`EXCLUDED_STRATEGIES`), e.g. "CMA_ES",
    "Sep_CMA_ES", "SimpleGA", "DifferentialEvolution", "PSO", "RandomSearch" (uniform in the unit cube). Also
    readable as the module attribute ``STRATEGIES`` (computed when first read)."""
    return tuple(sorted(_strategies()))


def __getattr__(name: str):
    if name == "STRATEGIES":
        return strategies()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


SEED_MODES = ("common", "independent", "fixed")
SEED_REDUCES = ("mean", "max")
#: ``fold_in`` constants that separate the key streams of "fixed" seeds and of re-evaluation from the search's.
FIXED_SEEDS_STREAM = 0x5EED
RERANK_STREAM = 0x2E2A


@dataclass(frozen=True)
class EvolveConfig:
    """Static configuration of a search (hashable; validated on construction).

    Attributes:
        strategy: evosax strategy name (:func:`strategies`); "CMA_ES" by default, "SimpleGA" is the genetic
            algorithm closest to the authors' (inspyred) one.
        population_size: candidates per generation.
        generations: generations in the whole search.
        chunk_size: generations per compiled chunk (a checkpoint and a progress line between chunks).
        seeds_per_candidate: evaluations (networks) per candidate per generation.
        seed: seed of the search's PRNG key.
        sigma_init: initial search width in unit-cube coordinates (CMA-ES std; the mutation std of strategies that
            take a std schedule; the std of the others that have ``std_init``).
        top_k: best candidates kept (the paper reported its top 30).
        seed_mode: "common": the same seeds for every candidate of a generation, new ones each generation (a
            fairer comparison within a generation); "independent": a seed per evaluation; "fixed": the same seeds
            for every candidate of every generation (a deterministic fitness; may overfit those seeds).
        seed_reduce: how a candidate's seeds combine: "mean" or "max" (worst case).
        strategy_params: ``((name, value), ...)`` overrides of the strategy's evosax params, e.g.
            ``(("crossover_rate", 0.2),)`` for SimpleGA (the authors' later GA used uniform crossover at 0.2).
        eval_batch_size: where networks are not already run in groups (``--networks-at-once 0``, the default on
            accelerators): candidates evaluated at once (each with all its seeds in one ``vmap``); the population
            is run in batches of this size one after the other (``lax.map``). 0 = the whole population at once.
    """

    strategy: str = "CMA_ES"
    population_size: int = 16
    generations: int = 50
    chunk_size: int = 10
    seeds_per_candidate: int = 1
    seed: int = 0
    sigma_init: float = 0.2
    top_k: int = 30
    seed_mode: str = "common"
    seed_reduce: str = "mean"
    strategy_params: tuple = ()
    eval_batch_size: int = 0

    def __post_init__(self):
        check_choice(self, "strategy", strategies())
        check_range(self, "population_size", 2, None, integer=True)
        check_range(self, "generations", 1, None, integer=True)
        check_range(self, "chunk_size", 1, None, integer=True)
        check_range(self, "seeds_per_candidate", 1, None, integer=True)
        check_range(self, "seed", 0, 2**31 - 1, integer=True)
        check_range(self, "sigma_init", 0.0, 10.0, lo_open=True)
        check_range(self, "top_k", 1, None, integer=True)
        check_choice(self, "seed_mode", SEED_MODES)
        check_choice(self, "seed_reduce", SEED_REDUCES)
        check_range(self, "eval_batch_size", 0, self.population_size, integer=True)
        pairs = dict(self.strategy_params.items() if isinstance(self.strategy_params, dict) else self.strategy_params)
        object.__setattr__(self, "strategy_params", tuple(sorted((str(k), float(v)) for k, v in pairs.items())))
        make_strategy(self, n_dims=2)   # the strategy's own constraints (e.g. an even population) and param names

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["strategy_params"] = dict(self.strategy_params)
        return d


def make_strategy(config: EvolveConfig, n_dims: int):
    """The evosax strategy object and its params for ``n_dims`` unit-cube dimensions."""
    cls = _strategies()[config.strategy]
    kwargs = {}
    signature = inspect.signature(cls.__init__).parameters
    if "std_schedule" in signature:
        kwargs["std_schedule"] = optax.constant_schedule(config.sigma_init)
    if "sampling_fn" in signature:   # RandomSearch: uniform over the unit cube
        kwargs["sampling_fn"] = lambda key: jax.random.uniform(key, (n_dims,), jnp.float32)
    try:
        es = cls(population_size=config.population_size, solution=jnp.zeros((n_dims,), jnp.float32), **kwargs)
        params = es.default_params
    except AssertionError as e:   # evosax states its constraints as assertions (e.g. "Population size must be even")
        raise ConfigError(f"EvolveConfig.population_size = {config.population_size!r}: {config.strategy} "
                          f"refuses it ({e})") from None
    known = {f.name for f in dataclasses.fields(params)}
    if "std_init" in known:
        params = params.replace(std_init=jnp.asarray(config.sigma_init, jnp.float32))
    for name, value in config.strategy_params:
        if name not in known:
            raise ConfigError(f"EvolveConfig.strategy_params: {name!r} is not a parameter of {config.strategy}; "
                              f"known: {', '.join(sorted(known))}")
        params = params.replace(**{name: jnp.asarray(value, jnp.float32)})
    return es, params


# --------------------------------------------------------------------------------------------------- state
@struct.dataclass
class History:
    """Per generation (axis 0 has ``config.generations`` entries; not yet run = NaN / -1).

    best, median: the generation's best and median candidate fitness over its finite candidates.
    best_so_far: the best candidate fitness of the search up to and including the generation.
    nonfinite_evals: evaluations (candidate x seed) whose fitness was NaN or +-inf.
    nonfinite_candidates: candidates that failed (any non-finite evaluation).
    best_unit: the generation's best candidate in the unit cube, (generations, n_dims).
    metrics_best / metrics_mean: the fitness's reported metrics (mean over seeds) of the generation's best
        candidate / averaged over its candidates.
    """

    best: jnp.ndarray
    median: jnp.ndarray
    best_so_far: jnp.ndarray
    nonfinite_evals: jnp.ndarray
    nonfinite_candidates: jnp.ndarray
    best_unit: jnp.ndarray
    metrics_best: dict
    metrics_mean: dict


@struct.dataclass
class Archive:
    """The ``top_k`` best candidates seen so far, best first (empty slots: fitness +inf, unit NaN, generation -1)."""

    unit: jnp.ndarray          # (top_k, n_dims)
    fitness: jnp.ndarray       # (top_k,)
    generation: jnp.ndarray    # (top_k,) int32, the generation that evaluated it
    metrics: dict              # name -> (top_k,)


@struct.dataclass
class SearchState:
    """Everything a search needs to continue (arrays only; a checkpoint holds exactly this)."""

    generation: jnp.ndarray    # int32 (), generations completed
    key: jnp.ndarray           # uint32 (2,), raw PRNG key
    strategy: object           # the evosax strategy's state
    history: History
    archive: Archive


class Search(NamedTuple):
    """What :func:`make_search` returns.

    A generation is three compiled programs: ``ask`` (the strategy proposes a population; one device), ``evaluate``
    (every candidate x seed trains and is tested; split over the device mesh) and ``tell`` (the strategy, history and
    archive take the fitness; one device). The strategy's programs are compiled alone, so their arithmetic, and the
    whole search, is bit for bit the same on one device, many, or many processes (compiled into one program with the
    sharded evaluation, XLA fused the strategy's sums differently per layout and the searches drifted apart).
    """

    init: Callable            # key -> SearchState (jitted)
    run_chunk: Callable       # SearchState -> SearchState: chunk_size generations (the generations left, at most)
    ask: Callable             # jitted: SearchState -> (population (P, n), strategy state, evaluation key)
    evaluate: Callable        # jitted over the mesh: (key, population) -> (fitness (P,), failed evals (P,), metrics)
    tell: Callable            # jitted: (SearchState, population, strategy state, fitness, failed, metrics) -> state
    config: EvolveConfig
    space: SearchSpace
    metric_names: tuple       # names of the fitness's reported metrics
    mesh: object = None

    def compile(self, state: SearchState) -> float:
        """Compile ``ask``, ``evaluate`` and ``tell`` for ``state`` ahead of the first generation; seconds taken."""
        t0 = time.perf_counter()
        population, es_state, key = jax.eval_shape(self.ask, state)
        self.ask.lower(state).compile()
        on_mesh = (key, population)
        if self.mesh is not None:   # what run_chunk hands the evaluation: whole arrays on the mesh
            whole = jax.sharding.NamedSharding(self.mesh, jax.sharding.PartitionSpec())
            on_mesh = tuple(jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=whole) for x in on_mesh)
        self.evaluate.lower(*on_mesh).compile()
        evaluated = jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype),
                                 jax.eval_shape(self.evaluate, *on_mesh))
        self.tell.lower(state, population, es_state, *evaluated).compile()
        return time.perf_counter() - t0


def with_generations(state: SearchState, generations: int) -> SearchState:
    """``state`` with its per-generation history resized to ``generations`` entries (new entries empty: NaN / -1).

    Extending a search (asking for more generations than it was started with) changes nothing else: the strategy
    state, key and archive do not depend on the planned length, so an extended search continues exactly as one
    planned that long from the start. Works on abstract states (``jax.eval_shape``) too."""
    h = state.history

    def fit(a, fill):
        g = a.shape[0]
        if g >= generations:
            return a[:generations]
        pad = jnp.full((generations - g,) + tuple(a.shape[1:]), fill, a.dtype)
        return jnp.concatenate([a, pad])

    history = History(best=fit(h.best, jnp.nan), median=fit(h.median, jnp.nan),
                      best_so_far=fit(h.best_so_far, jnp.nan),
                      nonfinite_evals=fit(h.nonfinite_evals, -1), nonfinite_candidates=fit(h.nonfinite_candidates, -1),
                      best_unit=fit(h.best_unit, jnp.nan),
                      metrics_best={m: fit(v, jnp.nan) for m, v in h.metrics_best.items()},
                      metrics_mean={m: fit(v, jnp.nan) for m, v in h.metrics_mean.items()})
    return state.replace(history=history)


def raw_key(key) -> jnp.ndarray:
    """A raw ``uint32[2]`` key from a raw or typed PRNG key."""
    key = jnp.asarray(key)
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        key = jax.random.key_data(key)
    return key.astype(jnp.uint32)


def _strong(tree):
    """Drop JAX weak types (a checkpoint does not keep them, and a weak/strong mismatch would recompile)."""
    return jax.tree.map(lambda x: lax.convert_element_type(x, jnp.result_type(x)), tree)


def rank_failures_last(fitness):
    """Fitness to tell the strategy: non-finite entries (failed evaluations) replaced by a value strictly worse than
    every finite one (the worst finite plus the finite spread, at least 1e-6 + 1e-3 |worst| more), so that they rank
    last; on the finite values' own scale, so strategies that use fitness values (not ranks) are not swamped by an
    arbitrary constant. All failed: all 0 (a tie)."""
    fitness = jnp.asarray(fitness, jnp.float32)
    failed = ~jnp.isfinite(fitness)
    finite = jnp.where(failed, jnp.nan, fitness)
    worst, best = jnp.nanmax(finite), jnp.nanmin(finite)
    spread = jnp.maximum(worst - best, 1e-6 + 1e-3 * jnp.abs(worst))
    penalty = jnp.where(jnp.all(failed), 0.0, worst + spread)
    return jnp.where(failed, penalty, fitness)


def _combine_seeds(f, reduce: str):
    """Per-seed fitness (..., S) -> (fitness (...), non-finite mask (..., S)); a candidate with any non-finite
    evaluation gets NaN."""
    bad = ~jnp.isfinite(f)
    f_ok = jnp.where(bad, 0.0, f)
    combined = jnp.mean(f_ok, axis=-1) if reduce == "mean" else jnp.max(f_ok, axis=-1)
    return jnp.where(jnp.any(bad, axis=-1), jnp.nan, combined), bad


def _like(tree, reference):
    """``tree`` with the dtypes (and strong types) of ``reference``."""
    return jax.tree.map(lambda a, b: lax.convert_element_type(a, b.dtype), tree, reference)


def _normalise(fitness_fn: Callable) -> Callable:
    """Wrap a fitness so it always returns (float32 scalar, {name: float32 scalar})."""

    def call(key, mp):
        out = fitness_fn(key, mp)
        f, metrics = (out if isinstance(out, tuple) else (out, {}))
        f = jnp.asarray(f, jnp.float32)
        if f.shape != ():
            raise ValueError(f"a fitness must return a scalar; got shape {f.shape}")
        metrics = {str(k): jnp.asarray(v, jnp.float32) for k, v in dict(metrics).items()}
        for k, v in metrics.items():
            if v.shape != ():
                raise ValueError(f"fitness metric {k!r} must be a scalar; got shape {v.shape}")
        return f, metrics

    return call


def make_search(fitness_fn: Callable, space: SearchSpace, config: EvolveConfig, mesh=None) -> Search:
    """Build the pure ``init`` and ``run_chunk`` of a search of ``fitness_fn`` over ``space``.

    ``fitness_fn(key, metaparams) -> fitness | (fitness, metrics)``, lower is better (see :mod:`jaxarm.evolve.fitness`).
    ``mesh``: a device mesh (:func:`jaxarm.parallel.mesh`) over which each generation's candidates x seeds are split
    (``shard_map``; padded to a multiple of its devices, the padding's fitness dropped); the strategy's ``ask`` and
    ``tell`` run on one device of every process (see :class:`Search`), so only the fitness crosses devices.
    None: one device.
    The same (fitness function object, space, config, mesh) returns the same :class:`Search`, so a search run again
    in the same process (resumed, or re-run in a notebook) reuses its compiled chunk.
    """
    if not isinstance(space, SearchSpace):
        raise TypeError(f"space must be a SearchSpace, got {type(space).__name__}")
    if not isinstance(config, EvolveConfig):
        raise TypeError(f"config must be an EvolveConfig, got {type(config).__name__}")
    try:
        hash(fitness_fn)
    except TypeError:
        return _make_search(fitness_fn, space, config, mesh)
    return _make_search_cached(fitness_fn, space, config, mesh)


def _on_mesh(tree, mesh):
    """Host or single-device values as whole (replicated) global arrays on ``mesh`` (unchanged without one)."""
    if mesh is None:
        return tree
    from jaxarm import parallel

    return parallel.put(parallel.host(tree), parallel.REPLICATED, mesh)


def candidates_per_call(seeds: int, mesh=None) -> int:
    """The fewest candidates whose ``seeds`` evaluations each fill whole groups on every device (no padding)."""
    from jaxarm import parallel

    group = max(1, parallel.networks_at_once()) * (1 if mesh is None else mesh.size)
    return group // math.gcd(group, seeds)


def _make_search(fitness_fn: Callable, space: SearchSpace, config: EvolveConfig, mesh=None) -> Search:
    from evosax.algorithms.population_based.base import PopulationBasedAlgorithm

    n, P, S, K, G = space.n_dims, config.population_size, config.seeds_per_candidate, config.top_k, config.generations
    es, params = make_strategy(config, n)
    population_based = isinstance(es, PopulationBasedAlgorithm)
    evaluate_one = _normalise(fitness_fn)
    start_unit = jnp.asarray(space.start_unit())

    # The metrics' names, from the fitness's output structure (one abstract trace, no evaluation).
    _, metric_shapes = jax.eval_shape(evaluate_one, jax.ShapeDtypeStruct((2,), jnp.uint32),
                                      jax.eval_shape(space.to_metaparams, jax.ShapeDtypeStruct((n,), jnp.float32)))
    metric_names = tuple(sorted(metric_shapes))

    def init(key) -> SearchState:
        key, k_init, k_pop = jax.random.split(raw_key(key), 3)
        if population_based:
            # A placeholder state holding the first population (uniform in the cube, the start point as its first
            # member); generation 0 evaluates it and initialises the strategy with its fitness (see generation_step).
            population = jax.random.uniform(k_pop, (P, n), jnp.float32).at[0].set(start_unit)
            es_state = es.init(k_init, population, jnp.full((P,), jnp.inf, jnp.float32), params)
        else:
            es_state = es.init(k_init, start_unit, params)
        nan_g = jnp.full((G,), jnp.nan, jnp.float32)
        history = History(best=nan_g, median=nan_g, best_so_far=nan_g,
                          nonfinite_evals=jnp.full((G,), -1, jnp.int32),
                          nonfinite_candidates=jnp.full((G,), -1, jnp.int32),
                          best_unit=jnp.full((G, n), jnp.nan, jnp.float32),
                          metrics_best={m: nan_g for m in metric_names},
                          metrics_mean={m: nan_g for m in metric_names})
        archive = Archive(unit=jnp.full((K, n), jnp.nan, jnp.float32), fitness=jnp.full((K,), jnp.inf, jnp.float32),
                          generation=jnp.full((K,), -1, jnp.int32),
                          metrics={m: jnp.full((K,), jnp.nan, jnp.float32) for m in metric_names})
        return _strong(SearchState(generation=jnp.zeros((), jnp.int32), key=key, strategy=es_state,
                                   history=history, archive=archive))


    fixed_keys = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(config.seed), FIXED_SEEDS_STREAM), S)

    def evaluate(k_eval, population):
        """Fitness (P,) (NaN = failed), failed-evaluation count (P,), metrics {name: (P,)}."""
        if config.seed_mode == "common":
            keys = jnp.broadcast_to(jax.random.split(k_eval, S)[None], (P, S, 2))
        elif config.seed_mode == "fixed":
            keys = jnp.broadcast_to(fixed_keys[None], (P, S, 2))
        else:
            keys = jax.random.split(k_eval, P * S).reshape(P, S, 2)
        mps = space.to_metaparams(population)
        # One flat vmap over candidates x seeds (not a vmap of a vmap): the network's batched spike delivery then
        # serves all P * S networks with one spike list (jaxarm.network.synapses).
        flat_keys = keys.reshape((P * S,) + keys.shape[2:])
        flat_mps = jax.tree_util.tree_map(lambda x: jnp.repeat(x, S, axis=0), mps)
        # groups of networks_at_once on CPUs; eval_batch_size bounds the memory where that is 0 (accelerators)
        from jaxarm import parallel

        whole = 0 if config.eval_batch_size in (0, P) else config.eval_batch_size * S
        batch = parallel.networks_at_once() or whole
        f, metrics = parallel.sharded_map(evaluate_one, mesh, batch)(flat_keys, flat_mps)
        f, metrics = f.reshape(P, S), {m: v.reshape(P, S) for m, v in metrics.items()}   # (P, S), {name: (P, S)}
        fitness, bad = _combine_seeds(f, config.seed_reduce)
        return fitness, jnp.sum(bad, axis=1), {m: jnp.mean(v, axis=1) for m, v in metrics.items()}

    def ask(state: SearchState):
        """The population to evaluate, the strategy state it came from, and the key of its evaluation."""
        _, k_ask, k_eval, _ = jax.random.split(state.key, 4)
        like = lambda tree: _like(tree, state.strategy)   # noqa: E731  (cond branches must agree on dtypes)

        def proposed():
            population, es_state = es.ask(k_ask, state.strategy, params)
            return population, like(es_state)

        # evosax initialises a population-based strategy from an *evaluated* population: its generation 0 evaluates
        # the first population (held by the placeholder state of init) and calls init instead of ask/tell.
        first = population_based & (state.generation == 0)
        population, es_state = (lax.cond(first, lambda: (state.strategy.population, state.strategy), proposed)
                                if population_based else proposed())
        return jnp.clip(population, 0.0, 1.0), es_state, k_eval

    def tell(state: SearchState, population, es_state, fitness, bad_evals, metrics) -> SearchState:
        key, _, _, k_tell = jax.random.split(state.key, 4)
        like = lambda tree: _like(tree, state.strategy)   # noqa: E731
        first = population_based & (state.generation == 0)
        failed = jnp.isnan(fitness)
        finite = jnp.where(failed, jnp.nan, fitness)
        told = rank_failures_last(fitness)

        def told_to(population, told, es_state):
            return like(es.tell(k_tell, population, told, es_state, params)[0])

        es_state = (lax.cond(first, lambda p, t, s: like(es.init(k_tell, p, t, params)), told_to, population, told,
                             es_state) if population_based else told_to(population, told, es_state))

        g = state.generation
        rankable = jnp.where(failed, jnp.inf, fitness)
        i_best = jnp.argmin(rankable)
        none_ok = jnp.all(failed)
        # Archive: merge and keep the top_k (stable sort: on ties the earlier entry stays ahead).
        arc = state.archive
        all_f = jnp.concatenate([arc.fitness, rankable])
        order = jnp.argsort(all_f, stable=True)[:K]
        archive = Archive(unit=jnp.concatenate([arc.unit, population])[order], fitness=all_f[order],
                          generation=jnp.concatenate([arc.generation, jnp.full((P,), g, jnp.int32)])[order],
                          metrics={m: jnp.concatenate([arc.metrics[m], metrics[m]])[order] for m in metric_names})
        h = state.history
        history = History(
            best=h.best.at[g].set(jnp.where(none_ok, jnp.nan, rankable[i_best])),
            median=h.median.at[g].set(jnp.nanmedian(finite)),
            best_so_far=h.best_so_far.at[g].set(jnp.where(jnp.isinf(archive.fitness[0]), jnp.nan, archive.fitness[0])),
            nonfinite_evals=h.nonfinite_evals.at[g].set(jnp.sum(bad_evals).astype(jnp.int32)),
            nonfinite_candidates=h.nonfinite_candidates.at[g].set(jnp.sum(failed).astype(jnp.int32)),
            best_unit=h.best_unit.at[g].set(jnp.where(none_ok, jnp.nan, population[i_best])),
            metrics_best={m: h.metrics_best[m].at[g].set(jnp.where(none_ok, jnp.nan, metrics[m][i_best]))
                          for m in metric_names},
            metrics_mean={m: h.metrics_mean[m].at[g].set(jnp.nanmean(metrics[m])) for m in metric_names},
        )
        new = SearchState(generation=g + 1, key=key, strategy=es_state, history=history, archive=archive)
        return _like(new, state)   # evosax may return weak-typed scalars; the state's types must not change

    ask_jit, tell_jit, evaluate_jit = jax.jit(ask), jax.jit(tell), jax.jit(evaluate)

    def run_chunk(state: SearchState) -> SearchState:
        """Up to ``chunk_size`` generations (none past ``generations``). ``state`` lives on one device of each
        process (every process holds the same); only the evaluation spans the mesh."""
        for _ in range(config.chunk_size):
            if int(np.asarray(jax.device_get(state.generation))) >= G:
                break
            population, es_state, k_eval = ask_jit(state)
            evaluated = evaluate_jit(*_on_mesh((k_eval, population), mesh))
            if mesh is not None:
                from jaxarm import parallel

                evaluated = parallel.host(evaluated)
            state = tell_jit(state, population, es_state, *evaluated)
        return state

    return Search(init=jax.jit(init), run_chunk=run_chunk, ask=ask_jit, evaluate=evaluate_jit, tell=tell_jit,
                  config=config, space=space, metric_names=metric_names, mesh=mesh)


_make_search_cached = functools.lru_cache(maxsize=16)(_make_search)


class Reevaluation(NamedTuple):
    """Candidates evaluated again with fresh seeds (see :func:`make_reevaluate`)."""

    fitness: jnp.ndarray           # (K,) seeds combined by ``seed_reduce``; NaN if any evaluation failed
    fitness_per_seed: jnp.ndarray  # (K, seeds)
    metrics: dict                  # name -> (K,), mean over seeds


def make_reevaluate(fitness_fn: Callable, space: SearchSpace, seeds: int, seed_reduce: str = "mean",
                    mesh=None) -> Callable:
    """``reevaluate(key, units (K, n_dims)) -> Reevaluation``: each candidate with the same ``seeds`` fresh keys
    (split from ``key``), the K x seeds evaluations in one :func:`jaxarm.parallel.sharded_map` (over ``mesh`` when
    given, in groups of :func:`jaxarm.parallel.networks_at_once`). A candidate's result depends on it alone, not on
    the others of the call: every evaluation runs in a group of the same size whatever the call holds
    (:func:`candidates_per_call` gives the K that fills whole groups).

    The search ranks candidates by noisy fitness, so its best are partly its luckiest; evaluating the top-k again
    with new seeds (and, for the reaching task, the full training length) gives the final ranking.
    """
    if seeds < 1:
        raise ConfigError(f"seeds = {seeds!r} is out of range; allowed >= 1")
    from jaxarm import parallel

    evaluate_one = _normalise(fitness_fn)

    @jax.jit
    def reevaluate(key, units) -> Reevaluation:
        units = jnp.asarray(units, jnp.float32)
        k = units.shape[0]
        keys = jnp.tile(jax.random.split(raw_key(key), seeds), (k, 1))   # candidate-major: (K * seeds, 2)
        mps = jax.tree.map(lambda x: jnp.repeat(x, seeds, axis=0), space.to_metaparams(units))
        f, metrics = parallel.sharded_map(evaluate_one, mesh)(keys, mps)
        f = f.reshape(k, seeds)
        fitness, _ = _combine_seeds(f, seed_reduce)
        return Reevaluation(fitness, f, {m: jnp.mean(v.reshape(k, seeds), axis=1) for m, v in metrics.items()})

    return reevaluate
