# Two entry points (see README): `make run` and `make test`. Both create .venv on first use.
PY      ?= python3
VENV    ?= .venv
BIN     := $(VENV)/bin
# CPU wheel by default; a GPU user sets TORCH_SPEC to the CUDA build they installed or want.
TORCH_SPEC ?= torch==2.13.0
export WARP_CACHE_PATH := $(CURDIR)/data/cache/warp
export RERUN_ANALYTICS ?= 0

.PHONY: venv run test test-slow bench clean-cache

$(BIN)/.installed: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q "$(TORCH_SPEC)"
	$(BIN)/pip install -q -e ".[dev]"
	touch $@

venv: $(BIN)/.installed

run: venv
	$(BIN)/python run.py $(ARGS)

test: venv
	$(BIN)/python -m pytest $(ARGS)

test-slow: venv
	$(BIN)/python -m pytest -m slow $(ARGS)

bench: venv
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean-cache:
	rm -rf data/cache data/datasets
