"""A bench file: the lines of a bench and the devices on them, for ``benchbus ioc BENCH.toml``.

::

    [ioc]                       # optional: what every device takes unless it says otherwise
    period = 0.5

    [[line]]
    name = "rs485"
    port = "/dev/ttyUSB0"       # as bb.Bus takes it: a serial port, tcp://HOST:PORT, ...
    baudrate = 19200            # the line's format; absent: its first device's defaults
    timeout = 0.2

    [[device]]
    line = "rs485"
    family = "drive"            # a built-in family by name...
    unit = 1
    prefix = "LAB:SPINDLE:"
    options = { family = "C20" }    # keywords of the family's class

    [[device]]
    line = "rs485"
    profile = "xy_md02.toml"    # ...or a device profile (relative to this file),
                                # or a profile's name ("sdm630": benchbus profile list)
    unit = 2
    prefix = "LAB:XY:"
    period = 2.0

A mistake is a :class:`~benchbus.ProfileError` naming the file, the line and the key, raised
by :func:`read_bench` before any port is opened.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import os
import re
import sys
from pathlib import Path
from typing import Any

from benchbus._core import Bus, Profile
from benchbus._device import BusDevice, LineDefaults
from benchbus._families import command_keys, family
from benchbus._library import locate
from benchbus._profile import Device, profile_line
from benchbus.exceptions import ProfileError

__all__ = ["Bench", "BenchDevice", "BenchLine", "open_bench", "read_bench"]

# The standard library's TOML reader from Python 3.11, its original (tomli) before.
_toml = importlib.import_module("tomllib" if sys.version_info >= (3, 11) else "tomli")

#: The keys of a ``[[line]]`` and the types their values take; ``name`` and ``port`` are
#: required.
LINE_KEYS: dict[str, tuple[type, ...]] = {
    "name": (str,),
    "port": (str,),
    "baudrate": (int,),
    "parity": (str,),
    "stopbits": (int,),
    "bytesize": (int,),
    "framing": (str,),
    "timeout": (int, float),
    "retries": (int,),
    "echo": (bool,),
    "rs485": (bool,),
}
#: What the values of a ``[[line]]``'s keys may be, beyond their types (``bb.Bus`` checks
#: them again when it opens the line).
LINE_VALUES: dict[str, tuple[str, Any]] = {
    "baudrate": ("a positive number", lambda v: v > 0),
    "parity": ('"N", "E" or "O"', lambda v: v in ("N", "E", "O")),
    "stopbits": ("1 or 2", lambda v: v in (1, 2)),
    "bytesize": ("7 or 8", lambda v: v in (7, 8)),
    "framing": ('"rtu" or "ascii"', lambda v: v in ("rtu", "ascii")),
    "timeout": ("a positive number of seconds", lambda v: math.isfinite(v) and v > 0),
    "retries": ("0 or more", lambda v: v >= 0),
}
#: The keys of a ``[[device]]``; ``line``, ``unit``, ``prefix`` and one of ``family`` and
#: ``profile`` are required.
DEVICE_KEYS: dict[str, tuple[type, ...]] = {
    "line": (str,),
    "family": (str,),
    "profile": (str,),
    "unit": (int,),
    "prefix": (str,),
    "period": (int, float),
    "options": (dict,),
}
#: The keys of ``[ioc]``.
IOC_KEYS: dict[str, tuple[type, ...]] = {"period": (int, float), "read_only": (bool,)}


@dataclasses.dataclass(frozen=True)
class BenchLine:
    """A line of the bench: its port and the ``bb.Bus`` keywords it is opened with."""

    #: What its devices call it.
    name: str
    #: The port, as ``bb.Bus`` takes it.
    port: str
    #: The line's format and timing given (``baudrate``, ``timeout``...).
    options: dict[str, Any]


@dataclasses.dataclass(frozen=True)
class BenchDevice:
    """A device of the bench: a family's class or a profile, at a unit on a line."""

    #: The line it is on.
    line: str
    #: Its unit address.
    unit: int
    #: The start of its PV names.
    prefix: str
    #: The family's key, or None for a profile's device.
    family: str | None
    #: The profile, or None for a family's device.
    profile: Profile | None
    #: Seconds between two reads (None: the IOC's).
    period: float | None
    #: Keywords of the family's class.
    options: dict[str, Any]
    #: Where the file declares it, for messages: ``bench.toml:9: device[0]``.
    at: str = ""

    def line_defaults(self) -> LineDefaults:
        """The line format the device opens its own port at."""
        if self.profile is not None:
            return profile_line(self.profile)
        return family(self.family or "").line


