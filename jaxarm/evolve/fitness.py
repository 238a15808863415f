"""Fitness functions for the search, by name: a registry, the options they are built from, and benchmarks.

A fitness function is pure: ``fn(key, metaparams) -> fitness`` or ``-> (fitness, metrics)``, where ``key`` is a raw
``uint32[2]`` PRNG key (one seed of one candidate), ``metaparams`` an unbatched :class:`MetaParams`, ``fitness`` a
float32 scalar (**lower is better**; NaN or +-inf means the evaluation failed, e.g. a diverged arm or network) and
``metrics`` an optional dict of float32 scalars reported beside it (e.g. ``success_rate``). The search ``vmap``\\ s it
over candidates x seeds, so it must not contain Python control flow on traced values.

The authors' fitness (spec ``original_model.md`` §7) is the worst target's hand-target distance: train one network
per target with the candidate's metaparameters, test it, take the distance of each target's test and the maximum over
targets. The reaching fitness is registered by the training code, e.g. in a module listed in
:data:`PLUGIN_MODULES`::

    from jaxarm.evolve import fitness

    def make_reaching(options: fitness.FitnessOptions) -> fitness.Fitness:
        fns = [make_train(LoopConfig(arm=options.arm, task=...target=t...)) for t in options.targets]
        def fn(key, mp):
            dist, success = [], []
            for t, k in zip(fns, jax.random.split(key, len(fns))):   # a few targets: unrolled is fine
                k_train, k_test = jax.random.split(k)
                result = t.test(k_test, t.train(k_train, mp)[0], mp)
                # the authors' fitness (docs/model.md, Metaparameters): mean of the test's distance at
                # ~20 ms and at its last sample
                dist.append(0.5 * (result.distance_m[2] + result.distance_m[-1]))
                success.append(result.success)
            return jnp.max(jnp.stack(dist)), {"success_rate": jnp.mean(jnp.stack(success).astype(jnp.float32))}
        return fitness.Fitness(fn, network_seconds_per_eval=len(options.targets) * (train_s + test_s),
                               epochs=train_s // 30)   # how long an evaluation trains: its presets say so

    fitness.register("reaching", make_reaching, "worst target's test hand-target distance, m (the authors' fitness)")

Registered here: ``quadratic`` (a noisy quadratic with a known optimum inside the bounds, for testing the engine) and
``quadratic-diverging`` (the same, NaN on part of the space, for testing the failure handling).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.arm.registry import ARMS
from jaxarm.config.validate import ConfigError, check_choice, check_range
from jaxarm.learning.metaparams import BOUNDS, NAMES, MetaParams, to_unit


@dataclass(frozen=True)
class FitnessOptions:
    """What a registered fitness is built for (the ``jaxarm evolve`` options).

    Attributes:
        arm: a name of :data:`jaxarm.arm.registry.ARMS`, "simple" or "musculoskeletal".
        targets: target names (see :data:`jaxarm.task.config.TARGET_ANGLES_RAD`); the paper's are left and bottom.
        train_s: simulated training length per evaluation, s (short for a fast proxy; the paper's protocol is
            12 epochs x 30 s = 360 s), or ``None`` for the fitness's default (the paper's protocol).
        dt_ms: the network's clock step, ms, or ``None`` for NetworkConfig's default (0.25 ms).
        network: the NetworkConfig the networks are built from (``--network``, ``--network-scale``), or ``None`` for
            the paper's; ``dt_ms``, when given, replaces its clock step.
    """

    arm: str = "musculoskeletal"
    targets: tuple[str, ...] = ("left", "bottom")
    train_s: float | None = None
    dt_ms: float | None = None
    network: Any = None

    def network_config(self):
        """The networks' NetworkConfig: ``network`` (or the default) with ``dt_ms`` when given."""
        import dataclasses

        from jaxarm.config.network import NetworkConfig

        net = self.network or NetworkConfig()
        return net if self.dt_ms is None else dataclasses.replace(net, dt_ms=self.dt_ms)

    def __post_init__(self):
        from jaxarm.task.config import TARGET_ANGLES_RAD   # light (no JAX work)
        check_choice(self, "arm", ARMS)
        targets = tuple(self.targets)
        if not targets:
            raise ConfigError("FitnessOptions.targets = (): give at least one target")
        for t in targets:
            if t not in TARGET_ANGLES_RAD:
                raise ConfigError(f"FitnessOptions.targets: unknown target {t!r}; known: {', '.join(TARGET_ANGLES_RAD)}")
        object.__setattr__(self, "targets", targets)
        if self.train_s is not None:
            check_range(self, "train_s", 0.0, None, lo_open=True)
        if self.dt_ms is not None:
            from jaxarm.config.network import NetworkConfig   # light: validates the step (divides 1 ms, in range)
            NetworkConfig(dt_ms=self.dt_ms)


class Fitness(NamedTuple):
    """A built fitness: the pure function and what one evaluation costs.

    ``network_seconds_per_eval``: simulated network-seconds one call of ``fn`` runs (0 for a benchmark); the progress
    line multiplies it by evaluations per second.
    ``ignores``: metaparameters ``fn`` does not read (e.g. a noise rate a rule without babbling never uses);
    ``jaxarm evolve`` freezes them at the published value rather than search directions that cannot matter.
    ``epochs``: the training epochs one evaluation runs, counted as the task's ``--epochs`` counts them (reaching:
    epochs; centre-out: epochs per target), or None for a benchmark that trains nothing; the search records it, and
    a preset made from the search takes it as its protocol, so the found sets say how they were evaluated.
    """

    fn: Callable
    network_seconds_per_eval: float = 0.0
    ignores: tuple = ()
    epochs: int | None = None


