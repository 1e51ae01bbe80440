# Every target builds its own .venv, so each works from a fresh clone.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= runs/demo

.PHONY: demo test bench docs clean venv venv-dev

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# The stamp files re-install whenever pyproject.toml changes.
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@ $(VENV)/.installed

venv: $(VENV)/.installed
venv-dev: $(VENV)/.installed-dev

demo: venv
	$(BIN)/semmap run graphs/demo.yaml --out $(OUT) --record smooth.y
	$(BIN)/semmap graph graphs/demo.yaml --format png -o $(OUT)/graph.png
	@echo "Outputs are in $(OUT)/: run.json, signals.png, graph.png, readings.csv, probes.npz"

test: venv-dev
	$(BIN)/python -m pytest -q -n 2

bench: venv
	$(BIN)/python benchmarks/run_all.py

docs: venv
	$(BIN)/semmap blocks --markdown -o docs/blocks.md

clean:
	rm -rf $(VENV) runs .pytest_cache
