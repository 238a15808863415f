"""The chunked driver: compile once, run chunks, checkpoint and report between them, write the results.

Files in the output folder:

* ``checkpoints/<generation>/``: orbax checkpoints of the whole search state (the last two kept). A folder that holds
  one is resumed, provided it was started with the same configuration.
* ``history.json``: per generation best / median / best-so-far fitness, failed evaluations and candidates, the
  fitness's metrics, and each generation's best metaparameters; plus the configuration and costs. Written after
  every chunk.
* ``top_k.json``: the best ``top_k`` candidates of the whole search, best first, as complete metaparameter sets;
  with ``reevaluate_seeds``, each also evaluated again with that many fresh seeds after the search, and the list
  ranked by that re-evaluation (the search's own ranking favours lucky draws of a noisy fitness).
* ``reevaluation.json``: the re-evaluation's results so far, one candidate at a time with its unit-cube
  coordinates, so a killed re-evaluation resumes where it stopped and an extended search re-evaluates only the
  candidates new to its archive.
* ``convergence.png``: best, median and best-so-far fitness and failures per generation.

Non-finite numbers are written to JSON as ``null``.
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path
from typing import Callable, NamedTuple

import jax
import numpy as np

from jaxarm import parallel
from jaxarm.config.validate import ConfigError
from jaxarm.evolve.checkpoint import SearchCheckpointer
from jaxarm.evolve.fitness import Fitness
from jaxarm.evolve.search import (RERANK_STREAM, EvolveConfig, Reevaluation, SearchState, candidates_per_call,
                                  make_reevaluate, make_search, with_generations)
from jaxarm.evolve.space import SearchSpace

HISTORY_FILE = "history.json"
TOP_K_FILE = "top_k.json"
PLOT_FILE = "convergence.png"
REEVALUATION_FILE = "reevaluation.json"
CHECKPOINT_DIR = "checkpoints"


class SearchResult(NamedTuple):
    state: SearchState
    finished: bool              # all generations done (False when stopped by max_chunks)
    out_dir: Path


def _num(x):
    """A JSON number, or None for NaN/inf."""
    x = float(x)
    return x if math.isfinite(x) else None


def _jsonable(obj):
    return json.loads(json.dumps(obj))


def _write_json(path: Path, obj) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(obj, indent=1, allow_nan=False) + "\n")
    tmp.replace(path)   # a reader never sees half a file


def _without_generations(description: dict) -> dict:
    """A run description minus the planned number of generations (which a resumed run may change)."""
    d = dict(description)
    d["config"] = {k: v for k, v in dict(d.get("config", {})).items() if k != "generations"}
    return d


def describe(space: SearchSpace, config: EvolveConfig, fitness_meta: dict | None) -> dict:
    """The run's identity: a checkpoint is resumed only by a run with the same description."""
    return _jsonable({"config": config.to_dict(), "space": space.to_dict(), "fitness": fitness_meta or {}})


def top_k_table(state: SearchState, space: SearchSpace, reevaluation=None) -> list[dict]:
    """The archive as JSON-ready rows, best first (empty slots left out). With ``reevaluation`` (a
    :class:`~jaxarm.evolve.search.Reevaluation` of the archive's filled slots, in archive order) each row also holds
    it, and the rows are ranked by it (failed re-evaluations last); ``search_rank`` keeps the search's order."""
    arc = jax.device_get(state.archive)
    rows = []
    for i in range(arc.fitness.shape[0]):
        if not np.isfinite(arc.fitness[i]):
            continue
        mp = space.to_metaparams(arc.unit[i]).to_dict()
        rows.append({"rank": len(rows) + 1, "search_rank": len(rows) + 1, "fitness": _num(arc.fitness[i]),
                     "generation": int(arc.generation[i]), "metaparams": mp,
                     "unit": {n: _num(v) for n, v in zip(space.names, arc.unit[i])},
                     "metrics": {m: _num(v[i]) for m, v in arc.metrics.items()}})
    if reevaluation is not None:
        ev = jax.device_get(reevaluation)
        for j, row in enumerate(rows):
            row["reevaluation"] = {"fitness": _num(ev.fitness[j]),
                                   "fitness_per_seed": [_num(x) for x in ev.fitness_per_seed[j]],
                                   "metrics": {m: _num(v[j]) for m, v in ev.metrics.items()}}
        order = sorted(range(len(rows)), key=lambda j: (not np.isfinite(ev.fitness[j]),
                                                         float(ev.fitness[j]) if np.isfinite(ev.fitness[j]) else 0.0))
        rows = [rows[j] for j in order]
        for r, row in enumerate(rows):
            row["rank"] = r + 1
    return rows


