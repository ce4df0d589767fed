# Quick start: `make demo`, `make test` and `make docs` — each works on a fresh machine with only python3.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
STORE  ?= bench-data/bench.sqlite

.PHONY: demo test docs lint bench-speed clean postgresql chromium poppler

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,dev,docs]'
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

## test: the whole suite (hypothesis derandomised in CI) on three workers per two cores (pytest-xdist,
## each idle worker taking tests from the busiest): with one per core the suite keeps the cores 78 %
## busy — a fifth of its time is spent waiting on subprocesses, browsers and servers. It includes
## tests/test_docs.py: the strict docs build and the README's and tutorial's runnable commands
TEST_WORKERS ?= $(shell n=$$(nproc); echo $$(( n * 3 / 2 > 1 ? n * 3 / 2 : 1 )))
test: $(STAMP) postgresql chromium poppler
	$(BIN)/python -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --dist worksteal

## docs: the documentation site from docs/ into build/site/, strictly (a broken link or anchor
## fails); the CLI reference page is generated from the parsers at build time (scripts/cli_reference.py)
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

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

## poppler: poppler's pdftoppm/pdftotext, with which the tests render the reports' PDFs page by
## page (Debian's poppler-utils, apt-get installed as root when missing)
poppler:
	command -v pdftoppm >/dev/null 2>&1 || (apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y poppler-utils)