@dataclasses.dataclass(frozen=True)
class Bench:
    """A bench file, read and checked."""

    #: The file.
    path: Path
    #: Its lines, in its order.
    lines: list[BenchLine]
    #: Its devices, in its order.
    devices: list[BenchDevice]
    #: ``[ioc]``'s period (None: not given).
    period: float | None
    #: ``[ioc]``'s read_only.
    read_only: bool


class _Where:
    """Lines of the file by table and key, for messages: the ``n``-th ``[[kind]]``'s
    line, and the line of a key in it."""

    def __init__(self, path: Path, text: str) -> None:
        self.path = path
        self.lines = text.splitlines()

    def _start(self, kind: str, n: int) -> int | None:
        header = re.compile(rf"^\s*\[\[\s*{kind}\s*\]\]" if kind != "ioc" else r"^\s*\[\s*ioc\s*\]")
        seen = 0
        for i, line in enumerate(self.lines):
            if header.match(line):
                if seen == n:
                    return i
                seen += 1
        return None

    def at(self, kind: str, n: int) -> str:
        """``FILE:LINE: kind[n]``: where the ``n``-th ``[[kind]]`` starts."""
        start = self._start(kind, n)
        return f"{self.path}:{'?' if start is None else start + 1}: {kind}[{n}]"

    def error(self, kind: str, n: int, key: str | None, text: str) -> ProfileError:
        """A ProfileError for ``text``, at the key ``key`` of the ``n``-th ``[[kind]]``."""
        start = self._start(kind, n)
        at = start
        if start is not None and key is not None:
            pattern = re.compile(rf"^\s*{re.escape(key)}\s*=|[{{,]\s*{re.escape(key)}\s*=")
            for i in range(start + 1, len(self.lines)):
                if re.match(r"^\s*\[", self.lines[i]):
                    break
                if pattern.search(self.lines[i]):
                    at = i
                    break
        where = f"{self.path}:{at + 1}" if at is not None else str(self.path)
        dotted = kind if kind == "ioc" else f"{kind}[{n}]"
        if key is not None:
            dotted += f".{key}"
        return ProfileError(
            f"{where}: {dotted}: {text}",
            path=str(self.path),
            line=0 if at is None else at + 1,
            key=dotted,
        )


def _checked(
    where: _Where, kind: str, n: int, table: object, keys: dict[str, tuple[type, ...]]
) -> dict[str, Any]:
    """``table`` as a dict whose keys are known and whose values have their types."""
    if not isinstance(table, dict):
        raise where.error(kind, n, None, "must be a table")
    for key, value in table.items():
        if key not in keys:
            raise where.error(kind, n, key, f"unknown key: one of {', '.join(keys)}")
        types = keys[key]
        if (isinstance(value, bool) and bool not in types) or not isinstance(value, types):
            wanted = " or ".join(t.__name__ for t in types)
            raise where.error(kind, n, key, f"must be {wanted}, got {value!r}")
    return dict(table)


def _period(where: _Where, kind: str, n: int, value: float | None) -> float | None:
    if value is not None and (not math.isfinite(value) or value <= 0):
        raise where.error(kind, n, "period", f"must be a positive number of seconds, got {value}")
    return None if value is None else float(value)


