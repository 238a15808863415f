"""The notebooks run: every code cell of each notebook, in order, in one namespace, at the smallest sizes
(``JAXARM_NOTEBOOK_TINY=1``: the notebooks shrink their networks and durations and never read a ``runs/`` folder);
their own ``assert`` statements check what they show."""
import json
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))
#: Run in the slow suite (each compiles a search, a robot pipeline or several networks: ~20-50 s; the default suite's 8-minute
#: budget).
SLOW = {"evolution.ipynb", "robot.ipynb", "gradients.ipynb", "network.ipynb", "quickstart.ipynb"}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_valid_and_its_code_parses(path):
    nb = json.loads(path.read_text())
    assert nb["nbformat"] == 4
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            compile("".join(cell["source"]), f"{path.name}", "exec")


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.name in SLOW else p
                                  for p in NOTEBOOKS], ids=lambda p: p.name)
def test_notebook_runs_at_tiny_size(path, monkeypatch, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.setenv("JAXARM_NOTEBOOK_TINY", "1")
    monkeypatch.chdir(tmp_path)          # self-contained: nothing to find in a runs/ folder
    namespace: dict = {}
    cells = [c for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code"]
    assert cells
    for i, cell in enumerate(cells):
        exec(compile("".join(cell["source"]), f"{path.name}[{i}]", "exec"), namespace)
    assert namespace["TINY"] is True
    plt.close("all")
