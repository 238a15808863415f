"""XLA:CPU thunks per closed-loop 10 ms interval of one network: what the runtime dispatches between kernel calls.

    python benchmarks/thunks.py [--json-out FILE]      # both arms, JAX's rolled threefry and jaxarm's unrolled one

XLA:CPU runs a compiled program as a sequence of thunks (a fusion, a copy, a loop's condition, a custom call, ...),
each with a fixed dispatch cost. One network's 10 ms interval is small, so the count shows in its time. The script
compiles one training epoch (the authors' metaparameters, one network at a time as a CPU device runs its share) and
counts the operations XLA:CPU runs as thunks in the interval loop's body, loops multiplied out by their trip counts
(``jaxarm.cpu_dispatch``'s threefry lowering against JAX's, each in its own process). Counting only, no timing: the
numbers depend on the JAX version, not on the machine's load. Takes about a minute.
"""
from __future__ import annotations

import argparse
import collections
import datetime
import json
import os
import platform
import re
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Operations that are not thunks of their own (tuple plumbing and constants).
NOT_THUNKS = {"get-tuple-element", "tuple", "parameter", "constant", "bitcast"}
EPOCH_S = 2.0


def computations(hlo: str) -> dict[str, list[str]]:
    comps, cur = {}, None
    for line in hlo.split("\n"):
        head = re.match(r"^(ENTRY )?(%[\w.\-]+) .*\{$", line)
        if head:
            cur = head.group(2)
            comps[cur] = []
        elif line == "}":
            cur = None
        elif cur:
            comps[cur].append(line.strip())
    return comps


def thunks_in(comps: dict, name: str, times: int, counts: collections.Counter) -> None:
    """Add the thunk-running operations of computation ``name``, run ``times`` times, to ``counts``."""
    for line in comps.get(name, []):
        op = re.search(r"= .*? ([a-z][a-z\-]*)\(", line)
        if not op or op.group(1) in NOT_THUNKS:
            continue
        counts[op.group(1)] += times
        if op.group(1) == "while":
            trips = re.search(r'known_trip_count":\{"n":"(\d+)"', line)
            thunks_in(comps, re.search(r"body=(%[\w.\-]+)", line).group(1), times * (int(trips.group(1)) if trips else 1),
                      counts)
        for called in re.findall(r"(?:to_apply|branch_computations)=\{?(%[\w.\-]+)", line):
            thunks_in(comps, called, times, counts)


def interval_thunks(arm: str) -> dict:
    """In this process: the thunks of one training interval of ``arm`` (one network at a time)."""
    sys.path.insert(0, REPO)
    import jax

    from jaxarm.learning.metaparams import MetaParams
    from jaxarm.loop import LoopConfig
    from jaxarm.parallel import map_networks
    from jaxarm.task.config import TaskConfig
    from jaxarm.train import make_train

    fns = make_train(LoopConfig(arm=arm, task=TaskConfig(epochs=1, epoch_duration_s=EPOCH_S)))
    mp = MetaParams.original()
    carry = jax.jit(jax.vmap(fns.init))(jax.random.split(jax.random.PRNGKey(0), 2))
    hlo = jax.jit(lambda c, mp: map_networks(lambda ci: fns.epoch(ci, mp), 1)(c)).lower(carry, mp).compile().as_text()
    comps = computations(hlo)
    intervals = str(round(EPOCH_S * 1000 / 10))
    bodies = [body for body, n in re.findall(r'while\(.*?body=(%[\w.\-]+).*?known_trip_count":\{"n":"(\d+)"', hlo)
              if n == intervals]
    if len(bodies) != 1:
        raise SystemExit(f"expected one loop of {intervals} intervals in the compiled epoch, found {len(bodies)}")
    counts = collections.Counter()
    thunks_in(comps, bodies[0], 1, counts)
    return {"total": sum(counts.values()), "by_op": dict(counts.most_common())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json-out", default=None)
    ap.add_argument("--worker", metavar="ARM", help=argparse.SUPPRESS)   # the lowering comes from the environment
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(interval_thunks(args.worker)))
        return 0
    import jax

    out = {"what": "XLA:CPU thunks per closed-loop 10 ms interval of one network (training epoch, one network at a "
                   "time), loops multiplied out; JAX's rolled threefry lowering on CPU against jaxarm.cpu_dispatch's",
           "command": "python benchmarks/thunks.py" + (f" --json-out {args.json_out}" if args.json_out else ""),
           "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"), "machine": platform.machine(),
           "jax": jax.__version__, "thunks_per_interval": {}}
    for arm in ("simple", "musculoskeletal"):
        for lowering, rolled in (("jax_rolled_threefry", "1"), ("jaxarm_unrolled_threefry", "0")):
            env = dict(os.environ, JAXARM_ROLLED_THREEFRY=rolled)
            run = subprocess.run([sys.executable, __file__, "--worker", arm], env=env, capture_output=True,
                                 text=True, check=True)
            result = json.loads(run.stdout.strip().splitlines()[-1])
            out["thunks_per_interval"].setdefault(arm, {})[lowering] = result
            print(f"{arm:16s} {lowering:26s} {result['total']:5d} thunks per interval", file=sys.stderr)
    text = json.dumps(out, indent=1)
    if args.json_out:
        with open(args.json_out, "w") as f:
            f.write(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
