# Every target builds its own .venv, so each works from a fresh clone.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= runs/demo

.PHONY: demo test bench eval docs clean venv venv-dev

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
# following until the robot is back at its start, the online and offline maps,
# the door signs read on the way and placed on the map (the hybrid map), and
# the semantic map (places, the ontology's knowledge, objects).
demo: venv
	$(BIN)/semmap run graphs/semantic_mapping.yaml --out $(OUT) --record follower.FrontCP --record follower.RightCP
	$(BIN)/semmap render $(OUT) --gif
	$(BIN)/semmap graph graphs/semantic_mapping.yaml --format png -o $(OUT)/graph.png
	@echo "Outputs are in $(OUT)/: semantic_map.ttl (the semantic map: places, kinds,"
	@echo "connectivity, signs, objects, people; query it with 'semmap sparql $(OUT) QUERY'),"
	@echo "places.geojson and maps/semantic.png (the places), signs.json (the signs read,"
	@echo "placed on the map) and maps/hybrid.png, objects/ (recognised objects), maps/ (online and offline maps,"
	@echo "map_server YAML + PGM + PNG), signs/captures/ (the zoomed captures) and"
	@echo "signs/sightings.csv (every reading, with the plate it went to), path.png and"
	@echo "run.gif (the exploration), velocity_plot.png, graph.png (the pipeline),"
	@echo "trajectory.csv, sonar.npz, probes.npz and run.json (scores, stops, timings)."
	@echo "Ask the robot: $(BIN)/semmap ask \"go to the kitchen\" --map $(OUT) [--execute]"

test: venv-dev
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

bench: venv
	$(BIN)/python benchmarks/run_all.py

# The standard evaluation: the main pipeline on 60 generated buildings (12 of
# each kind) that no tuning has looked at (keep seeds >= 1000 out of tuning),
# one run each, on a process pool; summary in $(EVAL_OUT)/summary.md and
# summary.png. Rerunning it resumes; `semmap sweep --report $(EVAL_OUT)` redraws.
# EVAL_STEPS sets each run's budget in ticks of 0.1 s (empty: the graph's 15000,
# 1,500 s; 36000 gives an hour).
EVAL_OUT    ?= runs/eval
EVAL_WORLDS ?= gen:any:1000-1059
EVAL_STEPS  ?=
eval: venv
	$(BIN)/semmap sweep graphs/semantic_mapping.yaml --worlds $(EVAL_WORLDS) --seeds 0 \
		$(if $(EVAL_STEPS),--steps $(EVAL_STEPS)) --timeout 1200 --out $(EVAL_OUT)
	@echo "Summary: $(EVAL_OUT)/summary.md and $(EVAL_OUT)/summary.png; every run: $(EVAL_OUT)/results.csv and $(EVAL_OUT)/runs/"

docs: venv
	$(BIN)/semmap blocks --markdown -o docs/blocks.md

clean:
	rm -rf $(VENV) runs .pytest_cache