class _Entry(NamedTuple):
    make_fn: Callable[[FitnessOptions], Fitness]
    help: str


_REGISTRY: dict[str, _Entry] = {}
#: Built fitness functions by (name, options): building the same one twice returns the same function object, so
#: that :func:`jaxarm.evolve.search.make_search` finds its compiled search again.
_BUILT: dict[tuple, Fitness] = {}


def register(name: str, make_fn: Callable[[FitnessOptions], Fitness | Callable], help: str = "") -> None:
    """Register ``make_fn(options) -> Fitness`` (or a bare pure function) under ``name``; a later registration of the
    same name replaces the earlier one."""
    if not name or not isinstance(name, str):
        raise ValueError(f"fitness name must be a non-empty string, got {name!r}")
    _REGISTRY[name] = _Entry(make_fn, help)
    for key in [k for k in _BUILT if k[0] == name]:
        del _BUILT[key]


def available() -> dict[str, str]:
    """``{name: help}`` of the registered fitness functions."""
    _load_plugins()
    return {k: v.help for k, v in sorted(_REGISTRY.items())}


def build(name: str, options: FitnessOptions) -> Fitness:
    """Build the fitness registered as ``name`` for ``options``."""
    _load_plugins()
    if name not in _REGISTRY:
        raise ConfigError(f"fitness = {name!r} is not registered; available: {', '.join(sorted(_REGISTRY))}")
    if (name, options) not in _BUILT:
        built = _REGISTRY[name].make_fn(options)
        _BUILT[(name, options)] = built if isinstance(built, Fitness) else Fitness(built)
    return _BUILT[(name, options)]


#: Modules imported before the registry is read, so that their ``register`` calls run (the training code's module
#: that registers "reaching" goes here once it exists). A module that does not exist yet is skipped.
PLUGIN_MODULES: tuple[str, ...] = ("jaxarm.evolve.reaching",)


def _load_plugins() -> None:
    import importlib
    for module in PLUGIN_MODULES:
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as e:
            if e.name != module:   # the module exists but something it imports is missing: a real error
                raise


# --------------------------------------------------------------------------------------------------- benchmarks
def _golden_point(n: int) -> np.ndarray:
    """A fixed point inside (0.2, 0.8)^n that is not the cube's centre: 0.2 + 0.6 * frac(i * golden ratio)."""
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    return (0.2 + 0.6 * np.mod(np.arange(1, n + 1) * phi, 1.0)).astype(np.float32)


#: The optimum of the ``quadratic`` benchmark in the unit cube of :data:`BOUNDS` (one entry per field of ``NAMES``).
QUADRATIC_OPTIMUM_UNIT = _golden_point(len(NAMES))


def quadratic_optimum() -> MetaParams:
    """The ``quadratic`` benchmark's optimum as metaparameters (inside :data:`BOUNDS`)."""
    out = {}
    for name, x in zip(NAMES, QUADRATIC_OPTIMUM_UNIT.tolist()):
        b = BOUNDS[name]
        out[name] = b.lo * (b.hi / b.lo) ** x if b.scale == "log" else b.lo + x * (b.hi - b.lo)
    return MetaParams.from_dict(out)


def make_quadratic(noise_std: float = 0.01, diverge_above: float | None = None) -> Callable:
    """Noisy quadratic benchmark: ``mean_i (u_i - u*_i)^2 + noise_std * N(0, 1)``.

    ``u`` is ``mp`` on the unit cube of :data:`BOUNDS` (every field; a frozen field adds a constant), ``u*`` is
    :data:`QUADRATIC_OPTIMUM_UNIT`, so the noiseless minimum is 0 at :func:`quadratic_optimum`. The noise is drawn
    from ``key``: a candidate's seeds differ, the same seed gives the same value. With ``diverge_above`` the fitness
    is NaN wherever ``learn_rate``'s unit coordinate exceeds it (a stand-in for a diverged network).

    Metrics: ``distance`` = Euclidean distance to the optimum in the unit cube (noiseless).
    """
    u_star = jnp.asarray(QUADRATIC_OPTIMUM_UNIT)
    i_lr = NAMES.index("learn_rate")

    def fitness(key, mp):
        u = to_unit(mp)
        sq = (u - u_star) ** 2
        f = jnp.mean(sq) + noise_std * jax.random.normal(key, (), jnp.float32)
        if diverge_above is not None:
            f = jnp.where(u[i_lr] > diverge_above, jnp.nan, f)
        return f, {"distance": jnp.sqrt(jnp.sum(sq))}

    return fitness


register("quadratic", lambda options: Fitness(make_quadratic(0.01)),
         "benchmark: mean squared unit-cube distance to a fixed optimum inside the bounds + N(0, 0.01^2) noise "
         "(minimum 0; ignores arm/targets)")
register("quadratic-diverging", lambda options: Fitness(make_quadratic(0.01, diverge_above=0.6)),
         "benchmark: 'quadratic', but NaN where learn_rate's unit coordinate > 0.6 (tests failure handling)")
