"""Compare two `jaxarm evolve` output folders bit for bit and write experiments/slurm_local.sh's result file.

Compared: history.json's per-generation history, top_k.json whole, and every checkpoint step's search state (every
array of the orbax ``state`` item, by its bytes, dtype and shape) and its ``meta`` item (all but its timings).
Exit status 0 when all are identical, 1 when something differs, 2 when a run failed or a folder is missing what it
should hold.

    python experiments/slurm_local_compare.py --slurm RUN_A --one RUN_B [--result FILE] [--job-log LOG] ...
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np


def _arrays(step: Path) -> dict[str, np.ndarray]:
    import jax
    import orbax.checkpoint as ocp

    tree = ocp.StandardCheckpointer().restore(str(step.absolute() / "state"))
    return {jax.tree_util.keystr(p): np.asarray(x) for p, x in jax.tree_util.tree_leaves_with_path(tree)}


#: What a checkpoint's meta item may differ in between two runs of the same search: how long it took.
TIMINGS = ("compile_s", "run_s", "evaluations_per_s", "network_seconds_per_s")


def _meta(step: Path):
    """The checkpoint's JSON description without its timings (:data:`TIMINGS`, wherever they are)."""
    def drop(x):
        if isinstance(x, dict):
            return {k: drop(v) for k, v in x.items() if k not in TIMINGS}
        return [drop(v) for v in x] if isinstance(x, list) else x

    return drop(json.loads((step / "meta" / "metadata").read_text()))


def compare(a: Path, b: Path) -> dict:
    """What is identical between runs ``a`` and ``b`` (raises FileNotFoundError for a missing file)."""
    out: dict = {}
    ha, hb = (json.loads((d / "history.json").read_text()) for d in (a, b))
    out["history.json history"] = {"identical": ha["history"] == hb["history"],
                                   "generations": len(ha["history"].get("best", []))}
    ta, tb = (json.loads((d / "top_k.json").read_text()) for d in (a, b))
    out["top_k.json"] = {"identical": ta == tb, "candidates": len(ta.get("top_k", []))}
    steps_a = sorted((p.name for p in (a / "checkpoints").iterdir() if p.name.isdigit()), key=int)
    steps_b = sorted((p.name for p in (b / "checkpoints").iterdir() if p.name.isdigit()), key=int)
    if steps_a != steps_b or not steps_a:
        out["checkpoint steps"] = {"identical": False, "a": steps_a, "b": steps_b}
        return out
    for s in steps_a:
        xa, xb = _arrays(a / "checkpoints" / s), _arrays(b / "checkpoints" / s)
        differ = sorted(k for k in set(xa) | set(xb) if k not in xa or k not in xb or xa[k].dtype != xb[k].dtype
                        or xa[k].shape != xb[k].shape or xa[k].tobytes() != xb[k].tobytes())
        out[f"checkpoint {s} state"] = {"identical": not differ, "arrays": len(xa),
                                        "bytes": int(sum(x.nbytes for x in xa.values())), "differ": differ}
        out[f"checkpoint {s} meta"] = {"identical": _meta(a / "checkpoints" / s) == _meta(b / "checkpoints" / s),
                                       "not_compared": list(TIMINGS)}
    return out


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def machine() -> dict:
    cpu = ""
    try:
        cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                    if line.startswith("model name")), "")
    except OSError:
        pass
    mem = ""
    try:
        kb = int(next(line.split()[1] for line in Path("/proc/meminfo").read_text().splitlines()
                      if line.startswith("MemTotal")))
        mem = f"{kb / 2**20:.1f} GiB"
    except (OSError, StopIteration, ValueError):
        pass
    os_name = ""
    try:
        os_name = next(line.split("=", 1)[1].strip('"') for line in Path("/etc/os-release").read_text().splitlines()
                       if line.startswith("PRETTY_NAME="))
    except (OSError, StopIteration):
        pass
    return {"host": socket.gethostname(), "cpu": cpu, "cores": os.cpu_count(), "memory": mem, "os": os_name,
            "kernel": platform.release(), "python": platform.python_version()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slurm", type=Path, required=True, help="the SLURM job's --out")
    ap.add_argument("--one", type=Path, required=True, help="the one process's --out")
    ap.add_argument("--result", type=Path, default=None, help="write the result JSON here")
    ap.add_argument("--job-log", type=Path, default=None)
    ap.add_argument("--one-log", type=Path, default=None)
    for name in ("job-id", "submit", "one-command", "sinfo", "scontrol", "slurm-version", "jaxarm", "command"):
        ap.add_argument(f"--{name}", default="")
    for name in ("job-rc", "one-rc", "job-s", "one-s"):
        ap.add_argument(f"--{name}", type=int, default=None)
    args = ap.parse_args(argv)

    def lines(path):
        try:
            return path.read_text(errors="replace").splitlines() if path else []
        except OSError:
            return []

    try:
        comparison = compare(args.slurm, args.one)
        error = None
    except (OSError, KeyError, ValueError) as e:
        comparison, error = {}, f"{type(e).__name__}: {e}"
    failed = args.job_rc not in (0, None) or args.one_rc not in (0, None) or error is not None
    identical = bool(comparison) and all(v["identical"] for v in comparison.values()) and not failed
    report = []
    for name, v in comparison.items():
        extra = ", ".join(f"{k} {v[k]}" for k in ("generations", "candidates", "arrays", "bytes") if k in v)
        report.append(f"slurm_local: {name}: {'identical' if v['identical'] else 'DIFFERENT'}"
                      + (f" ({extra})" if extra else "") + (f" differ: {v['differ']}" if v.get("differ") else ""))
    if error:
        report.append(f"slurm_local: cannot compare: {error}")
    verdict = ("the SLURM job gave the same bits as one process" if identical else
               "a run failed" if failed else "the SLURM job's results DIFFER from one process's")
    report.append(f"slurm_local: {verdict}")
    commit = _git("rev-parse", "HEAD")
    job_log = lines(args.job_log)
    record = {
        "what": "the docs' SLURM recipe (experiments/slurm_evolve.sbatch, docs/scaling.md 'A SLURM cluster') "
                "scaled to one machine and submitted with sbatch to a one-machine SLURM started by "
                "experiments/slurm_local.sh, against the same command as one process",
        "command": args.command or "bash experiments/slurm_local.sh",
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "commit": commit,
        "commit_short": commit[:7],
        "uncommitted_changes": bool(_git("status", "--porcelain", "--untracked-files=no")),
        "jaxarm_imported_from": args.jaxarm,
        "machine": machine(),
        "slurm": {"version": args.slurm_version, "sinfo": args.sinfo, "submit": args.submit, "job_id": args.job_id,
                  "job_status": args.job_rc, "scontrol": args.scontrol, "wall_s": args.job_s,
                  "log": job_log, "log_text": "\n".join(job_log)},
        "one_process": {"command": args.one_command, "status": args.one_rc, "wall_s": args.one_s,
                        "log": lines(args.one_log)[-30:]},
        "comparison": comparison,
        "comparison_text": "\n".join(report),
        "identical": identical,
    }
    if error:
        record["error"] = error
    if args.result:
        args.result.parent.mkdir(parents=True, exist_ok=True)
        args.result.write_text(json.dumps(record, indent=1) + "\n")
    print("\n".join(report[:-1]))
    print(report[-1] + (f" (written to {args.result})" if args.result else ""))
    return 0 if identical else 2 if failed else 1


if __name__ == "__main__":
    sys.exit(main())
