"""``benchbus read``: read registers, coils or discrete inputs."""

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


#: Each table: the Bus method that reads it, the most a request takes, and whether it holds
#: bits.
TABLES = {
    "holding": ("read_holding_registers", 125, False),
    "input": ("read_input_registers", 125, False),
    "coils": ("read_coils", 2000, True),
    "discrete": ("read_discrete_inputs", 2000, True),
}


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus read`` as ``args`` say; the exit status."""
    method, most, bits = TABLES[args.table]
    if bits and (args.hex or args.signed or args.decimals or args.type or args.order):
        raise UsageError(
            f"--table {args.table} reads bits: leave out --hex, --signed, --decimals, --type "
            "and --order"
        )
    if args.hex and (args.signed or args.decimals):
        raise UsageError("--hex prints the raw words: leave out --signed and --decimals")
    if args.order and not args.type:
        raise UsageError("--order says how a --type value lies: give --type with it")
    if args.type and (args.hex or args.signed or args.decimals):
        raise UsageError("--type prints typed values: leave out --hex, --signed and --decimals")
    width = VALUE_TYPES[args.type] if args.type else 1
    total = args.count * width
    what = "coils" if args.table == "coils" else "inputs" if bits else "registers"
    if args.address + total > 0x10000:
        raise UsageError(f"{total} {what} from {args.address:#06x} run past 0xFFFF")
    unit = unit_of(args, "read")
    read: list[int] = []
    with open_bus(args, "read") as bus:
        for start in range(args.address, args.address + total, most):
            count = min(most, args.address + total - start)
            read += getattr(bus, method)(unit, start, count)
    if bits or not args.type:
        for offset, item in enumerate(read):
            address = args.address + offset
            print(f"0x{address:04X}  {address}  {_text(int(item), args)}")
        return 0
    values = bb.from_registers(read, args.type, args.order or "ABCD")
    for index, typed in enumerate(values):
        address = args.address + index * width
        print(f"0x{address:04X}  {address}  {typed}")
    return 0


def _text(word: int, args: argparse.Namespace) -> str:
    """A register (or a bit, 0 or 1) as ``--hex``, ``--signed`` and ``--decimals`` say."""
    if args.hex:
        return f"0x{word:04X}"
    value = _signed(word) if args.signed else word
    return str(Decimal(value).scaleb(-args.decimals)) if args.decimals else str(value)


#: What ``benchbus read`` does, as ``--help`` says.
HELP = "read registers (0x03, 0x04), coils (0x01) or discrete inputs (0x02)"
#: The rest of its ``--help``.
EPILOG = (
    "Prints one line per register, bit (1 or 0) or --type value: the address in hex, in "
    "decimal, and the value. --table says which table: holding registers (0x03, the "
    "default), input registers (0x04), coils (0x01) or discrete inputs (0x02)."
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
        help="registers, bits or --type values to read (default 1; more than 125 registers "
        "or 2000 bits go in several requests)",
    )
    parser.add_argument(
        "--table",
        choices=tuple(TABLES),
        default="holding",
        help="the table to read: holding (default), input, coils or discrete",
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
