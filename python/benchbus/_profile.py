"""Devices described by a profile: a TOML file that lists a device's registers, read and
checked by the core (``Profile``), and the device object it gives (``Device``).

The core plans the requests, converts the values and checks every write before anything is
sent (the compiled base ``ProfileCore``); this module adds the attributes named after the
registers, the enums built from the profile, the repr and the context manager.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Iterator, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, NamedTuple

from benchbus._core import Bus, Profile, ProfileCore
from benchbus._device import (
    BusDevice,
    LineDefaults,
    PrintableIntEnum,
    _declared,
    as_enum,
    did_you_mean,
)
from benchbus._display import html_table
from benchbus._names import class_name

if TYPE_CHECKING:
    from collections.abc import Iterable

__all__ = [
    "PROFILE_LINE",
    "Device",
    "ProfileLimits",
    "ProfileLine",
    "ProfileRegister",
    "profile_line",
]


class ProfileLine(NamedTuple):
    """A profile's ``[line]``: how the device's own port is opened (None: not given)."""

    #: Bits per second.
    baudrate: int | None
    #: "N", "E" or "O".
    parity: str | None
    #: 1 or 2.
    stopbits: int | None
    #: Reply timeout, seconds.
    timeout: float | None
    #: "rtu" or "ascii".
    framing: str | None
    #: 7 or 8.
    bytesize: int | None


class ProfileLimits(NamedTuple):
    """A profile's ``[limits]``: what the device takes in one request (None: not given)."""

    #: Registers (bits, in a table of bits) one read may ask for.
    max_read: int | None
    #: Registers (bits) one write may carry.
    max_write: int | None
    #: Seconds between two writes.
    min_write_interval: float | None
    #: Whether neighbouring registers may be read in one request (default True).
    block_reads: bool | None
    #: Whether one request may also read unlisted addresses between two registers (default
    #: False).
    read_gaps: bool | None = None
    #: What a write's reply carries: ``"strict"``, the Modbus echo (the default), or
    #: ``"count"``, a register count of 1 in place of the value for a 0x06 write (as PBL
    #: drives answer).
    write_echo: str | None = None
    #: Whether every register write is function 0x10, also of one register (a device that
    #: does not take 0x06); None or False: 0x06 for one register.
    write_multiple: bool | None = None


#: The whole numbers each integer type holds, exactly (a profile's ``min`` / ``max`` are
#: floats, which cannot say 2**64 - 1).
INTEGER_RANGES: dict[str, tuple[int, int]] = {
    "u16": (0, 2**16 - 1),
    "i16": (-(2**15), 2**15 - 1),
    "u32": (0, 2**32 - 1),
    "i32": (-(2**31), 2**31 - 1),
    "u64": (0, 2**64 - 1),
    "i64": (-(2**63), 2**63 - 1),
}


class ProfileRegister(NamedTuple):
    """One ``[[register]]`` of a profile, as the core checked it."""

    #: The attribute name (a Python identifier).
    name: str
    #: Its address (the first of a multi-register value).
    address: int
    #: "holding", "input", "coil" or "discrete".
    table: str
    #: "u16", "i16", "u32", "i32", "u64", "i64", "f32", "f64", "bool" or "string".
    type: str
    #: The bit (0..15) of a register a bool is, or None.
    bit: int | None
    #: How many registers a string takes, or None.
    length: int | None
    #: A multi-register value's layout: "ABCD", "CDAB", "BADC" or "DCBA".
    order: str
    #: Engineering value = raw x scale + offset.
    scale: float
    #: See ``scale``.
    offset: float
    #: Unit of the engineering value ("" for none).
    unit: str
    #: "r", "rw", "rw-stopped" (written only while a motor is stopped: the manuals' W/R*)
    #: or "w".
    access: str
    #: Lowest value a write may carry (None for a bool or a string).
    min: float | None
    #: Highest value a write may carry (None for a bool or a string).
    max: float | None
    #: Enum members, ``{number: name}`` (empty for none).
    enum: dict[int, str]
    #: The simulator's initial value, if the file gives one.
    default: int | float | bool | str | None
    #: Free text.
    description: str
    #: The line of its ``[[register]]`` header in the file.
    line: int
    #: The models of the profile's ``models`` that have it (``()``: every model).
    models: tuple[str, ...] = ()
    #: Its write range ``(min, max)`` on a model where it differs from ``min`` / ``max``.
    ranges: Mapping[str, tuple[float, float]] = MappingProxyType({})
    #: A field of the register's bits ``(first, last)``, an unsigned number (``bits``), or
    #: None for the whole word.
    bits: tuple[int, int] | None = None
    #: The register whose value is this one's number of decimal places (engineering value
    #: = raw / 10^places; ``min`` / ``max`` are then in the raw digits), or None.
    decimals: str | None = None

    def integer_range(self) -> tuple[int, int] | None:
        """The exact range of an unscaled integer register's type (its engineering values
        are then whole numbers), or of its field of bits; None for a float, a scaled value
        (also one scaled by its ``decimals``), a bool or a string."""
        if self.scale != 1.0 or self.offset != 0.0 or self.decimals is not None:
            return None
        if self.bits is not None:
            first, last = self.bits
            return (0, (1 << (last - first + 1)) - 1)
        return INTEGER_RANGES.get(self.type)


