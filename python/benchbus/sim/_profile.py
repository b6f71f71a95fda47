"""A simulated device served from a device profile (TOML), read here in pure Python.

The profile is read by this module alone (``tomllib``, or ``tomli`` before Python 3.11),
never by benchbus's core, so that the simulator judges the core's reading of the same file.
"""

from __future__ import annotations

import importlib
import math
import os
import struct
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Union

from benchbus.sim._device import RegisterDevice, Row, SimException
from benchbus.sim._rtu import count_echo

# The standard library's TOML reader from Python 3.11, its original (tomli) before.
_toml = importlib.import_module("tomllib" if sys.version_info >= (3, 11) else "tomli")

__all__ = ["ProfileDevice"]

#: An engineering value: a number, a bool, an enum member's name or a string.
Value = Union[int, float, bool, str]

_TOP_KEYS = {"device", "line", "limits", "register"}
_DEVICE_KEYS = {"name", "description", "models", "maker", "model", "kind", "source"}
_LINE_KEYS = {"baudrate", "parity", "stopbits", "timeout", "framing", "bytesize"}
_LIMIT_KEYS = {
    "max_read",
    "max_write",
    "min_write_interval",
    "block_reads",
    "read_gaps",
    "write_echo",
    "write_multiple",
}
_REGISTER_KEYS = {
    "name",
    "address",
    "table",
    "type",
    "order",
    "scale",
    "offset",
    "unit",
    "access",
    "min",
    "max",
    "description",
    "enum",
    "bit",
    "bits",
    "length",
    "default",
    "models",
    "ranges",
    "decimals",
}
_TABLES = ("holding", "input", "coil", "discrete")
_BIT_TABLES = ("coil", "discrete")
#: struct format (big-endian) and registers of each numeric type.
_NUMERIC = {
    "u16": ("H", 1),
    "i16": ("h", 1),
    "u32": ("I", 2),
    "i32": ("i", 2),
    "u64": ("Q", 4),
    "i64": ("q", 4),
    "f32": ("f", 2),
    "f64": ("d", 4),
}
_TYPES = (*_NUMERIC, "bool", "string")
_ORDERS = ("ABCD", "CDAB", "BADC", "DCBA")
_ACCESS = ("r", "rw", "rw-stopped", "w")


@dataclass(frozen=True)
class _Register:
    """One ``[[register]]`` of a profile, checked."""

    name: str
    address: int
    table: str
    type: str
    order: str
    scale: float
    offset: float
    unit: str
    access: str
    min: float | None
    max: float | None
    enum: dict[int, str] | None
    bit: int | None
    length: int
    description: str
    #: A field of the register's bits, (first, last), or None.
    bits: tuple[int, int] | None = None
    #: The register whose value is this one's number of decimal places, or None.
    decimals: str | None = None

    @property
    def width(self) -> int:
        """Registers (or bits) the value takes."""
        if self.type == "string":
            return self.length
        if self.type == "bool":
            return 1
        return _NUMERIC[self.type][1]

    @property
    def addresses(self) -> range:
        return range(self.address, self.address + self.width)

    @property
    def scaled(self) -> bool:
        return self.scale != 1 or self.offset != 0

    @property
    def field_top(self) -> int:
        """The largest number its field of bits holds (0 without ``bits``)."""
        if self.bits is None:
            return 0
        return (1 << (self.bits[1] - self.bits[0] + 1)) - 1

    @property
    def own_bits(self) -> set[int] | None:
        """The bits of its word it takes (a bool's bit, a field's), None for all of them."""
        if self.bit is not None:
            return {self.bit}
        if self.bits is not None:
            return set(range(self.bits[0], self.bits[1] + 1))
        return None


