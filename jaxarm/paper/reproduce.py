"""``jaxarm reproduce``: the paper's success statistic (trained networks reaching the target), two ways.

    jaxarm reproduce --arm musculoskeletal --out runs/repro-msarm         # the arm's default protocol
    jaxarm reproduce --arm musculoskeletal --preset NAME --out runs/repro-msarm
    jaxarm reproduce --list-presets
    jaxarm reproduce --make-preset NAME --from-search runs/evolve-msarm     # a preset from a finished search

(a) ``seeds``: the preset's best metaparameter set, trained with ``--networks`` (30) seeds per target: how reliable
    one configuration is.
(b) ``top30``: the preset's top configurations (up to 30, ranked), one network each (set i with seed i): what the
    paper counted ("the 30 best metaparameter configurations of the evolutionary search"). A preset without a top
    list (e.g. ``original``) reports (b) as null, with the reason.

Without ``--preset``, each (target, mode) runs what the arm's headline numbers ran (:data:`DEFAULT_PROTOCOL`: a
preset, its epochs and settings), printed first. Network i uses the key ``PRNGKey(seed + i)`` in both. The protocol
is ``jaxarm train``'s: ``epochs`` of 30 s (default: the preset's ``epochs`` metaparameter, 12), a 1 s test, success =
the hand enters the 4 cm circle. Each
(target, mode) is an ordinary ``jaxarm train`` output folder (``OUT/TARGET/seeds``, ``OUT/TARGET/top30``: results.json,
trajectories.npz, reach.png, per-epoch checkpoints): running the same command again resumes a killed reproduction
from its last completed epoch, and reuses folders that are finished.

``OUT/success_table.json``: ``targets[T]`` = {seeds, seeds_n, top30, top30_n, top30_note, naive counts, median
closest/final distance of each mode, the paper's count, the (target, mode) protocol, and ``measures``: the paper's
§3.2 reach measures and Fig. 7 jerk of each mode beside the paper's values and the ratio}, plus arm, presets (and
their provenance), command, seed, protocol, timing (wall s, network-seconds per s) and the paper's numbers. The same
tables are printed, the second in Markdown (:func:`results_markdown`).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shlex
import sys
import time
from pathlib import Path

import jax
import numpy as np

from jaxarm import parallel, parallel_cli, runfolder
from jaxarm.arm.registry import ARMS, BACKENDS
from jaxarm.config.network import RUNTIME_FIELDS, SAME_STEP_INHIBITION
from jaxarm.config.validate import ConfigError
from jaxarm.paper import presets as preset_lib
from jaxarm.task.registry import DEFAULT as TASK_DEFAULT, TASKS

#: Trained networks reaching the target in the paper (Dura-Bernal et al. 2015, §3.2), out of PAPER_N: its 30 best
#: metaparameter configurations of the search, one network each (our mode (b)).
PAPER_SUCCESS: dict[str, dict[str, int]] = {"musculoskeletal": {"left": 29, "bottom": 26},
                                            "simple": {"left": 28, "bottom": 27}}
PAPER_N = 30
PAPER_SOURCE = "Dura-Bernal et al. 2015, §3.2: trained networks whose hand entered the 4 cm circle in the 1 s test"
TABLE_FILE = "success_table.json"
MODES = ("seeds", "top30")
#: Targets reproduced when neither --targets nor the preset names any: the paper's two.
DEFAULT_TARGETS = ("left", "bottom")


def _median_of(results: dict, key: str):
    vals = [n[key] for n in results["networks"] if n.get(key) is not None]
    return round(float(np.median(vals)), 5) if vals else None


def _finished(run) -> dict | None:
    """The folder's results.json when it holds this exact run, finished (same loop config and meta)."""
    path = run.out / "results.json"
    if not path.is_file():
        return None
    try:
        res = runfolder.read_json(path)
    except runfolder.DamagedFile as e:     # written again from the batch's checkpoints, which were kept
        print(f"jaxarm reproduce: note: {e}; writing it again", file=sys.stderr)
        return None
    want = run.config_record()
    return res if _comparable(res.get("config")) == _comparable(want) else None


def _comparable(config):
    if not isinstance(config, dict):
        return config
    config = json.loads(json.dumps(config))
    net = config.get("loop", {}).get("network")
    if isinstance(net, dict):
        for k in RUNTIME_FIELDS:   # how, not what: a folder finished with other values is reused (the two kernels
            net.pop(k, None)       # agree to float rounding, tests/test_native_kernel.py; threads never change results)
    return config


