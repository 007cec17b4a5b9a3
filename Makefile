# upm: `make demo` and `make test` set everything up on a fresh clone (a .venv with maturin and the
# Python dependencies, the extension built in release mode), then run. `make help` lists the rest.
SHELL := /bin/bash
.DEFAULT_GOAL := help

VENV ?= .venv
PY := $(VENV)/bin/python
export VIRTUAL_ENV := $(abspath $(VENV))
# pyo3's build script (cargo clippy, cargo test) must see the same interpreter as maturin.
export PYO3_PYTHON := $(abspath $(PY))
export PATH := $(abspath $(VENV))/bin:$(PATH)

RUST_SOURCES := Cargo.toml Cargo.lock $(shell find crates -name '*.rs' -o -name Cargo.toml)
PY_DIRS := python tests bench examples
# pytest on every core (pytest-xdist; at most 4 workers, as each runs the core's threads too); a
# worker that runs out of tests takes some of another's. `make test PYTEST_WORKERS=` runs serially.
PYTEST_WORKERS ?= -n auto --maxprocesses=4 --dist worksteal

$(VENV)/.deps: pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet 'maturin>=1.9,<2'
	touch $@

$(VENV)/.built: $(VENV)/.deps $(RUST_SOURCES) pyproject.toml
	$(VENV)/bin/maturin develop --release --extras dev --quiet
	touch $@

# The desk's browser tests and `upm replay --screenshot` drive Debian's Chromium through Playwright
# (Playwright's own browser download is not reachable here).
.PHONY: chromium
chromium: ## install Debian's chromium when it is missing (for the desk's browser tests)
	@command -v chromium >/dev/null || command -v chromium-browser >/dev/null || \
	  { echo "installing Debian's chromium"; \
	    $$( [ "$$(id -u)" = 0 ] || echo sudo ) apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive $$( [ "$$(id -u)" = 0 ] || echo sudo ) apt-get install -y -qq chromium >/dev/null; }

.PHONY: help
help: ## list the targets
	@grep -hE '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-8s %s\n", $$1, $$2}'

.PHONY: install
install: $(VENV)/.built ## create .venv, install the dependencies, build the extension (release)

.PHONY: demo
demo: $(VENV)/.built ## the main job: 8 chips sorted by colour through the full loop (camera, vision, the predictive planner planning while the plate plays, board protocol, emulator); figures in out/
	$(PY) -m upm.cli demo sort8 --board --planner predictive --pipeline 6 --out out
	$(PY) -m upm.cli figures --out out/figures

.PHONY: test
test: $(VENV)/.built chromium ## every check: cargo test, clippy, the layers, pytest, ruff, mypy + stubtest
	$(VENV)/bin/lint-imports --no-cache
	cargo fmt --all --check
	cargo test --quiet
	# (the one-pass short run again on the AVX2 build: on an AVX-512 machine the default is the other)
	UPM_SIMD=avx2 cargo test --quiet -p upm-core --lib sim::short
	cargo clippy --workspace --all-targets --quiet -- -D warnings
	$(PY) -m pytest -q $(PYTEST_WORKERS)
	$(PY) -m ruff check $(PY_DIRS)
	$(PY) -m ruff format --check $(PY_DIRS)
	$(PY) -m mypy
	$(PY) -m mypy.stubtest upm._core

.PHONY: test-fast
test-fast: $(VENV)/.built ## the edit loop: the layers, then pytest without the tests marked slow
	$(VENV)/bin/lint-imports --no-cache
	$(PY) -m pytest -q -m "not slow" $(PYTEST_WORKERS)

.PHONY: lint
lint: $(VENV)/.built ## ruff (fixing what it can), clippy, mypy, the layers (import-linter)
	$(VENV)/bin/lint-imports --no-cache
	$(PY) -m ruff format $(PY_DIRS)
	$(PY) -m ruff check --fix $(PY_DIRS)
	cargo clippy --workspace --all-targets -- -D warnings
	$(PY) -m mypy

.PHONY: bench
bench: $(VENV)/.built ## side-by-side benchmarks (ours vs the peer, ratios printed)
	cargo bench --quiet -p upm-core
	$(PY) bench/theory.py
	$(PY) bench/solvers.py
	$(PY) bench/vision.py
	$(PY) bench/sweeps.py
	$(PY) -m pip install --quiet 'mujoco>=3.1' 'numba>=0.60'
	$(PY) bench/integrator.py --mujoco
	$(PY) bench/contacts.py
	$(PY) -m pip install --quiet 'gymnasium>=1.2'
	$(PY) bench/envs.py

.PHONY: wheel
wheel: $(VENV)/.deps ## the abi3 wheel (manylinux_2_17, stripped, linked with zig) and the sdist into dist/, then checked
	$(PY) -m pip install --quiet 'ziglang==0.14.1'
	rm -rf dist
	$(VENV)/bin/maturin build --release --zig --compatibility manylinux_2_17 --strip --out dist
	$(VENV)/bin/maturin sdist --out dist
	$(PY) .ci/check_wheel.py dist

.PHONY: clean
clean: ## remove build products and the venv
	cargo clean
	rm -rf $(VENV) dist out .pytest_cache .ruff_cache .mypy_cache
