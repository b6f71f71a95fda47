"""The documentation site's hooks (docs_hooks/), called directly on small parsers and on
packages griffe reads from a temporary directory."""

from __future__ import annotations

import argparse
import importlib.util
import types
from pathlib import Path

import pytest

from benchbus.cli import build_parser

HOOKS = Path(__file__).resolve().parent.parent / "docs_hooks"


def hook(name: str) -> types.ModuleType:
    """The hook module ``docs_hooks/<name>.py``, loaded as MkDocs loads it."""
    spec = importlib.util.spec_from_file_location(name, HOOKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


cli_reference = hook("cli_reference")


# ---- the CLI reference ---------------------------------------------------------------------------


class Colourful(argparse.ArgumentParser):
    """A parser that colours its usage while its ``color`` is true, as Python 3.14's do when
    stdout is a terminal or FORCE_COLOR is set."""

    color = True

    def format_usage(self) -> str:
        usage = super().format_usage()
        return f"\x1b[1;34m{usage}\x1b[0m" if self.color else usage


def test_the_cli_reference_has_no_colour(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FORCE_COLOR", "1")
    monkeypatch.delenv("NO_COLOR", raising=False)
    parser = Colourful(prog="tool", description="A tool.")
    parser.add_argument("--level", type=int, default=3, help="how much")
    commands = parser.add_subparsers(dest="command")
    commands.add_parser("go", description="Go somewhere.").add_argument("where")
    text = cli_reference.reference(parser)
    assert "\x1b" not in text
    assert "usage: tool [-h] [--level LEVEL] {go} ..." in text
    assert "usage: tool go [-h] where" in text
    # benchbus's own parser (argparse's colours where it has them: Python 3.14).
    assert "\x1b" not in cli_reference.reference(build_parser())
