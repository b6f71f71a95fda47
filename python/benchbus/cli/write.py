"""``benchbus write``: write holding registers or coils, or a profile's register by name."""

from __future__ import annotations

import argparse
from decimal import Decimal, InvalidOperation

import benchbus as bb
from benchbus._profile import known
from benchbus.cli._args import (
    BOOLS,
    VALUE_TYPES,
    Parser,
    add_profile_option,
    add_value_options,
    argument,
    integer,
    parse_int,
    profile_value,
)
from benchbus.cli._errors import UsageError
from benchbus.cli._line import (
    open_bus,
    profile_of,
    profiled,
    refused_as_usage,
    unit_of,
)
from benchbus.cli._output import shown

__all__ = ["HELP", "add_arguments", "run"]


def _word(text: str, decimals: int) -> int:
    """A register word from a value as written on the command line.

    Without ``decimals``: an integer -32768..65535 (decimal or hex; negative values are
    written in two's complement). With ``decimals`` N: a decimal number with at most N
    decimals, written as value x 10**N.
    """
    if decimals == 0:
        try:
            value = parse_int(text)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    else:
        try:
            scaled = Decimal(text.strip()).scaleb(decimals)
        except InvalidOperation:
            raise UsageError(f"{text!r} is not a number") from None
        if not scaled.is_finite() or scaled != scaled.to_integral_value():
            raise UsageError(f"{text!r} has more than {decimals} decimals")
        value = int(scaled)
    if not -0x8000 <= value <= 0xFFFF:
        raise UsageError(f"{text!r} does not fit in a register (-32768 to 65535 raw)")
    return value & 0xFFFF


def _typed_words(texts: list[str], kind: str, order: str) -> list[int]:
    """The registers of values of ``kind`` as written on the command line, laid out as
    ``order``."""
    values: list[float] = []
    for text in texts:
        try:
            values.append(float(text) if kind.startswith("f") else parse_int(text))
        except ValueError as exc:
            what = "a number" if kind.startswith("f") else "a whole number (decimal or hex)"
            raise UsageError(f"{text!r} is not {what}") from exc
    try:
        return bb.to_registers(values, kind, order)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise UsageError(str(exc)) from None


def _write_coils(args: argparse.Namespace) -> int:
    """``benchbus write --table coils``: 0x05 for one value, 0x0F for several."""
    if args.type or args.order or args.decimals or args.multiple or args.accept_count_echo:
        raise UsageError(
            "--table coils writes bits: leave out --type, --order, --decimals, --multiple "
            "and --accept-count-echo"
        )
    values = []
    for text in args.values:
        if text.strip().lower() not in BOOLS:
            raise UsageError(f"{text!r} is not a coil value (1/0, on/off, true/false)")
        values.append(BOOLS[text.strip().lower()])
    if args.address + len(values) > 0x10000:
        raise UsageError(f"{len(values)} coils from {args.address:#06x} run past 0xFFFF")
    unit = unit_of(args, "write", broadcast=True)
    with open_bus(args, "write") as bus:
        if unit == 0:
            if len(values) == 1:
                bus.broadcast_write_coil(args.address, values[0])
            else:
                bus.broadcast_write_coils(args.address, values)
            how = "broadcast"
        elif len(values) == 1:
            bus.write_coil(unit, args.address, values[0])
            how = "0x05"
        else:
            for i in range(0, len(values), 1968):
                bus.write_coils(unit, args.address + i, values[i : i + 1968])
            how = "0x0F"
    shown = " ".join("1" if v else "0" for v in values)
    print(f"unit {unit}: wrote coils {shown} at 0x{args.address:04X} ({how})")
    return 0


