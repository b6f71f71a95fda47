"""The line a command talks on: the Bus options of its family's (or its own, or a device
profile's) defaults with the line options given (``--baudrate``, ``--timeout``, ...), the Bus,
the unit."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
from collections.abc import Iterator
from typing import Any, TypeVar

import benchbus as bb
from benchbus._device import BusDevice
from benchbus._families import check_identity, command_families, family
from benchbus._profile import profile_line
from benchbus.cli._args import PORT_ENV
from benchbus.cli._errors import UsageError

_D = TypeVar("_D", bound=BusDevice)


@dataclasses.dataclass(frozen=True)
class BusOptions:
    """What a command opens its Bus with: line format, reply timeout, retries and unit, and
    the framing (``"rtu"`` or ``"ascii"``) with its data bits."""

    baudrate: int
    parity: str
    timeout: float
    retries: int
    unit: int = 1
    framing: str = "rtu"
    bytesize: int = 8
    #: None: 1, or 2 for 7 data bits without parity (see :func:`stopbits_of`).
    stopbits: int | None = None

    def describe(self, stopbits: int = 1) -> str:
        """``19200 8N1``, or ``9600 7E1 ASCII``."""
        ascii = " ASCII" if self.framing == "ascii" else ""
        return f"{self.baudrate} {self.bytesize}{self.parity}{stopbits}{ascii}"


#: The Bus options of each command (the scan's timeout is per unit probed).
BUS_OPTIONS = {
    "scan": BusOptions(19200, "N", 0.05, 0),
    "read": BusOptions(19200, "N", 0.1, 2),
    "write": BusOptions(19200, "N", 0.1, 2),
    "gateway": BusOptions(19200, "N", 0.1, 2),
    **{
        f.key: BusOptions(f.line.baudrate, f.line.parity, f.line.timeout, 2)
        for f in command_families()
    },
}


def read_profile(path: str) -> bb.Profile:
    """The device profile at ``path`` (or of that name), read and checked; its mistake
    (file, line, key) or an unreadable file is a UsageError, before any port opens (a file
    that is not there but whose stem is a profile's name says so)."""
    from benchbus._library import meant

    try:
        return bb.Profile(path)
    except (bb.ProfileError, OSError) as exc:
        stem = os.path.splitext(os.path.basename(path))[0]
        missing = not os.path.exists(path) and path.endswith(".toml")
        raise UsageError(f"{exc}{meant(stem) if missing else ''}") from None


def profile_of(args: argparse.Namespace) -> bb.Profile | None:
    """The device profile ``--profile`` names (None without one), as :func:`read_profile`
    reads it."""
    path = opt(args, "profile")
    return None if path is None else read_profile(path)


def profile_options(profile: bb.Profile) -> BusOptions:
    """The Bus options of a device ``profile`` describes: the line the device opens its own
    port at (its ``[line]``, else 9600 8N1, 0.2 s; Modbus ASCII 7E1), 2 retries."""
    line = profile_line(profile)
    return BusOptions(
        baudrate=line.baudrate,
        parity=line.parity,
        timeout=line.timeout,
        retries=2,
        framing=line.framing,
        bytesize=line.bytesize or 8,
        stopbits=line.stopbits,
    )


def open_profiled(bus: bb.Bus, args: argparse.Namespace, profile: bb.Profile) -> bb.Device:
    """The device ``profile`` describes at the unit given (``--unit``, else 1) on ``bus``."""
    return bb.Device.from_profile(profile, bus, unit_of(args, profile_options(profile)))


@contextlib.contextmanager
def profiled(args: argparse.Namespace, profile: bb.Profile) -> Iterator[bb.Device]:
    """The device ``profile`` describes (:func:`open_profiled`), on a Bus opened at the
    profile's line with the options given and closed after the block; a check the device
    makes before anything is sent is a UsageError (:func:`refused_as_usage`)."""
    with open_bus(args, profile_options(profile)) as bus:
        device = open_profiled(bus, args, profile)
        with refused_as_usage():
            yield device


@contextlib.contextmanager
def refused_as_usage() -> Iterator[None]:
    """A ValueError or TypeError of a check made before anything is sent (a profile
    device's: a write-only register read, a value out of range...) as a UsageError; the
    line's own errors pass."""
    try:
        yield
    except (ValueError, TypeError) as exc:
        if isinstance(exc, bb.BenchbusError):
            raise
        raise UsageError(str(exc)) from None


#: Whose defaults a command's line takes: a key of :data:`BUS_OPTIONS`, or the options
#: themselves (a profile's, :func:`profile_options`).
Defaults = str | BusOptions


def adapter_options(args: argparse.Namespace) -> dict[str, Any]:
    """The Bus's ``rs485``, ``rts_delay`` and ``echo`` from ``--rs485``, ``--rts-delay`` and
    ``--echo``."""
    rs485, delay = bool(opt(args, "rs485", False)), opt(args, "rts_delay")
    if delay is not None and not rs485:
        raise UsageError("--rts-delay goes with --rs485")
    return {"rs485": rs485, "rts_delay": delay, "echo": bool(opt(args, "echo", False))}


def opt(args: argparse.Namespace, name: str, default: Any = None) -> Any:
    """The option ``name`` if it was given, else ``default``."""
    return getattr(args, name, default)


def port_of(args: argparse.Namespace) -> str:
    """``--port``, else ``$BENCHBUS_PORT``; a UsageError without either."""
    port = opt(args, "port") or os.environ.get(PORT_ENV)
    if not port:
        raise UsageError(f"--port is required (or set ${PORT_ENV})")
    return str(port)


def bus_options_of(args: argparse.Namespace, family: Defaults) -> BusOptions:
    """The family's Bus options with the line options given on the command line."""
    base = family if isinstance(family, BusOptions) else BUS_OPTIONS[family]
    # Modbus ASCII's line format is the serial line spec's 7E1 unless given; a --framing
    # other than the defaults' brings its own parity and data bits.
    ascii = opt(args, "framing", base.framing) == "ascii"
    switched = ascii != (base.framing == "ascii")
    return BusOptions(
        baudrate=opt(args, "baudrate", base.baudrate),
        parity=opt(args, "parity", ("E" if ascii else "N") if switched else base.parity),
        timeout=opt(args, "timeout", base.timeout),
        retries=opt(args, "retries", base.retries),
        unit=opt(args, "unit", base.unit),
        framing="ascii" if ascii else "rtu",
        bytesize=opt(args, "bytesize", (7 if ascii else 8) if switched else base.bytesize),
        stopbits=None if switched else base.stopbits,
    )


def stopbits_of(args: argparse.Namespace, options: BusOptions) -> int:
    """``--stopbits``, else the defaults' (a profile's), else 1, or 2 for 7 data bits without
    parity (7N2: Modbus ASCII does not allow 7N1)."""
    plain_seven = options.bytesize == 7 and options.parity == "N"
    return int(opt(args, "stopbits", options.stopbits or (2 if plain_seven else 1)))


def open_bus(args: argparse.Namespace, family: Defaults, *, reconnect: bool = False) -> bb.Bus:
    """A Bus on the port at the ``family``'s line with the options given (see
    :func:`new_bus`)."""
    options = bus_options_of(args, family)
    return new_bus(
        port_of(args),
        baudrate=options.baudrate,
        parity=options.parity,
        stopbits=stopbits_of(args, options),
        timeout=options.timeout,
        retries=options.retries,
        reconnect=reconnect,
        framing=options.framing,
        bytesize=options.bytesize,
        **adapter_options(args),
    )


def new_bus(port: str, **options: Any) -> bb.Bus:
    """``bb.Bus(port, **options)``; options the Bus refuses together (``--echo`` over
    ``tcp://``...) are a UsageError: nothing was sent."""
    try:
        return bb.Bus(port, **options)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def unit_of(args: argparse.Namespace, family: Defaults, *, broadcast: bool = False) -> int:
    """The unit to talk to (``--unit``, else the family's); 0 only for a ``broadcast``."""
    unit = int(bus_options_of(args, family).unit)
    if unit == 0 and not broadcast:
        raise UsageError("unit 0 is the broadcast address: give --unit 1 to 255")
    return unit


def open_drive(bus: bb.Bus, args: argparse.Namespace) -> bb.Drive:
    """The Drive at the unit given, of ``--family`` (BLD by default), on ``bus``."""
    return bb.Drive(bus, unit_of(args, "drive"), family=opt(args, "family", "BLD"))


def open_device(bus: bb.Bus, args: argparse.Namespace, kind: str) -> BusDevice:
    """The device of the family ``kind`` at the unit given on ``bus`` (a drive of
    ``--family``)."""
    if kind == "drive":
        return open_drive(bus, args)
    return family(kind).open(bus, unit_of(args, kind))


def check_family(device: BusDevice, key: str) -> None:
    """Refuse a unit recognised as another family than the command talks to: the device's
    own identity check where it has one (once), else the same check made here
    (:class:`benchbus.WrongDevice`, which :func:`~benchbus.cli._errors.one_line` words for
    the command line)."""
    if key == type(device).IDENTITY:
        device.verify_identity()
    else:
        check_identity(key, device.bus, device.unit)


@contextlib.contextmanager
def commanded(args: argparse.Namespace, key: str, kind: type[_D]) -> Iterator[_D]:
    """The device of the family ``key`` (a ``kind``) at the unit given, for its command's
    action: on a Bus opened at the family's line and closed after the block, its family
    checked first for ``status`` (:func:`check_family`)."""
    with open_bus(args, key) as bus:
        # Not the device's own `with`: a drive's would stop the motor on leaving.
        device = open_device(bus, args, key)
        if not isinstance(device, kind):
            raise TypeError(f"the {key} family's device is a {type(device).__name__}")
        if args.action == "status":
            check_family(device, key)
        yield device
