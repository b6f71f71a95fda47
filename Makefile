# One command each: `make demo` installs benchbus and runs its demo on simulated devices,
# `make test` installs and runs every test, `make lint` every check, `make docs` builds the
# documentation site into site/ (`make docs-serve`: a live preview), `make bench` the
# benchmark beside minimalmodbus, pymodbus and modbus-rs, `make cross` the checks for other systems
# (Windows: cross-built, run under wine; it installs what it needs).
#
# Every target installs into a virtual environment: the active one if there is one
# ($VIRTUAL_ENV), else .venv here, made on first use. Debian 12 and Ubuntu 23.04+ refuse
# `pip install` into the system Python (PEP 668); their Python makes a venv only with the
# python3-venv package installed.
BASE_PYTHON ?= python3
ifdef VIRTUAL_ENV
VENV := $(VIRTUAL_ENV)
else
VENV := .venv
endif
PYTHON := $(VENV)/bin/python
PIP := $(PYTHON) -m pip install --quiet --editable
# pytest's workers (pytest-xdist): twice the cores, as most of a test's time is spent
# waiting on a line. The tests that keep a line's time (marked timing: tests/conftest.py,
# TIMING_FILES) run after the others, by themselves, three workers for two cores
# (TIMING_WORKERS): they wait on a simulated line most of the time (a third of the cores
# busy), the quick benchmark, which keeps a core busy, starts first, and more workers than
# that delay a simulated slave's bytes past the bounds those tests hold a call to. The
# EPICS tests (marked epics) run last, by themselves: each starts an IOC process, which
# loads the machine, and holds it to time bounds of its own.
CORES := $(shell nproc 2>/dev/null || echo 1)
TEST_WORKERS ?= $(shell echo $$(( $(CORES) * 2 )))
TIMING_WORKERS ?= $(shell echo $$(( $(CORES) * 3 / 2 )))
# Bytecode is written even where the environment says not to (PYTHONDONTWRITEBYTECODE):
# each simulator and command a test starts runs in a process of its own, and each would
# compile the package again, as each pytest run would rewrite the tests' asserts (some
# 15 s of a run). It goes to __pycache__ folders, which git ignores.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: install demo test lint fmt example bench cross wheel wheel-smoke docs docs-serve

$(VENV)/bin/python:
	@$(BASE_PYTHON) -m venv $(VENV) >/dev/null 2>&1 || { rm -rf $(VENV); \
	  echo "error: '$(BASE_PYTHON) -m venv' failed: cannot make the virtual environment $(VENV)." >&2; \
	  echo "  On Debian or Ubuntu install the python3-venv package (apt install python3-venv)," >&2; \
	  echo "  or activate a virtual environment of your own, then run make again." >&2; exit 1; }
	@$(PYTHON) -m pip install --quiet --upgrade pip

install: $(VENV)/bin/python
	$(PIP) ".[dev]"

demo: $(VENV)/bin/python
	$(PIP) ".[demo]"
	$(PYTHON) -m benchbus demo

# The site's tests render pages in Debian's chromium (headless): installed when missing.
test: install
	.ci/need.sh 'chromium|chromium-browser=chromium'
	cargo test --quiet
	$(PYTHON) -m pytest -q -n $(TEST_WORKERS) -m "not timing and not epics"
	$(PYTHON) -m pytest -q -n $(TIMING_WORKERS) -m "timing and not epics"
	$(PYTHON) -m pytest -q -n $(TEST_WORKERS) -m epics

lint: install
	cargo fmt --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --all-targets --features python -- -D warnings
	RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --quiet --features python
	$(PYTHON) -m ruff check python tests examples bench docs_hooks
	$(PYTHON) -m ruff format --check python tests examples bench docs_hooks
	$(PYTHON) -m mypy python/benchbus
	$(PYTHON) -m mypy docs_hooks
	$(PYTHON) -m benchbus._aio_stubgen --check
	$(PYTHON) -m mypy.stubtest benchbus._core
	$(PYTHON) -m check_jsonschema --builtin-schema vendor.github-workflows .github/workflows/*.yml

# The documentation site (MkDocs, its sources in docs/), strict: a warning, a broken link or
# anchor fails it. NO_MKDOCS_2_WARNING silences the theme's notice about MkDocs 2.
DOCS := NO_MKDOCS_2_WARNING=1 $(PYTHON) -m mkdocs
docs: $(VENV)/bin/python
	$(PIP) ".[docs]"
	$(DOCS) build --strict

# A live preview on http://127.0.0.1:8000, rebuilt as docs/ and the docstrings change.
docs-serve: $(VENV)/bin/python
	$(PIP) ".[docs]"
	$(DOCS) serve --dev-addr 127.0.0.1:8000 --watch python/benchbus --watch docs_hooks

# An abi3 wheel for Linux (cp39-abi3, manylinux2014: glibc 2.17 and later) in dist/, built
# against an old glibc with zig (PyPI's ziglang), no Docker; maturin audits the tag. maturin
# runs `python -m ziglang`, so this environment's python comes first on PATH.
wheel: $(VENV)/bin/python
	$(PYTHON) -m pip install --quiet "maturin>=1.7,<2" ziglang
	rm -f dist/benchbus-*.whl
	PATH="$(abspath $(VENV))/bin:$$PATH" $(PYTHON) -m maturin build --release --quiet \
	  --zig --compatibility manylinux2014 --out dist

# That wheel installed into a fresh environment outside the checkout, and its smoke suite
# (tests/wheel_smoke) run there.
wheel-smoke: wheel
	.ci/wheel-smoke.sh

# The checks for other operating systems that can run on Linux (see docs/guides/platforms.md).
# macOS: clippy for both Apple targets; Windows: clippy, the Rust suite and COM ports under
# wine, and the Windows wheel (the scripts install their own targets and tools).
cross: install
	.ci/cross-macos.sh
	PYTHON=$(PYTHON) .ci/cross-windows.sh

fmt: $(VENV)/bin/python
	cargo fmt
	$(PYTHON) -m ruff format python tests examples bench docs_hooks

example: $(VENV)/bin/python
	$(PIP) ".[sim]"
	$(PYTHON) examples/first_steps.py
	$(PYTHON) examples/drive_bench.py

bench: $(VENV)/bin/python
	$(PIP) ".[bench]"
	$(PYTHON) bench/run.py
