"""``jaxarm evolve``: search the metaparameters with an evosax strategy, in compiled chunks, resumable.

Examples::

    jaxarm evolve --fitness quadratic --generations 100 --population 16 --out runs/evolve-bench
    jaxarm evolve --arm musculoskeletal --targets left,bottom --strategy CMA_ES --population 32 \\
        --seeds-per-candidate 2 --generations 100 --train-s 60 --out runs/evolve-msarm
    jaxarm evolve --task centre-out-8 --arm simple --population 16 --train-s 240 --out runs/evolve-centre-out
    jaxarm evolve --list-fitness
    jaxarm evolve --list-strategies

Running the same command again in a folder that holds a checkpoint resumes the search from it.
"""
from __future__ import annotations

import argparse
import json
import sys

from jaxarm import parallel, parallel_cli, runfolder
from jaxarm.arm.registry import ARMS
from jaxarm.config.validate import ConfigError
from jaxarm.task.registry import DEFAULT as DEFAULT_TASK, TASKS

#: the fitness of the default task (--task gives its own: TASKS[task].fitness)
DEFAULT_FITNESS = TASKS[DEFAULT_TASK].fitness


def _pairs(text: str, what: str) -> dict:
    """'a=1,b=2' -> {'a': 1.0, 'b': 2.0}; 'a,b' -> {'a': None, 'b': None}."""
    out = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value) if sep else None
        except ValueError:
            raise ConfigError(f"--{what}: {item!r}: the value must be a number") from None
    return out


def build_parser() -> argparse.ArgumentParser:
    from jaxarm.run import add_network_arguments

    ap = argparse.ArgumentParser(prog="jaxarm evolve", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=runfolder.folder_argument,
                    help="output folder (checkpoints, history.json, top_k.json, convergence.png); resumed when it "
                         "holds a checkpoint; one command at a time (OUT/jaxarm.lock)")
    ap.add_argument("--task", choices=tuple(TASKS), default=DEFAULT_TASK,
                    help="reaching (default): one network per target, the paper's search; centre-out-8: one network "
                         "trained on the original's eight centre-out targets in turn, with a target code "
                         "(jaxarm.task.centre_out), fitness centre-out")
    ap.add_argument("--fitness", default=None,
                    help=f"registered fitness (default {DEFAULT_FITNESS!r}, or the --task's; see --list-fitness)")
    ap.add_argument("--arm", choices=tuple(ARMS), default="musculoskeletal", help="arm")
    ap.add_argument("--targets", default=None, help="comma-separated targets (default left,bottom, or the --task's)")
    ap.add_argument("--train-s", type=float, default=None,
                    help="simulated training length per evaluation, s (default: the candidate's epochs x 30 s)")
    ap.add_argument("--dt-ms", type=float, default=None,
                    help="network clock step, ms (default 0.25); reproduce the found sets with the same "
                         "`jaxarm reproduce --dt-ms`")
    add_network_arguments(ap, "; reproduce the found sets with the same `jaxarm reproduce --network`")
    ap.add_argument("--strategy", default="CMA_ES", help="evosax strategy (default CMA_ES; SimpleGA for a GA; "
                                                          "see --list-strategies)")
    ap.add_argument("--population", type=int, default=16, help="candidates per generation (default 16)")
    ap.add_argument("--seeds-per-candidate", type=int, default=1, help="evaluations per candidate (default 1)")
    ap.add_argument("--generations", type=int, default=50, help="generations (default 50)")
    ap.add_argument("--chunk", type=int, default=10, help="generations per compiled chunk / checkpoint (default 10)")
    ap.add_argument("--seed", type=int, default=0, help="search seed (default 0)")
    ap.add_argument("--sigma", type=float, default=0.2, help="initial search width in unit-cube units (default 0.2)")
    ap.add_argument("--top-k", type=int, default=30, help="best candidates kept and written (default 30)")
    ap.add_argument("--seed-mode", choices=("common", "independent", "fixed"), default="common",
                    help="common: the same seeds for every candidate of a generation (default); independent: a seed "
                         "per evaluation; fixed: the same seeds in every generation")
    ap.add_argument("--seed-reduce", choices=("mean", "max"), default="mean", help="combine seeds by mean or max")
    ap.add_argument("--freeze", default="",
                    help="fields held fixed: 'name' (published value) or 'name=value', comma-separated")
    ap.add_argument("--search", default="",
                    help="search only these fields (comma-separated); the others are frozen at published values")
    ap.add_argument("--start", default="", help="start values of searched fields, 'name=value,...'")
    ap.add_argument("--strategy-param", default="",
                    help="evosax params of the strategy, 'name=value,...' (e.g. crossover_rate=0.2 for SimpleGA)")
    ap.add_argument("--eval-batch", type=int, default=0,
                    help="candidates evaluated at once (0 = the whole population; smaller uses less memory); only where "
                         "--networks-at-once is 0 (accelerators): CPUs already run networks in small groups")
    ap.add_argument("--reevaluate-seeds", type=int, default=0,
                    help="after the search, evaluate the top-k again with this many fresh seeds and rank by it")
    ap.add_argument("--reevaluate-train-s", type=float, default=None,
                    help="training length of the re-evaluation, s (default: --train-s)")
    ap.add_argument("--reevaluate-targets", default=None,
                    help="targets of the re-evaluation, a subset of --targets (default: --targets); ranks a "
                         "two-target search's top-k for one target, as the paper took the best sets for each case")
    ap.add_argument("--max-chunks", type=int, default=None, help="stop after this many chunks (resume later)")
    ap.add_argument("--list-fitness", action="store_true", help="list registered fitness functions and exit")
    ap.add_argument("--list-strategies", action="store_true", help="list evosax strategies and exit")
    parallel_cli.add_arguments(ap)
    return ap


