"""``benchbus read``: read registers, coils or discrete inputs, or a profile's registers by
name."""

from __future__ import annotations

import argparse
import sys
from decimal import Decimal

import benchbus as bb
from benchbus._profile import known
from benchbus.cli._args import (
    PROG,
    VALUE_TYPES,
    Parser,
    add_profile_option,
    add_value_options,
    argument,
    integer,
)
from benchbus.cli._errors import UsageError
from benchbus.cli._line import (
    open_bus,
    profile_of,
    profiled,
    refused_as_usage,
    unit_of,
)
from benchbus.cli._output import print_table, shown

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


def _read_profile(args: argparse.Namespace, profile: bb.Profile) -> int:
    """``benchbus read --profile FILE [NAME ...]``: the registers named (every readable one
    without names) in engineering units, in the fewest requests the profile allows."""
    raw = (args.hex, args.signed, args.decimals, args.type, args.order)
    if args.table != "holding" or any(raw):
        raise UsageError(
            "--profile reads registers by name, in engineering units: leave out --table, "
            "--hex, --signed, --decimals, --type and --order"
        )
    with refused_as_usage():
        names = [known(profile, n) for n in args.targets]
    names = names or [r.name for r in profile.registers if r.access != "w"]
    with profiled(args, profile) as device:
        values = device.read_many(names)
    units = device.units()
    print_table(None, [[name, shown(value, units[name])] for name, value in values.items()])
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus read`` as ``args`` say; the exit status."""
    profile = profile_of(args)
    if profile is not None:
        return _read_profile(args, profile)
    if not args.targets:
        raise UsageError("the following arguments are required: ADDRESS")
    if len(args.targets) > 2:
        raise UsageError(f"unrecognized arguments: {' '.join(args.targets[2:])}")
    args.address = argument(args.targets[0], integer(0, 0xFFFF, "ADDRESS"), "ADDRESS")
    args.count = 1
    if len(args.targets) == 2:
        args.count = argument(args.targets[1], integer(1, 0x10000, "COUNT"), "COUNT")
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
        one_a_request = False
        for start in range(args.address, args.address + total, most):
            count = min(most, args.address + total - start)
            if not one_a_request:
                try:
                    read += getattr(bus, method)(unit, start, count)
                    continue
                except bb.ModbusException as exc:
                    if exc.code != ILLEGAL_DATA_VALUE or count == 1:
                        raise
                    print(
                        f"{PROG}: read: unit {unit} refused {count} {what} in one request "
                        f"(exception 0x03: illegal data value): some devices, BLD drives "
                        f"among them, read one a request; reading them one at a time",
                        file=sys.stderr,
                    )
                    one_a_request = True
            for address in range(start, start + count):
                read += getattr(bus, method)(unit, address, 1)
    if bits or not args.type:
        for offset, item in enumerate(read):
            print(labelled(args.address + offset, _text(int(item), args)))
        return 0
    values = bb.from_registers(read, args.type, args.order or "ABCD")
    for index, typed in enumerate(values):
        print(labelled(args.address + index * width, str(typed)))
    return 0


#: The exception code a device answers to a request for more registers than it reads at
#: once (BLD drives: more than one).
ILLEGAL_DATA_VALUE = 0x03


def labelled(address: int, value: str) -> str:
    """One line of ``benchbus read``: ``0x2001 (8193) = 1234``, the address in hex and in
    decimal, then the value."""
    return f"0x{address:04X} ({address}) = {value}"


def _text(word: int, args: argparse.Namespace) -> str:
    """A register (or a bit, 0 or 1) as ``--hex``, ``--signed`` and ``--decimals`` say."""
    if args.hex:
        return f"0x{word:04X}"
    value = _signed(word) if args.signed else word
    return str(Decimal(value).scaleb(-args.decimals)) if args.decimals else str(value)


#: What ``benchbus read`` does, as ``--help`` says.
HELP = (
    "read registers (0x03, 0x04), coils (0x01) or discrete inputs (0x02), or a device "
    "profile's registers by name"
)
#: The rest of its ``--help``.
EPILOG = (
    "Prints one line per register, bit (1 or 0) or --type value: the address in hex, in "
    "decimal in parentheses, and the value after '=' (0x2001 (8193) = 1500). A device "
    "that refuses a read of several registers with exception 0x03 (illegal data value), as "
    "BLD drives do, is read one register a request, and a line on stderr says so. --table "
    "says which table: holding registers (0x03, the "
    "default), input registers (0x04), coils (0x01) or discrete inputs (0x02). With "
    "--profile FILE, the registers NAME ... of that device profile (every readable one "
    "without names), one line each: the name and the value in engineering units with its "
    "unit (an enum by its member's name, a bool as true or false), read in the fewest "
    "requests the profile allows."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus read`` (``parents``: its option groups, for its actions)."""
    parser.add_argument(
        "targets",
        nargs="*",
        metavar="ADDRESS [COUNT] | NAME",
        help="the first address and how many registers, bits or --type values to read "
        "(default 1; more than 125 registers or 2000 bits go in several requests); with "
        "--profile, register names",
    )
    add_profile_option(parser, "read its registers by name")
    parser.add_argument(
        "--table",
        choices=tuple(TABLES),
        default="holding",
        help="the table to read: holding (default), input, coils or discrete",
    )
    parser.add_argument("--hex", action="store_true", help="print the values in hex")
    parser.add_argument("--signed", action="store_true", help="values are 16-bit two's complement")
    add_value_options(parser, "read", "divide")
