"""``benchbus read``: read holding registers."""

from __future__ import annotations

import argparse
from decimal import Decimal

import benchbus as bb
from benchbus.cli._args import VALUE_TYPES, Parser, add_value_options, integer
from benchbus.cli._errors import UsageError
from benchbus.cli._line import open_bus, unit_of

__all__ = ["HELP", "add_arguments", "run"]


def _signed(word: int) -> int:
    return word - 0x10000 if word & 0x8000 else word


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus read`` as ``args`` say; the exit status."""
    if args.hex and (args.signed or args.decimals):
        raise UsageError("--hex prints the raw words: leave out --signed and --decimals")
    if args.order and not args.type:
        raise UsageError("--order says how a --type value lies: give --type with it")
    if args.type and (args.hex or args.signed or args.decimals):
        raise UsageError("--type prints typed values: leave out --hex, --signed and --decimals")
    width = VALUE_TYPES[args.type] if args.type else 1
    total = args.count * width
    if args.address + total > 0x10000:
        raise UsageError(f"{total} registers from {args.address:#06x} run past 0xFFFF")
    unit = unit_of(args, "read")
    words: list[int] = []
    with open_bus(args, "read") as bus:
        for start in range(args.address, args.address + total, 125):
            count = min(125, args.address + total - start)
            words += bus.read_holding_registers(unit, start, count)
    if args.type:
        values = bb.from_registers(words, args.type, args.order or "ABCD")
        for index, typed in enumerate(values):
            address = args.address + index * width
            print(f"0x{address:04X}  {address}  {typed}")
        return 0
    for offset, word in enumerate(words):
        address = args.address + offset
        if args.hex:
            text = f"0x{word:04X}"
        else:
            value = _signed(word) if args.signed else word
            text = str(Decimal(value).scaleb(-args.decimals)) if args.decimals else str(value)
        print(f"0x{address:04X}  {address}  {text}")
    return 0


#: What ``benchbus read`` does, as ``--help`` says.
HELP = "read holding registers (function 0x03)"
#: The rest of its ``--help``.
EPILOG = (
    "Prints one line per register (per value with --type): the address in hex, in decimal, "
    "and the value."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus read`` (``parents``: its option groups, for its actions)."""
    parser.add_argument("address", type=integer(0, 0xFFFF, "ADDRESS"), metavar="ADDRESS")
    parser.add_argument(
        "count",
        type=integer(1, 0x10000, "COUNT"),
        nargs="?",
        default=1,
        metavar="COUNT",
        help="registers (or --type values) to read (default 1; more than 125 registers go in "
        "several requests)",
    )
    parser.add_argument("--hex", action="store_true", help="print the values in hex")
    parser.add_argument("--signed", action="store_true", help="values are 16-bit two's complement")
    parser.add_argument(
        "--decimals",
        type=integer(0, 9, "decimals"),
        default=0,
        metavar="N",
        help="divide the values by 10**N",
    )
    add_value_options(parser, "read")
