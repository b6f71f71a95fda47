"""The command line as a package: each command a module, its parser beside its handler."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

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
            "ioc",
            "profile",
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


def test_the_drive_speeds_are_bounded_by_the_register_table(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``benchbus drive`` takes the speeds the speed setpoint's row allows, on both families."""
    from benchbus._core import DriveCore

    rows = [
        next(r for r in DriveCore._table(family) if r.name == "speed_setpoint")
        for family in ("BLD", "C20")
    ]
    assert rows[0] == rows[1] and (rows[0].low, rows[0].high) == (0.0, 3000.0)
    top = int(rows[0].high)
    actions = _subcommands(_subcommands(cli.build_parser())["drive"])
    set_speed, start = actions["set-speed"], actions["start"]
    assert set_speed.parse_args([str(top)]).rpm == top
    assert start.parse_args(["--speed", str(top)]).speed == top
    for parser, args in ((set_speed, [str(top + 1)]), (start, ["--speed", "-1"])):
        with pytest.raises(SystemExit):
            parser.parse_args(args)
        assert f"must be 0 to {top}, got" in capsys.readouterr().err
