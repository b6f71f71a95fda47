"""``benchbus doctor``: what stands between benchbus and a port."""

from __future__ import annotations

import argparse

import benchbus as bb
from benchbus.cli._args import Parser
from benchbus.cli._errors import in_cli_words
from benchbus.cli._line import bus_options_of, opt, port_of, unit_of

_S = argparse.SUPPRESS

__all__ = ["HELP", "add_arguments", "run"]


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus doctor`` as ``args`` say; the exit status."""
    options = bus_options_of(args, "read")
    findings = bb.doctor(
        port_of(args),
        baudrate=options.baudrate,
        parity=options.parity,
        stopbits=opt(args, "stopbits", 1),
        unit=unit_of(args, "read"),
        timeout=options.timeout,
        sysfs_root=args.sysfs_root,
        proc_root=args.proc_root,
    )
    for finding in findings:
        print(in_cli_words(str(finding)))
    return 1 if any(f.verdict == "fail" for f in findings) else 0


#: What ``benchbus doctor`` does, as ``--help`` says.
HELP = "check a serial port: what stands between benchbus and the devices on it"
#: The rest of its ``--help``.
EPILOG = (
    "One line per finding: its verdict (ok, info, warn, fail), what was checked, "
    "what was found and the fix. Checks the platform, the port and who holds it, the "
    "permission to open it, the USB chip and an FTDI's latency timer, the driver's "
    "low-latency mode, the kernel RS485 mode, and whether a request comes back (a local "
    "echo: one read of register 0 goes to --unit). Exits 1 if any finding fails."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True, "rs485": False, "framing": False}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus doctor`` (``parents``: its option groups, for its actions)."""
    parser.add_argument("--sysfs-root", metavar="DIR", help=_S)  # other trees, for tests
    parser.add_argument("--proc-root", metavar="DIR", help=_S)