def batch_layout(groups: list, devices: int, at_once: int) -> str:
    """How a reproduction's batch (``groups``: its (target, mode) runs) fills its groups of ``at_once`` networks on
    ``devices`` devices: whole groups, or the padding and the ``--networks`` that fills them (the seeds groups have
    ``--networks`` networks each, the sets groups one per set)."""
    from jaxarm.run import SetsRun

    n = sum(g.n for g in groups)
    seeded = [g for g in groups if not isinstance(g, SetsRun)]
    fixed = n - sum(g.n for g in seeded)
    fill = ("--networks", lambda v: len(seeded) * v + fixed, seeded[0].n) if seeded else None
    return parallel.padding_note(n, f"the batch's {n} networks", devices, at_once, jax.process_count(), fill)


def _train_together(groups: list, out: Path, progress: bool, stop_after: int | None, log):
    """Train every group's networks in one batch (one compiled program over every device), test them, and write
    each group's ordinary `jaxarm train` folder (results, trajectories, figure, and a checkpoint of its trained
    networks for `jaxarm test --from`). The batch checkpoints itself in ``out/checkpoints``; a batch whose folders
    are all finished is reused. Returns {folder: (results, timing)} or None when ``stop_after`` stopped it early."""
    from jaxarm.checkpoint import Checkpointer
    from jaxarm.experiment import write_outputs
    from jaxarm.run import Runner, select, stack_rows, unstack
    from jaxarm.task.config import Target

    done = {g.out: _finished(g) for g in groups}
    if all(r is not None for r in done.values()):
        for g in groups:
            log(f"  {g.out}: finished earlier, reused")
        return {g.out: (done[g.out], {"reused": True}) for g in groups}
    first = groups[0]
    rows, start = [], 0
    for g in groups:
        rows.append(slice(start, start + g.n))
        start += g.n
    batch = Runner(first.config, [s for g in groups for s in g.seeds],
                  stack_rows([m for g in groups for m in unstack(g.mps)]),
                  Target(*(np.concatenate(parts) for parts in zip(*(g.targets for g in groups)))), out,
                  {"reproduction": [{"folder": os.path.relpath(g.out, out), **g.meta()} for g in groups],
                   "label": f"{first.config.arm}: {len(groups)} groups, {start} networks"})
    log(f"training {start} networks of {len(groups)} groups in one batch over {batch.mesh.size} device(s) -> "
        f"{out / 'checkpoints'}")
    log(batch_layout(groups, batch.mesh.size, batch.at_once))
    carry, history, wall, epochs_run, compile_s = batch.train(progress=progress, stop_after=stop_after)
    if int(parallel.host(carry.epoch)[0]) < first.config.task.epochs:
        return None
    trained, naive = batch.test(carry.trained), batch.test(batch.naive())
    host_carry = parallel.host(carry)
    results = {}
    for g, r in zip(groups, rows):
        part = select(r, trained, naive, history)
        res = write_outputs(g, part.trained, part.naive, part.history, wall, epochs_run, compile_s)
        with Checkpointer(g.out / "checkpoints") as ckpt:   # the group's trained networks, for `jaxarm test --from`
            ckpt.save(g.config.task.epochs, (jax.tree.map(lambda x: x[r], host_carry), part.history),
                      g.meta() | {"layout": {"padded_networks": g.n}})
        results[g.out] = res, {"reused": False, "batch_networks": start, "train_wall_s": round(wall, 2),
                               "epochs_run": epochs_run, "compile_s": round(compile_s, 2)}
    return results


#: What ``jaxarm reproduce --arm ARM`` runs without ``--preset``: the protocol of each arm's headline numbers (README,
#: "Results beside the paper"). target -> mode -> (preset, epochs or None for the preset's own, {metaparameter: value}).
DEFAULT_PROTOCOL: dict[str, dict[str, dict[str, tuple[str, int | None, dict]]]] = {
    # bottom (b): the 30 sets of two searches that stayed closest after entry among those that reached on every one
    # of 4 fresh seeds (jaxarm rerank --rank-by stay; the paper's 3.2 cm after entry); the rest the 2 cm search's
    "musculoskeletal": {"left": {m: ("msarm-cmaes-2cm-rerank", None, {}) for m in MODES},
                        "bottom": {"seeds": ("msarm-cmaes-2cm-rerank", None, {}),
                                   "top30": ("msarm-rerank-bottom-stay", None, {})}},
    # each target: the pool of its searches' best sets ranked by how often they reach on fresh seeds (jaxarm
    # rerank, in stages: 32 seeds for the left sets, 24 for the bottom ones): (a) the most reliable set, (b) the 30
    # most reliable; left shoulder-only babbling for 6 epochs, bottom single-group babbling for 16
    "simple": {t: {m: (name, None, {}) for m in MODES}
               for t, name in (("left", "simple-rerank-left-32"), ("bottom", "simple-rerank-bottom-24"))},
}


