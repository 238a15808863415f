"""XLA:CPU's thread pool: one thread per device (jaxarm's setting) against one per core (XLA's default), alternated.

    python benchmarks/pool_threads.py [--rounds 3] [--json-out FILE]

Each round runs, once with ``PJRT_NPROC=1`` (what ``import jaxarm`` sets for one device) and once with
``PJRT_NPROC`` = this machine's usable cores (XLA's own default), each in fresh processes:

* ``benchmarks/network.py --networks 1,64 --no-brian2 --threads 1``: the network alone on one device, with its
  CPU time (``network_s_per_cpu_s``: how many cores the process really used);
* ``benchmarks/train.py --networks 8``: the closed loop on one device, both arms;
* ``jaxarm train --networks 16 --epochs 1 --epoch-s 15`` over every core (one device per core: then jaxarm sets
  the pool to the device count, so this row compares one pool thread per device against XLA's default, which
  are the same size on a machine whose devices fill its cores; it checks that nothing is lost there), both arms.

Medians over the rounds and the ratios (one thread per device / XLA's default), with every round's figures, the
command, date, machine and commit. Keys: ``network alone N`` and ``network alone N per CPU-second`` (N networks),
``closed loop ARM 8 one device``, ``jaxarm train ARM 16 every core``; settings ``one per device`` and ``one per
core`` (XLA's default). About 4 minutes a round on a 2-core machine.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from arm import commit  # benchmarks/arm.py, beside this script: the commit, marked when the tree has changes

ROOT = Path(__file__).resolve().parents[1]


def usable_cores() -> int:
    sys.path.insert(0, str(ROOT))
    from jaxarm.parallel import usable_cores as cores
    return cores()


def pool_env(threads: int) -> dict:
    """This process's environment with XLA's CPU pool sized to ``threads`` (``NPROC`` dropped: it would win)."""
    env = dict(os.environ, PJRT_NPROC=str(threads))
    env.pop("NPROC", None)
    return env


def run_json(cmd: list[str], threads: int) -> dict:
    out = subprocess.run(cmd, check=True, cwd=ROOT, env=pool_env(threads), capture_output=True, text=True).stdout
    return json.loads(out[out.index("{"):])     # the script's JSON, after any lines it printed before


def one_round(threads: int, folder: Path) -> dict:
    py = sys.executable
    net = run_json([py, "benchmarks/network.py", "--networks", "1,64", "--repeats", "3", "--no-brian2", "--threads",
                    "1", "--json"], threads)
    train = run_json([py, "benchmarks/train.py", "--networks", "8", "--seconds", "2", "--repeats", "3", "--threads",
                      "1", "--json"], threads)
    figures = {f"network alone {n}": net["network_s_per_s"][n] for n in ("1", "64")}
    figures |= {f"network alone {n} per CPU-second": net["network_s_per_cpu_s"][n] for n in ("1", "64")}
    figures |= {f"closed loop {arm} 8 one device": train["network_s_per_s"][f"{arm}_8"]
                for arm in ("simple", "musculoskeletal")}
    for arm in ("simple", "musculoskeletal"):
        out = folder / f"{arm}-{threads}"
        subprocess.run([str(Path(py).with_name("jaxarm")), "train", "--arm", arm, "--target", "left", "--networks",
                        "16", "--epochs", "1", "--epoch-s", "15", "--no-progress", "--out", str(out)], check=True,
                       cwd=ROOT, env=pool_env(threads), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        res = json.loads((out / "results.json").read_text())
        figures[f"jaxarm train {arm} 16 every core"] = res["timing"]["network_s_per_s"]
        shutil.rmtree(out, ignore_errors=True)
    return figures


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json-out", default=None)
    args = ap.parse_args(argv)
    cores = usable_cores()
    settings = {"one per device": 1, "one per core": cores}   # jaxarm's setting; XLA's default
    rounds = {name: [] for name in settings}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for name, threads in settings.items():
                rounds[name].append(one_round(threads, Path(tmp)))
                print(f"round {r + 1}, {name}: {rounds[name][-1]}", file=sys.stderr, flush=True)
    keys = list(rounds["one per device"][0])
    median = {name: {k: round(statistics.median(f[k] for f in rs), 2) for k in keys} for name, rs in rounds.items()}
    out = {"what": "XLA:CPU's thread pool (PJRT_NPROC): one thread per device against one per core, alternated "
                   "rounds, medians (network-s per wall-second unless said)",
           "command": "python benchmarks/pool_threads.py" + "".join(
               f" {a}" for a in (argv if argv is not None else sys.argv[1:])),
           "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
           "machine": f"{platform.machine()}, {cores} cores", "commit": commit(),
           "pool_threads": settings, "median": median,
           "one_per_device_over_default": {k: round(median["one per device"][k]
                                                    / median["one per core"][k], 3) for k in keys},
           "rounds": rounds}
    text = json.dumps(out, indent=1)
    if args.json_out:
        Path(args.json_out).write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