class ProfileDevice(RegisterDevice):
    """A simulated unit that serves a device profile (a TOML file of ``[[register]]`` rows).

    ::

        dev = ProfileDevice("examples/profiles/xy_md02.toml", values={"temperature": 23.4})
        with Simulator({1: dev}) as sim:
            ...  # any master reads input register 0x0001 as 234
        dev.value("temperature")  # 23.4
        dev.set_value("humidity", 51.0)

    Every table of the profile is served: ``holding`` registers (0x03, 0x06, 0x10, 0x16,
    0x17), ``input`` registers (0x04), ``coil`` (0x01, 0x05, 0x0F) and ``discrete`` inputs
    (0x02). A value is stored as the profile says: ``raw = (value - offset) / scale`` in
    its ``type`` (u16 i16 u32 i32 u64 i64 as integers, rounded; f32 f64 as IEEE 754), its
    bytes most significant first (``ABCD``) or in the ``order`` given: ``CDAB`` the
    registers in reverse order, ``BADC`` the two bytes of each register swapped, ``DCBA``
    both; a ``string`` as ``length`` registers of two characters each (first character in
    the high byte, padded with NUL bytes); a ``bool`` on a register as its ``bit`` (the
    whole register 0 / 1 without one); a ``u16`` with ``bits = [first, last]`` as those
    bits of its word; an ``enum`` register as the member's number.

    Initial values: a register's ``default``, then ``values`` (engineering values by
    register name, an enum member by name or number), which win; others are 0.

    Refused requests, as the Modbus Application Protocol gives their meanings:

    - an address the profile does not declare, a read touching a write-only (``"w"``)
      register, or a write that covers only part of a multi-register value: exception 2
      (illegal data address: the address is not one the device allows for that request);
    - a write touching a read-only (``"r"``) register: exception 2 too
      (:attr:`RegisterDevice.readonly_code`), the address is not writable, whatever the
      value; nothing is written;
    - a written value outside the register's ``min`` / ``max`` or not a member of its
      ``enum``: exception 3 (illegal data value: the address is fine, the value is not);
      nothing is written;
    - more registers than ``[limits] max_read`` / ``max_write`` in one request (bits, for
      coils and discrete inputs): exception 3, as :attr:`SimDevice.max_read`.

    ``min_write_interval`` and ``block_reads`` are read (and checked) but not enforced.
    A broken profile raises ``ValueError`` naming the file and the register.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        values: Mapping[str, Value] | None = None,
        *,
        identity: Mapping[int, str] | None = None,
        max_read: int | None = None,
        max_write: int | None = None,
        max_read_bits: int | None = None,
        max_write_bits: int | None = None,
    ) -> None:
        """Read the profile at ``path`` (or of that name, as ``bb.Profile`` finds it: a
        lab's ``BENCHBUS_PROFILES``, then the shipped ones) and serve it; ``values`` by
        register name win over the profile's ``default`` keys. The limits (``max_read``
        ...) given here win over the profile's ``[limits]``; see :class:`RegisterDevice`."""
        from benchbus._library import locate

        #: The profile's path (a name's file: ``BENCHBUS_PROFILES``', else a shipped one).
        self.path: str = locate(path)
        profile = _load(self.path)
        device = _table(self.path, profile, "device", _DEVICE_KEYS)
        #: The profile's ``[device] name`` (the file's stem without one).
        self.name: str = str(device.get("name", os.path.splitext(os.path.basename(self.path))[0]))
        #: The profile's ``[device] description``.
        self.description: str = str(device.get("description", ""))
        #: The profile's ``[line]`` table (baudrate, parity, ...), as written.
        self.line: dict[str, Any] = _table(self.path, profile, "line", _LINE_KEYS)
        #: The profile's ``[limits]`` table, as written.
        self.limits: dict[str, Any] = _table(self.path, profile, "limits", _LIMIT_KEYS)
        _check_line(self.path, self.line)
        _check_limits(self.path, self.limits)
        rows = profile.get("register", [])
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ValueError(f"{self.path}: 'register' must be an array of tables ([[register]])")
        models = device.get("models")
        if models is not None and not _names(models):
            raise ValueError(f"{self.path}: [device] models must be an array of names")
        #: The profile's ``[device] models``: every row is served as written (a register's
        #: ``models`` and ``ranges`` are checked, not applied: its min / max hold).
        self.models: tuple[str, ...] = tuple(models or ())
        for i, row in enumerate(rows):
            _check_models(self.path, i, row, self.models)
        regs = [_register(self.path, i, row) for i, row in enumerate(rows)]
        names = {reg.name: reg for reg in regs}
        ranges = {reg.name: row.get("ranges", {}) for reg, row in zip(regs, rows)}
        for reg in regs:
            places = names.get(str(reg.decimals)) if reg.decimals is not None else None
            if reg.decimals is not None and not _gives_places(places, reg, ranges):
                raise ValueError(
                    f"{self.path}: {reg.name}'s decimals name no other readable, unscaled"
                    " integer register whose values are 0..9 places"
                )
        self._regs: dict[str, _Register] = {}
        self._at: dict[str, dict[int, list[_Register]]] = {t: {} for t in _TABLES}
        for reg in regs:
            self._add(reg)
        #: Each table's rows: readable unless a register at the address is write-only,
        #: writable unless one is read-only (the words are in the lists).
        self._table_rows: dict[str, dict[int, Row]] = {
            table: {a: Row(_access(regs), default=None) for a, regs in at.items()}
            for table, at in self._at.items()
        }
        top = {"max_read": 125, "max_read_bits": 2000, "max_write": 123, "max_write_bits": 1968}
        limit = {
            "max_read": self.limits.get("max_read"),
            "max_read_bits": self.limits.get("max_read"),
            "max_write": self.limits.get("max_write"),
            "max_write_bits": self.limits.get("max_write"),
        }
        given = {
            "max_read": max_read,
            "max_read_bits": max_read_bits,
            "max_write": max_write,
            "max_write_bits": max_write_bits,
        }
        chosen = {
            k: given[k] if given[k] is not None else (min(v, top[k]) if v is not None else None)
            for k, v in limit.items()
        }
        if self.limits.get("read_gaps"):
            self._read_gaps = "inside"
        if self.limits.get("write_multiple"):
            # A device that takes its registers' writes by 0x10 alone: 0x06 is illegal.
            self.functions = self.functions - {0x06}
        super().__init__(
            identity=identity,
            max_read=chosen["max_read"],
            max_write=chosen["max_write"],
            max_read_bits=chosen["max_read_bits"],
            max_write_bits=chosen["max_write_bits"],
        )
        for i, row in enumerate(rows):
            if "default" in row:
                reg = regs[i]
                try:
                    if reg.decimals is not None:  # in the device's digits, as min / max
                        self._put_words(reg, row["default"])
                    else:
                        self.set_value(reg.name, row["default"])
                except (TypeError, ValueError) as e:
                    raise ValueError(f"{self.path}: register {reg.name!r}: default: {e}") from e
        # The registers giving others their places first: those are set at the places given.
        assigned = list((values or {}).items())
        gives = {str(reg.decimals) for reg in regs if reg.decimals is not None}
        for name, value in sorted(assigned, key=lambda item: item[0] not in gives):
            self.set_value(name, value)

    # ---- the profile -------------------------------------------------------------------

    def _add(self, reg: _Register) -> None:
        if reg.name in self._regs:
            raise ValueError(f"{self.path}: register {reg.name!r}: the name is used twice")
        at = self._at[reg.table]
        for address in reg.addresses:
            for other in at.get(address, []):
                if not _may_share(reg, other):
                    raise ValueError(
                        f"{self.path}: register {reg.name!r}: address {address:#06x} of the "
                        f"{reg.table} table is also {other.name!r}'s"
                    )
        if reg.address + reg.width > 0x10000:
            raise ValueError(f"{self.path}: register {reg.name!r}: runs past address 0xFFFF")
        self._regs[reg.name] = reg
        for address in reg.addresses:
            at.setdefault(address, []).append(reg)

    @property
    def names(self) -> tuple[str, ...]:
        """The profile's register names, in the file's order."""
        return tuple(self._regs)

    def unit_of(self, name: str) -> str:
        """The ``unit`` of register ``name`` ("" without one)."""
        return self._reg(name).unit

    def _reg(self, name: str) -> _Register:
        try:
            return self._regs[name]
        except KeyError:
            raise KeyError(f"{self.name} has no register {name!r}") from None

    # ---- values by name ------------------------------------------------------------------

    def value(self, name: str) -> Value:
        """The engineering value of register ``name``, decoded from the tables as a master
        would: a number (an int for an integer type without scale or offset), a bool, an
        enum member's name (its number if the register holds no member) or a string."""
        reg = self._reg(name)
        if reg.table in _BIT_TABLES:
            return self._bits(reg.table)[reg.address]
        raw = _decode(reg, self._table_words(reg.table)[reg.address : reg.address + reg.width])
        if reg.decimals is None:
            return raw
        return float(raw) / math.pow(10, self._places(reg))

    def _places(self, reg: _Register) -> int:
        """The decimal places of ``reg``: the value its ``decimals`` register holds now."""
        given = self._reg(str(reg.decimals))
        places = self.value(given.name)
        if isinstance(places, str) and given.enum:  # an enum's member: its number
            places = next((n for n, m in given.enum.items() if m == places), places)
        if isinstance(places, bool) or not isinstance(places, int) or not 0 <= places <= 9:
            raise ValueError(f"{reg.decimals} holds {places!r}, not 0..9 decimal places")
        return places

    def set_value(self, name: str, value: Value) -> None:
        """Set register ``name`` to an engineering value (whatever its access), as the
        device itself would. ValueError if it does not fit the type, its ``min`` / ``max``
        or its ``enum``; TypeError for a value of the wrong kind. A register with
        ``decimals`` is set at the places its decimals register holds now (set that one
        first), its ``default`` being the device's digits."""
        reg = self._reg(name)
        if reg.table in _BIT_TABLES:
            if not isinstance(value, bool):
                raise TypeError(f"{name} is True or False, not {value!r}")
            self._bits(reg.table)[reg.address] = value
            return
        if reg.decimals is not None and _number(value) and not isinstance(value, bool):
            # In the device's digits at its decimal places now: 25.3 at one place is 253.
            digits = float(value) * 10 ** self._places(reg)
            if not math.isclose(digits, round(digits), abs_tol=1e-6):
                raise ValueError(f"{name} takes {self._places(reg)} decimal places, not {value!r}")
            value = round(digits)
        self._put_words(reg, value)

    def _put_words(self, reg: _Register, value: Value) -> None:
        """Put ``value`` (as the register's words encode it) in ``reg``'s words."""
        words = self._table_words(reg.table)
        current = words[reg.address : reg.address + reg.width]
        words[reg.address : reg.address + reg.width] = _encode(reg, value, current)

    def _table_words(self, table: str) -> list[int]:
        return self.registers if table == "holding" else self.input_registers

    def _bits(self, table: str) -> list[bool]:
        return self.coils if table == "coil" else self.discrete_inputs

    # ---- the wire ------------------------------------------------------------------------

    def _row(self, address: int) -> Row | None:
        return self._table_rows["holding"].get(address)

    def _rows_of(self, table: str) -> Callable[[int], Row | None]:
        """Only the addresses the profile declares, with their access."""
        return self._table_rows[table].get

    def write_holding(self, address: int, values: list[int]) -> None:
        """Store ``values`` if every register they touch is declared, writable, written
        whole and given a value in its range; else nothing."""
        self._writable(self._row, address, len(values))
        end = address + len(values)
        touched = {reg.name: reg for a in range(address, end) for reg in self._at["holding"][a]}
        if any(r.address < address or r.address + r.width > end for r in touched.values()):
            raise SimException(SimException.ILLEGAL_DATA_ADDRESS)
        for reg in touched.values():
            words = values[reg.address - address : reg.address - address + reg.width]
            if not _in_range(reg, _decode(reg, words)):
                raise SimException(SimException.ILLEGAL_DATA_VALUE)
        super().write_holding(address, values)

    def shape_reply(self, request: bytes, reply: bytes) -> bytes:
        """With ``[limits] write_echo = "count"``, a 0x06 write is answered with a register
        count of 1 in place of the value."""
        return count_echo(reply) if self.limits.get("write_echo") == "count" else reply

    def __repr__(self) -> str:
        """Class name, the profile's device name and its register count."""
        return f"{type(self).__name__}({self.name!r}, {len(self._regs)} registers)"


