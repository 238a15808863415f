"""`jaxarm reproduce` as one batch against the sequential reproduce of an earlier commit, alternated in one sitting.

    python benchmarks/reproduce_batch.py --baseline 2ed7486 [--networks 8] [--epochs 2] [--epoch-s 10] [--repeats 2]
                                         [--arm musculoskeletal] [--preset P] [--baseline-threads 2]

The baseline (default 2ed7486, the last commit before scale-out) trained a reproduction's (target, mode) groups one
after another, each a batch on one CPU device with ``JAXARM_NATIVE_THREADS=2`` (its fastest setting on two cores;
``--baseline-threads 1`` runs it as its default did, on one core);
this checkout trains every group in one batch over every core (its default). Both run the same command,
``jaxarm reproduce --arm ARM --preset PRESET --networks N --top N --epochs E --epoch-s S``, in fresh output folders
and fresh processes, alternately, ``--repeats`` times each; reported: median wall time of the whole command
(compilation, training, tests, writing) and the ratio. The baseline is checked out with ``git worktree`` into a
temporary folder and run with this interpreter (``PYTHONPATH``), so both use the same installed libraries.

Counts are not compared: commits in between changed the model (the P cells' first volley at 1 ms, the muscle
sub-steps), which re-draws every spike train. The later commits' arm sub-steps make this checkout's closed loop
slower per network, so the ratio understates what batching alone saves.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def command(args, out: Path) -> list[str]:
    return [sys.executable, "-m", "jaxarm.cli", "reproduce", "--arm", args.arm, "--preset", args.preset,
            "--networks", str(args.networks), "--top", str(args.networks), "--epochs", str(args.epochs),
            "--epoch-s", str(args.epoch_s), "--no-progress", "--out", str(out)]


def imported_from(env: dict, cwd: Path) -> Path:
    """The folder ``jaxarm`` is imported from under ``env`` in ``cwd``."""
    p = subprocess.run([sys.executable, "-c", "import jaxarm, os; print(os.path.dirname(jaxarm.__file__))"],
                       env=env, cwd=cwd, capture_output=True, text=True, check=True)
    return Path(p.stdout.strip()).resolve()


def timed(cmd: list[str], env: dict, cwd: Path) -> float:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{p.stderr[-3000:]}")
    return wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default="2ed7486", help="commit with the sequential reproduce")
    ap.add_argument("--arm", default="musculoskeletal", choices=["simple", "musculoskeletal"])
    ap.add_argument("--preset", default="msarm-cmaes-2cm-rerank")
    ap.add_argument("--networks", type=int, default=8, help="(a) seeds and (b) top sets per target")
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--epoch-s", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--baseline-threads", type=int, default=2,
                    help="JAXARM_NATIVE_THREADS of the baseline: 2 (default) is its fastest setting on two cores, 1 "
                         "its own default, what `jaxarm reproduce` used unless that variable was set")
    ap.add_argument("--json", action="store_true", help="print only the final JSON line")
    args = ap.parse_args(argv)
    walls = {"sequential": [], "one_batch": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = tmp / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base), args.baseline],
                       check=True)
        try:
            env_old = {**os.environ, "PYTHONPATH": str(base), "JAXARM_NATIVE_THREADS": str(args.baseline_threads)}
            env_new = {**os.environ, "PYTHONPATH": str(ROOT)}
            env_new.pop("JAXARM_NATIVE_THREADS", None)
            # ``python -m`` puts the working directory first on sys.path, ahead of PYTHONPATH: run both commands
            # from a neutral folder, and check that each imports the checkout it is meant to time.
            neutral = tmp / "cwd"
            neutral.mkdir()
            for env, root in ((env_old, base), (env_new, ROOT)):
                got = imported_from(env, neutral)
                if got != (root / "jaxarm").resolve():
                    raise RuntimeError(f"expected jaxarm from {root}, the command imports it from {got}")
            for r in range(args.repeats):
                for name, env in (("sequential", env_old), ("one_batch", env_new)):
                    wall = timed(command(args, tmp / f"{name}-{r}"), env, neutral)
                    walls[name].append(wall)
                    if not args.json:
                        print(f"{name:10s} repeat {r}: {wall:7.1f} s", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], check=False)
    med = {k: round(statistics.median(v), 1) for k, v in walls.items()}
    out = {"wall_s": med, "walls": walls, "ratio_one_batch_to_sequential": round(med["one_batch"] / med["sequential"], 3),
           "network_seconds": 4 * args.networks * args.epochs * args.epoch_s,
           "config": {"baseline": args.baseline, "arm": args.arm, "preset": args.preset, "networks": args.networks,
                      "epochs": args.epochs, "epoch_s": args.epoch_s, "repeats": args.repeats,
                      "baseline_threads": args.baseline_threads,
                      "cpu_count": os.cpu_count(), "machine": platform.machine(), "date": time.strftime("%Y-%m-%d")}}
    if not args.json:
        print(f"median wall: sequential {med['sequential']} s, one batch {med['one_batch']} s, ratio "
              f"{out['ratio_one_batch_to_sequential']}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