def evolve_main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        parallel_cli.start_from_arguments(args)
    except ConfigError as e:
        print(f"jaxarm evolve: {e}", file=sys.stderr)
        return 2
    from jaxarm.evolve import fitness as fitness_registry
    if args.list_fitness:
        for name, help_ in fitness_registry.available().items():
            print(f"{name}  {help_}")
        return 0
    if args.list_strategies:
        from jaxarm.evolve.search import strategies
        print("\n".join(strategies()))
        return 0
    if args.out is None:
        print("jaxarm evolve: --out is required", file=sys.stderr)
        return 2
    from jaxarm.evolve.runner import run_search
    from jaxarm.evolve.search import EvolveConfig
    from jaxarm.evolve.space import SearchSpace
    from jaxarm.learning.metaparams import ORIGINAL, RETIRED

    try:
        freeze = {k: (ORIGINAL[k] if v is None and k in ORIGINAL else v)
                  for k, v in _pairs(args.freeze, "freeze").items()}
        for name in [k for k in freeze if k in RETIRED]:   # commands recorded before these names left
            print(f"jaxarm evolve: --freeze {name}: no longer a metaparameter ({RETIRED[name]}); dropped",
                  file=sys.stderr)
            del freeze[name]
        start = _pairs(args.start, "start")
        strategy_params = _pairs(args.strategy_param, "strategy-param")
        for what, d in (("start", start), ("strategy-param", strategy_params)):
            missing = [k for k, v in d.items() if v is None]
            if missing:
                raise ConfigError(f"--{what}: {missing[0]!r} needs a value (name=value)")
        network = _network(args)
        _apply_task(args)
        options = fitness_registry.FitnessOptions(
            arm=args.arm, targets=tuple(t.strip() for t in args.targets.split(",") if t.strip()),
            train_s=args.train_s, dt_ms=args.dt_ms, network=network)
        fitness = fitness_registry.build(args.fitness, options)
        search = [s.strip() for s in args.search.split(",") if s.strip()] or None
        ignored = [n for n in fitness.ignores if n not in freeze]   # searched or frozen by default alike
        if ignored:
            if parallel.is_main_process():
                print(f"jaxarm evolve: {args.fitness} does not use {', '.join(ignored)}: frozen at "
                      + ", ".join(f"{n}={ORIGINAL[n]}" for n in ignored))
            freeze.update({n: ORIGINAL[n] for n in ignored})
            search = None if search is None else [n for n in search if n not in ignored]
            if search == []:
                raise ConfigError(f"--search: {args.fitness} uses none of the fields given")
        space = SearchSpace.make(search=search, freeze=freeze, start=start)
        config = EvolveConfig(strategy=args.strategy, population_size=args.population, generations=args.generations,
                              chunk_size=args.chunk, seeds_per_candidate=args.seeds_per_candidate, seed=args.seed,
                              sigma_init=args.sigma, top_k=args.top_k, seed_mode=args.seed_mode,
                              seed_reduce=args.seed_reduce, strategy_params=strategy_params,
                              eval_batch_size=args.eval_batch)
        meta = {"name": args.fitness, "arm": options.arm, "targets": list(options.targets), "train_s": options.train_s,
                "network_seconds_per_eval": fitness.network_seconds_per_eval}
        if fitness.epochs is not None:  # how long an evaluation trains: the protocol of a preset made from it
            meta["epochs"] = int(fitness.epochs)
        if options.dt_ms is not None:   # recorded only when given, so searches from before --dt-ms still resume
            meta["dt_ms"] = options.dt_ms
        if network is not None:         # the same: only a network other than the paper's is recorded
            meta["network"] = network.to_dict(changed_only=True)
        if args.max_chunks is not None and args.max_chunks < 1:
            raise ConfigError(f"--max-chunks = {args.max_chunks}: must be >= 1")
        if args.reevaluate_seeds < 0:
            raise ConfigError(f"--reevaluate-seeds = {args.reevaluate_seeds}: must be >= 0")
        reevaluate_fitness, reevaluate_meta = None, None
        re_targets = options.targets
        if args.reevaluate_targets is not None:
            re_targets = tuple(t.strip() for t in args.reevaluate_targets.split(",") if t.strip())
            outside = [t for t in re_targets if t not in options.targets]
            if not re_targets or outside or len(set(re_targets)) != len(re_targets):
                raise ConfigError(f"--reevaluate-targets = {args.reevaluate_targets!r}: must be distinct targets "
                                  f"among --targets ({','.join(options.targets)})")
            if not args.reevaluate_seeds:
                raise ConfigError("--reevaluate-targets needs --reevaluate-seeds >= 1")
        if args.reevaluate_seeds and (args.reevaluate_train_s is not None or re_targets != options.targets):
            re_train_s = args.reevaluate_train_s if args.reevaluate_train_s is not None else options.train_s
            reevaluate_fitness = fitness_registry.build(args.fitness, fitness_registry.FitnessOptions(
                arm=options.arm, targets=re_targets, train_s=re_train_s, dt_ms=options.dt_ms, network=network))
            reevaluate_meta = {"train_s": re_train_s,
                               "network_seconds_per_eval": reevaluate_fitness.network_seconds_per_eval}
            if re_targets != options.targets:
                reevaluate_meta["targets"] = list(re_targets)
        if parallel.is_main_process():
            print(f"jaxarm evolve: {args.fitness} on {space.n_dims} metaparameters ({', '.join(space.names)}); "
                  f"frozen: {json.dumps(dict(space.frozen))}")
            print(f"jaxarm evolve: {generation_layout(config)}", flush=True)
        with runfolder.claim(args.out, "jaxarm evolve"):
            result = run_search(fitness, space, config, args.out, fitness_meta=meta, max_chunks=args.max_chunks,
                                reevaluate_seeds=args.reevaluate_seeds, reevaluate_fitness=reevaluate_fitness,
                                reevaluate_meta=reevaluate_meta)
    except ConfigError as e:
        print(f"jaxarm evolve: {e}", file=sys.stderr)
        return 2
    return 0 if result.finished or args.max_chunks is not None else 1