#: What ``jaxarm reproduce --task centre-out-8 --arm ARM`` trains without ``--preset``: the arm's centre-out preset,
#: whose sets and network (the target code, and which pathways learn) a search at the full protocol found
#: (docs/centre-out.md); an arm without one trains the authors' set on the paper's network with the default code.
CENTRE_OUT_PRESETS: dict[str, str] = {"simple": "simple-centre-out-code"}


def describe_protocol(plan: dict) -> str:
    """One line per target: which preset, epochs and --set each mode runs."""
    lines = []
    for target, modes in plan.items():
        parts = []
        for mode, step in modes.items():
            extra = "".join(f" --set {k}={v:g}" for k, v in step["set"].items())
            parts.append(f"({'a' if mode == 'seeds' else 'b'}) {step['preset'].name}, {step['epochs']} epochs{extra}")
        lines.append(f"  {target}: " + "; ".join(parts))
    return "\n".join(lines)


def reproduction_plan(preset, arm: str, targets, epochs, top: int, overrides: dict, directory: Path) -> dict:
    """target -> mode -> {preset, sets, epochs, set}: what each (target, mode) group trains. One ``preset``
    for every group, or (None) the arm's :data:`DEFAULT_PROTOCOL`; ``epochs`` and ``overrides`` apply to all."""
    from jaxarm.learning.metaparams import MetaParams

    if preset is None:
        protocol = DEFAULT_PROTOCOL[arm]
        targets = list(targets if targets is not None else protocol)
        unknown = [t for t in targets if t not in protocol]
        if unknown:
            raise ConfigError(f"--targets = {','.join(targets)!r}: the {arm} arm's default protocol has "
                              f"{', '.join(protocol)}; give --preset for other targets")
        steps = {t: {m: (preset_lib.load(name, directory), ep, s) for m, (name, ep, s) in protocol[t].items()}
                 for t in targets}
    else:
        targets = list(targets if targets is not None else (preset.targets or DEFAULT_TARGETS))
        steps = {t: {m: (preset, None, {}) for m in MODES} for t in targets}
    if not targets or len(set(targets)) != len(targets):
        raise ConfigError(f"--targets = {','.join(targets)!r}: give one or more distinct targets")
    plan = {}
    for target, modes in steps.items():
        plan[target] = {}
        for mode, (p, ep, fixed) in modes.items():
            changes = {**fixed, **overrides}
            sets = [p.best_metaparams()] if mode == "seeds" else p.top_metaparams(top)
            if not sets:
                continue
            if changes:
                sets = [MetaParams.from_dict({**m.to_dict(), **changes}) for m in sets]
            if epochs is not None:
                n_epochs = epochs
            elif ep is not None:
                n_epochs = ep
            else:                              # the preset's published numbers used this length
                n_epochs = p.epochs
            plan[target][mode] = {"preset": p, "sets": sets, "epochs": n_epochs, "set": changes}
    return plan


