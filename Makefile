# Quick start: `make demo` and `make test` — each works on a fresh machine with only python3.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
STORE  ?= bench-data/bench.sqlite

.PHONY: demo test lint bench-speed clean postgresql chromium

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,dev]'
	touch $(STAMP)

## demo: factory acceptance of a simulated accelerometer and a simulated FOG on the simulated
## station (start-up, tumble, rate table, noise), with verdicts, stored runs and HTML reports
demo: $(STAMP)
	$(BIN)/bench --store $(STORE) acceptance --station sim --unit QA-SIM-0003 --seed 1 \
		--report bench-data/reports
	$(BIN)/bench --store $(STORE) acceptance --station sim --unit FOG-SIM-0002 --seed 1 \
		--report bench-data/reports

## postgresql: PostgreSQL's initdb/pg_ctl for the central store's tests (Debian's package,
## apt-get installed as root when missing); the tests start their own server (scripts/pg)
postgresql:
	$(PYTHON) scripts/pg install

## test: the whole suite (hypothesis derandomised in CI), one worker per core (pytest-xdist)
test: $(STAMP) postgresql chromium
	$(BIN)/python -m pytest -q -p no:cacheprovider -n auto

## lint: the linter, the type checker and the import-layer contracts on the whole tree
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(BIN)/lint-imports

## bench-speed: the benchmark scripts, side by side with their peers
bench-speed: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) bench-data build *.egg-info

## chromium: Debian's chromium for the operator page's browser tests (Playwright drives it;
## it cannot download a browser of its own), apt-get installed as root when missing
chromium:
	command -v chromium >/dev/null 2>&1 || (apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y chromium)