def generation_layout(config, mesh=None) -> str:
    """How a generation's candidates x seeds run on ``mesh`` (default: every device of every process): whole groups
    of :func:`jaxarm.parallel.networks_at_once` per device, or the fraction of padding and the ``--population`` that
    fills them (as :func:`jaxarm.evolve.search.make_search` splits a generation)."""
    import jax

    mesh = parallel.mesh() if mesh is None else mesh
    P, S = config.population_size, config.seeds_per_candidate
    at_once = parallel.networks_at_once() or (0 if config.eval_batch_size in (0, P) else config.eval_batch_size * S)
    return parallel.padding_note(P * S, f"a generation's {P * S} evaluations ({P} candidates x {S} seed(s))",
                                 mesh.size, at_once, jax.process_count(), ("--population", lambda p: p * S, P),
                                 unit="evaluations")


def _apply_task(args) -> None:
    """Fill ``--targets`` and ``--fitness`` from ``--task`` where they were not given; a reaching fitness with
    ``--task centre-out-8`` is an error, as it would not search the task asked for."""
    task = TASKS[args.task]
    fitness = task.fitness
    if args.targets is None:
        args.targets = ",".join(task.targets)
    if args.fitness is None:
        args.fitness = fitness
    if args.task != DEFAULT_TASK and not args.fitness.startswith(fitness):
        raise ConfigError(f"--fitness {args.fitness} does not score --task {args.task}: use the task's fitness "
                          f"({fitness!r}) or leave --fitness out")


def _network(args):
    """The NetworkConfig of ``--network`` / ``--network-scale`` (without ``--dt-ms``, which FitnessOptions keeps
    apart so searches from before these options still resume), or None: the paper's network."""
    from jaxarm.network import NetworkConfig
    from jaxarm.run import network_config

    if args.network is None and args.network_scale is None:
        return None
    net = network_config(argparse.Namespace(network=args.network, network_scale=args.network_scale))
    return None if net == NetworkConfig() else net


def main() -> int:   # python -m jaxarm.evolve.cli
    return evolve_main(sys.argv[1:])


if __name__ == "__main__":
    raise SystemExit(main())
