"""``jaxarm rerank``: rank a pool of metaparameter sets by how often they reach, on the reproduction's protocol.

    jaxarm rerank --arm simple --target left --pool simple-cmaes-left-local,simple-cmaes-left-shoulder \\
        --seeds 8 --out runs/rerank-left                                  # every set of both presets x 8 seeds
    jaxarm rerank --arm simple --target left --pool runs/rerank-left --best 20 --seeds 16 --first-seed 1008 \\
        --out runs/rerank-left-2 --make-preset simple-left-reranked        # the 20 best again, 16 more seeds each

A search ranks its candidates by a noisy fitness over a few seeds, so the order of its best sets is mostly luck, and
two searches' best lists cannot be compared at all. This command trains every set of a pool (the best and top sets
of presets, or the best sets of an earlier ranking) with the same ``--seeds`` fresh network keys
(``PRNGKey(first_seed + j)``, default from 1000, apart from the reproduction's keys 0..29) for the protocol
``jaxarm reproduce`` runs (``--epochs`` of ``--epoch-s``, the 1 s test, success = the hand enters the 4 cm circle),
all in one batch over every device, and ranks the sets by their success rate over every seed they were tested with
(this run's and, for a pool from an earlier ranking, that ranking's), then by the mean closest approach
(``--rank-by stay``: first by the mean distance after entry, the paper's measure of a reach that stays). The
reproduction's statistics are then measured on other keys than the ones that chose the sets.

Outputs in ``--out``: ``ranking.json`` (the pool's sources, protocol, seeds, command, timing and every set with its
per-seed results and rank) and ``checkpoints/`` (a killed run started again with the same command resumes from its
last completed epoch; once ranked, it trains nothing). ``--make-preset NAME`` writes a preset of the ranking: its
best set and its 30 best, with the ranking's commands, the pool presets' provenance and the counts in its
provenance (``--make-preset NAME --from-rerank DIR`` for a finished folder).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import shlex
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from jaxarm import parallel, parallel_cli, runfolder
from jaxarm.arm.registry import ARMS, BACKENDS
from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import as_current
from jaxarm.paper import presets as preset_lib

RANKING_FILE = "ranking.json"
#: The first network key of a ranking by default: far above the reproduction's keys (0..29 and the seeds a user
#: passes to ``jaxarm reproduce --seed``), so the sets are chosen and measured on different networks.
DEFAULT_FIRST_SEED = 1000


def _set_key(metaparams: dict) -> tuple:
    return tuple(sorted((k, float(v)) for k, v in metaparams.items()))


def _pool_epochs(described: list[dict]) -> int:
    """The training length the pool's sources share (a preset's protocol, an earlier ranking's); a one-line error
    when they differ."""
    values = sorted({d["epochs"] for d in described})
    if len(values) != 1:
        raise ConfigError(f"--pool: the sources train for different numbers of epochs ({values}); give --epochs")
    return values[0]


def pool_from(sources: list[str], best: int | None, preset_dir: Path) -> tuple[list[dict], list[dict]]:
    """(sets, sources): the distinct sets of ``sources`` in order, each ``{"metaparams", "source", "earlier"}``
    (``earlier``: the per-seed results an earlier ranking holds for it), and a description of every source.

    A source is a preset (name or .json path: its best set, then its top sets) or an earlier ``jaxarm rerank`` folder
    (its ``best`` best-ranked sets, default all of them). A set in several sources is kept once, at its first."""
    sets: dict[tuple, dict] = {}
    described = []
    for source in sources:
        folder = Path(source)
        if (folder / RANKING_FILE).is_file():
            ranking = json.loads((folder / RANKING_FILE).read_text())
            rows = ranking["sets"][:best] if best is not None else ranking["sets"]
            described.append({"ranking": str(folder), "command": ranking.get("command"), "sets": len(rows),
                              "pool": ranking.get("pool"), "epochs": ranking["protocol"]["epochs"]})
            found = [(row["metaparams"], row["source"], row["runs"]) for row in rows]
        else:
            try:
                preset = preset_lib.load(source, preset_dir)
            except ConfigError as e:
                raise ConfigError(f"--pool {source!r}: neither a `jaxarm rerank` folder (no {RANKING_FILE}) nor a "
                                  f"preset ({e})") from None
            described.append({"preset": preset.name, "description": preset.description,
                              "provenance": preset.provenance, "sets": 1 + len(preset.top), "epochs": preset.epochs})
            found = [(preset.best, f"{preset.name} best", [])]
            found += [(row["metaparams"], f"{preset.name} top[{i}]", []) for i, row in enumerate(preset.top)]
        for metaparams, where, runs in found:
            metaparams = as_current(metaparams)   # an earlier ranking's sets may carry them
            sets.setdefault(_set_key(metaparams), {"metaparams": metaparams, "source": where,
                                                  "earlier": list(runs)})
    if not sets:
        raise ConfigError("--pool: no metaparameter sets found")
    return list(sets.values()), described


#: How a ranking orders sets of equal success rate: ``reach`` by the mean closest approach; ``stay`` by the mean
#: distance to the target centre after first entry over the networks that entered (the paper's §3.2 measure: reaches
#: that stop near the target rank first), then the closest approach.
RANK_BY = ("reach", "stay")


def _check_rank_by(by: str) -> None:
    if by not in RANK_BY:
        raise ConfigError(f"--rank-by = {by!r}: must be one of {', '.join(RANK_BY)}")


def rank(sets: list[dict], by: str = "reach") -> list[dict]:
    """The sets ordered by success rate over all their runs (highest first), then (``by``, :data:`RANK_BY`) by the
    mean closest approach, or by the mean distance after entry and then the closest approach (smallest first),
    then by pool order; each with ``rank``, ``successes``, ``n``, ``rate``, ``mean_min_distance_m``,
    ``mean_distance_after_m``."""
    _check_rank_by(by)
    inf = float("inf")
    rows = []
    for i, s in enumerate(sets):
        success = [x for r in s["runs"] for x in r["success"]]
        dist = [x for r in s["runs"] for x in r["min_distance_m"]]
        after = [x for r in s["runs"] for x in r.get("distance_after_m", []) if x is not None]
        rows.append({**s, "successes": int(sum(success)), "n": len(success),
                     "rate": float(np.mean(success)) if success else 0.0,
                     "mean_min_distance_m": round(float(np.mean(dist)), 5) if dist else None,
                     "mean_distance_after_m": round(float(np.mean(after)), 5) if after else None, "_order": i})

    def key(r):
        closest = r["mean_min_distance_m"] if r["mean_min_distance_m"] is not None else inf
        if by == "stay":
            after = r["mean_distance_after_m"] if r["mean_distance_after_m"] is not None else inf
            return -r["rate"], after, closest, r["_order"]
        return -r["rate"], closest, r["_order"]

    rows.sort(key=key)
    return [{"rank": i + 1, **{k: v for k, v in r.items() if k != "_order"}} for i, r in enumerate(rows)]


def rerank(arm: str, target: str, pool: list[str], out: Path, *, seeds: int = 8,
           first_seed: int = DEFAULT_FIRST_SEED, best: int | None = None, epochs: int | None = None,
           rank_by: str = "reach", epoch_s: float = 30.0, test_s: float = 1.0, backend: str = "fast",
           progress: bool = True, command: str | None = None, stop_after: int | None = None, log=print,
           preset_dir: Path = preset_lib.PRESET_DIR) -> dict | None:
    """Train every set of the pool with ``seeds`` network keys ``first_seed ..``, test, rank (``rank_by``,
    :data:`RANK_BY`); write and return ranking.json's content (None when ``stop_after`` stopped the training early:
    run again to resume)."""
    from jaxarm.analysis.reach import distance_metrics
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.run import Runner, stack_rows
    from jaxarm.task.config import Target, TaskConfig

    if not 1 <= seeds <= 1024:
        raise ConfigError(f"--seeds = {seeds}: must be in [1, 1024]")
    if first_seed < 0:
        raise ConfigError(f"--first-seed = {first_seed}: must be >= 0")
    if best is not None and best < 1:
        raise ConfigError(f"--best = {best}: must be >= 1")
    if epochs is not None and not 1 <= epochs <= 1000:
        raise ConfigError(f"--epochs = {epochs}: must be in [1, 1000]")
    _check_rank_by(rank_by)   # before any training
    sets, sources = pool_from(pool, best, preset_dir)
    new_seeds = list(range(first_seed, first_seed + seeds))
    used = sorted({s for st in sets for r in st["earlier"] for s in r["seeds"]} & set(new_seeds))
    if used:
        raise ConfigError(f"--first-seed = {first_seed}: seeds {used[0]}..{used[-1]} already tested these sets in "
                          f"the earlier ranking; give --first-seed >= "
                          f"{max(s for st in sets for r in st['earlier'] for s in r['seeds']) + 1}")
    mps = [MetaParams.from_dict(s["metaparams"]) for s in sets]
    n_epochs = epochs if epochs is not None else _pool_epochs(sources)
    config = LoopConfig(arm=arm, backend=backend, task=TaskConfig(target=target, epochs=n_epochs,
                                                                  epoch_duration_s=epoch_s, test_duration_s=test_s))
    out = Path(out)
    n = len(sets) * seeds
    identity = {"arm": arm, "target": target, "backend": backend, "epochs": n_epochs, "epoch_s": epoch_s,
                "test_s": test_s, "seeds": new_seeds, "sets": [s["metaparams"] for s in sets],
                "earlier": [s["earlier"] for s in sets], "rank_by": rank_by}
    finished = _finished(out, identity)
    if finished is not None:
        log(f"{out / RANKING_FILE}: this ranking finished earlier, reused")
        return finished
    batch = Runner(config, new_seeds * len(sets), stack_rows([m for m in mps for _ in range(seeds)]),
                  Target.stack([config.task.target] * n), out,
                  {"rerank": {k: v for k, v in identity.items() if k not in ("earlier", "rank_by")},
                   "label": f"{arm}/{target}: {len(sets)} sets x {seeds} seeds"})
    log(f"{len(sets)} sets x {seeds} seeds ({first_seed}..{first_seed + seeds - 1}) = {n} networks, {n_epochs} x "
        f"{epoch_s:g} s on the {arm} arm, {target} target, one batch over {batch.mesh.size} device(s) -> {out}")
    import jax

    log(parallel.padding_note(n, f"the batch's {n} networks", batch.mesh.size, batch.at_once, jax.process_count(),
                              ("--seeds", lambda v: len(sets) * v, seeds)))
    t0 = time.perf_counter()
    carry, _, wall, epochs_run, compile_s = batch.train(progress=progress, stop_after=stop_after)
    if int(parallel.host(carry.epoch)[0]) < n_epochs:
        log(f"stopped after {stop_after} epoch(s); run the same command again to resume")
        return None
    result = batch.test(carry.trained)
    success = np.asarray(result.success, bool).reshape(len(sets), seeds)
    closest = np.asarray(result.min_distance_m, np.float64).reshape(len(sets), seeds)
    after = np.asarray(distance_metrics(result.distance_m, config.task.update_interval_s,
                                        config.task.success_radius_m).distance_after_m,
                       np.float64).reshape(len(sets), seeds)
    for s, ok, d, a in zip(sets, success, closest, after):
        s["runs"] = s.pop("earlier") + [{"seeds": new_seeds, "success": [bool(x) for x in ok],
                                         "min_distance_m": [round(float(x), 5) for x in d],
                                         "distance_after_m": [None if np.isnan(x) else round(float(x), 5)
                                                              for x in a]}]
    ranked = rank(sets, rank_by)
    table = {
        "arm": arm, "target": target, "command": command, "pool": sources, "rank_by": rank_by, "identity": identity,
        "protocol": {"epochs": n_epochs, "epoch_s": epoch_s, "test_s": test_s, "seeds": new_seeds,
                     "success_radius_m": config.task.success_radius_m, "backend": backend,
                     "keys": "network j of every set uses PRNGKey(seed j); a set's rate counts every run it had",
                     "loop": json.loads(json.dumps(asdict(config), default=str))},
        "timing": {"train_wall_s": round(wall, 2), "compile_s": round(compile_s, 2), "epochs_run": epochs_run,
                   "network_seconds_trained": epochs_run * epoch_s * n,
                   "network_s_per_s": round(epochs_run * epoch_s * n / wall, 2) if wall > 0 else None,
                   "wall_s_this_invocation": round(time.perf_counter() - t0, 2),
                   "device": parallel.describe()},
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "sets": ranked,
    }
    if parallel.is_main_process():
        out.mkdir(parents=True, exist_ok=True)
        (out / RANKING_FILE).write_text(json.dumps(table, indent=1) + "\n")
        log(format_ranking(table))
        log(f"-> {out / RANKING_FILE}")
    return table


def _finished(out: Path, identity: dict) -> dict | None:
    """The folder's ranking when it was made from this exact pool, protocol and seeds (a rerun, e.g. to add
    --make-preset, then trains nothing)."""
    path = out / RANKING_FILE
    if not path.is_file():
        return None
    try:
        table = runfolder.read_json(path)
    except runfolder.DamagedFile as e:     # ranked again from the checkpoints, which were kept
        print(f"jaxarm rerank: note: {e}; ranking again", file=sys.stderr)
        return None
    return table if table.get("identity") == json.loads(json.dumps(identity)) else None


def format_ranking(table: dict, rows: int = 40) -> str:
    seeds = table["protocol"]["seeds"]
    lines = [f"{table['arm']} arm, {table['target']} target, {table['protocol']['epochs']} epochs; this run's seeds "
             f"{seeds[0]}..{seeds[-1]}; ranked by {table.get('rank_by', 'reach')}",
             "rank  reached      rate  mean closest (cm)  after entry (cm)  source"]
    cm = lambda x: "-" if x is None else f"{100 * x:.2f}"   # noqa: E731
    for r in table["sets"][:rows]:
        lines.append(f"{r['rank']:>4}  {r['successes']:>3}/{r['n']:<5}  {r['rate']:>5.2f}  "
                     f"{cm(r['mean_min_distance_m']):>17}  {cm(r.get('mean_distance_after_m')):>16}  {r['source']}")
    if len(table["sets"]) > rows:
        lines.append(f"... {len(table['sets']) - rows} more in {RANKING_FILE}")
    return "\n".join(lines)


def preset_from_ranking(folder: Path, name: str, description: str | None = None) -> preset_lib.Preset:
    """A preset of a finished ranking: ``best`` its rank-1 set, ``top`` its first 30, the protocol's epochs, and
    the ranking (commands, pool provenance, counts, cost) as provenance."""
    path = Path(folder) / RANKING_FILE
    if not path.is_file():
        raise ConfigError(f"--from-rerank {folder}: {RANKING_FILE} not found (a finished `jaxarm rerank` folder)")
    table = json.loads(path.read_text())
    rows = table["sets"][:preset_lib.MAX_TOP]
    epochs = table["protocol"]["epochs"]
    top = [{"rank": r["rank"], "successes": r["successes"], "n": r["n"], "source": r["source"],
            "metaparams": r["metaparams"]} for r in rows]
    if description is None:
        description = (f"{table['arm']} arm, {table['target']} target: the {len(rows)} sets of a pool that reached "
                       f"most often over {rows[0]['n']} fresh seeds each (jaxarm rerank, {epochs} epochs)")
    provenance = {"source": "jaxarm rerank", "command": table.get("command"), "folder": str(folder),
                  "seed": table["protocol"]["seeds"][0], "rank_by": table.get("rank_by", "reach"),
                  "pool": table["pool"], "protocol": {k: v for k, v in table["protocol"].items() if k != "loop"},
                  "cost": table["timing"], "ranked": table["date"],
                  "date": _dt.datetime.now(_dt.timezone.utc).date().isoformat()}
    return preset_lib.Preset(name=name, description=description, arms=(table["arm"],), best=rows[0]["metaparams"],
                             top=tuple(top), provenance=provenance, targets=(table["target"],),
                             protocol={"epochs": int(epochs), "why": f"ranked on {epochs} epochs"})


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="jaxarm rerank", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=tuple(ARMS))
    ap.add_argument("--target", help="one target (left, bottom, ...)")
    ap.add_argument("--pool",
                    help="comma-separated presets (names or .json paths: best and top sets) and earlier `jaxarm "
                         "rerank` folders (their --best sets)")
    ap.add_argument("--best", type=int, default=None,
                    help="from an earlier ranking in --pool, only its BEST best-ranked sets (default: all)")
    ap.add_argument("--seeds", type=int, default=8, help="networks per set (default 8)")
    ap.add_argument("--first-seed", type=int, default=DEFAULT_FIRST_SEED,
                    help=f"network j of every set uses PRNGKey(first_seed + j) (default {DEFAULT_FIRST_SEED}, apart "
                         "from the reproduction's seeds)")
    ap.add_argument("--epochs", type=int, default=None,
                    help="training epochs (default: the protocol epochs the pool's sources share)")
    ap.add_argument("--rank-by", choices=RANK_BY, default="reach",
                    help="sets of equal success rate ordered by the mean closest approach (reach, default) or by the "
                         "mean distance after entry, the paper's measure of staying (stay)")
    ap.add_argument("--epoch-s", type=float, default=30.0, help="seconds per epoch (paper: 30)")
    ap.add_argument("--test-s", type=float, default=1.0, help="test duration, s (paper: 1)")
    ap.add_argument("--backend", choices=BACKENDS, default="fast", help="musculoskeletal geometry backend")
    ap.add_argument("--out", type=runfolder.folder_argument,
                    help="output folder (a rerun resumes it; one command at a time, OUT/jaxarm.lock)")
    ap.add_argument("--make-preset", metavar="NAME", help="when ranked, also write preset NAME.json of the ranking")
    ap.add_argument("--from-rerank", type=Path, metavar="DIR",
                    help="with --make-preset: write the preset of this finished ranking folder and exit")
    ap.add_argument("--description", help="the preset's one-line description (default: from the ranking)")
    ap.add_argument("--preset-dir", type=Path, default=preset_lib.PRESET_DIR,
                    help=f"where presets are read and written (default: the package's, {preset_lib.PRESET_DIR})")
    ap.add_argument("--no-progress", action="store_true")
    parallel_cli.add_arguments(ap)
    return ap


def rerank_main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        if args.from_rerank is not None:
            if not args.make_preset:
                ap.error("--from-rerank needs --make-preset NAME")
            p = preset_from_ranking(args.from_rerank, args.make_preset, args.description)
            print(f"preset {p.name!r}: best set + {len(p.top)} top sets -> {preset_lib.save(p, args.preset_dir)}")
            return 0
        missing = [o for o, v in (("--arm", args.arm), ("--target", args.target), ("--pool", args.pool),
                                  ("--out", args.out)) if v is None]
        if missing:
            ap.error(f"{', '.join(missing)} required (or --make-preset NAME --from-rerank DIR)")
        parallel_cli.start_from_arguments(args)
        pool = [p.strip() for p in args.pool.split(",") if p.strip()]
        with runfolder.claim(args.out, "jaxarm rerank"):
            table = rerank(args.arm, args.target, pool, args.out, seeds=args.seeds, first_seed=args.first_seed,
                           best=args.best, epochs=args.epochs, rank_by=args.rank_by, epoch_s=args.epoch_s,
                           test_s=args.test_s,
                           backend=args.backend, progress=not args.no_progress, preset_dir=args.preset_dir,
                           command=shlex.join(["jaxarm", "rerank", *argv]))
        if table is not None and args.make_preset and parallel.is_main_process():
            p = preset_from_ranking(args.out, args.make_preset, args.description)
            print(f"preset {p.name!r}: best set + {len(p.top)} top sets -> {preset_lib.save(p, args.preset_dir)}")
    except ConfigError as e:
        print(f"jaxarm rerank: {e}", file=sys.stderr)
        return 2
    return 0 if table is not None else 1