def reproduce(preset: preset_lib.Preset | None, arm: str, targets, out: Path, *, networks: int = 30, seed: int = 0,
              epochs: int | None = None, epoch_s: float = 30.0, test_s: float = 1.0, top: int = preset_lib.MAX_TOP,
              backend: str = "fast", progress: bool = True, command: str | None = None,
              overrides: dict[str, float] | None = None, stop_after: int | None = None,
              dt_ms: float | None = None, log=print, preset_dir: Path = preset_lib.PRESET_DIR,
              network=None) -> dict | None:
    """Run (or resume) modes (a) and (b) for every target (``targets`` None: the preset's own targets if it names
    any, else :data:`DEFAULT_TARGETS`); write and return the success table. ``preset`` None: the arm's
    :data:`DEFAULT_PROTOCOL` (a preset, epochs and settings per target and mode). ``overrides`` ({name: value},
    each within its bound; ``--set``) replaces those metaparameters in the best set and in every top set alike (an
    ``epochs`` override sets the training length, as ``--epochs`` does). ``stop_after``:
    stop the first unfinished folder after that many epochs of this call and return None (tests use it to
    interrupt a run). ``dt_ms``: the network clock step (None: NetworkConfig's default), recorded in the runs'
    meta when not the default. ``network``: the NetworkConfig to start from (None: the paper's; ``--network``,
    ``--network-scale``); its fields that differ from the defaults are recorded in the runs' meta."""
    from jaxarm.run import Run, SetsRun
    from jaxarm.run import stack_rows as stack
    from jaxarm.loop import LoopConfig
    from jaxarm.task.config import TaskConfig

    if not 1 <= networks <= 4096:
        raise ConfigError(f"--networks = {networks}: must be in [1, 4096]")
    if not 1 <= top <= preset_lib.MAX_TOP:
        raise ConfigError(f"--top = {top}: must be in [1, {preset_lib.MAX_TOP}]")
    if seed < 0:
        raise ConfigError(f"--seed = {seed}: must be >= 0")
    if epochs is not None and not 1 <= epochs <= 1000:
        raise ConfigError(f"--epochs = {epochs}: must be in [1, 1000]")
    overrides = dict(overrides or {})
    plan = reproduction_plan(preset, arm, targets, epochs, top, overrides, preset_dir)
    targets = list(plan)
    if preset is None:
        log(f"the {arm} arm's default protocol (the README's headline numbers; --preset NAME runs one preset):\n"
            + describe_protocol(plan))
    else:
        why = f" ({preset.protocol['why']})" if preset.protocol and epochs is None and "why" in preset.protocol else ""
        log(f"preset {preset.name!r}{why}:\n" + describe_protocol(plan))
        if arm not in preset.arms:
            log(f"note: preset {preset.name!r} was tuned for the {'/'.join(preset.arms)} arm; running it on the "
                f"{arm} arm")
        other = [t for t in targets if preset.targets is not None and t not in preset.targets]
        if other:
            log(f"note: preset {preset.name!r} was tuned for the {','.join(preset.targets)} target; running it on "
                f"{','.join(other)} too")
    no_top = {t: None if "top30" in plan[t] else f"preset {plan[t]['seeds']['preset'].name!r} has no top list "
                                                 "(only its best set is known)" for t in targets}

    from jaxarm.network import NetworkConfig

    network = network or NetworkConfig()
    if dt_ms is not None:
        network = dataclasses.replace(network, dt_ms=dt_ms)

    def config(target, n_epochs):
        return LoopConfig(arm=arm, backend=backend, network=network, task=TaskConfig(
            target=target, epochs=n_epochs, epoch_duration_s=epoch_s, test_duration_s=test_s))

    configs = {t: {m: config(t, step["epochs"]) for m, step in modes.items()} for t, modes in plan.items()}  # validate
    out = Path(out)
    t_start = time.perf_counter()
    groups = {}
    for target, modes in plan.items():
        for mode, step in modes.items():
            folder = out / target / mode
            groups[(target, mode)] = (Run(configs[target][mode], networks, seed, folder, step["sets"][0])
                                      if mode == "seeds" else
                                      SetsRun(configs[target][mode], seed, folder, stack(step["sets"])))
    for (target, mode), run in groups.items():
        log(f"{arm} arm, {target} target, ({'a' if mode == 'seeds' else 'b'}) {mode}: {run.n} networks, "
            f"{run.config.task.epochs} x {epoch_s:g} s -> {run.out}")
    # Every (target, mode) group trains in one batch; groups of another length (--epochs unset and the top sets'
    # epochs differing from the best set's) form a second batch: a compiled loop has one length.
    by_epochs: dict[int, list] = {}
    for key, run in groups.items():
        by_epochs.setdefault(run.config.task.epochs, []).append(key)
    got, batches = {}, {}
    for n_epochs, keys in by_epochs.items():
        home = out if len(by_epochs) == 1 else out / f"batch-{n_epochs}-epochs"   # its checkpoints/ go here
        one = _train_together([groups[k] for k in keys], home, progress, stop_after, log)
        if one is None:
            log(f"stopped after {stop_after} epoch(s); run the same command again to resume")
            return None
        for k in keys:
            got[k] = one[groups[k].out]
        batches[f"{n_epochs} epochs"] = next(iter(one.values()))[1]
    rows = {}
    for target in targets:
        a = got[(target, "seeds")][0]
        b = got[(target, "top30")][0] if "top30" in plan[target] else None
        paper = PAPER_SUCCESS.get(arm, {}).get(target)
        rows[target] = {
            "seeds": a["success_count"], "seeds_n": a["n_networks"],
            "top30": None if b is None else b["success_count"], "top30_n": 0 if b is None else b["n_networks"],
            "top30_note": no_top[target] if b is None else (
                None if b["n_networks"] == PAPER_N else f"the preset's top list gives {b['n_networks']} sets, not 30"),
            "seeds_naive": a["naive"]["success_count"],
            "top30_naive": None if b is None else b["naive"]["success_count"],
            "seeds_median_min_distance_m": _median_of(a, "min_distance_m"),
            "seeds_median_final_distance_m": _median_of(a, "final_distance_m"),
            "top30_median_min_distance_m": None if b is None else _median_of(b, "min_distance_m"),
            "top30_median_final_distance_m": None if b is None else _median_of(b, "final_distance_m"),
            "paper": paper, "paper_n": PAPER_N if paper is not None else None,
            "folders": {m: str(Path(target) / m) for m in plan[target]},
            "protocol": {m: {"preset": step["preset"].name, "epochs": step["epochs"], "set": step["set"]}
                         for m, step in plan[target].items()},
        }
        if parallel.is_main_process():   # the files are process 0's
            rows[target]["measures"] = {m: _measures(out / target / m) for m in plan[target]}
    wall = time.perf_counter() - t_start
    trained = [t for t in batches.values() if not t["reused"]]
    train_wall = sum(t["train_wall_s"] for t in trained)
    net_s = sum(t["epochs_run"] * epoch_s * t["batch_networks"] for t in trained)
    presets = {step["preset"].name: step["preset"] for modes in plan.values() for step in modes.values()}
    first = plan[targets[0]]
    table = {
        "arm": arm, "backend": backend, "preset": preset.name if preset is not None else f"default ({arm} arm)",
        "presets": {name: {"description": p.description, "arms": list(p.arms), "provenance": p.provenance}
                    for name, p in presets.items()},
        "command": command, **measured_on(), "seed": seed, "set": overrides,
        "protocol": {"networks_seeds": networks, "top_sets": max((len(m["top30"]["sets"]) for m in plan.values()
                                                                 if "top30" in m), default=0),
                     "epochs_seeds": first["seeds"]["epochs"],
                     "epochs_top30": first["top30"]["epochs"] if "top30" in first else None,
                     "per_target": "targets.<target>.protocol", "epoch_s": epoch_s, "test_s": test_s,
                     "success_radius_m": configs[targets[0]]["seeds"].task.success_radius_m,
                     "keys": "network i uses PRNGKey(seed + i); in top30, network i trains with the preset's set i"},
        "targets": rows,
        "paper": {"source": PAPER_SOURCE, "n": PAPER_N, "success": PAPER_SUCCESS.get(arm),
                  "statistic": "the 30 best configurations of the search, one network each: our top30"},
        "timing": {"wall_s_this_invocation": round(wall, 2), "train_wall_s": round(train_wall, 2),
                   "network_seconds_trained": net_s,
                   "network_s_per_s": round(net_s / train_wall, 3) if train_wall > 0 else None,
                   "note": "wall_s_this_invocation includes compilation, tests and writing (a rerun that reuses "
                           "finished folders is short); every group trains in one batch (a second one only for "
                           "groups of another length): train_wall_s and network_seconds_trained are the batches' "
                           "training in this invocation",
                   "device": jax.default_backend(), "layout": parallel.describe(), "batches": batches},
    }
    if parallel.is_main_process():
        out.mkdir(parents=True, exist_ok=True)
        (out / TABLE_FILE).write_text(json.dumps(table, indent=1) + "\n")
        log(format_table(table))
        log(results_markdown(table))
        log(f"-> {out / TABLE_FILE}")
    return table


