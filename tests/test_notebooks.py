"""The tutorial notebooks (``notebooks/*.ipynb``) are stored with their outputs, made by ``make notebooks``
(``notebooks/execute.py``) at the sizes of each notebook's parameter cell, and the site shows them as stored.

* Every notebook parses, and its stored copy is complete: every code cell ran, in order, without an error; every
  cell that draws holds its PNG; its metadata says when, where and how long it ran; its story says how long it
  takes (no execution: the default suite).
* Executed again at the same sizes (the slow suite: 1-7 min each, beyond the default suite's 8-minute budget), a
  notebook gives the same outputs: the same cells print the same lines with only their numbers free, draw the
  same number of images, and print the same key values (the cells tagged ``key-values`` and the lines of
  :data:`KEY_LINES`: numbers no float rounding moves, from the model's constants and geometry, a run's protocol,
  a seeded packet timing or a result file; compared as printed). On the machine that stored them (the same CPU model and
  widest vector extension, JAX and Python) every printed number must be equal
  too, but for the few lines that time something or depend on the wall clock (:data:`VOLATILE`): the notebooks are
  deterministic. On another machine the spike trains of a trained network may part from the stored ones after
  a while, as the changelog says two machines' do, so the trained numbers are left free there.
"""
from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
_spec = importlib.util.spec_from_file_location("notebooks_execute", ROOT / "notebooks" / "execute.py")
execute = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(execute)

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|\bnan\b|\binf\b")

#: Besides the cells tagged ``key-values`` (every number they print), the printed lines (a regex each, matched from
#: the line's start) whose numbers must equal the stored ones on any machine: they come from the model's constants,
#: a run's protocol or a seeded packet timing, not from a trained network's spikes.
KEY_LINES = {
    "quickstart.ipynb": [r"\d+ frames of \d+x\d+ at"],
    "network.ipynb": [r"\('ES', 'IS'"],
    "gradients.ipynb": [],
    "robot.ipynb": [r"packet interval mean / SD"],
    "evolution.ipynb": [r"pub\."],
    "paper_comparison.ipynb": [r"simple arm, preset"],
}
KEY_TAG = "key-values"
#: Lines whose numbers may differ between two runs on one machine: wall times, and the live UDP stream's timing.
VOLATILE = [r".* in [\d.]+ s after", r".*\bwall\b", r".*\bcompil", r"sent \d+, received", r"mean \|error\| live",
            r".*network-s/s", r".*\d+ s\)?$"]


def code_cells(nb: dict) -> list[dict]:
    return [c for c in nb["cells"] if c["cell_type"] == "code"]


def _text(data) -> str:
    return "".join(data) if isinstance(data, list) else str(data)


def printed_lines(cell: dict) -> list[str]:
    """What a cell printed or returned as text (stdout, a result's text, a Markdown table), line by line;
    stderr (warnings) left out."""
    out = []
    for o in cell.get("outputs", []):
        if o["output_type"] == "stream" and o["name"] == "stdout":
            out += _text(o["text"]).splitlines()
        elif o["output_type"] in ("execute_result", "display_data"):
            data = o["data"]
            if "text/markdown" in data:
                out += _text(data["text/markdown"]).splitlines()
            elif "text/plain" in data and not any(k.startswith(("image/", "text/html")) for k in data):
                out += _text(data["text/plain"]).splitlines()
    return [line for line in out if line.strip()]


def images(cell: dict) -> int:
    return sum("image/png" in o.get("data", {}) for o in cell.get("outputs", []))


def skeleton(line: str) -> str:
    """A printed line with its numbers masked and its spacing dropped (numpy pads arrays by their widest entry)."""
    return re.sub(r"\s+", "", NUMBER.sub("#", line))


def numbers(line: str) -> list[str]:
    return NUMBER.findall(line)


def story(nb: dict) -> str:
    return _text(nb["cells"][0]["source"])


# ---------------------------------------------------------------- the stored copies (default suite)
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_valid_and_its_code_parses(path):
    nb = json.loads(path.read_text())
    assert nb["nbformat"] == 4
    for cell in code_cells(nb):
        compile("".join(cell["source"]), f"{path.name}", "exec")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_stored_with_its_outputs(path):
    nb = json.loads(path.read_text())
    cells = code_cells(nb)
    # every code cell ran, in order, once
    assert [c["execution_count"] for c in cells] == list(range(1, len(cells) + 1)), "run `make notebooks`"
    for i, cell in enumerate(cells):
        assert not [o for o in cell["outputs"] if o["output_type"] == "error"], f"code cell {i} raised"
        assert "execution" not in cell["metadata"], "volatile timestamps stored (notebooks/execute.py drops them)"
        if re.search(r"plt\.subplots|plt\.plot\(|imshow", "".join(cell["source"])):
            assert images(cell) >= 1, f"code cell {i} draws but holds no PNG"
    # a parameter cell first, with the full sizes and their time in its comments
    params = cells[0]
    assert "parameters" in params["metadata"].get("tags", []), "the first code cell is the parameter cell"
    assert re.search(r"[Ff]ull size", "".join(params["source"])), "the parameter cell gives the full sizes"
    executed = nb["metadata"]["jaxarm"]["executed"]
    assert executed["seconds"] > 0 and len(executed["cell_seconds"]) == len(cells)
    # the story says what it shows and how long it takes, at the stored size and at full size
    text = story(nb)
    assert nb["cells"][0]["cell_type"] == "markdown" and text.startswith("# ")
    assert re.search(r"stored outputs", text) and re.search(r"full size", text), "the story gives both times"


def test_notebooks_are_small():
    total = sum(p.stat().st_size for p in NOTEBOOKS)
    assert total < 3e6, f"the stored notebooks hold {total / 1e6:.1f} MB"


