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

# The main job on the default world (office): exploration by fuzzy perimeter
# following until the robot is back at its start.
demo: venv
	$(BIN)/semmap run graphs/perimeter_following.yaml --out $(OUT) --record follower.FrontCP --record follower.RightCP
	$(BIN)/semmap render $(OUT) --gif
	$(BIN)/semmap graph graphs/perimeter_following.yaml --format png -o $(OUT)/graph.png
	@echo "Outputs are in $(OUT)/: path.png and run.gif (the exploration), velocity_plot.png"
	@echo "(v and w over time), graph.png (the pipeline), trajectory.csv, sonar.npz, probes.npz"
	@echo "and run.json (collisions, distance, loop closure, wall-distance error)."

test: venv-dev
	$(BIN)/python -m pytest -q -n 2

bench: venv
	$(BIN)/python benchmarks/run_all.py

docs: venv
	$(BIN)/semmap blocks --markdown -o docs/blocks.md

clean:
	rm -rf $(VENV) runs .pytest_cache