def measured_on() -> dict:
    """When, where and from which code a result is measured: ``date`` (UTC), ``machine`` (architecture and usable
    cores) and ``commit`` (this checkout's, ``-dirty`` with uncommitted changes to tracked files; None outside a git
    checkout)."""
    import platform
    import subprocess
    from datetime import datetime, timezone

    def git(*args) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(Path(__file__).resolve().parent), *args], capture_output=True,
                                  text=True, timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    head = git("rev-parse", "--short", "HEAD")
    commit = None if head is None else head + ("-dirty" if git("status", "--porcelain", "--untracked-files=no")
                                               else "")
    return {"date": datetime.now(timezone.utc).strftime("%Y-%m-%d"),
            "machine": f"{platform.machine()}, {parallel.usable_cores()} cores", "commit": commit}


def _measures(folder: Path) -> dict:
    """A group's reach measures (§3.2) and jaxarm.paper.comparison's jerk (Fig. 7), each beside the paper's value."""
    from jaxarm.paper.comparison import beside_paper, target_stats

    return beside_paper(target_stats(folder))


def results_markdown(table: dict) -> str:
    """The whole results table in Markdown: per target, the counts then every measure, (a) and (b) beside the
    paper's value and the ratio ours / paper ((a) mean (SD) over the networks that reached, as the paper averaged)."""
    from jaxarm.paper.comparison import MEASURES

    def cell(m):
        if m is None or m["mean"] is None:
            return "–"
        return f"{m['mean']:.3g}" + (f" ({m['sd']:.2g})" if m["sd"] is not None else "")

    lines = ["| target | quantity | (a) best set, N seeds | (b) top sets | paper | (a) / paper | (b) / paper |",
             "|---|---|---|---|---|---|---|"]
    for target, r in table["targets"].items():
        b = "n/a" if r["top30"] is None else f"{r['top30']}/{r['top30_n']}"
        paper = "–" if r["paper"] is None else f"{r['paper']}/{r['paper_n']}"

        def ratio(k, n):   # fraction reaching over the paper's fraction
            return "–" if r["paper"] is None or k is None else f"{(k / n) / (r['paper'] / r['paper_n']):.2f}"

        lines.append(f"| {target} | networks reaching (naive (a)) | {r['seeds']}/{r['seeds_n']} "
                     f"({r['seeds_naive']}/{r['seeds_n']}) | {b} | {paper} | "
                     f"{ratio(r['seeds'], r['seeds_n'])} | {ratio(r['top30'], r['top30_n'] or 1)} |")
        meas = r.get("measures", {})
        for key, label in MEASURES:
            a, bm = meas.get("seeds", {}).get(key), meas.get("top30", {}).get(key)
            ref = a or bm
            if ref is None:
                continue
            paper = "–" if ref["paper"] is None else f"{ref['paper']:.3g}" + (
                f" ({ref['paper_sd']:.2g})" if ref["paper_sd"] is not None else "")
            rr = lambda m: "–" if m is None or m["ratio"] is None else f"{m['ratio']:.2f}"  # noqa: E731
            lines.append(f"| {target} | {label} | {cell(a)} | {cell(bm)} | {paper} | {rr(a)} | {rr(bm)} |")
    return "\n".join(lines)


