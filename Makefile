# Quick start: `make demo` and `make test` — each works on a fresh machine with only python3.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
STORE  ?= bench-data/bench.sqlite

.PHONY: demo test bench-speed clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

## demo: the start-up acquisition (30 min at 100 Hz, simulated) and its start-up model
demo: $(STAMP)
	$(BIN)/bench --store $(STORE) run startup --station sim --unit QA-SIM-0001 --seed 1 \
		--analyze --report bench-data/reports

## test: the whole suite (hypothesis derandomised in CI)
test: $(STAMP)
	$(BIN)/python -m pytest -q -p no:cacheprovider

## bench-speed: the benchmark scripts, side by side with their peers
bench-speed: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) bench-data build *.egg-info
