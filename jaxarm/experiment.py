"""``jaxarm train`` and ``jaxarm test``: train many networks on a task (reaching targets, or ``--task centre-out-8``),
test them, write the results; every task through the one runner (:class:`jaxarm.run.Run`).

    jaxarm train --arm simple --target left --networks 30 --seed 0 --out runs/simple_left
    jaxarm test  --from runs/simple_left                   # re-test the trained networks (e.g. another duration)

Network i of a run uses the key ``PRNGKey(seed + i)`` (its wiring, noise and babbling), so any network can be
reproduced alone. All networks train together, split over every device of every process (:mod:`jaxarm.run`,
:mod:`jaxarm.parallel`: by default every core of this machine; ``--coordinator`` for several machines); epochs run
one compiled call each, with an orbax checkpoint after every epoch: a killed run started again with the same command
resumes from its last completed epoch and ends with the same results as an uninterrupted run, on any layout.

Outputs in ``--out`` (one subfolder per target when several are given):
``results.json`` (success_count, per-network seed/success/distances/reach metrics, the naive networks' results,
per-epoch rates and weights averaged over networks, the full configuration), ``history.npz`` (the same per-epoch
rates, gains, distances and critic counts for every network: arrays (epochs, networks, ...)), ``trajectories.npz``
(t, q, hand, u, distance for the trained and naive networks), ``checkpoints/`` (orbax: wiring, learned gains, babbling state) and ``reach.png`` (hand paths
and velocity profiles, trained vs naive, in the paper's layout). With ``--record-spikes``: ``spikes.npz``
(every cell's spikes in the tests, and with ``--record-train-s`` in the last seconds of chosen epochs;
:mod:`jaxarm.record`) and, for the musculoskeletal arm, ``muscles.npz``; ``jaxarm figures`` and ``jaxarm video``
draw them. With ``--task centre-out-8``: ``results.json`` and ``trajectories.npz`` of the task's own
(:func:`jaxarm.run_centre_out.write_outputs`: every network tested on every target) and ``checkpoints/``; with
``--record-spikes`` its tests are recorded as one window per target (``test_right``, ``naive_test_right``, ...).
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
from pathlib import Path

import jax
import numpy as np
import sys

from jaxarm import parallel, parallel_cli, runfolder
from jaxarm.analysis.reach import reach_metrics
from jaxarm.arm.registry import ARMS, BACKENDS
from jaxarm.config.network import SAME_STEP_INHIBITION
from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import MetaParams
from jaxarm.learning.registry import DEFAULT, RULES, rule_from_meta
from jaxarm.loop import LoopConfig
from jaxarm.network import NetworkConfig
from jaxarm.run import Run, SetsRun, add_network_arguments, learning_curve, network_config
from jaxarm.task.config import TARGET_ANGLES_RAD, TEST_EM_NOISE_EVENTS, TaskConfig
from jaxarm.task.registry import DEFAULT as TASK_DEFAULT, TASKS, by_identity
from jaxarm.train import fresh_noise


def _metrics(result, target_xy, dt):
    m = jax.vmap(lambda xy: reach_metrics(xy, target_xy, dt))(result.hand_m)
    return {k: np.asarray(v) for k, v in m._asdict().items()}


def _network_rows(seeds, metrics) -> list[dict]:
    rows = []
    for i, seed in enumerate(seeds):
        row = {"seed": int(seed)}
        for k, v in metrics.items():
            x = v[i].item()
            row[k] = bool(x) if k == "success" else (None if np.isnan(x) else round(float(x), 5))
        rows.append(row)
    return rows


def write_outputs(run, trained_res, naive_res, history, wall_s, epochs_run, compile_s=None):
    """Write a run's results.json, history.npz, trajectories.npz and reach.png (process 0 only; every process returns
    the results). ``run``: a :class:`~jaxarm.run.Runner` of one target (its ``learning_curve``, if it was tested
    after every epoch, becomes results.json's); the results and history are host arrays."""
    task = run.config.task
    dt = task.update_interval_s
    target = np.asarray(task.target_xy_m, np.float32)
    seeds = run.seeds
    m_tr, m_nv = _metrics(trained_res, target, dt), _metrics(naive_res, target, dt)
    steps = history.gradient_steps       # gradient learning: (epochs, networks, steps per epoch) per field
    hist = {k: np.asarray(v) for k, v in history._asdict().items() if k != "gradient_steps"}
    spec = run.config.network.spec
    pop_names, pathways = spec.network_populations, spec.pathways
    results = {
        "success_count": int(m_tr["success"].sum()),
        "n_networks": run.n,
        "target": task.target,
        "target_xy_m": target.round(5).tolist(),
        "networks": [row | {"test_rates_hz": {p: round(float(r), 3) for p, r in zip(pop_names, rates)}}
                     for row, rates in zip(_network_rows(seeds, m_tr), np.asarray(trained_res.rates_hz))],
        "naive": {"success_count": int(m_nv["success"].sum()), "networks": _network_rows(seeds, m_nv)},
        "history": {
            "rates_last10s_hz": {p: hist["rates_last10s_hz"][:, :, j].mean(axis=1).round(3).tolist()
                                 for j, p in enumerate(pop_names)},
            "mean_wgain": {pw.name: hist["mean_wgain"][:, :, j].mean(axis=1).round(4).tolist()
                           for j, pw in enumerate(pathways)},
            "final_distance_m": hist["final_distance_m"].mean(axis=1).round(4).tolist(),
            "rewards": hist["rewards"].sum(axis=1).tolist(),
            "punishments": hist["punishments"].sum(axis=1).tolist(),
            "lost_spikes": int(hist["lost_spikes"].sum()),
        } | ({} if steps is None else {"gradient": {
            "loss_m": np.asarray(steps.loss_m).mean(axis=(1, 2)).round(5).tolist(),
            "grad_norm": np.median(np.asarray(steps.grad_norm), axis=(1, 2)).round(5).tolist(),
            "skipped_steps": (~np.asarray(steps.finite)).sum(axis=(1, 2)).tolist()}}),
        "test_rates_hz": {p: float(np.asarray(trained_res.rates_hz)[:, j].mean().round(3))
                          for j, p in enumerate(pop_names)},
        "timing": {"train_wall_s_this_invocation": round(wall_s, 2), "epochs_run_this_invocation": epochs_run,
                   "compile_s": None if compile_s is None else round(compile_s, 2),
                   "network_s_per_s": round(epochs_run * task.epoch_duration_s * run.n / wall_s, 2) if wall_s else None,
                   "device": jax.default_backend(), "layout": parallel.describe()},
        "config": run.config_record(),
    }
    if run.learning_curve:
        results["learning_curve"] = learning_curve(run.learning_curve, m_nv["success"], task.epoch_duration_s)
    if not parallel.is_main_process():
        return results
    run.out.mkdir(parents=True, exist_ok=True)
    (run.out / "results.json").write_text(json.dumps(results, indent=1))
    # per network and epoch (results.json holds the means): what a comparison with the original's one network needs
    np.savez_compressed(run.out / "history.npz", seeds=np.asarray(seeds), populations=np.asarray(pop_names),
                        pathways=np.asarray([pw.name for pw in pathways]),
                        **{k: v for k, v in hist.items() if k != "lost_spikes"},
                        **({} if steps is None else {f"gradient_{k}": np.asarray(v)
                                                     for k, v in steps._asdict().items()}))
    t = np.arange(trained_res.hand_m.shape[1]) * dt
    np.savez_compressed(run.out / "trajectories.npz", t=t, q=np.asarray(trained_res.q_rad),
                        hand=np.asarray(trained_res.hand_m), u=np.asarray(trained_res.u),
                        distance=np.asarray(trained_res.distance_m), naive_q=np.asarray(naive_res.q_rad),
                        naive_hand=np.asarray(naive_res.hand_m), target=target, seeds=np.asarray(seeds))
    plot_reach(run.out / "reach.png", t, np.asarray(trained_res.hand_m), np.asarray(naive_res.hand_m), target,
               task.success_radius_m, f"{run.config.arm} arm, {task.target} target")
    if getattr(run, "record", None) is not None:
        from jaxarm.recordfile import write_run_records

        results["record"] = write_run_records(run, trained_res, naive_res)
        (run.out / "results.json").write_text(json.dumps(results, indent=1))
    return results


def add_record_arguments(ap, train: bool) -> None:
    """The spike-recording options of `jaxarm train` (``train``) and `jaxarm test`."""
    g = ap.add_argument_group("spike recording (jaxarm.record; off by default, and then the loop is unchanged)")
    g.add_argument("--record-spikes", action="store_true",
                   help="record every cell's spikes in the tests (trained and naive) into OUT/spikes.npz, and each "
                        "muscle's activation, forces and lengths into OUT/muscles.npz (musculoskeletal arm)")
    g.add_argument("--record-networks", type=int, nargs="+", default=[], metavar="K",
                   help="write the records of these networks only (0-based indices in the run; default all)")
    g.add_argument("--record-max-rate-hz", type=float, default=50.0,
                   help="bound on the mean rate over all cells that sizes each window's buffer (default 50 Hz: "
                        "35,200 slots, 282 KB per network per recorded second); a network whose spikes need more "
                        "slots is an error")
    g.add_argument("--record-max-mb", type=float, default=1024.0,
                   help="refuse recording buffers above this many MB for the batch (default 1024)")
    if train:
        g.add_argument("--record-train-s", type=float, default=0.0, metavar="S",
                       help="also record the last S seconds of the epochs in --record-epochs (default 0: tests only)")
        g.add_argument("--record-epochs", type=int, nargs="+", default=[], metavar="E",
                       help="1-based epochs whose last --record-train-s seconds are recorded (default: the last)")


def record_config(args):
    """The RecordConfig of a command's options, or None without --record-spikes (and without --record-train-s)."""
    from jaxarm.record import RecordConfig

    train_s = getattr(args, "record_train_s", 0.0)
    if not (args.record_spikes or train_s):
        if args.record_networks or getattr(args, "record_epochs", None):
            raise ConfigError("--record-networks/--record-epochs need --record-spikes")
        return None
    return RecordConfig(max_rate_hz=args.record_max_rate_hz, max_mb=args.record_max_mb, train_last_s=train_s,
                        epochs=tuple(getattr(args, "record_epochs", ()) or ()), networks=tuple(args.record_networks))


def plot_reach(path, t, hand, naive_hand, target, radius, title):
    """Hand paths and velocity profiles, trained vs naive (the paper's layout)."""
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:   # a notebook's own backend stays (a switch closes its figures)
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    for hands, color, label in ((naive_hand, "0.6", "naive"), (hand, "tab:blue", "trained")):
        for i, h in enumerate(hands):
            ax[0].plot(h[:, 0] * 100, h[:, 1] * 100, color=color, lw=0.8, alpha=0.7, label=label if i == 0 else None)
            speed = np.linalg.norm(np.diff(h, axis=0), axis=1) / (t[1] - t[0])
            ax[1].plot(t[1:], speed, color=color, lw=0.8, alpha=0.7, label=label if i == 0 else None)
    ax[0].add_patch(plt.Circle(target * 100, radius * 100, fill=False, color="tab:red"))
    ax[0].plot(*(hand[0, 0] * 100), "ko")
    ax[0].set(title=f"hand paths ({title})", xlabel="x (cm)", ylabel="y (cm)", aspect="equal")
    ax[1].set(title="hand speed", xlabel="time (s)", ylabel="speed (m/s)")
    ax[0].legend()
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _add_common(ap):
    ap.add_argument("--arm", choices=tuple(ARMS), default="simple",
                    help="simple (authors' kinematic arm, their default) or musculoskeletal")
    ap.add_argument("--backend", choices=BACKENDS, default="fast", help="musculoskeletal geometry backend")
    ap.add_argument("--target", nargs="+", default=["left"], choices=sorted(TARGET_ANGLES_RAD),
                    help="target(s); one subfolder of --out each when several (paper: left bottom)")
    ap.add_argument("--networks", type=int, default=4, help="networks trained in parallel (paper: 30)")
    ap.add_argument("--seed", type=int, default=0, help="network i uses PRNGKey(seed + i)")
    ap.add_argument("--epochs", type=int, default=None,
                    help="training epochs (default: --preset's, else 12, the paper's)")
    ap.add_argument("--epoch-s", type=float, default=30.0, help="seconds per epoch (paper: 30)")
    ap.add_argument("--test-s", type=float, default=1.0, help="test duration, s (paper: 1)")
    _add_test_noise_option(ap)
    ap.add_argument("--no-progress", action="store_true")


CROSSINGS = ("after_step", "per_event")
CROSSING_HELP = ("a step whose input lifts a cell from below threshold past Vblock: after_step (default; blocked, "
                 "fires once it decays back) or per_event (fires, as the event-driven original, which tests after "
                 "every event; NetworkConfig.crossing)")


SAME_STEP_INHIBITION_HELP = ("a step whose excitation lifts a cell past threshold and whose inhibition brings it back: "
                             "end_of_step (default; no spike) or random_order (fires where a coin per cell and step "
                             "says the excitation came first, as the event-driven original would; halves what a "
                             "0.5 ms step loses; NetworkConfig.same_step_inhibition)")


def _add_test_noise_option(ap, default="unlimited"):
    ap.add_argument("--test-em-noise-events", choices=TEST_EM_NOISE_EVENTS, default=default,
                    help="EM test noise: unlimited (default) or netstim (each EM cell's noise stops after "
                         "ceil(test ms x rate / 1000) events, as the original's NetStims; TaskConfig."
                         "test_em_noise_events)")


def _configs(args) -> list[tuple[str, LoopConfig, object]]:
    """(name, LoopConfig, task) of every run the options ask for: the registered task's runs
    (:data:`jaxarm.task.registry.TASKS`; reaching: one per --target, centre-out-8: one), each network spec with what
    its task adds (centre-out: a target code, unless the network has one)."""
    learning = getattr(args, "learning", DEFAULT)
    out = []
    for name, task in TASKS[getattr(args, "task", TASK_DEFAULT)].Config.from_options(
            targets=args.target, epochs=args.epochs, epoch_duration_s=args.epoch_s, test_duration_s=args.test_s,
            test_em_noise_events=args.test_em_noise_events):
        net = network_config(args, getattr(args, "preset_network", None))
        spec = task.prepare_spec(net.spec)
        if spec is not net.spec:
            net = dataclasses.replace(net, spec=spec)
        out.append((name, LoopConfig(arm=args.arm, backend=args.backend, network=net, task=task.task_config(),
                                     learning=learning, rule=RULES[learning].config_from_arguments(args)), task))
    return out


def _check(ap, args):
    if not 1 <= args.networks <= 4096:
        ap.error(f"--networks = {args.networks}: must be in [1, 4096]")
    if args.seed < 0:
        ap.error(f"--seed = {args.seed}: must be >= 0")
    if args.epochs < 1:
        ap.error(f"--epochs = {args.epochs}: must be >= 1 (an untrained network is the naive test's; "
                 "`jaxarm test --from` re-tests trained ones)")
    twice = sorted({t for t in args.target if args.target.count(t) > 1})
    if twice:
        ap.error(f"--target {' '.join(args.target)}: {', '.join(twice)} given more than once; give each target once")


def train_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="jaxarm train", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_common(ap)
    ap.add_argument("--out", type=runfolder.folder_argument, required=True,
                    help="output folder (a rerun resumes from its checkpoints; one command at a time: a second is "
                         "refused while the first holds OUT/jaxarm.lock)")
    ap.add_argument("--preset", default=None, metavar="NAME",
                    help="train with a stored preset's metaparameters instead of the authors': its best set "
                         "(`jaxarm reproduce --list-presets` lists the names; or the path of a preset .json file); "
                         "--epochs defaults to the preset's")
    ap.add_argument("--set-from-preset", type=int, default=None, metavar="INDEX",
                    help="with --preset: its ranked set INDEX instead of its best set (0 = the top-ranked)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="NAME=VALUE",
                    help="train and test with this metaparameter changed from the authors' value, or from "
                         "--preset's (repeatable; e.g. v_em_max=60); the training length is --epochs")
    add_network_arguments(ap, "; the options below override it")
    ap.add_argument("--dt-ms", type=float, default=None,
                    help=f"network clock step, ms (default {NetworkConfig().dt_ms}; must divide 1 ms, e.g. 0.1 to "
                         "check that a result does not depend on the step)")
    ap.add_argument("--threshold-test", choices=("every_step", "on_event"), default=None,
                    help="when a cell's threshold is tested: every_step (default) or on_event (only in steps with "
                         "input, as the event-driven original; NetworkConfig.threshold_test)")
    ap.add_argument("--crossing", choices=CROSSINGS, default=None, help=CROSSING_HELP)
    ap.add_argument("--same-step-inhibition", choices=SAME_STEP_INHIBITION, default=None,
                    help=SAME_STEP_INHIBITION_HELP)
    ap.add_argument("--no-readout-clip", dest="readout_clip", action="store_const", const=False, default=None,
                    help="do not clip the motor excitations to [0, 1] (the hoc code does not; the default clips, as "
                         "the paper's thresholded readout and every published preset; NetworkConfig.readout_clip)")
    g = ap.add_argument_group("learning")
    g.add_argument("--learning", choices=tuple(RULES), default=DEFAULT,
                   help="; ".join(f"{name}: {rule.summary}" for name, rule in RULES.items()))
    for rule in RULES.values():
        rule.add_arguments(g)
    ap.add_argument("--task", choices=tuple(TASKS), default=TASK_DEFAULT,
                    help="reaching (default): one --target per network, the paper's task; centre-out-8: the "
                         "original's eight centre-out targets from one network, --epochs per target, cycled epoch by "
                         "epoch, a target code added to the network unless --network has one, every network tested "
                         "on every target (jaxarm.run_centre_out; checkpoints, resume, --coordinator and "
                         "--record-spikes as reaching, the tests recorded as one window per target)")
    ap.add_argument("--test-each-epoch", action="store_true",
                    help="also test every network after every epoch: results.json's learning_curve (successes per "
                         "epoch, and per network the training seconds until its test first succeeded)")
    add_record_arguments(ap, train=True)
    parallel_cli.add_arguments(ap)
    args = ap.parse_args(argv)
    try:
        base = preset_metaparams(args)
    except ConfigError as e:
        ap.error(str(e))
    _check(ap, args)
    try:
        parallel_cli.start_from_arguments(args)
        configs = _configs(args)
        overrides = parse_overrides(args.overrides)
        record = record_config(args)
    except ConfigError as e:
        ap.error(str(e))
    mp = MetaParams.from_dict({**base, **overrides})
    with runfolder.claim(args.out, "jaxarm train"):   # one writer per folder; --out checked before any work
        return _train_targets(ap, args, configs, mp, record)


def said(run, res) -> str:
    """The line ``jaxarm train`` prints for a reaching run's results."""
    return (f"{run.config.arm} arm, {run.config.task.target} target: {res['success_count']}/{run.n} trained networks "
            f"reached the {run.config.task.success_radius_m * 100:.0f} cm circle (naive: "
            f"{res['naive']['success_count']}/{run.n}); median min distance "
            f"{np.median([n['min_distance_m'] for n in res['networks']]) * 100:.1f} cm -> {run.out / 'results.json'}")


def said_test(run, res) -> str:
    """The line ``jaxarm test`` prints for a reaching run's re-test."""
    return f"{res['success_count']}/{run.n} networks reached the target -> {run.out / 'results.json'}"


def _task_outputs(name: str, test: bool = False):
    """(write the results, the line that says them) of the task registered as ``name``: its outputs module's
    ``write_outputs`` and ``said`` (reaching's: this module's); with ``test``, ``said_test`` where the module has one
    (the line ``jaxarm test`` prints)."""
    module = importlib.import_module(TASKS[name].outputs)
    return module.write_outputs, (getattr(module, "said_test", module.said) if test else module.said)


def _train_targets(ap, args, configs, mp, record) -> int:
    """Every run of ``configs`` ((name, LoopConfig, task): one per reaching target, or the one centre-out run)
    through the one runner (:class:`jaxarm.run.Run`: checkpoints, resume, every device of every process)."""
    write, say = _task_outputs(args.task)
    summary = {}
    for name, cfg, task in configs:
        out = args.out / name if len(configs) > 1 else args.out
        try:
            run = Run(cfg, args.networks, args.seed, out, mp, record=record, task=task)
        except ConfigError as e:
            ap.error(str(e))
        if parallel.is_main_process() and not args.no_progress:   # on stderr with the progress bar, silenced with it
            print(parallel.padding_note(run.n, f"{run.n} networks", run.mesh.size, run.at_once,
                                        jax.process_count(), ("--networks", lambda v: v, run.n)), file=sys.stderr,
                  flush=True)
        carry, history, wall, epochs_run, compile_s = run.train(progress=not args.no_progress,
                                                                test_each_epoch=args.test_each_epoch)
        res = write(run, run.test(carry.trained), run.test(run.naive(), "naive test"), history, wall, epochs_run,
                    compile_s)
        if "success_count" in res:
            summary[name] = res["success_count"]
        if parallel.is_main_process():
            print(say(run, res), flush=True)
    if len(configs) > 1 and parallel.is_main_process():
        (args.out / "summary.json").write_text(json.dumps({"success_count": summary, "networks": args.networks}))
    return 0


def preset_metaparams(args) -> dict[str, float]:
    """The metaparameters ``--preset NAME [--set-from-preset INDEX]`` name ({} without ``--preset``: the authors'),
    ``args.epochs`` when not given: the preset's protocol's (the paper's 12 without a preset), and
    ``args.preset_network``: the preset's network (None: the paper's; ``--network`` takes precedence).
    :class:`ConfigError` in one line for an unknown name or an index out of range."""
    from jaxarm.paper import presets

    args.preset_network = None
    if args.preset is None:
        if args.set_from_preset is not None:
            raise ConfigError(f"--set-from-preset {args.set_from_preset}: give the preset with --preset NAME")
        values = {}
        epochs = presets.PAPER_EPOCHS
    else:
        try:
            preset = presets.load(args.preset)
        except ConfigError as e:
            raise ConfigError(f"--preset: {e}") from None
        i = args.set_from_preset
        if i is None:
            values = preset.best
        elif not preset.top:
            raise ConfigError(f"--set-from-preset {i}: preset {preset.name!r} has no ranked sets, only its best set; "
                              "leave --set-from-preset out")
        elif not 0 <= i < len(preset.top):
            raise ConfigError(f"--set-from-preset {i}: preset {preset.name!r} has {len(preset.top)} ranked sets; "
                              f"give an index in [0, {len(preset.top) - 1}]")
        else:
            values = preset.top[i]["metaparams"]
        epochs = preset.epochs
        args.preset_network = preset.network_config()
    if args.epochs is None:
        args.epochs = epochs
    return dict(values)


def parse_overrides(items: list[str]) -> dict[str, float]:
    """``["name=value", ...]`` -> ``{name: value}``, each a known metaparameter within its bounds."""
    from jaxarm.learning.metaparams import BOUNDS

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if name == "epochs":
            raise ConfigError("--set epochs: use --epochs for the training length")
        if not sep or name not in BOUNDS:
            raise ConfigError(f"--set {item!r}: expected NAME=VALUE with NAME one of {', '.join(BOUNDS)}")
        try:
            v = float(value)
        except ValueError:
            raise ConfigError(f"--set {item!r}: {value!r} is not a number") from None
        b = BOUNDS[name]
        if not (b.lo <= v <= b.hi):
            raise ConfigError(f"--set {name} = {v:g} is outside its range [{b.lo:g}, {b.hi:g}] {b.unit}")
        out[name] = v
    return out


def test_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="jaxarm test", description="Re-test networks trained by `jaxarm train`.")
    ap.add_argument("--from", dest="src", type=Path, required=True, help="a `jaxarm train` output folder")
    ap.add_argument("--test-s", type=float, default=None, help="test duration, s (default: 1, the paper's; the training run's --test-s is not recorded)")
    ap.add_argument("--out", type=Path, default=None, help="where to write (default: SRC/test)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="NAME=VALUE",
                    help="test with this metaparameter changed (repeatable; e.g. v_em_max=60 or "
                         "em_noise_rate_test_hz=150); the trained weights are kept")
    ap.add_argument("--threshold-test", choices=("every_step", "on_event"), default=None,
                    help="test with this threshold test (default: as trained); the trained weights are kept")
    ap.add_argument("--crossing", choices=CROSSINGS, default=None,
                    help="test with this crossing rule (default: as trained); the trained weights are kept")
    ap.add_argument("--same-step-inhibition", choices=SAME_STEP_INHIBITION, default=None,
                    help="test with this rule for a step's excitation and inhibition (default: as trained); the "
                         "trained weights are kept")
    ap.add_argument("--fresh-noise", type=int, default=None, metavar="J",
                    help="test with fresh background-noise streams (each network's noise key folded with J >= 0) "
                         "instead of the streams it trained with, which the test re-uses by default as the original "
                         "re-seeds its noise identically at every run")
    _add_test_noise_option(ap)
    add_record_arguments(ap, train=False)
    parallel_cli.add_arguments(ap)
    args = ap.parse_args(argv)
    if args.fresh_noise is not None and args.fresh_noise < 0:   # refused before any work
        ap.error(f"--fresh-noise = {args.fresh_noise}: must be >= 0")
    try:
        parallel_cli.start_from_arguments(args)
        overrides = parse_overrides(args.overrides)
        record = record_config(args)
    except ConfigError as e:
        ap.error(str(e))
    from jaxarm.checkpoint import Checkpointer

    if not (args.src / "checkpoints").is_dir():
        ap.error(f"--from {args.src}: no checkpoints/ folder there; give the --out folder of a `jaxarm train` run "
                 "(or a target's seeds/ or top30/ folder of a `jaxarm reproduce` run)")
    with Checkpointer(args.src / "checkpoints") as ckpt:
        meta = ckpt.read_meta()
        if meta is None:
            ap.error(f"--from {args.src}: no readable checkpoint in {ckpt.directory}; the training run wrote no "
                     "completed epoch yet")
    if meta["epochs"] != ckpt.latest_step():
        raise SystemExit(f"{args.src} finished {ckpt.latest_step()} of {meta['epochs']} epochs: rerun `jaxarm train` "
                         "with the same options to finish it first")
    # the task rebuilt from what the run recorded: a task of its own records its identity under "task"
    # (jaxarm train --task centre-out-8); reaching's identity is the description itself (target, epochs, epoch_s)
    identity = meta.get("task")
    found = by_identity(identity.get("name") if identity else None)
    if found is None:
        ap.error(f"--from {args.src}: a run of task {identity.get('name')!r}, which this version does not "
                 f"register (tasks: {', '.join(TASKS)}); test it with the version that trained it")
    task_name, entry = found
    task = entry.Config.from_identity(identity or meta, test_duration_s=args.test_s or 1.0,
                                      test_em_noise_events=args.test_em_noise_events)
    tc = task.task_config()
    # the threshold rules change neither the wiring nor the state layout, so trained networks can be tested either way
    network = network_config(meta | {k: v for k, v in (("threshold_test", args.threshold_test),
                                                       ("crossing", args.crossing),
                                                       ("same_step_inhibition", args.same_step_inhibition)) if v})
    learning, rule = rule_from_meta(meta)   # the rule's carry is restored with the gains (gradient: Adam's state)
    cfg = LoopConfig(arm=meta["arm"], backend=meta["backend"], network=network, task=tc, learning=learning,
                     rule=rule)
    out = args.out or args.src / "test"
    with runfolder.claim(out, "jaxarm test"):   # one writer per folder, as for jaxarm train
        return _test_into(ap, args, meta, cfg, out, record, overrides, task, task_name)


def _test_into(ap, args, meta, cfg, out, record, overrides, task, task_name) -> int:
    try:
        if isinstance(meta["metaparams"], list):   # a SetsRun folder (e.g. `jaxarm reproduce`'s top30/)
            from jaxarm.run import stack_rows

            run = SetsRun(cfg, meta["seed"], out, stack_rows([MetaParams.from_dict(m) for m in meta["metaparams"]]),
                          record=record)
        else:
            run = Run(cfg, meta["networks"], meta["seed"], out, MetaParams.from_dict(meta["metaparams"]), task=task,
                      record=record)
    except ConfigError as e:
        ap.error(str(e))
    carry, history = run.restore_trained(args.src / "checkpoints")
    if overrides:   # after the restore: the checkpoint was written with the trained metaparameters
        run.override(overrides)
    trained, naive = carry.trained, run.naive()
    if args.fresh_noise is not None:
        trained, naive = (fresh_noise(t, args.fresh_noise) for t in (trained, naive))
    write, say = _task_outputs(task_name, test=True)
    res = write(run, run.test(trained), run.test(naive, "naive test"), history, 0.0, 0)
    if parallel.is_main_process():
        print(say(run, res))
    return 0