def read_bench(path: str | os.PathLike[str]) -> Bench:
    """The bench file at ``path``, read and checked, nothing opened; ProfileError naming
    the file, the line and the key of the first mistake (OSError for an unreadable
    file)."""
    file = Path(path)
    text = file.read_text(encoding="utf-8")
    where = _Where(file, text)
    try:
        data = _toml.loads(text)
    except ValueError as exc:  # tomllib's TOMLDecodeError says the line itself
        raise ProfileError(f"{file}: {exc}", path=str(file)) from None
    unknown = set(data) - {"ioc", "line", "device"}
    if unknown:
        raise ProfileError(
            f"{file}: unknown table {sorted(unknown)[0]!r}: [ioc], [[line]] and [[device]]",
            path=str(file),
        )
    ioc = _checked(where, "ioc", 0, data.get("ioc", {}), IOC_KEYS)
    lines: list[BenchLine] = []
    for n, table in enumerate(data.get("line", [])):
        line = _checked(where, "line", n, table, LINE_KEYS)
        for required in ("name", "port"):
            if required not in line:
                raise where.error("line", n, None, f"{required} is required")
        for option, (wanted, fits) in LINE_VALUES.items():
            if option in line and not fits(line[option]):
                raise where.error("line", n, option, f"must be {wanted}, got {line[option]!r}")
        if any(line["name"] == other.name for other in lines):
            raise where.error("line", n, "name", f"a line is called {line['name']!r} already")
        name, port = line.pop("name"), line.pop("port")
        lines.append(BenchLine(name, port, line))
    if not lines:
        raise ProfileError(f"{file}: no [[line]]: a bench needs a line", path=str(file))
    devices: list[BenchDevice] = []
    families = command_keys()
    for n, table in enumerate(data.get("device", [])):
        device = _checked(where, "device", n, table, DEVICE_KEYS)
        for required in ("line", "unit", "prefix"):
            if required not in device:
                raise where.error("device", n, None, f"{required} is required")
        if ("family" in device) == ("profile" in device):
            raise where.error("device", n, None, "give family or profile, one of them")
        if not any(device["line"] == line.name for line in lines):
            named = ", ".join(line.name for line in lines)
            raise where.error("device", n, "line", f"no line {device['line']!r}: one of {named}")
        if not 1 <= device["unit"] <= 255:
            raise where.error("device", n, "unit", f"must be 1 to 255, got {device['unit']}")
        if not device["prefix"]:
            raise where.error("device", n, "prefix", "must not be empty")
        if any(device["prefix"] == other.prefix for other in devices):
            raise where.error("device", n, "prefix", f"{device['prefix']!r} is taken already")
        profile = None
        key: str | None = device.get("family")
        if key is not None and key not in families:
            raise where.error(
                "device", n, "family", f"no family {key!r}: one of {', '.join(families)}"
            )
        if "profile" in device:
            try:
                # A file beside the bench file, else a profile's name (no folder, no .toml).
                profile = Profile(locate(str(device["profile"]), here=file.parent))
            except (ProfileError, OSError) as exc:
                raise where.error("device", n, "profile", str(exc)) from None
        options = device.get("options", {})
        if options and key is None:
            raise where.error("device", n, "options", "options go with family")
        if key is not None:
            cls = family(key).device or BusDevice
            try:
                inspect.signature(cls.__init__).bind(None, None, 1, **options)
            except TypeError as exc:
                raise where.error("device", n, "options", str(exc)) from None
        period = _period(where, "device", n, device.get("period"))
        at = where.at("device", n)
        made = BenchDevice(
            device["line"], device["unit"], device["prefix"], key, profile, period, options, at
        )
        devices.append(made)
    if not devices:
        raise ProfileError(f"{file}: no [[device]]: a bench needs a device", path=str(file))
    return Bench(
        file,
        lines,
        devices,
        _period(where, "ioc", 0, ioc.get("period")),
        ioc.get("read_only", False),
    )


def open_bench(bench: Bench) -> list[tuple[str, BusDevice, float | None]]:
    """Open the bench's lines (each a Bus that reconnects a lost port) and its devices
    on them: ``(prefix, device, period)`` each. A line's format not given is its first
    device's default. If opening a line fails, the lines opened already are closed."""
    buses: dict[str, Bus] = {}
    made: list[tuple[str, BusDevice, float | None]] = []
    try:
        for line in bench.lines:
            first = next((d for d in bench.devices if d.line == line.name), None)
            if first is None:
                continue
            defaults = first.line_defaults()
            options = {
                "baudrate": defaults.baudrate,
                "parity": defaults.parity,
                "stopbits": defaults.stopbits,
                "timeout": defaults.timeout,
                "framing": defaults.framing,
                "bytesize": defaults.bytesize or 8,
                "reconnect": True,
                **line.options,
            }
            buses[line.name] = Bus(line.port, **options)
        for device in bench.devices:
            bus = buses[device.line]
            made_device: BusDevice
            try:
                if device.profile is not None:
                    made_device = Device.from_profile(device.profile, bus, device.unit)
                else:
                    maker = family(device.family or "")
                    made_device = maker.open(bus, device.unit, **device.options)
            except (ValueError, TypeError) as exc:  # an option's value the class refuses
                raise ProfileError(f"{device.at}: {exc}", path=str(bench.path)) from None
            made.append((device.prefix, made_device, device.period))
    except BaseException:
        for bus in buses.values():
            bus.close()
        raise
    return made
