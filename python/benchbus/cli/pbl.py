"""``benchbus pbl``: a PBL drive's status and common actions."""

from __future__ import annotations

import argparse

import benchbus as bb
from benchbus.cli._args import Parser, add_command, integer
from benchbus.cli._errors import UsageError
from benchbus.cli._line import commanded, refused_as_usage
from benchbus.cli._output import enum_name, measured, print_table

__all__ = ["HELP", "add_arguments", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus pbl`` as ``args`` say; the exit status."""
    with commanded(args, "pbl", bb.PblDrive) as pbl:
        unit = pbl.unit
        if args.action == "status":
            status = pbl.status()
            sample = pbl.sample()
            alarms = sorted(pbl.alarms)
            u = pbl.units()
            rows = [
                ("running", f"yes, {enum_name(status.direction)}" if status.running else "no"),
                ("direction asked", enum_name(pbl.direction)),
                ("speed", measured(sample["speed"], u["speed"])),
                ("speed setpoint", measured(pbl.speed_setpoint, u["internal_speed"])),
                ("bus voltage", measured(sample["bus_voltage"], u["bus_voltage"])),
                ("current", measured(sample["current"], u["current"])),
                ("power", measured(sample["power"], u["power"])),
                ("alarms", ", ".join(alarms) if alarms else "none"),
                ("start/stop source", enum_name(pbl.start_stop_source)),
            ]
            print_table(None, rows)
        elif args.action in ("start", "reverse"):
            source = pbl.start_stop_source
            if source != bb.StartStopSource.COMMUNICATION:
                if not args.take_control:
                    raise UsageError(
                        f"unit {unit} takes start/stop from {enum_name(source)} (parameter 204), "
                        "so it would ignore a start: add --take-control to switch it to "
                        "COMMUNICATION"
                    )
                pbl.start_stop_source = bb.StartStopSource.COMMUNICATION
            if args.speed is not None:
                with refused_as_usage():
                    pbl.speed_setpoint = args.speed
            reverse = args.action == "reverse"
            pbl.direction = bb.Direction.REVERSE if reverse else bb.Direction.FORWARD
            pbl.start()
            way = "reverse" if reverse else "forward"
            print(f"unit {unit}: running {way} at {pbl.speed_setpoint} rpm")
        elif args.action == "stop":
            pbl.stop()
            print(f"unit {unit}: stopping")
        else:
            with refused_as_usage():
                pbl.speed_setpoint = args.rpm
            print(f"unit {unit}: speed setpoint {args.rpm} rpm")
    return 0


#: What ``benchbus pbl`` does, as ``--help`` says.
HELP = "a PBL-series drive (115200 8E1): status and common actions"
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus pbl`` (``parents``: its option groups, for its actions)."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    add_command(actions, "status", "running, direction, speeds, measurements and alarms", parents)
    for name, what in (("start", "run forward"), ("reverse", "run in reverse")):
        p = add_command(actions, name, f"{what} (control word bits 1 and 0)", parents)
        p.add_argument(
            "--speed", type=integer(0, 65535, "rpm"), metavar="RPM", help="set the setpoint first"
        )
        p.add_argument(
            "--take-control",
            action="store_true",
            help="set the start/stop source (204) to communication first if it is not",
        )
    add_command(actions, "stop", "stop (clear control word bit 0)", parents)
    p = add_command(actions, "set-speed", "set the speed setpoint (parameter 201)", parents)
    p.add_argument("rpm", type=integer(0, 65535, "RPM"), metavar="RPM")
