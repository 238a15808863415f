"""Evolutionary search of the metaparameters, compiled: evosax ask -> vmapped fitness -> tell inside ``lax.scan``.

* :mod:`~jaxarm.evolve.space`: which metaparameters are searched (unit cube <-> :class:`MetaParams`) or frozen.
* :mod:`~jaxarm.evolve.search`: :class:`EvolveConfig` and :func:`make_search` (pure ``init`` / ``run_chunk``).
* :mod:`~jaxarm.evolve.fitness`: the registry of fitness functions (``register``, ``build``) and benchmarks.
* :mod:`~jaxarm.evolve.checkpoint`: orbax checkpoints of the search state between chunks.
* :mod:`~jaxarm.evolve.runner`: the chunked driver (progress lines, history/top-k JSON, convergence plot).
* :mod:`~jaxarm.evolve.cli`: ``jaxarm evolve``.
"""
from jaxarm.evolve.fitness import Fitness, FitnessOptions, register
from jaxarm.evolve.search import EvolveConfig, SearchState, make_search, strategies
from jaxarm.evolve.space import SearchSpace

__all__ = ["Fitness", "FitnessOptions", "register", "strategies", "EvolveConfig", "SearchState", "make_search",
           "SearchSpace"]


def __getattr__(name: str):
    # STRATEGIES is read on first use (importing evosax's algorithms starts JAX's backends: jaxarm.evolve.search)
    if name == "STRATEGIES":
        return strategies()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
