"""The fault-injection table of docs/faults.md: run every case of tests/test_faults.py, check it as the test does,
and print a markdown table (case, exit status, the one line the command answered).

    python experiments/fault_table.py              # the default suite's cases (about a minute on 2 cores)
    python experiments/fault_table.py --slow       # and the slow ones (two real train processes, a real full disk)

A case whose check fails is printed with FAILED and its reason, and the script exits 1. Paths under the
temporary work folder are shown relative to it; PIDs and host names are this run's.
"""
from __future__ import annotations

import argparse
import importlib.util
import re
import sys
import tempfile
import time
from pathlib import Path

import jax

ROOT = Path(__file__).resolve().parents[1]
jax.config.update("jax_num_cpu_devices", 2)        # as the test suite (tests/conftest.py)


def _load_tests():
    spec = importlib.util.spec_from_file_location("test_faults", ROOT / "tests" / "test_faults.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["test_faults"] = mod        # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--slow", action="store_true", help="also the slow cases (none are in the table yet)")
    args = ap.parse_args(argv)
    tests = _load_tests()
    failed = 0
    rows = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="faults-") as tmp:
        ws = tests.Workspace(Path(tmp))
        for i, case in enumerate(c for c in tests.CASES if args.slow or not c.slow):
            try:
                got = tests.check(case, ws)
                line = got.shown or tests.one_line(got.err, ()) or ""
                code = str(got.code)
            except BaseException as e:  # noqa: BLE001 - a case that fails is reported in the table
                if isinstance(e, KeyboardInterrupt):
                    raise
                failed += 1
                code, line = "FAILED", f"{type(e).__name__}: {str(e).strip().splitlines()[0] if str(e).strip() else ''}"
            line = re.sub(re.escape(tmp) + r"/(\d\d-)?", "", line)
            quote = "``" if "`" in line else "`"     # a code span around text with backticks needs two
            rows.append(f"| {i + 1} | {_cell(case.name)} | {code} | {quote} {_cell(line)} {quote} |")
    print("| # | case | exit | the answer (one line on stderr) |")
    print("|---|---|---|---|")
    print("\n".join(rows))
    print(f"\n{len(rows)} cases, {failed} failed, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