def _may_share(a: _Register, b: _Register) -> bool:
    """Whether two registers may be declared at one address: different bits of it (bools'
    bits, fields), or bits and the one-word number that is the whole word (a status word
    and its flags and fields)."""
    a_bits, b_bits = a.own_bits, b.own_bits
    if a_bits is not None and b_bits is not None:
        return not a_bits & b_bits
    part, word = (a, b) if a_bits is not None else (b, a)
    return part.own_bits is not None and word.type in ("u16", "i16")


def _access(regs: list[_Register]) -> str:
    """The access of a word that ``regs`` share."""
    readable = "" if any(r.access == "w" for r in regs) else "r"
    return readable + ("" if any(r.access == "r" for r in regs) else "w")


# ---- reading the file ----------------------------------------------------------------------


def _load(path: str) -> dict[str, Any]:
    try:
        with open(path, "rb") as f:
            profile: dict[str, Any] = _toml.load(f)
    except ValueError as e:  # TOMLDecodeError
        raise ValueError(f"{path}: not valid TOML: {e}") from e
    unknown = set(profile) - _TOP_KEYS
    if unknown:
        raise ValueError(f"{path}: unknown key(s) {', '.join(sorted(unknown))}")
    return profile


def _table(path: str, profile: dict[str, Any], key: str, allowed: set[str]) -> dict[str, Any]:
    table = profile.get(key, {})
    if not isinstance(table, dict):
        raise ValueError(f"{path}: [{key}] must be a table")
    unknown = set(table) - allowed
    if unknown:
        raise ValueError(f"{path}: [{key}]: unknown key(s) {', '.join(sorted(unknown))}")
    return dict(table)