#: The line of a device whose profile says nothing of it: 9600 8N1, 0.2 s.
PROFILE_LINE = LineDefaults(9600, "N", 0.2)


def profile_line(profile: Profile) -> LineDefaults:
    """The line a device opens its own port at: the profile's, else :data:`PROFILE_LINE`
    (Modbus ASCII: 7E1 unless the profile says otherwise)."""
    given = profile.line
    ascii = given.framing == "ascii"
    parity = given.parity or ("E" if ascii else PROFILE_LINE.parity)
    bytesize = given.bytesize or (7 if ascii else 8)
    return LineDefaults(
        baudrate=given.baudrate or PROFILE_LINE.baudrate,
        parity=parity,
        timeout=given.timeout or PROFILE_LINE.timeout,
        # Seven data bits without parity take two stop bits (Modbus ASCII's 7N2).
        stopbits=given.stopbits or (2 if bytesize == 7 and parity == "N" else 1),
        framing=given.framing or PROFILE_LINE.framing,
        bytesize=bytesize,
    )


@functools.lru_cache(maxsize=256)
def _enum(name: str, members: tuple[tuple[str, int], ...]) -> type[PrintableIntEnum]:
    """The enum of a register called ``name`` (one class per definition)."""
    made: type[PrintableIntEnum] = PrintableIntEnum(class_name(name), members)  # type: ignore[call-arg, arg-type, assignment]
    return made


#: Held while an enum class is made, so that threads sharing a device get the same class.
_MAKING = threading.Lock()


class _Enums(Mapping[str, type[PrintableIntEnum]]):
    """A device's enum classes by register name, each made when first asked for: a class
    costs about 0.1 ms and 3 KB, and a profile may have thousands of enum registers."""

    def __init__(self, members: dict[str, dict[int, str]]) -> None:
        """The enums of the registers ``members`` names, each ``{number: name}``."""
        self._members = members
        self._made: dict[str, type[PrintableIntEnum]] = {}

    def __getitem__(self, name: str) -> type[PrintableIntEnum]:
        """The enum class of the register ``name`` (KeyError for a register without one)."""
        made = self._made.get(name)
        if made is None:
            members = self._members[name]
            with _MAKING:
                made = self._made.get(name)
                if made is None:
                    made = _enum(name, tuple((member, n) for n, member in members.items()))
                    self._made[name] = made
        return made

    def __contains__(self, name: object) -> bool:
        """Whether the register ``name`` has an enum."""
        return name in self._members

    def __iter__(self) -> Iterator[str]:
        """The enum registers' names, in the profile's order."""
        return iter(self._members)

    def __len__(self) -> int:
        """How many registers have an enum."""
        return len(self._members)

    def __repr__(self) -> str:
        """As a dict of the classes shows."""
        return repr(dict(self.items()))


def as_profile(profile: Profile | str | os.PathLike[str]) -> Profile:
    """``profile`` itself, or the profile read from the file it names (a path, or a
    profile's name)."""
    return profile if isinstance(profile, Profile) else Profile(profile)


