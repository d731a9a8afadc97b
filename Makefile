# Two commands set everything up on a fresh Debian/Ubuntu machine:
#   make demo   renders the bundled example scenario into out/demo
#   make test   runs the linter and the test suite
PYTHON ?= python3
# Python caches the bytecode of satsight's modules (src/**/__pycache__, ignored by git):
# with PYTHONDONTWRITEBYTECODE set, every process the tests start compiles ~150 modules
# from source again (~0.25 s each).
unexport PYTHONDONTWRITEBYTECODE
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.satsight-installed
OUT    ?= out/demo

.PHONY: demo test bench lint system-deps clean

system-deps:
	@bash scripts/ensure_system_deps.sh

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

demo: system-deps $(STAMP)
	$(BIN)/satsight demo --out $(OUT) --overwrite

test: system-deps $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -n auto --dist worksteal

bench: system-deps $(STAMP)
	$(BIN)/python benchmarks/render_bench.py

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

clean:
	rm -rf $(VENV) out .pytest_cache
