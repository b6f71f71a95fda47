"""``benchbus profile``: work with device profiles (TOML files describing a device)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from benchbus.cli._args import Parser, add_command
from benchbus.cli._errors import UsageError
from benchbus.cli._output import print_table

if TYPE_CHECKING:
    from benchbus import Profile, ProfileRegister

__all__ = ["HELP", "add_arguments", "run"]


def _range(row: ProfileRegister) -> str:
    """A register's writable range, as the profile gives it ("" for none)."""
    if row.enum:
        return "|".join(f"{k}={v}" for k, v in sorted(row.enum.items()))
    low, high = row.min, row.max
    if low is None and high is None:
        return ""
    return f"{'' if low is None else f'{low:g}'}..{'' if high is None else f'{high:g}'}"


def _scale(row: ProfileRegister) -> str:
    """The register's scale (and offset), or the register its decimal places come from."""
    if row.decimals is not None:
        return f"10^-{row.decimals}"
    return f"{row.scale:g}" + (f" {row.offset:+g}" if row.offset else "")


def _kind(row: ProfileRegister) -> str:
    """The register's type, with its bit, bits, length or order where it has one."""
    if row.bit is not None:
        return f"bool bit {row.bit}"
    if row.bits is not None:
        return f"u16 bits {row.bits[0]}..{row.bits[1]}"
    if row.length is not None:
        return f"string x{row.length}"
    if row.type in ("u16", "i16", "bool"):
        return str(row.type)
    return f"{row.type} {row.order}"


def check(path: str, profile: Profile | None = None) -> int:
    """``benchbus profile check``: load ``path`` (a file or a profile's name) and print its
    table (a profile's mistake is a usage error: the file, its line and the key);
    ``profile``: the profile itself, already read."""
    from benchbus._profile import profile_line
    from benchbus.cli._line import read_profile

    if profile is None:
        profile = read_profile(path)
    line = profile_line(profile)  # as the device opens its own port
    limits = profile.limits
    print(f"{profile.name}: {profile.description}".rstrip(": "))
    made = " ".join(part for part in (profile.maker, profile.model) if part)
    for label, text in (("device", made), ("kind", profile.kind), ("source", profile.source)):
        if text:
            print(f"{label}: {text}")
    print(
        f"line {line.baudrate} {line.bytesize}{line.parity}{line.stopbits}"
        f" {line.framing}, timeout {line.timeout:g} s; at most"
        f" {limits.max_read or 'the protocol limit'} read,"
        f" {limits.max_write or 'the protocol limit'} written a request"
    )
    rows = [
        [
            row.name,
            row.table,
            f"0x{row.address:04X}",
            _kind(row),
            _scale(row),
            row.unit,
            row.access,
            _range(row),
        ]
        for row in profile.registers
    ]
    print_table(["name", "table", "address", "type", "scale", "unit", "access", "range"], rows)
    return 0


#: How much of a profile's source ``list`` shows (``show`` gives all of it).
SOURCE_SHOWN = 60


def _short(text: str) -> str:
    """``text`` cut to :data:`SOURCE_SHOWN` characters, ``...`` saying so."""
    return text if len(text) <= SOURCE_SHOWN else text[: SOURCE_SHOWN - 3].rstrip() + "..."


def listing() -> int:
    """``benchbus profile list``: every profile found by name, sorted by name (where a
    lab's ``BENCHBUS_PROFILES`` and the shipped ones both have a name, the lab's), then
    the built-in families, with maker, model, kind, source and where each comes from; a
    file that does not read is listed and its mistake said, exit status 1."""
    from benchbus import Profile, ProfileError
    from benchbus._library import SHIPPED, families, profiles

    rows: list[list[str]] = []
    broken: list[str] = []
    for name, path in profiles().items():
        where = "shipped" if Path(path).parent == SHIPPED else str(Path(path).parent)
        try:
            p = Profile(path)
        except (ProfileError, OSError) as exc:
            broken.append(str(exc))
            rows.append([name, "", "", "", "(does not read: see below)", where])
            continue
        rows.append([name, p.maker, p.model, p.kind, _short(p.source), where])
    for key, cls in families().items():
        family = Profile.family(key)
        rows.append([key, family.maker, family.model, family.kind, _short(family.source), cls])
    print_table(["name", "maker", "model", "kind", "source", "from"], rows)
    for error in broken:
        print(error, file=sys.stderr)
    return 1 if broken else 0


def show(name: str) -> int:
    """``benchbus profile show``: the profile ``name`` (a file, a profile's name, else a
    built-in family's key) and its table, as ``check`` prints it."""
    from benchbus import Profile, ProfileError
    from benchbus._library import families, locate

    if name in families():
        try:
            locate(name)  # a file or a lab's profile of that name wins, as for Profile()
        except ProfileError:
            return check(name, Profile.family(name))
    return check(name)


def export(key: str, output: str | None) -> int:
    """``benchbus profile export``: the built-in family ``key`` as a profile, on stdout or
    into the file ``output``."""
    from benchbus import Profile

    try:
        text = Profile.family(key).to_toml()
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if output is None:
        print(text, end="")
    else:
        try:
            with open(output, "w", encoding="utf-8") as f:
                f.write(text)
        except OSError as exc:
            raise UsageError(f"cannot write {output}: {exc.strerror}") from None
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus profile`` as ``args`` say; the exit status."""
    if args.action == "export":
        return export(args.family, args.output)
    if args.action == "list":
        return listing()
    if args.action == "show":
        return show(args.name)
    return check(args.path)


#: What ``benchbus profile`` does, as ``--help`` says.
HELP = (
    "check a device profile (a TOML file) and print its register table, list and show the"
    " profiles found by name, or export a family's"
)
#: The rest of its ``--help``.
EPILOG = (
    "A profile is a TOML file or a name: the folders of BENCHBUS_PROFILES (os.pathsep "
    "apart) are searched first, then the profiles benchbus ships. "
    "A profile's mistakes (unknown keys, overlapping addresses, a type that does not fit "
    "its table...) are reported with the file, the line and the key, exit status 2; "
    "'list' lists a file that does not read and exits with status 1. "
    "'export' writes a built-in family's register table as a profile, made from the same "
    "table the family's class uses; the rules its class keeps in code are listed at the top."
)


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus profile`` (``parents``: its option groups)."""
    from benchbus import Profile

    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    checking = add_command(actions, "check", "validate a profile and print its table", parents)
    checking.add_argument("path", metavar="FILE", help="the profile (TOML), or its name")
    add_command(
        actions,
        "list",
        "list the profiles found by name (BENCHBUS_PROFILES', the shipped ones) and the"
        " built-in families",
        parents,
    )
    showing = add_command(actions, "show", "print a profile's table, by name", parents)
    showing.add_argument(
        "name",
        metavar="NAME",
        help="a profile's name (see 'list'), a file, or a built-in family's table"
        f" ({', '.join(Profile.families())})",
    )
    exporting = add_command(
        actions, "export", "write a built-in family's register table as a profile", parents
    )
    exporting.add_argument(
        "family", metavar="FAMILY", help="drive (BLD2 / BLD3H), drive-c20, pbl or j2"
    )
    exporting.add_argument(
        "-o", "--output", metavar="FILE", help="write it to FILE instead of stdout"
    )