def format_table(table: dict) -> str:
    """The success table as text: ours (a) and (b) beside the paper's."""
    p = table["protocol"]
    head = (f"jaxarm reproduce: {table['arm']} arm, preset {table['preset']!r}, seed {table['seed']}, "
            f"epochs of {p['epoch_s']:g} s, {p['test_s']:g} s test, success = within "
            f"{p['success_radius_m'] * 100:g} cm")
    for target, r in table["targets"].items():
        head += "\n  " + target + ": " + "; ".join(
            f"({'a' if m == 'seeds' else 'b'}) {q['preset']}, {q['epochs']} epochs"
            + "".join(f" --set {k}={v:g}" for k, v in q["set"].items()) for m, q in r["protocol"].items())
    cols = ("target", "(a) best set, N seeds", "(b) top sets, 1 each", "paper (30 best configs)", "naive (a)",
            "median closest (a)/(b)")
    lines = []
    for target, r in table["targets"].items():
        b = "n/a" if r["top30"] is None else f"{r['top30']}/{r['top30_n']}"
        cm = lambda v: "-" if v is None else f"{v * 100:.1f} cm"  # noqa: E731
        lines.append((target, f"{r['seeds']}/{r['seeds_n']}", b,
                      "-" if r["paper"] is None else f"{r['paper']}/{r['paper_n']}",
                      f"{r['seeds_naive']}/{r['seeds_n']}",
                      f"{cm(r['seeds_median_min_distance_m'])} / {cm(r['top30_median_min_distance_m'])}"))
    widths = [max(len(c), *(len(row[i]) for row in lines)) for i, c in enumerate(cols)]
    fmt = lambda row: "  ".join(s.ljust(w) for s, w in zip(row, widths)).rstrip()  # noqa: E731
    out = [head, fmt(cols), fmt(["-" * w for w in widths])] + [fmt(row) for row in lines]
    notes = sorted({r["top30_note"] for r in table["targets"].values() if r["top30_note"]})
    out += [f"(b): {n}" for n in notes]
    t = table["timing"]
    rate = "" if t["network_s_per_s"] is None else (f"; training {t['train_wall_s']:.1f} s for "
                                                    f"{t['network_seconds_trained']:g} network-s, "
                                                    f"{t['network_s_per_s']:.2f} network-s/s")
    out.append(f"wall {t['wall_s_this_invocation']:.1f} s this invocation{rate} ({t['device']})")
    return "\n".join(out)