#: What each ``[line]`` key may be.
_LINE_VALUES: dict[str, tuple[object, ...]] = {
    "parity": ("N", "E", "O"),
    "stopbits": (1, 2),
    "framing": ("rtu", "ascii"),
    "bytesize": (7, 8),
}


def _check_line(path: str, line: dict[str, Any]) -> None:
    for key, allowed in _LINE_VALUES.items():
        v = line.get(key)
        if v is not None and (isinstance(v, bool) or v not in allowed):
            shown = " | ".join(repr(a) for a in allowed)
            raise ValueError(f"{path}: [line] {key} must be {shown}, not {v!r}")
    baudrate = line.get("baudrate")
    if baudrate is not None and (
        isinstance(baudrate, bool) or not isinstance(baudrate, int) or baudrate <= 0
    ):
        raise ValueError(f"{path}: [line] baudrate must be a positive integer, not {baudrate!r}")
    timeout = line.get("timeout")
    if timeout is not None and (not _number(timeout) or timeout <= 0):
        raise ValueError(f"{path}: [line] timeout must be > 0 s, not {timeout!r}")


def _check_limits(path: str, limits: dict[str, Any]) -> None:
    for key in ("max_read", "max_write"):
        v = limits.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 2000):
            raise ValueError(f"{path}: [limits] {key} must be an integer 1..2000, not {v!r}")
    interval = limits.get("min_write_interval", 0.0)
    if not _number(interval) or not interval >= 0:
        raise ValueError(f"{path}: [limits] min_write_interval must be >= 0 s, not {interval!r}")
    for key in ("block_reads", "read_gaps", "write_multiple"):
        if not isinstance(limits.get(key, False), bool):
            raise ValueError(f"{path}: [limits] {key} must be true or false")
    if limits.get("read_gaps") and limits.get("block_reads") is False:
        raise ValueError(f"{path}: [limits] read_gaps needs block reads")
    echo = limits.get("write_echo", "strict")
    if echo not in ("strict", "count"):
        raise ValueError(f"{path}: [limits] write_echo must be 'strict' or 'count', not {echo!r}")
    if echo == "count" and limits.get("write_multiple"):
        raise ValueError(f"{path}: [limits] write_echo 'count' is for 0x06, never sent here")


