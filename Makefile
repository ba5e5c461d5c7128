# Two entry points (see README): `make run` and `make test`. Both create .venv on first use.
PY      ?= python3
VENV    ?= .venv
BIN     := $(VENV)/bin
# CPU wheel by default; a GPU user sets TORCH_SPEC to the CUDA build they installed or want.
TORCH_SPEC ?= torch==2.13.0
export WARP_CACHE_PATH := $(CURDIR)/data/cache/warp
export RERUN_ANALYTICS ?= 0

.PHONY: venv run test test-slow bench reports clean-cache

# `make run` installs what run.py uses by default (the package + the extras sim, viz and mesh: the Newton/warp
# reference simulator, rerun, pymeshlab; about 3 GB); `make test` adds the test tools, Anny, usd-core and the
# submitit launcher (.[dev], about 0.3 GB more). pip shows its progress; set
# PIP_NO_CACHE_DIR=1 to keep pip from also caching the downloads (about 1.3 GB) under ~/.cache/pip.
$(BIN)/.installed: pyproject.toml
	@echo "== [1/3] creating $(VENV) (first use only; about 2.9 GB and 1-2 minutes in all)"
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	@echo "== [2/3] installing $(TORCH_SPEC) (about 0.75 GB installed for the CPU build)"
	$(BIN)/pip install --progress-bar on "$(TORCH_SPEC)"
	@echo "== [3/3] installing drapebench and its dependencies (rerun, warp/newton, pymeshlab, mlflow-skinny, ...)"
	$(BIN)/pip install --progress-bar on -e ".[sim,viz,mesh]"
	@du -sh $(VENV) | sed 's/^/== .venv is /'
	touch $@

$(BIN)/.installed-dev: $(BIN)/.installed
	@echo "== installing the test tools (pytest, anny, usd-core, submitit launcher)"
	$(BIN)/pip install --progress-bar on -e ".[dev]"
	touch $@

# The simulator's warp kernels, compiled once per environment (about a minute on 2 cores) before the
# first test session; warp keeps them in data/cache/warp (drapebench/reference/kernels.py).
KERNELS := $(WARP_CACHE_PATH)/.compiled

$(KERNELS): $(BIN)/.installed-dev drapebench/reference/scene.py drapebench/geometry/body_bvh.py
	$(BIN)/python -m drapebench.reference.kernels
	touch $@

venv: $(BIN)/.installed

run: venv
	$(BIN)/python run.py $(ARGS)

test: $(BIN)/.installed-dev $(KERNELS)
	$(BIN)/python -m pytest $(ARGS)

test-slow: $(BIN)/.installed-dev $(KERNELS)
	$(BIN)/python -m pytest -m slow $(ARGS)

# Every committed table from its experiments (drapebench/table_specs.py), then reports/claims.md: hours on 2 cores;
# finished runs are kept and skipped, so a stopped `make reports` goes on where it stopped.
# ARGS="--tables gaps_table1" for some tables, ARGS=--quick for the pipeline on a tiny scene; JOBS runs at once
# (default: one per core, each pinned to its core; the runs that share a model go to one of them in turn).
JOBS ?= $(shell nproc)
reports: $(BIN)/.installed-dev $(KERNELS)
	$(BIN)/python -m drapebench.reproduce --jobs $(JOBS) $(ARGS)

bench: venv
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean-cache:
	rm -rf data/cache data/datasets