def history_table(state: SearchState, space: SearchSpace) -> dict:
    """The history of the generations done, JSON-ready."""
    g = int(state.generation)
    h = jax.device_get(state.history)
    best_mp = [space.to_metaparams(u).to_dict() if np.all(np.isfinite(u)) else None for u in h.best_unit[:g]]
    return {
        "generation": list(range(g)),
        "best": [_num(v) for v in h.best[:g]],
        "median": [_num(v) for v in h.median[:g]],
        "best_so_far": [_num(v) for v in h.best_so_far[:g]],
        "nonfinite_evals": [int(v) for v in h.nonfinite_evals[:g]],
        "nonfinite_candidates": [int(v) for v in h.nonfinite_candidates[:g]],
        "metrics_best": {m: [_num(x) for x in v[:g]] for m, v in h.metrics_best.items()},
        "metrics_mean": {m: [_num(x) for x in v[:g]] for m, v in h.metrics_mean.items()},
        "best_metaparams": best_mp,
    }


def plot_convergence(history: dict, path: Path, title: str = "") -> None:
    """Best, median and best-so-far fitness per generation (top), failed candidates (bottom)."""
    import matplotlib
    if "matplotlib.pyplot" not in sys.modules:   # a notebook's own backend stays (a switch closes its figures)
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gen = np.asarray(history["generation"])
    as_arr = lambda k: np.asarray([np.nan if v is None else v for v in history[k]], float)   # noqa: E731
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    ax.plot(gen, as_arr("median"), color="0.6", lw=1, label="generation median")
    ax.plot(gen, as_arr("best"), color="C0", lw=1, label="generation best")
    ax.plot(gen, as_arr("best_so_far"), color="C3", lw=2, label="best so far")
    ax.set_ylabel("fitness (lower is better)")
    ax.legend(loc="upper right", frameon=False)
    ax.set_title(title, fontsize=9)
    ax2.bar(gen, history["nonfinite_candidates"], color="C1", width=1.0)
    ax2.set_ylabel("failed\ncandidates")
    ax2.set_xlabel("generation")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_search(fitness: Fitness | Callable, space: SearchSpace, config: EvolveConfig, out_dir: str | Path, *,
               fitness_meta: dict | None = None, max_chunks: int | None = None,
               reevaluate_seeds: int = 0, reevaluate_fitness: Fitness | Callable | None = None,
               reevaluate_meta: dict | None = None, log: Callable[[str], None] = print, mesh=None) -> SearchResult:
    """Run (or resume) a search, checkpointing and reporting after every chunk; write the result files.

    ``fitness``: a :class:`Fitness` or a bare pure function (see :mod:`jaxarm.evolve.fitness`). ``fitness_meta``: a
    JSON description of the fitness (name and options), stored with the checkpoints; resuming with a different one,
    or a different space or configuration, raises :class:`ConfigError`. ``max_chunks``: stop after that many chunks
    in this call (the search can be resumed later). ``reevaluate_seeds``: when the search is done, evaluate its
    top-k again with that many fresh seeds (the same for every candidate, from a key stream the search never uses)
    with ``reevaluate_fitness`` (default: ``fitness``; e.g. the same task with the full training length, or one of
    its targets) and rank ``top_k.json`` by it. ``reevaluate_meta``: a JSON description of ``reevaluate_fitness``
    (e.g. ``{"targets": ["bottom"], "train_s": 360}``), written to ``top_k.json`` as ``reevaluation``; its
    ``targets`` are part of the re-evaluation's identity (saved results for other targets are not reused). It is
    not part of the checkpointed search, so a finished search can be re-evaluated later.

    ``mesh``: the devices each generation's evaluations are split over (default: every device of every process,
    :func:`jaxarm.parallel.mesh`). With several processes every one runs this with the same arguments; the search
    state is replicated, process 0 writes the files and the log.
    """
    fitness = fitness if isinstance(fitness, Fitness) else Fitness(fitness)
    mesh = parallel.mesh() if mesh is None else mesh
    if not parallel.is_main_process():
        log = lambda line: None   # noqa: E731
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    search = make_search(fitness.fn, space, config, mesh)
    description = describe(space, config, fitness_meta)
    key = jax.random.PRNGKey(config.seed)
    evals_per_gen = config.population_size * config.seeds_per_candidate
    G = config.generations

    with SearchCheckpointer(out / CHECKPOINT_DIR) as ckpt:
        costs = {"compile_s": 0.0, "run_s": 0.0, "evaluations": 0}
        saved = ckpt.read_meta()
        if saved is not None:
            saved_run = saved.get("run", {})
            # The planned number of generations is not part of a search's identity: asking for more extends it.
            saved_g = saved_run.get("config", {}).get("generations", G)
            if _without_generations(saved_run) != _without_generations(description):
                diff = [k for k in description
                        if _without_generations(saved_run).get(k) != _without_generations(description)[k]]
                raise ConfigError(f"{out} holds a checkpoint of a different search (differs in: {', '.join(diff)}); "
                                  f"use another output folder or the same options (only --generations may change)")
            abstract = jax.eval_shape(lambda k: with_generations(search.init(k), saved_g), key)
            state, meta = ckpt.restore(abstract)
            done = int(state.generation)
            if done > G:
                raise ConfigError(f"generations = {G} is fewer than the {done} this search in {out} has done; "
                                  f"ask for at least {done}")
            state = with_generations(state, G)
            costs = meta.get("costs", costs)
            extended = f" (extended from {saved_g} generations)" if saved_g != G else ""
            log(f"resuming from the checkpoint at generation {done}/{G}{extended} in {ckpt.directory}")
        else:
            state = search.init(key)

        def generation(state) -> int:
            return int(state.generation)

        chunks, run_chunk = 0, None
        while generation(state) < G and (max_chunks is None or chunks < max_chunks):
            if run_chunk is None:   # compiled ahead, so the chunks' rates exclude compilation
                compile_s = search.compile(state)
                run_chunk = search.run_chunk
                costs["compile_s"] = costs["compile_s"] + compile_s
                log(f"compiled {config.strategy} chunk ({config.chunk_size} generations x {config.population_size} "
                    f"candidates x {config.seeds_per_candidate} seeds, {space.n_dims} dims) in {compile_s:.1f} s")
            g0 = generation(state)
            t0 = time.perf_counter()
            state = jax.block_until_ready(run_chunk(state))
            dt = time.perf_counter() - t0
            g1 = generation(state)
            n_eval = (g1 - g0) * evals_per_gen
            costs["run_s"] += dt
            costs["evaluations"] += n_eval
            chunks += 1
            # the state is the same on every process: saved from host copies (orbax writes them once)
            ckpt.save(jax.device_get(state), {"run": description, "costs": costs})
            h = jax.device_get(state.history)
            failed_chunk = int(np.sum(h.nonfinite_candidates[g0:g1]))
            failed_total = int(np.sum(h.nonfinite_candidates[:g1]))
            rate = n_eval / dt if dt > 0 else float("inf")
            net = (f" ({rate * fitness.network_seconds_per_eval:.3g} network-s/s)"
                   if fitness.network_seconds_per_eval > 0 else "")
            log(f"gen {g1:>{len(str(G))}}/{G} | best {h.best[g1 - 1]:.5g} | median {h.median[g1 - 1]:.5g} | "
                f"best so far {h.best_so_far[g1 - 1]:.5g} | failed {failed_chunk} (total {failed_total}) | "
                f"{rate:.3g} eval/s{net} | {dt:.2f} s")
            _write_outputs(jax.device_get(state), space, config, description, costs, fitness, out, plot=False)

        finished = generation(state) >= G
        host_state = jax.device_get(state)
        reevaluation = None
        if finished and reevaluate_seeds > 0:
            reevaluation = _reevaluate(host_state, space, config, reevaluate_fitness or fitness, reevaluate_seeds, log,
                                        out, reevaluate_meta, mesh)
        _write_outputs(host_state, space, config, description, costs, fitness, out, plot=True,
                       reevaluation=reevaluation,
                       reevaluation_meta=reevaluate_meta if reevaluation is not None else None)
        if finished:
            best = top_k_table(host_state, space, reevaluation)
            if best:
                again = best[0].get("reevaluation", {}).get("fitness")
                again = f"re-evaluated {again:.5g}, " if again is not None else ""
                log(f"done: best candidate: {again}search fitness {best[0]['fitness']:.5g} "
                    f"(generation {best[0]['generation']}); results in {out}")
        else:
            log(f"stopped at generation {generation(state)}/{G}; run again with the same options to resume")
    return SearchResult(host_state, finished, out)


