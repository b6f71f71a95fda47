"""``benchbus ioc``: serve devices as EPICS process variables (Channel Access and PV Access)."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, cast

from benchbus._bench import Bench, open_bench, read_bench
from benchbus._families import command_keys
from benchbus.cli._args import PROG, Parser, add_profile_option, seconds
from benchbus.cli._errors import CliError, UsageError
from benchbus.cli._line import (
    open_bus,
    open_device,
    open_profiled,
    opt,
    profile_of,
    profile_options,
)
from benchbus.exceptions import BenchbusError, ProfileError

if TYPE_CHECKING:
    from benchbus._device import BusDevice
    from benchbus.epics import Ioc, ServedDevice

#: The options a bench file says for itself (its lines' and devices'), refused beside one.
BENCH_SAYS = (
    "port",
    "baudrate",
    "parity",
    "stopbits",
    "framing",
    "bytesize",
    "unit",
    "timeout",
    "retries",
    "rs485",
    "rts_delay",
    "echo",
    "family",
)

__all__ = ["EPILOG", "HELP", "LINE_OPTIONS", "add_arguments", "run"]

#: What ``benchbus ioc`` does, as ``--help`` says.
HELP = "serve devices as EPICS process variables (Channel Access and PV Access)"
#: The rest of its ``--help``.
EPILOG = (
    "Serves one device (a family by name, or --profile FILE) at --port and --unit, or the "
    "devices of a bench file (bench.toml: lines and the devices on them), as EPICS records "
    "named PREFIX + each register's name: an input record for a read-only register, an "
    "output record for a writable one and its readback NAME_RBV; a family's actions (a "
    "drive's forward, stop...) as records that run them; PREFIX ioc:connected and the "
    "line's counters. Every device is read every --period seconds. Serves on loopback "
    "unless --interface (or EPICS_CAS_INTF_ADDR_LIST) says otherwise; --read-only serves "
    "the input records only. Runs until SIGINT or SIGTERM, then stops the motors and "
    "releases the ports. Needs pythonSoftIOC: pip install 'benchbus[epics]'."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}
#: Whether it takes ``--family``.
FAMILY_OPTION = True


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus ioc`` (``parents``: its option groups, for its actions)."""
    kinds = command_keys()
    parser.add_argument(
        "device",
        nargs="?",
        metavar="|".join(kinds) + "|BENCH.toml",
        help="a device family, or a bench file of lines and devices",
    )
    add_profile_option(parser, "serve its registers")
    parser.add_argument(
        "--prefix", metavar="PREFIX", help="the start of every PV name, e.g. LAB:XY:"
    )
    parser.add_argument(
        "--period",
        type=seconds,
        metavar="S",
        help="seconds between two reads of a device (default: the bench file's, else 1)",
    )
    parser.add_argument(
        "--read-only",
        action="store_true",
        help="serve only input records (a writable register's NAME_RBV): no writes",
    )
    parser.add_argument(
        "--interface",
        metavar="ADDR",
        help="the address to serve on (default loopback, or EPICS_CAS_INTF_ADDR_LIST)",
    )
    parser.add_argument(
        "--access-security",
        metavar="FILE",
        help="an EPICS access-security file (who may read and write what)",
    )
    parser.add_argument(
        "--shell",
        action="store_true",
        help="an interactive Python shell with EPICS's commands (dbl()...) while serving",
    )


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus ioc`` as ``args`` say (serves until SIGINT or SIGTERM)."""
    target = opt(args, "device")
    bench = _bench_of(target) if target is not None and target not in command_keys() else None
    profile = profile_of(args)
    if bench is None:
        if (profile is None) == (target is None):
            wanted = f"give a device ({'|'.join(command_keys())}), --profile FILE or a bench file"
            raise UsageError(f"{wanted}, not both" if profile is not None else wanted)
        if not args.prefix:
            raise UsageError("--prefix is required: the start of every PV name, e.g. LAB:XY:")
    elif profile is not None or args.prefix:
        raise UsageError("a bench file names its devices and prefixes: no --profile or --prefix")
    else:
        given = [
            f"--{o.replace('_', '-')}" for o in BENCH_SAYS if opt(args, o) not in (None, False)
        ]
        if given:
            raise UsageError(f"a bench file says its lines and units: no {', '.join(given)}")
    security = args.access_security
    if security is not None and not os.path.isfile(security):
        raise UsageError(f"--access-security: no file {security!r}")
    period = args.period or (bench.period if bench is not None else None) or 1.0
    read_only = args.read_only or (bench is not None and bench.read_only)
    from benchbus.epics import Ioc

    try:
        ioc = Ioc(period, read_only=read_only, interface=args.interface, access_security=security)
    except (ImportError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    if bench is not None:
        try:
            devices = open_bench(bench)
        except ProfileError as exc:  # an option's value the family's class refuses
            raise UsageError(str(exc)) from None
    else:
        line = target if profile is None else profile_options(profile)
        bus = open_bus(args, line, reconnect=True)
        try:
            one = (
                open_device(bus, args, target)
                if profile is None
                else open_profiled(bus, args, profile)
            )
        except BaseException:
            bus.close()
            raise
        devices = [(args.prefix, one, None)]
    try:
        for prefix, device, every in devices:
            ioc.add(prefix, cast("ServedDevice", device), period=every)
        ioc.start()
        _said(devices, ioc)
        ioc.run(shell=args.shell)
    except BaseException as exc:
        if ioc.started:  # Ctrl-C before serving: the motors stopped first, as run() does
            ioc.stop()
        for _, device, _ in devices:
            device.bus.close()
        if isinstance(exc, ValueError) and not isinstance(exc, BenchbusError):
            raise UsageError(str(exc)) from None
        if isinstance(exc, RuntimeError):  # the IOC did not start
            raise CliError(str(exc)) from None
        raise


def _said(devices: list[tuple[str, BusDevice, float | None]], ioc: Ioc) -> None:
    """The line that says what is served, on standard error."""
    units = ", ".join(f"{prefix} (unit {d.unit} on {d.bus.port})" for prefix, d, _ in devices)
    print(
        f"{PROG}: ioc: serving {len(ioc.names)} PVs of {units} (Ctrl-C or SIGTERM to stop)",
        file=sys.stderr,
        flush=True,
    )


def _bench_of(target: str) -> Bench:
    """The bench file ``target`` names, read and checked before any port opens; a mistake
    in it (file, line, key) or an unreadable file is a UsageError."""
    if not target.endswith(".toml") and not os.path.isfile(target):
        from benchbus._library import meant

        raise UsageError(
            f"no device family {target!r}: one of {', '.join(command_keys())}, or a bench"
            f" file{meant(target)}"
        )
    try:
        return read_bench(target)
    except (ProfileError, OSError) as exc:
        raise UsageError(str(exc)) from None