def known(profile: Profile, name: str) -> str:
    """``name`` if ``profile`` has a register of that name, else ValueError naming the
    closest ones."""
    if name in profile:
        return name
    hint = did_you_mean(name, (r.name for r in profile.registers))
    raise ValueError(f"{profile.name} has no register {name!r}{hint}")


class Device(ProfileCore, BusDevice):
    """A device described by a profile (a TOML file naming its registers): every register
    is an attribute, in engineering units.

    ::

        dev = bb.Device.from_profile("xy_md02.toml", "/dev/ttyUSB0", unit=1)
        print(dev.temperature, dev.humidity)      # 21.5 48.2 (degC, %RH)
        meter = bb.Device.from_profile("sdm630", bus, unit=2)   # a shipped profile
        dev.mode = "heat"                         # an enum: by name, number or member
        dev.read_many(["temperature", "humidity"])
        dev.sample()                              # every readable value, fewest requests

    Given a path, the device opens its own Bus at the profile's ``[line]`` (9600 8N1 and a
    0.2 s timeout where it is silent); given a Bus, it shares it (``timeout`` / ``retries``
    then apply to this device's requests only). Reads are planned by the core: each table
    apart, neighbouring registers in one request up to the profile's ``max_read`` (unless
    ``block_reads = false``), a value never split between two requests. Writes go at least
    ``min_write_interval`` apart; a write to a read-only register, a value out of its range,
    off its scale's steps or not an enum member, raises ValueError (TypeError for the wrong
    kind of value) before anything is sent. A ``bool`` that is one bit of a holding register
    is written by reading the register and writing it back with the bit changed, as one
    sequence on the Bus; a register with ``decimals`` by reading its decimal places, then
    checking the value at them (range, steps) and writing it, as one sequence.

    An enum register reads as a member of an ``IntEnum`` built from the profile (named
    after the register: ``mode`` gives ``Mode``, in :attr:`enums`); a value the profile does not
    list reads as that enum's ``UNKNOWN`` value carrying the number (``Mode.UNKNOWN(7)``,
    see :func:`benchbus.is_unknown`), as in every family.
    """

    #: Line format and reply timeout when the profile says nothing of them.
    LINE_DEFAULTS = PROFILE_LINE
    #: Each enum register's enum class, by register name.
    enums: Mapping[str, type[PrintableIntEnum]]
    #: The readable registers :meth:`sample` gives (every readable one but strings).
    SAMPLE_FIELDS: tuple[str, ...] | None

    def __init__(
        self,
        profile: Profile | str | os.PathLike[str],
        port_or_bus: str | os.PathLike[str] | Bus,
        unit: int = 1,
        *,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """The device ``profile`` describes at ``unit``; see :meth:`from_profile`."""
        checked = as_profile(profile)
        rows = checked.registers
        self.enums = _Enums({r.name: r.enum for r in rows if r.enum})
        self.SAMPLE_FIELDS = tuple(r.name for r in rows if r.access != "w" and r.type != "string")
        self._on_line(
            port_or_bus,
            unit,
            checked,
            timeout=timeout,
            retries=retries,
            line=profile_line(checked),
        )

    @classmethod
    def from_profile(
        cls,
        profile: Profile | str | os.PathLike[str],
        port_or_bus: str | os.PathLike[str] | Bus,
        unit: int = 1,
        *,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> Device:
        """The device ``profile`` (a :class:`Profile`, the path of its TOML file, or a
        profile's name: ``"sdm630"``, one of a lab's ``BENCHBUS_PROFILES`` or of the
        package's) describes, at ``unit`` on a Bus or on a port opened at the profile's line.

        A profile's mistake raises ``ProfileError`` (file, line, key) before any port is
        opened.
        """
        return cls(profile, port_or_bus, unit, timeout=timeout, retries=retries)

    def _known(self, name: str) -> str:
        """``name`` if the profile has it, else ValueError with the closest names."""
        return known(self.profile, name)

    def _shown(self, name: str, value: Any) -> Any:
        """``value`` of the register ``name`` as Python has it (an enum member)."""
        enum_type = self.enums.get(name)
        if enum_type is None or isinstance(value, bool):
            return value
        return as_enum(enum_type, value)

    def read(self, name: str) -> Any:
        """The register ``name``, in engineering units (an enum member, a bool, a str)."""
        return self.read_many([name])[name]

    def read_many(self, names: Iterable[str]) -> dict[str, Any]:
        """The registers ``names``, ``{name: value}`` in that order, read in the fewest
        requests the profile allows (:meth:`Profile.plan` shows which)."""
        wanted = [self._known(n) for n in names]
        values = self._read(wanted)
        return {n: self._shown(n, v) for n, v in zip(wanted, values)}

    def write(self, name: str, value: Any) -> None:
        """Write ``value`` (engineering units; an enum by member, name or number) to the
        register ``name``, checked before anything is sent (for a register with
        ``decimals``: against the widest range its places allow, then at its places, read
        first, before it is written)."""
        self._write(self._known(name), value)

    def get(self, name: str) -> Any:
        """:meth:`read`, under the name every benchbus device reads a register by."""
        return self.read(name)

    def set(self, name: str, value: Any) -> None:
        """:meth:`write`, under the name every benchbus device writes a register by."""
        self.write(name, value)

    def get_many(self, names: Iterable[str]) -> dict[str, Any]:
        """:meth:`read_many`, under the name every benchbus device reads registers by."""
        return self.read_many(names)

    def set_many(self, values: Mapping[str, Any] | Iterable[tuple[str, Any]]) -> None:
        """Write ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each as
        :meth:`write` does; every value is checked before the first is sent (the decimal
        places the values need read first)."""
        self._write_many(values)

    def sample(self) -> dict[str, Any]:
        """Every readable register but strings, ``{name: value}`` in the profile's order, in
        the fewest requests the profile allows: what :meth:`record` and ``benchbus
        monitor`` take."""
        return self.read_many(self.SAMPLE_FIELDS or ())

    def units(self) -> dict[str, str]:
        """The unit of every register by name ("" for none)."""
        return {r.name: r.unit for r in self.profile.registers}

    def _register_named(self, name: str) -> bool:
        """Whether ``name`` is a register (not a member of the object) of an attached device."""
        if name.startswith("_") or _declared(type(self), name):
            return False
        try:
            return name in self.profile
        except RuntimeError:  # not attached yet: its __init__ is running
            return False

    def __getattr__(self, name: str) -> Any:
        """A register's value, read now; AttributeError with the closest names otherwise."""
        if self._register_named(name):
            return self.read(name)
        raise self._no_attribute(name, "")

    def __setattr__(self, name: str, value: Any) -> None:
        """Write a register (``dev.mode = "heat"``), or set an attribute of the object;
        AttributeError with the closest names for a name it has neither of."""
        if self._register_named(name):
            self.write(name, value)
            return
        try:
            super().__setattr__(name, value)
        except AttributeError as exc:
            if getattr(exc, "name", None) != name:
                raise
            raise self._no_attribute(name, " to set") from None

    def _no_attribute(self, name: str, to: str) -> AttributeError:
        """An AttributeError for ``name`` naming the closest registers and members."""
        try:
            registers = [r.name for r in self.profile.registers]
        except RuntimeError:
            registers = []
        known = registers + [n for n in dir(type(self)) if not n.startswith("_")]
        hint = did_you_mean(name, known)
        error = AttributeError(
            f"{type(self).__name__!r} object has no attribute {name!r}{to}{hint}"
        )
        error.name, error.obj = name, self
        return error

    def __dir__(self) -> Iterable[str]:
        """The object's names and the registers' (for completion in notebooks)."""
        return [*super().__dir__(), *(r.name for r in self.profile.registers)]

    def _kind(self) -> str:
        """What the device is, as recordings name it: its profile's name."""
        return self.profile.name

    def __repr__(self) -> str:
        """Profile name, unit and bus."""
        return f"<Device {self.profile.name!r} unit={self.unit} on {self.bus!r}>"

    def _repr_html_(self) -> str:
        """The profile's registers with their units, for notebooks (nothing is read)."""
        rows = [
            [r.name, r.table, f"0x{r.address:04X}", r.type, r.unit, r.access, r.description]
            for r in self.profile.registers
        ]
        return html_table(
            ["name", "table", "address", "type", "unit", "access", "description"],
            rows,
            caption=f"{self.profile.name} (unit {self.unit})",
        )