def _reevaluate(state, space, config, fitness, seeds, log, out: Path, meta: dict | None = None, mesh=None):
    """Re-evaluate the archive in calls of :func:`candidates_per_call` candidates (their seeds fill whole groups on
    every device; the same fresh keys for all), with a progress line per candidate and each call's results saved to
    ``reevaluation.json`` as they come.

    Every candidate is evaluated with the same keys, so a result depends on the candidate alone: saved results are
    reused for every archive member they were computed for. A killed re-evaluation resumes with the candidates not yet
    done, and after a search is extended only the candidates new to the archive are evaluated. A file for
    other seeds, another training length or other targets is ignored."""
    fitness = fitness if isinstance(fitness, Fitness) else Fitness(fitness)
    filled = np.isfinite(np.asarray(state.archive.fitness))
    units = np.asarray(state.archive.unit, np.float32)[filled]
    if units.shape[0] == 0:
        return None
    reevaluate = make_reevaluate(fitness.fn, space, seeds, config.seed_reduce, mesh)
    per_call = min(candidates_per_call(seeds, mesh), units.shape[0])
    key = np.asarray(jax.random.fold_in(jax.random.PRNGKey(config.seed), RERANK_STREAM))
    unit_rows = [[float(x) for x in u] for u in units]
    identity = {"seeds": seeds, "seed_reduce": config.seed_reduce,
                "network_seconds_per_eval": fitness.network_seconds_per_eval}
    if meta and meta.get("targets") is not None:   # only when given: files written before this key still resume
        identity["targets"] = list(meta["targets"])
    path = out / REEVALUATION_FILE
    saved_by_unit: dict[tuple, dict] = {}
    if path.exists():
        saved = json.loads(path.read_text())
        if {k: saved.get(k) for k in identity} == identity and saved.get("targets") == identity.get("targets"):
            # Files written before results carried their unit list them in the order of "units".
            for i, c in enumerate(saved.get("candidates", [])):
                u = c.get("unit", (saved.get("units") or [])[i] if i < len(saved.get("units") or []) else None)
                if u is not None:
                    saved_by_unit[tuple(float(x) for x in u)] = {**c, "unit": [float(x) for x in u]}
    done: list[dict | None] = [saved_by_unit.get(tuple(u)) for u in unit_rows]
    n_reused = sum(c is not None for c in done)
    if n_reused:
        log(f"resuming the re-evaluation: {n_reused}/{units.shape[0]} candidates done ({path})")

    def save():
        if parallel.is_main_process():
            _write_json(path, {**identity, "units": unit_rows, "candidates": [c for c in done if c is not None]})

    t_all = time.perf_counter()
    todo = [i for i in range(units.shape[0]) if done[i] is None]
    for start in range(0, len(todo), per_call):
        rows = todo[start:start + per_call]
        # the last call is padded with copies to the same shape (no second compile; the copies are dropped)
        chunk = units[rows + [rows[-1]] * (per_call - len(rows))]
        t0 = time.perf_counter()
        args = (key, chunk) if mesh is None else parallel.put((key, chunk), parallel.REPLICATED, mesh)
        r = parallel.host(jax.block_until_ready(reevaluate(*args)))
        for j, i in enumerate(rows):
            done[i] = {"unit": unit_rows[i], "fitness": _num(r.fitness[j]),
                       "fitness_per_seed": [_num(x) for x in r.fitness_per_seed[j]],
                       "metrics": {m: _num(v[j]) for m, v in r.metrics.items()}}
        save()
        for i in rows:
            log(f"re-evaluated {i + 1}/{units.shape[0]}: fitness {_fmt(done[i]['fitness'])} over {seeds} fresh "
                f"seeds (search fitness {_fmt(float(np.asarray(state.archive.fitness)[filled][i]))}) | "
                f"{time.perf_counter() - t0:.1f} s for {len(rows)} in one call")
    save()
    nan = float("nan")
    as_array = lambda xs: np.asarray([nan if x is None else x for x in xs], np.float32)   # noqa: E731
    result = Reevaluation(
        fitness=as_array([c["fitness"] for c in done]),
        fitness_per_seed=np.stack([as_array(c["fitness_per_seed"]) for c in done]),
        metrics={m: as_array([c["metrics"][m] for c in done]) for m in done[0]["metrics"]})
    failed = int(np.sum(~np.isfinite(result.fitness_per_seed)))
    log(f"re-evaluated the top {units.shape[0]} with {seeds} fresh seeds each in "
        f"{time.perf_counter() - t_all:.1f} s this run (compile included); failed evaluations: {failed}")
    return result


