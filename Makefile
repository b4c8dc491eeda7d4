# Two entry points for a newcomer (see README):
#   make run   -- set up .venv and regenerate every table and figure at the quick scale
#   make test  -- set up .venv and run the test suite
# Everything else is a helper for those two.

PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
SCALE  ?= quick
CORES  ?= 2

.PHONY: setup run full test bench clean

$(BIN)/contactbench: pyproject.toml constraints.txt
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found; set PYTHON=/path/to/python3.11"; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test]'
	@touch $@

setup: $(BIN)/contactbench

run: setup
	$(BIN)/snakemake --cores $(CORES) --configfile workflows/config/$(SCALE).yaml --rerun-incomplete

full: setup
	$(MAKE) run SCALE=full

test: setup
	$(BIN)/python -m pytest -q

bench: setup
	$(BIN)/python -m pytest -q tests --benchmark-enable --benchmark-only

clean:
	rm -rf results/*/ .snakemake
