"""The table of a ``benchmarks/profile.py`` result: milliseconds per network-second of each part, with its share of
training. Its own module (no side effects on import), so docs/hooks.py renders the tables of docs/benchmarks.md from
the result files with the same code that prints them."""
from __future__ import annotations

ROWS = ["train", "learning", "test", "kernel", "kernel: copy_in", "kernel: p_window", "kernel: noise",
        "kernel: cell_decay", "kernel: jumps", "kernel: threshold", "kernel: cells", "kernel: spike_bookkeeping",
        "kernel: delivery", "kernel: tags", "arm", "arm skeleton", "arm muscles", "readout", "XLA between kernel calls",
        "host round trip", "profiled test (timer overhead)"]


def table(results: list[dict]) -> str:
    head = "| part (ms per network-second) | " + " | ".join(
        f"{r['arm']}, {r['networks']} net." for r in results) + " |"
    lines = [head, "|---|" + "---|" * len(results)]
    for row in ROWS:
        cells = []
        for r in results:
            v = r["ms_per_network_s"].get(row)
            if v is None:
                cells.append("–")
                continue
            share = "" if row in ("profiled test (timer overhead)",) else \
                f" ({100 * v / r['ms_per_network_s']['train']:.0f} %)"
            cells.append(f"{v:.2f}{share}")
        lines.append(f"| {row} | " + " | ".join(cells) + " |")
    lines.append("| network-s/s, train | " + " | ".join(f"{r['network_s_per_s']['train']:.1f}" for r in results)
                 + " |")
    return "\n".join(lines)
