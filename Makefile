# The two set-up commands of README.md. Both create .venv on first use and install jaxarm into it.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test test-slow bench docs notebooks

$(BIN)/jaxarm: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test]"
	touch $(BIN)/jaxarm

# The arms alone (seconds), then the main job on a small default: 4 + 4 networks per target trained 4 epochs with
# the evolved musculoskeletal preset, tested, counted (a few minutes on one core; rerunning resumes/reuses it).
demo: $(BIN)/jaxarm
	$(BIN)/jaxarm demo --out runs/demo
	$(BIN)/jaxarm reproduce --arm musculoskeletal --preset msarm-cmaes-2cm-rerank --networks 4 --top 4 --epochs 4 \
	    --out runs/demo/reach

# Both suites spread their test files over one worker process per CPU, at most four (pytest-xdist; each worker is
# a JAX process with its own two CPU devices, so more would only crowd the cores and the memory):
# `make test PYTEST_WORKERS="-n 0"` runs every test in one process.
PYTEST_WORKERS ?= -n auto --maxprocesses 4 --dist loadfile

test: $(BIN)/jaxarm
	$(BIN)/python -m pytest -q $(PYTEST_WORKERS)

test-slow: $(BIN)/jaxarm
	$(BIN)/python -m pytest -q -m slow $(PYTEST_WORKERS)

bench: $(BIN)/jaxarm
	$(BIN)/python benchmarks/arm.py --json
	$(BIN)/python benchmarks/network.py --json
	$(BIN)/python benchmarks/train.py --json
	$(BIN)/python benchmarks/wam.py

# The documentation site (mkdocs.yml, docs/) into site/; --strict: any warning (a broken link, a docstring the API
# reference cannot render) fails the build. Installs the docs extra into .venv on first use.
$(BIN)/mkdocs: pyproject.toml $(BIN)/jaxarm
	$(BIN)/pip install --quiet -e ".[docs]"
	touch $(BIN)/mkdocs

docs: $(BIN)/mkdocs
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

# The tutorials (notebooks/*.ipynb) executed and stored with their outputs, at the sizes of each notebook's
# parameter cell (notebooks/execute.py; 50 min on this project's 2-core machine, shared with other jobs). The site
# shows them as stored; `make test-slow` executes each again and compares.
notebooks: $(BIN)/jaxarm
	$(BIN)/python notebooks/execute.py
