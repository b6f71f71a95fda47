"""``benchbus drive``: a BLD2 / BLD3H / ZBLD.C20 drive's status and common actions."""

from __future__ import annotations

import argparse

import benchbus as bb
from benchbus._core import DriveCore
from benchbus.cli._args import Parser, add_command, integer
from benchbus.cli._line import commanded, refused_as_usage
from benchbus.cli._output import enum_name, measured, print_table

__all__ = ["HELP", "add_arguments", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus drive`` as ``args`` say; the exit status."""
    with commanded(args, "drive", bb.Drive) as drive:
        unit = drive.unit
        if args.action == "status":
            status = drive.status()
            t = drive.telemetry()
            u = drive.units()
            rows = [
                ("model", enum_name(drive.model)),
                ("state", enum_name(status.state)),
                ("fault", str(status.fault) if status.fault else "none"),
                ("speed", measured(t.speed, u["speed"])),
                ("speed setpoint", measured(drive.speed_setpoint, u["speed_setpoint"])),
                ("output frequency", measured(t.output_frequency, u["output_frequency"])),
                ("output current", measured(t.output_current, u["output_current"])),
                ("bus voltage", measured(t.bus_voltage, u["bus_voltage"])),
                ("temperature", measured(t.temperature, u["temperature"])),
                ("command source", enum_name(status.control_source)),
            ]
            print_table(None, rows)
        elif args.action in ("start", "reverse"):
            if args.speed is not None:
                with refused_as_usage():
                    drive.speed_setpoint = args.speed
            (drive.forward if args.action == "start" else drive.reverse)()
            way = "forward" if args.action == "start" else "reverse"
            print(f"unit {unit}: running {way} at {drive.speed_setpoint} rpm")
        elif args.action == "stop":
            drive.stop()
            print(f"unit {unit}: stopping")
        elif args.action == "set-speed":
            with refused_as_usage():
                drive.speed_setpoint = args.rpm
            print(f"unit {unit}: speed setpoint {args.rpm} rpm")
        else:
            drive.reset_fault()
            print(f"unit {unit}: fault reset")
    return 0


#: What ``benchbus drive`` does, as ``--help`` says.
HELP = "a BLD2 / BLD3H / ZBLD.C20 drive (19200 8N1): status and common actions"
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}
#: Whether it takes ``--family``.
FAMILY_OPTION = True


#: The speed setpoint's register (0x2001), from the drive's table: its range bounds the
#: command line's speeds (the same on both families).
_SPEED = next(row for row in DriveCore._table("BLD") if row.name == "speed_setpoint")


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus drive`` (``parents``: its option groups, for its actions)."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    low, high = int(_SPEED.low), int(_SPEED.high)

    add_command(actions, "status", "state, fault, speeds and measurements", parents)
    for name, what in (("start", "run forward"), ("reverse", "run in reverse")):
        p = add_command(actions, name, f"{what} at the speed setpoint", parents)
        p.add_argument(
            "--speed", type=integer(low, high, "rpm"), metavar="RPM", help="set the setpoint first"
        )
    add_command(actions, "stop", "stop (decelerate, or as the stop mode says)", parents)
    p = add_command(actions, "set-speed", "set the speed setpoint (0x2001)", parents)
    p.add_argument("rpm", type=integer(low, high, "RPM"), metavar="RPM")
    add_command(actions, "reset-fault", "reset a fault (command 7)", parents)
