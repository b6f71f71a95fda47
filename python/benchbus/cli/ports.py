"""``benchbus ports``: the serial ports and their USB adapters."""

from __future__ import annotations

import argparse

from benchbus.cli._args import Parser
from benchbus.cli._errors import CliError
from benchbus.cli._output import print_table

_S = argparse.SUPPRESS

__all__ = ["HELP", "add_arguments", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus ports`` as ``args`` say; the exit status."""
    from benchbus._core import list_ports

    found = list_ports(args.sysfs_root)
    if not found:
        raise CliError("no serial port found (is the adapter plugged in?)")

    def cell(port: dict[str, str | int | None], key: str) -> str:
        value = port.get(key)
        return "-" if value is None else str(value)

    rows = [
        [
            cell(p, "path"),
            cell(p, "chip"),
            "-" if p["vid"] is None else f"{p['vid']:04x}:{p['pid']:04x}",
            *(cell(p, k) for k in ("manufacturer", "product", "serial_number", "driver")),
        ]
        for p in found
    ]
    print_table(["port", "chip", "usb id", "manufacturer", "product", "serial", "driver"], rows)
    return 0


#: What ``benchbus ports`` does, as ``--help`` says.
HELP = "list the serial ports, with the USB adapter's ids, names and chip"
#: The rest of its ``--help``.
EPILOG = (
    "For a USB adapter: its vendor:product ids, the chip family they belong to "
    "(FTDI, CH340, CP210x, PL2303...), and the manufacturer, product and serial number "
    "it reports. A port without them is the board's own (or the system does not say)."
)


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus ports`` (``parents``: its option groups, for its actions)."""
    parser.add_argument("--sysfs-root", metavar="DIR", help=_S)  # another sysfs tree, for tests