# ---------------------------------------------------------------- executed again (slow suite)
def same_machine(stored: dict, now: dict) -> bool:
    keys = ("cpu", "machine", "python", "jax")
    return all(stored.get(k) == now.get(k) for k in keys)


def test_a_machine_is_its_cpu_model_and_vector_extension():
    """One model name ("AMD EPYC") has covered AVX-512 and AVX2 machines, whose XLA programs round differently: the
    recorded CPU names the widest vector extension too, so the two are not the same machine."""
    if not Path("/proc/cpuinfo").exists():
        pytest.skip("no /proc/cpuinfo here")
    assert execute.cpu().rsplit(", ", 1)[-1] in execute.VECTOR_EXTENSIONS
    assert not same_machine({"cpu": "AMD EPYC, avx512f", "machine": "m", "python": "3", "jax": "j"},
                            {"cpu": "AMD EPYC, avx2", "machine": "m", "python": "3", "jax": "j"})


def compare(name: str, stored: dict, new: dict) -> list[str]:
    """Differences between a stored notebook and the same notebook executed again (see the module docstring)."""
    problems = []
    old_cells, new_cells = code_cells(stored), code_cells(new)
    assert len(old_cells) == len(new_cells)
    exact = same_machine(stored["metadata"]["jaxarm"]["executed"], new["metadata"]["jaxarm"]["executed"])
    keys = [re.compile(k) for k in KEY_LINES[name]]
    volatile = [re.compile(v) for v in VOLATILE]
    for i, (a, b) in enumerate(zip(old_cells, new_cells)):
        if images(a) != images(b):
            problems.append(f"cell {i}: {images(a)} images stored, {images(b)} now")
        la, lb = printed_lines(a), printed_lines(b)
        if [skeleton(x) for x in la] != [skeleton(x) for x in lb]:
            problems.append(f"cell {i}: prints {lb} where it stored {la}")
            continue
        tagged = KEY_TAG in a.get("metadata", {}).get("tags", [])
        for x, y in zip(la, lb):
            if numbers(x) == numbers(y):
                continue
            if tagged or any(k.match(x.strip()) for k in keys):
                problems.append(f"cell {i}: key values {y!r} where it stored {x!r}")
            elif exact and not any(v.match(x.strip()) for v in volatile):
                problems.append(f"cell {i} (same machine, so every number): {y!r} where it stored {x!r}")
    return problems


def test_compare_sees_a_difference():
    """The comparison itself: equal notebooks pass; a changed key value, a changed line, a missing image fail."""
    def nb(key, lines, n_images=1, cpu="A"):
        def cell(text, tags):
            outputs = [{"output_type": "stream", "name": "stdout", "text": text + "\n"}]
            return {"cell_type": "code", "outputs": outputs, "source": "", "metadata": {"tags": tags}}
        cells = [cell(key, [KEY_TAG]), cell("\n".join(lines), [])]
        cells[1]["outputs"] += [{"output_type": "display_data", "data": {"image/png": "x"}}] * n_images
        return {"cells": cells, "metadata": {"jaxarm": {"executed": {"cpu": cpu, "machine": "m", "python": "3",
                                                                   "jax": "1"}}}}

    arms, trained = "elbow moment arms (mm): a -18.0, b 25.1", ["closest (cm): [ 1.2 10.4]", "10 frames of 4x3 at 10 fps"]
    stored = nb(arms, trained)
    assert compare("quickstart.ipynb", stored, stored) == []
    # another machine: a trained number is free; a tagged cell's numbers and a key line's are not
    assert compare("quickstart.ipynb", stored, nb(arms, ["closest (cm): [11.2 10.4]", trained[1]], cpu="B")) == []
    assert compare("quickstart.ipynb", stored, nb(arms.replace("-18.0", "-18.1"), trained, cpu="B"))
    assert compare("quickstart.ipynb", stored, nb(arms, [trained[0], "12 frames of 4x3 at 10 fps"], cpu="B"))
    # the same machine: every number; any machine: the lines printed and the images drawn
    assert compare("quickstart.ipynb", stored, nb(arms, ["closest (cm): [11.2 10.4]", trained[1]]))
    assert compare("quickstart.ipynb", stored, nb(arms, trained[:1], cpu="B"))
    assert compare("quickstart.ipynb", stored, nb(arms, trained, n_images=0, cpu="B"))


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_executes_to_its_stored_outputs(path, tmp_path):
    stored = json.loads(path.read_text())
    new = json.loads(json.dumps(execute.execute(path, cwd=tmp_path)))     # a fresh kernel in an empty folder
    problems = compare(path.name, stored, new)
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------- the library's figures in a notebook
def test_library_figures_keep_a_notebooks_backend():
    """Drawing a run's figures (``jaxarm figures``, ``export --figures``, a search's convergence plot) from a notebook
    leaves its backend alone: switching to Agg would close the notebook's figures and hide every later one. The
    library chooses Agg only when pyplot was not imported yet (the command line)."""
    import matplotlib.pyplot as plt

    from jaxarm.robot import figures as robot_figures
    from jaxarm.viz import figures

    before = plt.get_backend()
    plt.switch_backend("svg")               # stands for the notebook's inline backend
    try:
        fig = plt.figure()
        figures.plt()
        robot_figures._plt()
        assert plt.get_backend() == "svg" and plt.fignum_exists(fig.number)
    finally:
        plt.close("all")
        plt.switch_backend(before)
    for path in (ROOT / "jaxarm").rglob("*.py"):
        lines = path.read_text().splitlines()
        for i, line in enumerate(lines):
            if "matplotlib.use(" in line:
                assert 'if "matplotlib.pyplot" not in sys.modules' in lines[i - 1], f"{path}:{i + 1}"
