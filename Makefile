# One command each: `make demo` installs benchbus and runs its demo on simulated devices,
# `make test` installs and runs every test, `make lint` every check, `make bench` the
# benchmark beside minimalmodbus and pymodbus.
PYTHON ?= python3

.PHONY: install demo test lint fmt example bench

install:
	$(PYTHON) -m pip install --quiet --editable ".[dev]"

demo:
	$(PYTHON) -m pip install --quiet ".[demo]"
	$(PYTHON) -m benchbus demo

test: install
	cargo test --quiet
	$(PYTHON) -m pytest -q

lint: install
	cargo fmt --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --all-targets --features python -- -D warnings
	$(PYTHON) -m ruff check python tests examples bench
	$(PYTHON) -m ruff format --check python tests examples bench
	$(PYTHON) -m mypy python/benchbus
	$(PYTHON) -m mypy.stubtest benchbus._core

fmt:
	cargo fmt
	$(PYTHON) -m ruff format python tests examples bench

example:
	$(PYTHON) -m pip install --quiet ".[sim]"
	$(PYTHON) examples/first_steps.py
	$(PYTHON) examples/drive_bench.py

bench:
	$(PYTHON) -m pip install --quiet ".[bench]"
	$(PYTHON) bench/run.py
