# The two set-up commands of README.md. Both create .venv on first use and install jaxarm into it.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test test-slow bench

$(BIN)/jaxarm: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test]"
	touch $(BIN)/jaxarm

demo: $(BIN)/jaxarm
	$(BIN)/jaxarm demo --out runs/demo

test: $(BIN)/jaxarm
	$(BIN)/python -m pytest -q

test-slow: $(BIN)/jaxarm
	$(BIN)/python -m pytest -q -m slow

bench: $(BIN)/jaxarm
	$(BIN)/python benchmarks/arm.py --json
	$(BIN)/python benchmarks/network.py --json
	$(BIN)/python benchmarks/train.py --json
	$(BIN)/python benchmarks/wam.py
