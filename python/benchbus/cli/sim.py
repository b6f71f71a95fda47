"""``benchbus sim``: serve a simulated device on a pseudo-terminal."""

from __future__ import annotations

import argparse
import os
from typing import TYPE_CHECKING

from benchbus._families import FAMILIES, family
from benchbus.cli._args import (
    Parser,
    framing,
    integer,
    positive,
    profile_value,
    seconds,
    units_type,
)
from benchbus.cli._errors import CliError, UsageError
from benchbus.cli._serve import serve_until_stopped

if TYPE_CHECKING:
    from benchbus import Profile
    from benchbus.sim import SimDevice

__all__ = ["HELP", "SIM_DEVICES", "add_arguments", "run"]


#: Each simulated device, with the baud rate its family usually runs at.
SIM_DEVICES: dict[str, int] = {f.key: f.line.baudrate for f in FAMILIES}


def _sim_device(kind: str, args: argparse.Namespace) -> SimDevice:
    of = family(kind)
    given = {option: getattr(args, option, None) for option in of.sim_options}
    return of.simulate(**{option: v for option, v in given.items() if v is not None})


def _profile_devices(
    path: str, units: list[int], assignments: list[str]
) -> tuple[dict[int, SimDevice], Profile]:
    """A :class:`~benchbus.sim.ProfileDevice` of the profile at ``path`` for each unit, with
    the ``--value`` assignments; and the profile as the core reads it. A mistake in the
    profile or the assignments is a usage error: nothing is served."""
    from benchbus.cli._line import read_profile
    from benchbus.sim import ProfileDevice

    profile = read_profile(path)
    rows = {row.name: row for row in profile.registers}
    values: dict[str, bool | int | float | str] = {}
    for assignment in assignments:
        name, equals, text = assignment.partition("=")
        name = name.strip()
        if not equals:
            raise UsageError(f"--value takes NAME=VALUE, not {assignment!r}")
        if name not in rows:
            raise UsageError(
                f"--value: {profile.name} has no register {name!r} (it has {', '.join(rows)})"
            )
        try:
            values[name] = profile_value(rows[name], text)
        except UsageError as exc:
            raise UsageError(f"--value {exc}") from None
    try:
        return {u: ProfileDevice(profile.path, values) for u in units}, profile
    except (ValueError, TypeError) as exc:  # a value out of range, of the wrong kind
        raise UsageError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus sim`` as ``args`` say; the exit status."""
    kind: str | None = args.device
    if (kind is None) == (args.profile is None):
        raise UsageError(
            "give a device (drive|pbl|j2|instrument|atv31) or --profile FILE, not both"
            if kind
            else "give a device (drive|pbl|j2|instrument|atv31) or --profile FILE"
        )
    if args.value and args.profile is None:
        raise UsageError("--value sets a register of a --profile device")
    if args.profile is not None and (args.model is not None or args.speedup is not None):
        raise UsageError("--model and --speedup are for the built-in devices, not --profile")
    try:
        from benchbus.sim import Simulator
    except ModuleNotFoundError as exc:  # the message says what to install
        raise CliError(str(exc)) from None
    units: list[int] = args.unit
    devices: dict[int, SimDevice]
    if args.profile is not None:
        devices, profile = _profile_devices(args.profile, units, args.value)
        from benchbus._profile import profile_line

        line = profile_line(profile)  # a Device's own line: the profile's, else 9600 8N1
        baudrate: int = args.baudrate or line.baudrate
        served_framing: str = args.framing or line.framing
        what = f"{profile.name} from {os.path.basename(profile.path)}"
    else:
        assert kind is not None
        devices = {u: _sim_device(kind, args) for u in units}
        baudrate = args.baudrate or SIM_DEVICES[kind]
        served_framing = args.framing or "rtu"
        what = f"{args.model or 'BLD2'} drive" if kind == "drive" else kind
    simulator = Simulator(devices, baudrate=baudrate, framing=served_framing)
    simulator.start()
    try:
        at = ", ".join(str(u) for u in units)
        serve_until_stopped(
            simulator.port,
            f"simulating {what} (unit {at}, {baudrate} baud frame timing"
            f"{', Modbus ASCII' if served_framing == 'ascii' else ''})",
            args.seconds,
        )
    finally:
        simulator.stop()
    return 0


#: What ``benchbus sim`` does, as ``--help`` says.
HELP = "serve a simulated device on a pseudo-terminal until Ctrl-C"
#: The rest of its ``--help``.
EPILOG = (
    "The first line of stdout is the pseudo-terminal's path: open it as the port "
    "(any line format works on it). Stops on Ctrl-C, SIGTERM or after --seconds, with "
    "exit status 0. With --profile FILE instead of a device, it serves a device profile "
    "(a TOML file of registers): each register at its default, or as --value NAME=VALUE "
    "sets it; the frame timing and framing are the profile's [line] unless given (its "
    "parity is the master's to open: a pseudo-terminal carries none). A mistake in the "
    "profile is reported with the file, the line and the key, exit status 2."
)


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus sim`` (``parents``: its option groups, for its actions)."""
    parser.add_argument(
        "device",
        nargs="?",
        choices=tuple(SIM_DEVICES),
        metavar="|".join(SIM_DEVICES),
        help="drive: BLD2/BLD3H/C20; pbl: PBL drive; j2: J2 controller with a thermal "
        "process; instrument: Taisong meter; atv31: the Taisong manual's ATV31 drive "
        "(or --profile instead)",
    )
    parser.add_argument(
        "--profile",
        metavar="FILE",
        help="serve the device a profile (a TOML file, or a profile's name: 'benchbus profile"
        " list') describes, instead of a built-in one",
    )
    parser.add_argument(
        "--value",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="with --profile: a register's initial value (a number, true/false, an enum "
        "member or a string); repeatable",
    )
    parser.add_argument(
        "--unit",
        type=units_type(1, 255),
        default=[1],
        metavar="N",
        help="unit address, or several (1-3,5): one device each (default 1)",
    )
    parser.add_argument(
        "--baudrate",
        type=integer(50, 4_000_000, "baudrate"),
        metavar="BPS",
        help="the frame timing (default: the device's usual speed, or the profile's)",
    )
    parser.add_argument("--seconds", type=seconds, metavar="S", help="stop after S seconds")
    parser.add_argument(
        "--framing",
        type=framing,
        metavar="rtu|ascii",
        help="serve Modbus RTU (default) or Modbus ASCII (default for a profile: its own)",
    )
    parser.add_argument(
        "--model",
        type=str.upper,
        choices=("BLD2", "BLD3H", "C20"),
        help="the drive model (drive only; default BLD2)",
    )
    parser.add_argument(
        "--speedup",
        type=positive("speedup"),
        metavar="X",
        help="run the process X times faster than real time (j2, instrument)",
    )