def _check_models(path: str, index: int, row: dict[str, Any], models: tuple[str, ...]) -> None:
    """A register's ``models`` (names) and ``ranges`` (``{model: [min, max]}``) name only
    the profile's models."""
    where = f"{path}: register {row.get('name', f'#{index + 1}')!r}"
    named = row.get("models", [])
    ranges = row.get("ranges", {})
    if "models" in row and not _names(named):
        raise ValueError(f"{where}: models must be an array of names")
    if (
        not isinstance(ranges, dict)
        or ("ranges" in row and not ranges)
        or not all(
            isinstance(r, list) and len(r) == 2 and all(_number(v) for v in r) and r[0] <= r[1]
            for r in ranges.values()
        )
    ):
        raise ValueError(f"{where}: ranges must be {{ MODEL = [min, max] }}")
    if ranges and row.get("type", "u16") in ("bool", "string"):
        raise ValueError(f"{where}: a {row['type']} register takes no ranges")
    for model in [*named, *ranges]:
        if model not in models:
            raise ValueError(f"{where}: no model {model!r} in [device] models")


def _names(value: object) -> bool:
    """Whether ``value`` is a non-empty array of distinct non-empty names."""
    return (
        isinstance(value, list)
        and bool(value)
        and all(isinstance(m, str) and m.strip() for m in value)
        and len(set(value)) == len(value)
    )