def build_parser() -> argparse.ArgumentParser:
    from jaxarm.run import add_network_arguments

    ap = argparse.ArgumentParser(prog="jaxarm reproduce", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arm", choices=tuple(ARMS), help="arm (required for a reproduction)")
    ap.add_argument("--task", choices=tuple(TASKS), default=TASK_DEFAULT,
                    help="reaching (default): the paper's two-target statistics; centre-out-8: one network per seed "
                         "trained on the original's eight centre-out targets in turn with a target code, and the "
                         "control without it, tested on every target (--epochs per target, default 3; "
                         "docs/centre-out.md)")
    ap.add_argument("--preset", help="preset name (see --list-presets) or the path of a preset .json file "
                                     "(default: the arm's protocol of the README's headline numbers, which it prints; "
                                     "--task centre-out-8: the arm's centre-out preset, "
                                     + ", ".join(f"{v} on the {k} arm" for k, v in CENTRE_OUT_PRESETS.items())
                                     + ", else the authors' set)")
    ap.add_argument("--out", type=runfolder.folder_argument,
                    help="output folder (a rerun resumes it; one command at a time, OUT/jaxarm.lock)")
    ap.add_argument("--targets", default=None,
                    help="comma-separated targets (default: the preset's own targets if it was tuned for some, "
                         "else left,bottom)")
    ap.add_argument("--networks", type=int, default=30, help="(a): seeds of the best set per target (default 30)")
    ap.add_argument("--top", type=int, default=preset_lib.MAX_TOP,
                    help="(b): at most this many of the preset's top sets (default 30)")
    ap.add_argument("--seed", type=int, default=0, help="network i uses PRNGKey(seed + i) (default 0)")
    ap.add_argument("--epochs", type=int, default=None,
                    help="training epochs (default: the preset's `epochs` metaparameter, 12); fewer for a quick run")
    ap.add_argument("--epoch-s", type=float, default=30.0, help="seconds per epoch (paper: 30)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="NAME=VALUE",
                    help="change this metaparameter in the best set and in every top set (repeatable; e.g. "
                         "explore_tot=8); recorded in success_table.json")
    ap.add_argument("--test-s", type=float, default=1.0, help="test duration, s (paper: 1)")
    ap.add_argument("--backend", choices=BACKENDS, default="fast", help="musculoskeletal geometry backend")
    ap.add_argument("--dt-ms", type=float, default=None,
                    help="network clock step, ms (default 0.25, what every preset was searched with; e.g. 0.1 to "
                         "check that a count does not depend on the step)")
    from jaxarm.experiment import SAME_STEP_INHIBITION_HELP
    ap.add_argument("--same-step-inhibition", choices=SAME_STEP_INHIBITION, default=None,
                    help=SAME_STEP_INHIBITION_HELP + "; every preset was searched with end_of_step")
    add_network_arguments(ap, "; every preset was searched on the paper's network")
    ap.add_argument("--no-progress", action="store_true")
    parallel_cli.add_arguments(ap)
    ap.add_argument("--list-presets", action="store_true", help="list the presets, one per line, name first; exit")
    ap.add_argument("--all", action="store_true",
                    help="with --list-presets: also the archived presets of earlier searches (docs/searches.md)")
    g = ap.add_argument_group("making a preset from a finished `jaxarm evolve` folder")
    g.add_argument("--make-preset", metavar="NAME", help="write a preset NAME.json from --from-search and exit")
    g.add_argument("--from-search", type=Path, metavar="DIR", help="a `jaxarm evolve --out` folder")
    g.add_argument("--description", help="the preset's one-line description (default: from the search)")
    g.add_argument("--search-command", help="the exact `jaxarm evolve ...` command of the search (default: "
                                            "reconstructed from its history.json)")
    g.add_argument("--allow-unfinished", action="store_true",
                   help="accept a search stopped before its --generations (recorded in the preset's provenance)")
    g.add_argument("--preset-dir", type=Path, default=preset_lib.PRESET_DIR,
                   help=f"where presets are read and written (default: the package's, {preset_lib.PRESET_DIR})")
    return ap


def reproduce_main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        parallel_cli.start_from_arguments(args)
        if args.list_presets:
            for name, desc in preset_lib.available(args.preset_dir, archive=args.all).items():
                print(f"{name}  {desc}")
            return 0
        if args.make_preset:
            if args.from_search is None:
                ap.error("--make-preset needs --from-search DIR")
            p = preset_lib.from_search(args.from_search, args.make_preset, description=args.description,
                                       command=args.search_command, allow_unfinished=args.allow_unfinished)
            path = preset_lib.save(p, args.preset_dir)
            print(f"preset {p.name!r}: best set + {len(p.top)} top sets from {args.from_search} -> {path}")
            return 0
        missing = [o for o, v in (("--arm", args.arm), ("--out", args.out)) if v is None]
        if missing:
            ap.error(f"{', '.join(missing)} required (or --list-presets / --make-preset)")
        if args.preset is None and args.task == "centre-out-8":
            args.preset = CENTRE_OUT_PRESETS.get(args.arm)
        preset = None if args.preset is None else preset_lib.load(args.preset, args.preset_dir)
        if args.task == "centre-out-8":
            return _reproduce_centre_out(args, preset, argv)
        targets = None if args.targets is None else [t.strip() for t in args.targets.split(",") if t.strip()]
        from jaxarm.experiment import parse_overrides
        from jaxarm.run import network_config as network_config_of

        overrides = parse_overrides(args.overrides)
        network = network_config_of(args, None if preset is None else preset.network_config())
        with runfolder.claim(args.out, "jaxarm reproduce"):
            table = reproduce(preset, args.arm, targets, args.out, networks=args.networks, seed=args.seed,
                              overrides=overrides,
                              epochs=args.epochs, epoch_s=args.epoch_s, test_s=args.test_s, top=args.top,
                              backend=args.backend, progress=not args.no_progress, dt_ms=args.dt_ms,
                              preset_dir=args.preset_dir, network=network,
                              command=shlex.join(["jaxarm", "reproduce", *argv]))
    except ConfigError as e:
        print(f"jaxarm reproduce: {e}", file=sys.stderr)
        return 2
    return 0 if table is not None else 1


def _reproduce_centre_out(args, preset, argv) -> int:
    """``jaxarm reproduce --task centre-out-8``: :func:`jaxarm.run_centre_out.run_with_control` with the preset's
    best set (default: the authors' metaparameters), ``--networks`` seeds, ``--epochs`` per target; every device
    of every process (``--coordinator``), through the runner; a rerun skips the finished condition and resumes a
    killed one."""
    from jaxarm.experiment import parse_overrides
    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.run import network_config as network_config_of
    from jaxarm.run_centre_out import run_with_control, table_markdown
    from jaxarm.task.centre_out import CentreOut

    if args.targets is not None or args.top != preset_lib.MAX_TOP or args.backend != "fast":
        raise ConfigError("--task centre-out-8 takes the eight targets, the preset's best set only and the fast "
                          "backend (no --targets, --top, --backend)")
    task = CentreOut(epochs_per_target=3 if args.epochs is None else args.epochs, epoch_duration_s=args.epoch_s,
                     test_duration_s=args.test_s)
    net = network_config_of(args, None if preset is None else preset.network_config())
    if args.dt_ms is not None:
        net = dataclasses.replace(net, dt_ms=args.dt_ms)
    mp = MetaParams.from_dict({**(preset.best if preset is not None else {}), **parse_overrides(args.overrides)})
    say = print if parallel.is_main_process() else (lambda *a, **k: None)
    say(f"{args.arm} arm, eight centre-out targets: {args.networks} networks per condition (target code, "
          f"control), {task.epochs_per_target} x {task.epoch_duration_s:g} s per target, cycled "
          f"({task.task_config().epochs} epochs), metaparameters "
          f"{'of preset ' + preset.name if preset is not None else 'of the authors'} -> {args.out}")
    meta = {"command": shlex.join(["jaxarm", "reproduce", *argv]), **measured_on()}
    with runfolder.claim(args.out, "jaxarm reproduce --task centre-out-8"):
        result = run_with_control(LoopConfig(arm=args.arm, network=net, task=task.task_config()), task,
                                  range(args.seed, args.seed + args.networks), mp, args.out, meta=meta,
                                  progress=not args.no_progress)
        table = table_markdown(result)
        if parallel.is_main_process():
            (args.out / "centre_out.md").write_text(table + "\n")
    say(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(reproduce_main())
