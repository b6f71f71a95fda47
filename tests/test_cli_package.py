"""The command line as a package: each command a module, its parser beside its handler."""

from __future__ import annotations

import argparse
import subprocess
import sys

from benchbus import cli


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_each_command_is_a_module_that_parses_and_runs_it() -> None:
    commands = _subcommands(cli.build_parser())
    names = [m.__name__.rsplit(".", 1)[1] for m in cli.COMMANDS]
    assert (
        list(commands)
        == names
        == [
            "scan",
            "read",
            "write",
            "drive",
            "pbl",
            "j2",
            "monitor",
            "sim",
            "gateway",
            "ports",
            "doctor",
            "demo",
        ]
    )
    for module in cli.COMMANDS:
        name = module.__name__.rsplit(".", 1)[1]
        assert commands[name].get_default("handler") is module.run, name
        assert commands[name].description == module.HELP, name
        assert commands[name].epilog == getattr(module, "EPILOG", None), name


def test_the_entry_points_are_the_package_main() -> None:
    import benchbus.__main__ as entry

    assert entry.main is cli.main
    done = subprocess.run(
        [sys.executable, "-m", "benchbus", "--version"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert done.returncode == 0 and done.stdout.startswith("benchbus ")
