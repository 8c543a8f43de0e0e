# Two entry points for a fresh machine with only Python 3.11 and pip:
#   make run   -> set up .venv, compute the nominal mission's capacity bound, fly it with the paper's
#                 controller and the capacity-seeking one, compare both beside the bound
#   make test  -> set up .venv (with test extras), lint (ruff), type-check (mypy), run the test suite, build the docs
#   make docs  -> the documentation site (Sphinx + furo) in docs/_build/html, warnings as errors
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
OUT    ?= runs/demo
EXTRAS ?= dev

.PHONY: run test docs bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[$(EXTRAS)]'
	touch $@

# the main job needs only the runtime dependencies (not the test and documentation tools)
$(VENV)/.installed-run: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

run: $(VENV)/.installed-run
	$(BIN)/aerorelay info scenarios/nominal_tilted.toml
	$(BIN)/aerorelay bound scenarios/nominal_tilted.toml --out $(OUT)/bound
	$(BIN)/aerorelay run scenarios/nominal_tilted.toml --out $(OUT)/paper
	$(BIN)/aerorelay run scenarios/nominal_tilted.toml --planner capacity --out $(OUT)/capacity
	$(BIN)/aerorelay compare $(OUT)/paper $(OUT)/capacity

# numpy's and OpenBLAS's kernels are chosen by CPU (AVX-512 or not) and round differently; the recorded flights the
# tests compare at 1e-9 are flown on the same kernels on any x86-64 CPU with AVX2 (tests/sim/test_one_machinery.py)
TEST_PINS := OPENBLAS_CORETYPE=Haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR"

test: $(VENV)/.installed
	$(BIN)/ruff check src tests
	$(BIN)/mypy src
	$(TEST_PINS) $(BIN)/python -m pytest -q
	$(MAKE) docs

docs: $(VENV)/.installed
	$(BIN)/sphinx-build -W --keep-going -q -b html docs docs/_build/html

bench: $(VENV)/.installed
	$(BIN)/aerorelay bench scenarios/nominal_tilted.toml

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .hypothesis docs/_build docs/tutorials
