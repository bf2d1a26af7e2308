# Set-up from nothing: every target creates .venv when it is missing (CPU torch first, so that
# stable-baselines3 does not pull a CUDA build), and is quick when it exists.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench lint clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e ".[all]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m active_loc.demo

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -n 2 -q

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_multimodal.py --json reports/bench_multimodal.json
	$(BIN)/python benchmarks/bench_steps.py
	$(BIN)/python benchmarks/bench_maze.py
	$(BIN)/python benchmarks/bench_mcl.py
	$(BIN)/python benchmarks/bench_vector.py
	$(BIN)/python benchmarks/bench_training_split.py

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
