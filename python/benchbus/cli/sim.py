"""``benchbus sim``: serve a simulated device on a pseudo-terminal."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from benchbus._families import FAMILIES, family
from benchbus.cli._args import Parser, framing, integer, positive, seconds, units_type
from benchbus.cli._errors import CliError
from benchbus.cli._serve import serve_until_stopped

if TYPE_CHECKING:
    from benchbus.sim import SimDevice

__all__ = ["HELP", "SIM_DEVICES", "add_arguments", "run"]


#: Each simulated device, with the baud rate its family usually runs at.
SIM_DEVICES: dict[str, int] = {f.key: f.line.baudrate for f in FAMILIES}


def _sim_device(kind: str, args: argparse.Namespace) -> SimDevice:
    of = family(kind)
    return of.simulate(**{option: getattr(args, option) for option in of.sim_options})


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus sim`` as ``args`` say; the exit status."""
    try:
        from benchbus.sim import Simulator
    except ModuleNotFoundError as exc:  # the message says what to install
        raise CliError(str(exc)) from None
    kind: str = args.device
    units: list[int] = args.unit
    baudrate: int = args.baudrate or SIM_DEVICES[kind]
    simulator = Simulator(
        {u: _sim_device(kind, args) for u in units}, baudrate=baudrate, framing=args.framing
    )
    simulator.start()
    try:
        what = f"{args.model} drive" if kind == "drive" else kind
        at = ", ".join(str(u) for u in units)
        serve_until_stopped(
            simulator.port,
            f"simulating {what} (unit {at}, {baudrate} baud frame timing"
            f"{', Modbus ASCII' if args.framing == 'ascii' else ''})",
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
    "exit status 0."
)


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus sim`` (``parents``: its option groups, for its actions)."""
    parser.add_argument(
        "device",
        choices=tuple(SIM_DEVICES),
        metavar="|".join(SIM_DEVICES),
        help="drive: BLD2/BLD3H/C20; pbl: PBL drive; j2: J2 controller with a thermal "
        "process; instrument: Taisong meter; atv31: the Taisong manual's ATV31 drive",
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
        help="the frame timing (default: the device's usual speed)",
    )
    parser.add_argument("--seconds", type=seconds, metavar="S", help="stop after S seconds")
    parser.add_argument(
        "--framing",
        type=framing,
        default="rtu",
        metavar="rtu|ascii",
        help="serve Modbus RTU (default) or Modbus ASCII",
    )
    parser.add_argument(
        "--model",
        type=str.upper,
        choices=("BLD2", "BLD3H", "C20"),
        default="BLD2",
        help="the drive model (drive only)",
    )
    parser.add_argument(
        "--speedup",
        type=positive("speedup"),
        default=1.0,
        metavar="X",
        help="run the process X times faster than real time (j2, instrument)",
    )
