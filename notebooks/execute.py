"""Execute the tutorial notebooks and store them with their outputs (``make notebooks``).

    python notebooks/execute.py                      # all six, in place
    python notebooks/execute.py network.ipynb        # one
    python notebooks/execute.py --out DIR NOTEBOOK   # write the executed copy to DIR instead
    python notebooks/execute.py --out runs/nb-full --set EPOCHS=12 --set EPOCH_S=30.0 quickstart.ipynb   # other sizes

Each notebook runs in a fresh kernel started in a new temporary folder, where it writes its ``runs/``, at the sizes
of its parameter cell (the first code cell, tagged ``parameters``): the sizes the stored outputs were made with. What changes on every run and says nothing (the
cells' execution timestamps, the kernel's version) is left out; what the run took is kept in the notebook's metadata
(``jaxarm.executed``: seconds per code cell and in all, date, machine, CPU, Python and JAX), the numbers the stories
quote.
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NOTEBOOKS = sorted(HERE.glob("*.ipynb"))
#: Per-cell limit (s): the slowest cell at the stored sizes takes about a minute on one busy core.
CELL_TIMEOUT_S = 1200


def machine() -> str:
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count()
    return f"{platform.machine()}, {cores} cores"


#: Vector extensions, widest first: the first one the CPU has is part of its identity, because XLA and the native
#: kernel compile for it (one "AMD EPYC" model name has covered AVX-512 and AVX2 machines, which round alike only
#: where no vectorised sum or transcendental is involved).
VECTOR_EXTENSIONS = ("avx512f", "avx2", "avx", "sse4_2", "sve", "asimd")


def cpu() -> str:
    """The CPU's model name and its widest vector extension, e.g. "AMD EPYC, avx2"."""
    try:
        with open("/proc/cpuinfo") as f:
            lines = f.readlines()
    except OSError:
        return platform.processor()
    model = next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name")), platform.processor())
    flags = set(next((ln.split(":", 1)[1].split() for ln in lines if ln.startswith(("flags", "Features"))), []))
    widest = next((x for x in VECTOR_EXTENSIONS if x in flags), None)
    return f"{model}, {widest}" if widest else model


def execute(path: Path, cwd: Path | None = None, timeout: int = CELL_TIMEOUT_S, parameters: dict | None = None):
    """The notebook at ``path`` executed in a fresh kernel started in ``cwd`` (default: a new temporary folder, so
    that its ``runs/`` are its own); returns it (an ``nbformat`` node) with its outputs, per-cell times in
    ``metadata.jaxarm.executed`` and no volatile metadata. ``parameters`` (name -> value) are assigned at the end
    of the parameter cell, as papermill injects them."""
    import tempfile
    from importlib.metadata import version

    import nbformat
    from nbclient import NotebookClient

    if cwd is None:
        cwd = Path(tempfile.mkdtemp(prefix=f"jaxarm_{path.stem}_"))
    nb = nbformat.read(path, as_version=4)
    if parameters:
        cell = next(c for c in nb.cells if c.cell_type == "code")
        if "parameters" not in cell.metadata.get("tags", []):
            raise ValueError(f"{path.name}: its first code cell is not tagged 'parameters'")
        cell.source += "\n# set by notebooks/execute.py --set\n" + "".join(
            f"{k} = {v!r}\n" for k, v in parameters.items())
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
            cell.metadata.pop("execution", None)
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3", record_timing=True,
                            resources={"metadata": {"path": str(cwd)}})
    start = time.perf_counter()
    client.execute()
    total = time.perf_counter() - start
    cells = []
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        t = cell.metadata.pop("execution", {})
        a, b = t.get("iopub.execute_input"), t.get("shell.execute_reply")
        cells.append(round((_time(b) - _time(a)), 1) if a and b else None)
    nb.metadata.pop("widgets", None)
    nb.metadata["language_info"] = {"name": "python"}
    nb.metadata["jaxarm"] = {"executed": {"seconds": round(total, 1), "cell_seconds": cells,
                                          "date": datetime.date.today().isoformat(), "machine": machine(),
                                          "cpu": cpu(), "python": platform.python_version(),
                                          "jax": version("jax")}}
    if parameters:
        nb.metadata["jaxarm"]["executed"]["parameters"] = parameters
    return nb


def _time(stamp: str) -> float:
    return datetime.datetime.fromisoformat(stamp.replace("Z", "+00:00")).timestamp()


def main(argv=None) -> int:
    import nbformat

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("notebooks", nargs="*", help="notebook names or paths (default: every notebook in notebooks/)")
    ap.add_argument("--out", type=Path, help="write the executed notebooks here instead of in place")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="run with another value of a parameter-cell variable (a Python literal; repeatable; "
                         "only with --out: the stored notebooks keep the sizes their parameter cells say)")
    args = ap.parse_args(argv)
    import ast

    parameters = {}
    for item in args.set:
        name, _, value = item.partition("=")
        try:
            parameters[name.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            ap.error(f"--set {item}: VALUE must be a Python literal (a number, a quoted string, a tuple)")
    if parameters and not args.out:
        ap.error("--set needs --out: the stored notebooks keep the sizes their parameter cells say")
    paths = [Path(p) if Path(p).exists() else HERE / p for p in args.notebooks] or NOTEBOOKS
    for path in paths:
        print(f"{path.name}: executing ...", flush=True)
        nb = execute(path, parameters=parameters)
        dest = (args.out / path.name) if args.out else path
        dest.parent.mkdir(parents=True, exist_ok=True)
        nbformat.write(nb, dest)
        size = dest.stat().st_size
        print(f"{path.name}: {nb.metadata['jaxarm']['executed']['seconds']:.0f} s, {size / 1e3:.0f} kB -> {dest}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