def _fmt(x) -> str:
    return "nan" if x is None or not math.isfinite(x) else f"{x:.5g}"


def _write_outputs(state, space, config, description, costs, fitness, out: Path, plot: bool,
                   reevaluation=None, reevaluation_meta: dict | None = None) -> None:
    """history.json, top_k.json and (``plot``) convergence.png from a host copy of the state (process 0 only)."""
    if not parallel.is_main_process():
        return
    history = history_table(state, space)
    evals = costs["evaluations"]
    summary = {
        **description,
        "generations_done": int(state.generation),
        "costs": {**costs,
                  "evaluations_per_s": evals / costs["run_s"] if costs["run_s"] > 0 else None,
                  "network_seconds_per_s": (evals * fitness.network_seconds_per_eval / costs["run_s"]
                                            if costs["run_s"] > 0 and fitness.network_seconds_per_eval > 0 else None)},
        "history": history,
    }
    _write_json(out / HISTORY_FILE, summary)
    top = {"fitness": description["fitness"], "lower_is_better": True, "reevaluated": reevaluation is not None}
    if reevaluation_meta:
        top["reevaluation"] = _jsonable(reevaluation_meta)
    _write_json(out / TOP_K_FILE, {**top, "top_k": top_k_table(state, space, reevaluation)})
    if plot and history["generation"]:
        plot_convergence(history, out / PLOT_FILE,
                         title=f"{config.strategy}, population {config.population_size}, "
                               f"{config.seeds_per_candidate} seed(s)/candidate, {description['fitness'].get('name', '')}")