def _number(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _register(path: str, index: int, row: dict[str, Any]) -> _Register:
    where = f"{path}: register {row.get('name', f'#{index + 1}')!r}"

    def fail(message: str) -> ValueError:
        return ValueError(f"{where}: {message}")

    unknown = set(row) - _REGISTER_KEYS
    if unknown:
        raise fail(f"unknown key(s) {', '.join(sorted(unknown))}")
    name = row.get("name")
    if not isinstance(name, str) or not name.isidentifier():
        raise fail("name must be a Python identifier")
    address = row.get("address")
    if isinstance(address, bool) or not isinstance(address, int) or not 0 <= address <= 0xFFFF:
        raise fail(f"address must be 0..0xFFFF, not {address!r}")
    table = row.get("table", "holding")
    if table not in _TABLES:
        raise fail(f"table must be one of {', '.join(_TABLES)}, not {table!r}")
    kind = row.get("type", "bool" if table in _BIT_TABLES else "u16")
    if kind not in _TYPES:
        raise fail(f"type must be one of {', '.join(_TYPES)}, not {kind!r}")
    if table in _BIT_TABLES and kind != "bool":
        raise fail(f"a {table} is a bool, not {kind}")
    order = row.get("order", "ABCD")
    if order not in _ORDERS:
        raise fail(f"order must be one of {', '.join(_ORDERS)}, not {order!r}")
    scale = row.get("scale", 1.0)
    offset = row.get("offset", 0.0)
    if not _number(scale) or scale == 0:
        raise fail(f"scale must be a non-zero number, not {scale!r}")
    if not _number(offset):
        raise fail(f"offset must be a number, not {offset!r}")
    if (scale != 1 or offset != 0) and kind in ("bool", "string"):
        raise fail(f"a {kind} takes no scale or offset")
    default_access = "r" if table in ("input", "discrete") else "rw"
    access = row.get("access", default_access)
    if access not in _ACCESS:
        raise fail(f"access must be one of {', '.join(_ACCESS)}, not {access!r}")
    if table in ("input", "discrete") and access != "r":
        raise fail(f"the {table} table is read-only: access must be 'r'")
    low, high = row.get("min"), row.get("max")
    for key, v in (("min", low), ("max", high)):
        if v is not None and (not _number(v) or kind in ("bool", "string")):
            raise fail(f"{key} must be a number on a numeric register, not {v!r}")
    if low is not None and high is not None and low > high:
        raise fail(f"min {low} is above max {high}")
    enum = row.get("enum")
    members: dict[int, str] | None = None
    if enum is not None:
        if kind not in ("u16", "i16", "u32", "i32") or scale != 1 or offset != 0:
            raise fail("an enum is an unscaled integer register")
        if not isinstance(enum, dict) or not enum:
            raise fail('enum must be a table { number = "name" }')
        members = {}
        named: set[str] = set()
        for key, member in enum.items():
            try:
                number = int(key, 0)
            except ValueError:
                raise fail(f"enum key {key!r} is not a number") from None
            if not isinstance(member, str) or not member.isidentifier():
                raise fail(f"enum member {member!r} is not a Python identifier")
            if member in named:
                raise fail(f"enum member {member!r} is used twice")
            members[number] = member
            named.add(member)
    bit = row.get("bit")
    if bit is not None:
        if kind != "bool" or table in _BIT_TABLES:
            raise fail("bit is for a bool on a holding or input register")
        if isinstance(bit, bool) or not isinstance(bit, int) or not 0 <= bit <= 15:
            raise fail(f"bit must be 0..15, not {bit!r}")
    bits = row.get("bits")
    if bits is not None:
        ints = isinstance(bits, list) and all(type(b) is int for b in bits)
        if not ints or len(bits) != 2 or not 0 <= bits[0] <= bits[1] <= 15:
            raise fail(f"bits must be [first, last], 0 <= first <= last <= 15, not {bits!r}")
        if kind != "u16" or table in _BIT_TABLES:
            raise fail("bits is for a u16 on a holding or input register")
        if "order" in row:
            raise fail("a field of bits has no byte order")
        top = (1 << (bits[1] - bits[0] + 1)) - 1
        if any(not 0 <= n <= top for n in members or {}):
            raise fail(f"an enum member does not fit bits {bits[0]}..{bits[1]}")
        ends = sorted((offset, top * scale + offset))
        given = [low, high, *(v for r in row.get("ranges", {}).values() for v in r)]
        slack = abs(scale) * 1e-6
        if any(v is not None and not ends[0] - slack <= v <= ends[1] + slack for v in given):
            raise fail(f"a range beyond what bits {bits[0]}..{bits[1]} hold ({ends[0]}..{ends[1]})")
        bits = (bits[0], bits[1])
    length = row.get("length")
    if kind == "string":
        if isinstance(length, bool) or not isinstance(length, int) or not 1 <= length <= 125:
            raise fail(f"a string takes length (registers) 1..125, not {length!r}")
    elif length is not None:
        raise fail("length is for a string")
    unit = row.get("unit", "")
    description = row.get("description", "")
    if not isinstance(unit, str) or not isinstance(description, str):
        raise fail("unit and description are strings")
    decimals = row.get("decimals")
    if decimals is not None and (
        not isinstance(decimals, str)
        or kind not in ("u16", "i16", "u32", "i32", "u64", "i64")
        or scale != 1
        or offset != 0
        or members is not None
        or bits is not None
    ):
        raise fail("decimals names a register, on a whole integer without scale, enum or bits")
    return _Register(
        name=name,
        address=address,
        table=table,
        type=kind,
        order=order,
        scale=float(scale),
        offset=float(offset),
        unit=unit,
        access=access,
        min=None if low is None else float(low),
        max=None if high is None else float(high),
        enum=members,
        bit=bit,
        bits=bits,
        length=length or 0,
        description=description,
        decimals=decimals,
    )


# ---- values and words -----------------------------------------------------------------------


def _swap(order: str, words: list[int]) -> list[int]:
    """Words most significant first (ABCD) in ``order``, or back: CDAB reverses the
    registers, BADC swaps the two bytes of each, DCBA both (each its own inverse)."""
    out = list(words)
    if order in ("CDAB", "DCBA"):
        out.reverse()
    if order in ("BADC", "DCBA"):
        out = [(w >> 8) | (w & 0xFF) << 8 for w in out]
    return out


def _ordered(reg: _Register, data: bytes) -> list[int]:
    """Big-endian bytes ``data`` as the register's words, in its order."""
    return _swap(
        reg.order, [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]
    )


def _unordered(reg: _Register, words: list[int]) -> bytes:
    """The register's words back as big-endian bytes."""
    return b"".join(w.to_bytes(2, "big") for w in _swap(reg.order, words))


def _gives_places(places: _Register | None, reg: _Register, ranges: Mapping[str, Any]) -> bool:
    """Whether ``places`` may give ``reg`` its decimal places: another readable register,
    an unscaled integer without places of its own, every value of which (its range on
    every model, ``ranges`` by register name, or its enum's numbers) is 0..9."""
    if places is None or places is reg or places.access == "w" or places.decimals:
        return False
    code = _NUMERIC.get(places.type, ("f", 0))[0]
    if code in "fd" or places.scaled:
        return False
    if places.enum is not None:
        return all(0 <= n <= 9 for n in places.enum)
    # The whole numbers its struct code holds: lower case signed.
    bits = 8 * struct.calcsize(code)
    signed = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    whole = (
        (0, places.field_top)
        if places.bits is not None
        else (signed if code.islower() else (0, 2**bits - 1))
    )
    low = whole[0] if places.min is None else places.min
    high = whole[1] if places.max is None else places.max
    spans = [(low, high), *ranges.get(places.name, {}).values()]
    return all(span[0] >= 0 and span[1] <= 9 for span in spans)


def _decode(reg: _Register, words: list[int]) -> Value:
    if reg.type == "bool":
        word = words[0]
        return bool(word >> reg.bit & 1) if reg.bit is not None else word != 0
    data = _unordered(reg, words)
    if reg.type == "string":
        return data.rstrip(b"\0").decode("latin-1")
    raw: int | float = struct.unpack(">" + _NUMERIC[reg.type][0], data)[0]
    if reg.bits is not None:
        raw = int(raw) >> reg.bits[0] & reg.field_top
    if reg.enum is not None:
        return reg.enum.get(int(raw), raw)
    if not reg.scaled:
        return raw
    return float(raw * reg.scale + reg.offset)


def _in_range(reg: _Register, value: Value) -> bool:
    if reg.enum is not None:
        return isinstance(value, str)
    if isinstance(value, (bool, str)):
        return True
    if isinstance(value, float) and not math.isfinite(value):
        return False
    # A little slack for the scale's rounding: 0.1 * 1250 is 125.00000000000001.
    slack = abs(reg.scale) * 1e-6
    if reg.min is not None and value < reg.min - slack:
        return False
    return not (reg.max is not None and value > reg.max + slack)


def _encode(reg: _Register, value: Value, current: list[int]) -> list[int]:
    if reg.type == "bool":
        if not isinstance(value, bool):
            raise TypeError(f"{reg.name} is True or False, not {value!r}")
        if reg.bit is None:
            return [int(value)]
        mask = 1 << reg.bit
        return [current[0] | mask if value else current[0] & ~mask]
    if reg.type == "string":
        if not isinstance(value, str):
            raise TypeError(f"{reg.name} is a string, not {value!r}")
        data = value.encode("latin-1")
        if len(data) > 2 * reg.length:
            raise ValueError(f"{reg.name} holds {2 * reg.length} characters, not {len(data)}")
        return _ordered(reg, data.ljust(2 * reg.length, b"\0"))
    if reg.enum is not None:
        by_name = {member: number for number, member in reg.enum.items()}
        if isinstance(value, str) and value in by_name:
            value = by_name[value]
        elif isinstance(value, bool) or not isinstance(value, int) or value not in reg.enum:
            raise ValueError(f"{reg.name} is one of {', '.join(by_name)}, not {value!r}")
    elif isinstance(value, (bool, str)) or not _number(value):
        raise TypeError(f"{reg.name} is a finite number, not {value!r}")
    elif not _in_range(reg, value):
        raise ValueError(f"{reg.name} is {reg.min}..{reg.max}, not {value!r}")
    code, _ = _NUMERIC[reg.type]
    raw: int | float = value
    if reg.scaled:
        raw = (value - reg.offset) / reg.scale
    if code not in "fd":
        raw = round(raw)
    if reg.bits is not None:
        first, top = reg.bits[0], reg.field_top
        if not 0 <= raw <= top:
            raise ValueError(f"{reg.name} does not fit bits {first}..{reg.bits[1]}: {value!r}")
        return [current[0] & ~(top << first) | int(raw) << first]
    try:
        data = struct.pack(">" + code, raw)
    except (struct.error, OverflowError):
        raise ValueError(f"{reg.name} does not fit a {reg.type}: {value!r}") from None
    return _ordered(reg, data)
