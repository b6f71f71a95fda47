# One command each: `make test` installs and runs every test, `make lint` every check.
PYTHON ?= python3

.PHONY: install test lint fmt example

install:
	$(PYTHON) -m pip install --quiet --editable ".[dev]"

test: install
	cargo test --quiet
	$(PYTHON) -m pytest -q

lint: install
	cargo fmt --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --all-targets --features python -- -D warnings
	$(PYTHON) -m ruff check python tests examples
	$(PYTHON) -m ruff format --check python tests examples
	$(PYTHON) -m mypy python/benchbus
	$(PYTHON) -m mypy.stubtest benchbus._core

fmt:
	cargo fmt
	$(PYTHON) -m ruff format python tests examples

example:
	$(PYTHON) -m pip install --quiet ".[sim]"
	$(PYTHON) examples/first_steps.py
	$(PYTHON) examples/drive_bench.py