def _write_profile(args: argparse.Namespace, profile: bb.Profile) -> int:
    """``benchbus write --profile FILE NAME VALUE``: the register NAME, in engineering
    units, every check made before anything is sent."""
    if any((args.table != "holding", args.type, args.order, args.decimals, args.multiple)) or (
        args.accept_count_echo
    ):
        raise UsageError(
            "--profile writes a register by name, in engineering units: leave out --table, "
            "--type, --order, --decimals, --multiple and --accept-count-echo"
        )
    if len(args.values) != 1:
        raise UsageError("--profile writes one register: give NAME VALUE")
    with refused_as_usage():
        name = known(profile, args.address)
    register = profile[name]
    value = profile_value(register, args.values[0])
    with profiled(args, profile) as device:
        device.write(name, value)
    members = device.enums.get(name)
    written = members(value) if members is not None and isinstance(value, int) else value
    print(f"unit {device.unit}: wrote {name} {shown(written, register.unit)}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus write`` as ``args`` say; the exit status."""
    profile = profile_of(args)
    if profile is not None:
        return _write_profile(args, profile)
    args.address = argument(args.address, integer(0, 0xFFFF, "ADDRESS"), "ADDRESS")
    if args.table == "coils":
        return _write_coils(args)
    if args.order and not args.type:
        raise UsageError("--order says how a --type value lies: give --type with it")
    if args.type and args.decimals:
        raise UsageError("--type writes typed values: leave out --decimals")
    if args.type:
        words = _typed_words(args.values, args.type, args.order or "ABCD")
    else:
        words = [_word(v, args.decimals) for v in args.values]
    if args.address + len(words) > 0x10000:
        raise UsageError(f"{len(words)} registers from {args.address:#06x} run past 0xFFFF")
    unit = unit_of(args, "write", broadcast=True)
    if unit == 0 and len(words) > 1:
        raise UsageError("a broadcast (unit 0) writes one register")
    with open_bus(args, "write") as bus:
        if unit == 0:
            bus.broadcast_write_register(args.address, words[0])
            how = "broadcast"
        elif len(words) == 1 and not args.multiple and VALUE_TYPES.get(args.type, 1) == 1:
            bus.write_register(
                unit, args.address, words[0], accept_count_echo=args.accept_count_echo
            )
            how = "0x06"
        else:
            for i in range(0, len(words), 123):
                bus.write_registers(unit, args.address + i, words[i : i + 123])
            how = "0x10"
    shown = " ".join(str(w) for w in words)
    print(f"unit {unit}: wrote {shown} at 0x{args.address:04X} ({how})")
    return 0


#: What ``benchbus write`` does, as ``--help`` says.
HELP = (
    "write holding registers (0x06 for one value, 0x10 for several) or coils (0x05, 0x0F), "
    "or a device profile's register by name"
)
#: The rest of its ``--help``.
EPILOG = (
    "Values are -32768 to 65535 (negative ones in two's complement), decimal or hex; "
    "with --decimals N, decimal numbers written as value x 10**N; with --type, values of "
    "that type over as many registers as it takes (0x10). --table coils writes coils: "
    "1/0, on/off or true/false (0x05 for one, 0x0F for several). --unit 0 broadcasts and "
    "waits for no reply. With --profile FILE, NAME VALUE writes that register of the "
    "device profile in engineering units: a bool as true/false, on/off or 1/0; an enum by "
    "its member's name or number; a string as given; any other register a number (decimal "
    "or 0x hex). A value out of range, off the scale's steps or not a member, or a "
    "read-only register, is refused before anything is sent (exit status 2)."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus write`` (``parents``: its option groups, for its actions)."""
    parser.add_argument(
        "address",
        metavar="ADDRESS|NAME",
        help="the first register or coil; with --profile, the register's name",
    )
    parser.add_argument("values", nargs="+", metavar="VALUE")
    add_profile_option(parser, "write a register by name")
    parser.add_argument("--multiple", action="store_true", help="use 0x10 even for a single value")
    parser.add_argument(
        "--table",
        choices=("holding", "coils"),
        default="holding",
        help="the table to write: holding registers (default) or coils",
    )
    parser.add_argument(
        "--accept-count-echo",
        action="store_true",
        help="accept a 0x06 reply that carries a count of 1 instead of the value (PBL)",
    )
    add_value_options(parser, "write", "multiply")
