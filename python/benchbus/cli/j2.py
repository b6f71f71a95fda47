"""``benchbus j2``: a J2 controller's status and common actions."""

from __future__ import annotations

import argparse
import enum

import benchbus as bb
from benchbus.cli._args import PROG, Parser, add_command, number
from benchbus.cli._errors import UsageError
from benchbus.cli._line import commanded, refused_as_usage
from benchbus.cli._output import enum_name, fmt, measured, print_table

__all__ = ["HELP", "add_arguments", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus j2`` as ``args`` say; the exit status."""
    with commanded(args, "j2", bb.J2Controller) as j2:
        unit = j2.unit
        if args.action == "status":
            names = ["PV", "SV", "MV", "AM", "LSP", "USP", "AT", "RAPNF", "INP"]
            v = dict(zip(names, j2.read_many(names)))
            u = j2.units()
            rows = [
                ("pv", measured(v["PV"], u["PV"])),
                ("sv", measured(v["SV"], u["SV"])),
                ("mv", measured(v["MV"], u["MV"])),
                ("mode", enum_name(_enum(bb.J2Mode, v["AM"]))),
                ("limits", f"{fmt(v['LSP'])} to {measured(v['USP'], u['USP'])}"),
                ("autotune", "running" if v["AT"] else "off"),
                ("ramp", "running" if v["RAPNF"] else "off"),
                ("input", enum_name(_enum(bb.InputType, v["INP"]))),
            ]
            print_table(None, rows)
        elif args.action == "set-sv":
            with refused_as_usage():
                j2.sv = args.value
            print(f"unit {unit}: SV {fmt(args.value)}")
        elif args.action == "set-limits":
            with refused_as_usage():
                j2.limits = (args.low, args.high)
            u = j2.units()
            print(f"unit {unit}: limits {fmt(args.low)} to {measured(args.high, u['USP'])}")
        elif args.action in ("auto", "manual"):
            j2.mode = bb.J2Mode.AUTO if args.action == "auto" else bb.J2Mode.MANUAL
            print(f"unit {unit}: {args.action} mode")
        else:
            try:
                with refused_as_usage():
                    j2.set_output(args.percent, switch_to_manual=args.manual)
            except bb.StateError:
                raise UsageError(
                    f"unit {unit} is in automatic mode and takes an output in manual mode "
                    f"only: run '{PROG} j2 manual' first, or add --manual"
                ) from None
            print(f"unit {unit}: MV {fmt(args.percent)} %")
    return 0


def _enum(kind: type[enum.IntEnum], value: float) -> enum.IntEnum | int:
    try:
        return kind(int(value))
    except ValueError:
        return int(value)


#: What ``benchbus j2`` does, as ``--help`` says.
HELP = "a J2 PID controller (9600 8N1): status and common actions"
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus j2`` (``parents``: its option groups, for its actions)."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    add_command(actions, "status", "PV, SV, MV, mode, limits", parents)
    p = add_command(actions, "set-sv", "set the setpoint SV (checked against LSP to USP)", parents)
    p.add_argument("value", type=number, metavar="VALUE")
    p = add_command(
        actions, "set-limits", "set the setpoint limits LSP and USP (SV must lie within)", parents
    )
    p.add_argument("low", type=number, metavar="LOW")
    p.add_argument("high", type=number, metavar="HIGH")
    add_command(actions, "auto", "automatic mode: the PID sets the output", parents)
    add_command(actions, "manual", "manual mode: the output stays as set", parents)
    p = add_command(actions, "set-output", "set the output MV, percent (manual mode only)", parents)
    p.add_argument("percent", type=number, metavar="PERCENT")
    p.add_argument(
        "--manual", action="store_true", help="switch to manual mode first if in automatic"
    )
