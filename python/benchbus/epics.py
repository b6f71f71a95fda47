"""benchbus devices as EPICS process variables, served over Channel Access and PV Access.

::

    import benchbus as bb
    from benchbus.epics import Ioc

    bus = bb.Bus("/dev/ttyUSB0")
    ioc = Ioc(period=0.5)
    ioc.add("LAB:XY:", bb.Device.from_profile("xy_md02.toml", bus, unit=1))
    ioc.add("LAB:SPINDLE:", bb.Drive(bus, 2))
    ioc.run()          # serves until SIGINT / SIGTERM; ioc.start() serves in the background

Every register of a device's profile becomes records named ``PREFIX`` + its name: an input
record for a read-only register, an output record for a writable one, plus an input record
``PREFIX`` + name + ``_RBV`` where it is also readable (``--read-only``: only the input
records). A family's actions (a drive's ``forward``, ``stop``...) are records whose
processing runs them, and each device has records of its own under ``PREFIX`` +
``ioc:`` (``connected``, ``polls``, ``failures``, ``error`` and its line's counters).

One poller per line reads each device's readable registers in the fewest requests its
limits allow, every ``period`` seconds, and pushes the values with the time of the read. A
failed read puts that device's input records into INVALID severity with COMM status until
the next good read. A put is checked against the register's range, steps and access before
anything is sent (a refused value leaves the record as it was); a refusal found while
writing (a family's rule, the device's exception, a lost line) restores the record's previous
value and raises its WRITE alarm, and the IOC's log says why.

Needs pythonSoftIOC (``pip install 'benchbus[epics]'``). Without it the module still
imports, and :class:`Ioc` raises an ImportError that says what to install. An EPICS IOC is
one per process, and its records exist before it starts.
"""

from __future__ import annotations

import atexit
import concurrent.futures
import contextlib
import dataclasses
import enum
import importlib
import ipaddress
import logging
import math
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, NoReturn, Protocol

from benchbus._core import CancelToken
from benchbus._device import MotorDevice, is_unknown, member_name
from benchbus._families import FAMILIES
from benchbus._record import check_seconds
from benchbus.exceptions import (
    BenchbusError,
    Cancelled,
    FrameError,
    GatewayError,
    ModbusException,
    PortError,
    ResponseTimeout,
)

if TYPE_CHECKING:
    from benchbus._core import Bus, Profile
    from benchbus._profile import ProfileRegister

__all__ = [
    "BOOL_STATES",
    "EGU_MAX",
    "IOC",
    "MBB_STATES",
    "MEMBER_NAME",
    "PV_NAME_MAX",
    "RBV",
    "STATE_MAX",
    "Ioc",
    "Pv",
    "ServedDevice",
    "loopback_env",
    "pvs",
    "serve_on",
]

log = logging.getLogger("benchbus.epics")

#: The longest PV name EPICS takes (a record's name).
PV_NAME_MAX = 60
#: The longest state string of an ``mbbi`` / ``mbbo`` record (longer names are shortened).
STATE_MAX = 25
#: The longest engineering unit (``EGU``; longer units are shortened).
EGU_MAX = 15
#: The longest text of a ``stringin`` / ``stringout`` record; longer strings get a long
#: string record.
STRING_MAX = 39
#: The longest description (``DESC``; longer ones are cut).
DESC_MAX = 40
#: The most states an ``mbbi`` / ``mbbo`` record has; an enum with more members is served as
#: its number (``longin`` / ``longout``) and its member's name (a string record, ``_STR``).
MBB_STATES = 16
#: Decimal places shown for a float register whose scale asks for none (``PREC``).
FLOAT_PRECISION = 3
#: The largest single-precision float: a float register's range when it declares none.
FLOAT32_MAX = 3.4028234663852886e38
#: The suffix of the readback of a writable register.
RBV = "_RBV"
#: The suffix of the record that names the member of an enum served as its number.
MEMBER_NAME = "_STR"
#: Where a device's own records go, after its prefix: a profile's names cannot hold ``:``.
IOC = "ioc:"
#: The names the state records of a bool register show, for 0 and 1.
BOOL_STATES = ("false", "true")


class ServedDevice(Protocol):
    """What :meth:`Ioc.add` serves: any benchbus device with its register table as
    ``profile``, registers read with ``get`` / ``get_many`` and written with ``set``, on a
    ``bus``."""

    @property
    def profile(self) -> Profile:
        """The device's registers (a :class:`benchbus.Profile`)."""
        ...

    @property
    def bus(self) -> Bus:
        """The Bus the device is on."""
        ...

    def get(self, name: str) -> Any:
        """The register ``name``, in engineering units."""
        ...

    def get_many(self, names: Iterable[str]) -> dict[str, Any]:
        """The registers ``names``, read in the fewest requests."""
        ...

    def set(self, name: str, value: Any) -> None:
        """Write ``value`` to the register ``name``."""
        ...


@dataclasses.dataclass
class Pv:
    """One record an :class:`Ioc` serves: its name, its kind and fields, and what it shows or
    does."""

    #: The PV name (the prefix included).
    name: str
    #: The builder function of ``softioc.builder`` that makes it (``"aIn"``, ``"mbbOut"``...).
    kind: str
    #: The record's fields (``EGU``, ``PREC``, ``LOPR``, ``HOPR``, ``ZNAM``...).
    fields: dict[str, Any] = dataclasses.field(default_factory=dict)
    #: The register it shows or writes (None: an action or a record of the device's own).
    register: str | None = None
    #: The device's method its processing runs (an action).
    action: str | None = None
    #: An mbb record's state strings.
    states: tuple[str, ...] = ()
    #: The enum number at each state index of an mbb record.
    numbers: tuple[int, ...] = ()
    #: Whether it shows the member's name of an enum served as its number.
    member_name: bool = False

    @property
    def output(self) -> bool:
        """Whether a client writes it (an output record)."""
        return self.kind.endswith("Out") or self.kind == "Action"

    @property
    def base(self) -> str:
        """Its kind without ``In`` / ``Out``: ``a``, ``long``, ``int64``, ``bool``, ``mbb``,
        ``string``, ``longString``, ``Action``."""
        return self.kind.removesuffix("In").removesuffix("Out")

    def shown(self, value: Any) -> Any:
        """A register's value as the record holds it; None for a value it cannot show (an
        enum's number the profile does not list)."""
        if is_unknown(value):
            return None
        if self.member_name:
            return (member_name(value) if isinstance(value, enum.Enum) else str(value))[:STRING_MAX]
        base = self.base
        if base == "mbb":
            number = int(value)
            return self.numbers.index(number) if number in self.numbers else None
        if base == "bool":
            return int(bool(value))
        if base in ("long", "int64"):
            return int(value)
        if base == "string":  # EPICS's text ends at its first NUL: so does the record's
            return _fit(str(value).split("\0", 1)[0], STRING_MAX)
        if base == "longString":
            return _fit(str(value).split("\0", 1)[0], int(self.fields["length"]) - 1)
        return float(value)

    def written(self, value: Any) -> Any:
        """What a put of ``value`` writes to the register (ValueError for an mbb state
        index that names no member)."""
        base = self.base
        if base == "mbb":
            index = int(value)
            if not 0 <= index < len(self.numbers):
                raise ValueError(f"{self.name}: state {index} names no member")
            return self.numbers[index]
        if base == "bool":
            return bool(value)
        if base in ("long", "int64"):
            return int(value)
        if base in ("string", "longString"):
            return str(value)
        return float(value)


def _fit(text: str, most: int) -> str:
    """``text`` cut to what ``most`` bytes of UTF-8 hold: EPICS counts a string's bytes."""
    data = text.encode()
    return text if len(data) <= most else data[:most].decode(errors="ignore")


def _shortened(text: str, most: int, what: str, warnings: list[str]) -> str:
    """``text`` cut to ``most`` bytes (:func:`_fit`), with a warning saying so."""
    fitted = _fit(text, most)
    if fitted != text:
        warnings.append(f"{what} {text!r} is longer than {most} bytes: shown as {fitted!r}")
    return fitted


def _states(register: ProfileRegister, warnings: list[str]) -> tuple[str, ...]:
    """The state strings of an enum register: its members' names, shortened to
    :data:`STATE_MAX` and kept apart (``~2``, ``~3``... where two would read the same)."""
    made: list[str] = []
    for name in register.enum.values():
        state = _shortened(name, STATE_MAX, f"{register.name}: state", warnings)
        copy = 2
        while state in made:
            state = _fit(name, STATE_MAX - len(f"~{copy}")) + f"~{copy}"
            copy += 1
        made.append(state)
    return tuple(made)


def _decimals(x: float) -> int:
    """The decimal places ``x`` needs (9 at most)."""
    for places in range(10):
        scaled = abs(x) * 10**places
        if math.isclose(scaled, round(scaled), abs_tol=1e-6):
            return places
    return 9


def _whole_type(register: ProfileRegister, low: float, high: float) -> bool:
    """Whether ``low..high`` is all its type holds (no range of its own to display)."""
    if register.type in ("f32", "f64"):
        return max(abs(low), abs(high)) >= FLOAT32_MAX
    whole = register.integer_range()
    return whole is not None and (float(low), float(high)) == (float(whole[0]), float(whole[1]))


def _places(register: ProfileRegister, profile: Profile) -> int:
    """The most decimal places a register with ``decimals`` may read with: the most its
    places register holds on any model (9 at most)."""
    given = profile[str(register.decimals)]
    tops = [given.max, *(high for _, high in given.ranges.values())]
    most = max(given.enum) if given.enum else max(t for t in tops if t is not None)
    return min(int(most), 9)


def _numeric(register: ProfileRegister, egu: str, profile: Profile) -> tuple[str, dict[str, Any]]:
    """The record kind of a number register and its fields (units, display limits, the
    precision its scale asks for; for a register with ``decimals``, the most places it may
    read with, and no display limits: its range is in digits whose places change)."""
    fields: dict[str, Any] = {"EGU": egu}
    if register.decimals is not None:
        return "a", {**fields, "PREC": _places(register, profile)}
    whole = register.integer_range()
    low, high = register.min, register.max
    if low is not None and high is not None and not _whole_type(register, low, high):
        fields["LOPR"], fields["HOPR"] = low, high
    if whole is not None:
        low, high = whole
        limits: dict[str, Any] = {k: int(fields[k]) for k in ("LOPR", "HOPR") if k in fields}
        if low >= -(2**31) and high < 2**31:
            return "long", {**fields, **limits, "MDEL": 0}
        if low >= -(2**63) and high < 2**63:
            return "int64", {**fields, **limits, "MDEL": 0}
    if register.type in ("f32", "f64") and register.scale == 1.0 and register.offset == 0.0:
        places = FLOAT_PRECISION
    else:
        places = max(_decimals(register.scale), _decimals(register.offset))
    return "a", {**fields, "PREC": places}


def _kinds(
    register: ProfileRegister, warnings: list[str], profile: Profile
) -> tuple[str, dict[str, Any]]:
    """The record kind (the builder's name without ``In`` / ``Out``) of a register and the
    fields both its records share."""
    fields: dict[str, Any] = {}
    if register.description:
        fields["DESC"] = _fit(register.description, DESC_MAX)
    if register.type == "bool":
        return "bool", {**fields, "ZNAM": BOOL_STATES[0], "ONAM": BOOL_STATES[1]}
    if register.type == "string":
        # Two Latin-1 characters a register, each up to two bytes of UTF-8, and a NUL.
        most = 2 * 2 * (register.length or 0)
        if most <= STRING_MAX:
            return "string", fields
        return "longString", {**fields, "length": most + 1}
    if register.enum and len(register.enum) <= MBB_STATES:
        return "mbb", fields
    egu = _shortened(register.unit, EGU_MAX, f"{register.name}: unit", warnings)
    kind, numeric = _numeric(register, egu, profile)
    return kind, {**fields, **numeric}


def pvs(
    prefix: str,
    profile: Profile,
    *,
    read_only: bool = False,
    actions: Sequence[str] = (),
    stats: Sequence[str] = (),
) -> tuple[list[Pv], list[str]]:
    """The records that serve a device of ``profile`` under ``prefix``, and warnings for
    what was shortened (state strings, units).

    ``actions``: the device's methods served as records whose processing runs them;
    ``stats``: its line's counters, served as ``PREFIX ioc:<name>``. ``read_only``: only
    the input records. ValueError for a PV name longer than :data:`PV_NAME_MAX`, naming the
    register.
    """
    made: list[Pv] = []
    warnings: list[str] = []
    for register in profile.registers:
        readable = register.access != "w"
        writable = register.access != "r"
        kind, fields = _kinds(register, warnings, profile)
        states: tuple[str, ...] = ()
        numbers: tuple[int, ...] = ()
        if kind == "mbb":
            numbers = tuple(register.enum)
            states = _states(register, warnings)
        name = prefix + register.name
        if writable and not read_only:
            made.append(Pv(name, kind + "Out", dict(fields), register.name, None, states, numbers))
        if readable:
            shown = name + RBV if writable else name
            made.append(Pv(shown, kind + "In", dict(fields), register.name, None, states, numbers))
            if register.enum and not states:
                made.append(
                    Pv(shown + MEMBER_NAME, "stringIn", register=register.name, member_name=True)
                )
    if not read_only:
        made += [Pv(prefix + a, "Action", action=a) for a in actions]
    own_records = [
        Pv(prefix + IOC + "connected", "boolIn", {"ZNAM": "disconnected", "ONAM": "connected"}),
        Pv(prefix + IOC + "polls", "longIn", {"MDEL": 0}),
        Pv(prefix + IOC + "failures", "longIn", {"MDEL": 0}),
        Pv(prefix + IOC + "error", "stringIn"),
        *(Pv(prefix + IOC + s, "longIn", {"MDEL": 0}) for s in stats),
    ]
    made += own_records
    named: dict[str, Pv] = {}
    for pv in made:
        other = named.setdefault(pv.name, pv)
        if other is not pv:
            both = [p.register or p.action or "the device's own" for p in (other, pv)]
            raise ValueError(f"{pv.name} would be two records ({both[0]} and {both[1]})")
        if len(pv.name) > PV_NAME_MAX:
            what = pv.register or pv.action or pv.name[len(prefix) :]
            raise ValueError(
                f"{what}: the PV name {pv.name!r} is {len(pv.name)} characters, over EPICS's "
                f"{PV_NAME_MAX}: give a shorter prefix"
            )
    return made, warnings


def _actions(device: object) -> tuple[str, ...]:
    """The actions of the family ``device`` belongs to (none for a profile's device)."""
    for f in FAMILIES:
        if f.device is not None and isinstance(device, f.device):
            return f.actions
    return ()


def _softioc() -> None:
    """Import pythonSoftIOC now; ImportError saying what to install."""
    try:
        importlib.import_module("softioc.softioc")
    except ImportError as exc:
        raise ImportError(
            f"benchbus.epics needs pythonSoftIOC: pip install 'benchbus[epics]' ({exc})",
            name="softioc",
        ) from exc


#: No value (a value may be None).
_NONE = object()

#: What a failed read or write on the line is (its records then show COMM).
_LINE_FAILURES = (BenchbusError, OSError)
#: The failures of the line itself, not a refusal by the device: a reply that did not
#: come or came spoiled, a lost port, a gateway whose device did not answer.
_ON_LINE = (ResponseTimeout, FrameError, PortError, GatewayError, Cancelled, OSError)
#: Polls a block the device refused is read one register a request (none of them refused
#: alone) before it is tried as one request again.
SPLIT_POLLS = 50


# softioc 4.7's records where its API says nothing (its version is pinned): the device
# support object behind a record (the builder's wrapper takes no attributes), the value VAL
# holds now (a put that came while a write was on the wire waits there, to be processed
# next), an alarm given without touching VAL, and EPICS's lock of a record.
def _support(record: Any) -> Any:
    """The softioc device support object of ``record``."""
    from softioc.device_core import LookupRecord

    return LookupRecord(record.name)


def _held_in_val(record: Any) -> Any:
    """What the output record's VAL holds now."""
    return record._epics_to_value(record._read_value(record._record))


def _alarm_now(record: Any, severity: int, status: int, value: Any = _NONE) -> None:
    """Give the output record this alarm as its processing ends, VAL untouched (a later
    put waiting there is not lost); ``value``: what softioc restores should that put be
    refused (default: what it has)."""
    support = _support(record)
    kept = support._value[0] if value is _NONE else support._value_to_epics(value)
    support._value = (kept, severity, status)
    support._record.NSEV = severity
    support._record.NSTA = status


@contextlib.contextmanager
def _locked(record: Any) -> Iterator[None]:
    """EPICS's lock of ``record`` (the one its processing holds), held in the block."""
    import ctypes

    from epicscorelibs.ioc import dbCore

    address = ctypes.c_void_p(_support(record)._record.record.value)
    dbCore.dbScanLock(address)
    try:
        yield
    finally:
        dbCore.dbScanUnlock(address)


def _running() -> bool:
    """Whether EPICS's ``iocInit`` ended with the IOC running (it returns no status of its
    own through softioc: ``interruptAccept`` is set once records may process)."""
    import ctypes

    from epicscorelibs.ioc import dbCore

    return bool(ctypes.c_int.in_dll(dbCore, "interruptAccept").value)


class _Served:
    """One device an IOC serves: its records, its poll and its writes."""

    def __init__(
        self,
        prefix: str,
        device: ServedDevice,
        made: list[Pv],
        period: float,
        stopping: threading.Event,
    ) -> None:
        self.prefix = prefix
        self.device = device
        self.pvs = made
        self.period = period
        self.profile = device.profile
        self.stopping = stopping
        self.records: dict[str, Any] = {}
        #: The value each output record's register holds, as the record shows it: the
        #: device's at the first good read, then each write that worked (what a refused
        #: write restores).
        self.good: dict[str, Any] = {}
        #: The output records a client has put to (the first read no longer sets them).
        self.put_to: set[str] = set()
        #: The value each output record is being given from the device (not written back).
        self.syncing: dict[str, Any] = {}
        self.inputs = [p for p in made if not p.output and p.register is not None]
        self.outputs = [p for p in made if p.output and p.register is not None]
        self.names = list(dict.fromkeys(p.register for p in self.inputs if p.register))
        #: The registers read one a request: the device refused them when read alone.
        self.alone: set[str] = set()
        #: Polls left before a block the device refused is tried as one request again.
        self.split = 0
        self.polls = 0
        self.failures = 0
        self.connected: bool | None = None
        #: What each input record shows: (value, severity, status).
        self.held: dict[str, tuple[Any, int, int]] = {}

    def show(
        self, name: str, value: Any, severity: int = 0, status: int = 0, when: float | None = None
    ) -> None:
        """Give the input record ``name`` ``value`` (None: the one it has) and an alarm,
        stamped ``when``, if that changes what it shows: a record processes, and its
        monitors fire, on a change only (so its time is that of the read that changed it)."""
        held = self.held.get(name)
        if value is None and held is not None:
            value = held[0]
        if held == (value, severity, status):
            return
        record = self.records[name]
        if value is None:
            record.set_alarm(severity, status, timestamp=when)
        else:
            record.set(value, severity=severity, alarm=status, timestamp=when)
        self.held[name] = (value, severity, status)

    def own(self, name: str, value: Any) -> None:
        """Show ``value`` in the device's own record ``ioc:<name>``."""
        self.show(self.prefix + IOC + name, value)

    def read(self) -> tuple[dict[str, Any], dict[str, BaseException]]:
        """The readable registers' values, and the registers the device refused with the
        exception it gave; a failure of the line (a gateway's exception among them) is
        raised."""
        values: dict[str, Any] = {}
        refused: dict[str, BaseException] = {}
        alone = set(self.alone) if self.split <= 0 else set(self.names)
        self.split -= 1
        together = [n for n in self.names if n not in alone]
        if together:
            try:
                values.update(self.device.get_many(together))
            except GatewayError:
                raise
            except ModbusException:
                alone.update(together)  # this time, one a request: which one is refused?
                self.split = SPLIT_POLLS
        for name in self.names:
            if name in alone:
                try:
                    values[name] = self.device.get(name)
                except GatewayError:
                    raise
                except ModbusException as exc:
                    refused[name] = exc
        if refused:
            self.split = 0  # the refused ones alone, the others together again
        self.alone = set(refused)
        return values, refused

    def poll(self, alarm: Any) -> None:
        """Read the device once and show what was read (or the failure) in its records."""
        try:
            values, refused = self.read()
        except Cancelled:
            return  # the IOC is stopping
        except _LINE_FAILURES as exc:
            self.failed(exc, alarm)
            return
        when = time.time()
        self.polls += 1
        for pv in self.inputs:
            if pv.register in refused:
                self.show(pv.name, None, alarm.INVALID_ALARM, alarm.READ_ALARM, when)
                continue
            value = pv.shown(values[pv.register or ""])
            if value is None:  # an enum number the profile does not list
                self.show(pv.name, None, alarm.INVALID_ALARM, alarm.STATE_ALARM, when)
            else:
                self.show(pv.name, value, when=when)
        for pv in self.outputs:
            if pv.register in values and pv.name not in self.put_to:
                self.sync(pv, pv.shown(values[pv.register or ""]))
        if not self.connected:
            if self.connected is False:
                log.info("%s is answering again", self.prefix)
            self.connected = True
            self.own("connected", 1)
            self.own("error", "")
        self.counters()

    def sync(self, pv: Pv, value: Any) -> None:
        """Give the output record ``pv`` the device's ``value`` once, at the first good
        read, without writing it back: processed (its UDF alarm cleared), its check and its
        write skipped for that one value."""
        if value is None or (isinstance(value, float) and not math.isfinite(value)):
            return
        record = self.records[pv.name]
        with _locked(record):  # no client's put comes between the test and the set
            if pv.name in self.put_to or _support(record)._record.PACT:
                return
            self.put_to.add(pv.name)
            self.good[pv.name] = value
            self.syncing[pv.name] = value
            record.set(value, process=False)  # stored with no alarm: processing clears UDF
            record.set(value)

    def check(self, pv: Pv, value: Any) -> bool:
        """softioc's validate of a put: the core's checks of the write, nothing sent."""
        if self.syncing.get(pv.name, _NONE) == value:
            return True
        if self.stopping.is_set():
            log.warning("%s: put %r refused: the IOC is stopping", pv.name, value)
            return False
        if pv.register is not None:
            try:
                self.profile.check(pv.register, pv.written(value))
            except (ValueError, TypeError) as exc:
                log.warning("%s: put %r refused before sending: %s", pv.name, value, exc)
                return False
        self.put_to.add(pv.name)
        return True

    def write(self, pv: Pv, value: Any, alarm: Any) -> None:
        """Write a put of ``value`` to the device (or run the action), on the line's one
        writer thread, in the order of the puts; a refusal: :meth:`refuse`. A write that
        works clears the record's alarm."""
        if self.syncing.get(pv.name, _NONE) == value:
            del self.syncing[pv.name]
            return
        self.syncing.pop(pv.name, None)
        try:
            if self.stopping.is_set():
                raise Cancelled("the IOC is stopping")
            if pv.action is not None:
                getattr(self.device, pv.action)()
            elif pv.register is not None:
                self.device.set(pv.register, pv.written(value))
        except Exception as exc:  # whatever stopped the write, the record says so
            self.refuse(pv, value, exc, alarm)
            return
        if pv.action is None:
            self.good[pv.name] = value
        _alarm_now(self.records[pv.name], alarm.NO_ALARM, alarm.NO_ALARM)

    def refuse(self, pv: Pv, value: Any, exc: BaseException, alarm: Any) -> None:
        """A put of ``value`` not written: the record back at the register's value (a later
        put waiting in it stays) with a WRITE alarm, MAJOR where the device or its family's
        rule said no, INVALID where the line failed (the write may have been done); the log
        says why. Nothing is sent."""
        severity = alarm.INVALID_ALARM if isinstance(exc, _ON_LINE) else alarm.MAJOR_ALARM
        log.warning("%s: put %r refused: %s: %s", pv.name, value, type(exc).__name__, exc)
        previous = 0 if pv.action is not None else self.good.get(pv.name)
        record = self.records[pv.name]
        with _locked(record):
            if previous is not None and _held_in_val(record) == value:
                record.set(previous, process=False, severity=severity, alarm=alarm.WRITE_ALARM)
            elif previous is not None:  # a later put waits in VAL: softioc's value is restored
                _alarm_now(record, severity, alarm.WRITE_ALARM, previous)
            else:  # no value of the device is known (a write-only register)
                _alarm_now(record, severity, alarm.WRITE_ALARM)

    def failed(self, exc: BaseException, alarm: Any) -> None:
        """A read failed on the line: every input record INVALID / COMM, at once."""
        self.failures += 1
        text = f"{type(exc).__name__}: {exc}"
        if self.connected is not False:
            log.warning("%s does not answer: %s", self.prefix, text)
        self.connected = False
        for pv in self.inputs:
            self.show(pv.name, None, alarm.INVALID_ALARM, alarm.COMM_ALARM)
        self.own("connected", 0)
        self.own("error", _fit(text, STRING_MAX))
        self.counters()

    def counters(self) -> None:
        """The device's poll counters and its line's counters, in their records."""
        self.own("polls", self.polls)
        self.own("failures", self.failures)
        try:
            stats = self.device.bus.stats.as_dict()
        except _LINE_FAILURES:
            return
        for name, count in stats.items():
            if self.prefix + IOC + name in self.records:
                self.own(name, min(count, 2**31 - 1))


def _loopback(addresses: str) -> bool:
    """Whether every address of an ``EPICS_*_INTF_ADDR_LIST`` is a loopback one."""
    listed = addresses.split()  # none: EPICS serves on every interface
    try:
        return bool(listed) and all(ipaddress.ip_address(a).is_loopback for a in listed)
    except ValueError:
        return False


def serve_on(interface: str | None) -> str:
    """Set the addresses the Channel Access and PV Access servers listen on: ``interface``;
    absent, the standard ``EPICS_CAS_INTF_ADDR_LIST`` / ``EPICS_PVAS_INTF_ADDR_LIST`` if set,
    else loopback (with beacons to loopback too). The address served on (a warning, once,
    when it is beyond loopback)."""
    if interface is not None:
        os.environ["EPICS_CAS_INTF_ADDR_LIST"] = interface
        os.environ["EPICS_PVAS_INTF_ADDR_LIST"] = interface
    elif not os.environ.get("EPICS_CAS_INTF_ADDR_LIST"):
        os.environ["EPICS_CAS_INTF_ADDR_LIST"] = "127.0.0.1"
        os.environ.setdefault("EPICS_PVAS_INTF_ADDR_LIST", "127.0.0.1")
    served = os.environ["EPICS_CAS_INTF_ADDR_LIST"]
    pva = os.environ.setdefault("EPICS_PVAS_INTF_ADDR_LIST", served)
    if _loopback(served) and _loopback(pva):
        os.environ.setdefault("EPICS_CAS_AUTO_BEACON_ADDR_LIST", "NO")
        os.environ.setdefault("EPICS_CAS_BEACON_ADDR_LIST", "127.255.255.255")
        os.environ.setdefault("EPICS_PVAS_AUTO_BEACON_ADDR_LIST", "NO")
        os.environ.setdefault("EPICS_PVAS_BEACON_ADDR_LIST", "127.255.255.255")
    else:
        log.warning(
            "serving EPICS on %s (Channel Access) and %s (PV Access), beyond loopback: "
            "any host that reaches them may read and write the devices "
            "(see --read-only and --access-security)",
            served,
            pva,
        )
    return served


def _free_port() -> int:
    """A port free on loopback for both TCP and UDP now (Channel Access takes both)."""
    while True:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as tcp:
            tcp.bind(("127.0.0.1", 0))
            port = int(tcp.getsockname()[1])
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
                try:
                    udp.bind(("127.0.0.1", port))
                except OSError:
                    continue  # taken for UDP: another
        return port


def loopback_env(*also: Mapping[str, str]) -> dict[str, str]:
    """EPICS's variables for an IOC and its clients on this machine alone, on ports no
    other IOC uses (free ones, picked now): for tests and benchmarks that run IOCs side by
    side. Give them to the IOC's process (``benchbus ioc``) and to its clients.

    ``also``: the variables of other IOCs this one's clients should find too (their
    Channel Access ports are added to its ``EPICS_CA_ADDR_LIST``)::

        first, second = loopback_env(), loopback_env()
        clients = loopback_env(first, second)   # finds both over Channel Access
    """
    ca, pva, broadcast = _free_port(), _free_port(), _free_port()
    servers = [f"127.0.0.1:{ca}", *(e["EPICS_CA_ADDR_LIST"] for e in also)]
    return {
        "EPICS_CAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_CA_ADDR_LIST": " ".join(servers),
        "EPICS_CA_AUTO_ADDR_LIST": "NO",
        "EPICS_CA_SERVER_PORT": str(ca),
        "EPICS_CA_REPEATER_PORT": str(_free_port()),
        "EPICS_CAS_AUTO_BEACON_ADDR_LIST": "NO",
        "EPICS_CAS_BEACON_ADDR_LIST": "127.255.255.255",
        "EPICS_PVAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_PVA_ADDR_LIST": "127.0.0.1",
        "EPICS_PVA_AUTO_ADDR_LIST": "NO",
        "EPICS_PVAS_SERVER_PORT": str(pva),
        "EPICS_PVA_SERVER_PORT": str(pva),
        "EPICS_PVAS_BROADCAST_PORT": str(broadcast),
        "EPICS_PVA_BROADCAST_PORT": str(broadcast),
    }


class Ioc:
    """An EPICS IOC in this process that serves benchbus devices as process variables.

    ``period``: seconds between two reads of a device (each device may have its own);
    ``read_only``: serve only input records (a writable register's ``_RBV``);
    ``interface``: the address to serve on (default loopback, or the standard
    ``EPICS_CAS_INTF_ADDR_LIST``); ``access_security``: an EPICS access-security file.

    An IOC is one per process (a second raises RuntimeError), and its records exist before
    it starts: :meth:`add` every device, then :meth:`start` (serves in the background) or
    :meth:`run` (serves until SIGINT or SIGTERM, then stops the motors, closes the ports and
    ends the process). ImportError, saying what to install, without pythonSoftIOC.
    """

    _made: ClassVar[bool] = False

    def __init__(
        self,
        period: float = 1.0,
        *,
        read_only: bool = False,
        interface: str | None = None,
        access_security: str | os.PathLike[str] | None = None,
    ) -> None:
        """An IOC with nothing to serve yet."""
        #: Seconds between two reads of a device that has no period of its own.
        self.period = check_seconds("period", period)
        if interface is not None and not isinstance(interface, str):
            raise TypeError(f"interface must be an address (str), got {type(interface).__name__}")
        if interface is not None and not interface.split():
            raise ValueError("interface must name an address, got an empty one")
        if access_security is not None and not os.path.isfile(access_security):
            raise FileNotFoundError(f"no access-security file {os.fspath(access_security)!r}")
        _softioc()
        if Ioc._made:
            raise RuntimeError(
                "an EPICS IOC is one per process and this process has one: serve every "
                "device from it (run another IOC in a process of its own)"
            )
        Ioc._made = True
        #: Whether only input records are served.
        self.read_only = read_only
        self._interface = interface
        self._security = None if access_security is None else os.fspath(access_security)
        self._served: list[_Served] = []
        self._names: dict[str, str] = {}
        self._started = False
        self._stopping = threading.Event()
        #: The pollers' reads and the writers' writes are made under these: stopping
        #: cancels their further attempts.
        self._reads = CancelToken()
        self._writes = CancelToken()
        self._pollers: list[threading.Thread] = []
        #: Each line's writer: one thread, so puts reach the line in the order they came.
        self._writers: dict[int, concurrent.futures.ThreadPoolExecutor] = {}
        self._stopped = False

    @property
    def started(self) -> bool:
        """Whether the IOC serves (its records are fixed)."""
        return self._started

    @property
    def names(self) -> list[str]:
        """Every PV name served, in the order the records were added."""
        return list(self._names)

    def add(self, prefix: str, device: ServedDevice, *, period: float | None = None) -> None:
        """Serve ``device`` under ``prefix`` (``"LAB:XY:"``), read every ``period`` seconds
        (default: the IOC's).

        RuntimeError once the IOC has started; TypeError for a device without a profile;
        ValueError for a PV name over :data:`PV_NAME_MAX` characters or one served
        already. What is shortened (state strings, units) is logged as a warning."""
        if self._started:
            raise RuntimeError(
                "the IOC has started and EPICS takes no records after that: add() every "
                "device before start()"
            )
        if not isinstance(prefix, str) or not prefix:
            raise ValueError(f"prefix must be a non-empty str, got {prefix!r}")
        every = self.period if period is None else check_seconds("period", period)
        profile = getattr(device, "profile", None)
        if profile is None or not callable(getattr(device, "get_many", None)):
            raise TypeError(
                f"{type(device).__name__} has no register table to serve: give a device with a "
                "profile (bb.Device.from_profile, bb.Drive, bb.PblDrive, bb.J2Controller)"
            )
        stats = tuple(device.bus.stats.as_dict())
        made, warnings = pvs(
            prefix, profile, read_only=self.read_only, actions=_actions(device), stats=stats
        )
        for pv in made:
            if pv.name in self._names:
                raise ValueError(f"{pv.name} is served already (by {self._names[pv.name]})")
        for text in warnings:
            log.warning("%s%s", prefix, text)
        for pv in made:
            self._names[pv.name] = (
                f"{prefix} {type(device).__name__} unit {getattr(device, 'unit', None)}"
            )
        self._served.append(_Served(prefix, device, made, every, self._stopping))

    def start(self) -> None:
        """Make the records, start the IOC serving them and the pollers reading the
        devices, in the background. RuntimeError if started already or with nothing
        added."""
        if self._started:
            raise RuntimeError("the IOC has started already")
        if not self._served:
            raise RuntimeError("nothing to serve: add() a device before start()")
        serve_on(self._interface)
        _softioc()
        from softioc import alarm, asyncio_dispatcher, builder, softioc

        self._alarm = alarm
        for served in self._served:
            line = id(served.device.bus)
            if line not in self._writers:
                self._writers[line] = concurrent.futures.ThreadPoolExecutor(
                    1, thread_name_prefix="benchbus-ioc-writer"
                )
            for pv in served.pvs:
                served.records[pv.name] = self._record(builder, served, pv)
                if pv.kind == "longStringOut":  # softioc starts it at "": nothing known yet
                    served.records[pv.name].set(
                        "", severity=alarm.INVALID_ALARM, alarm=alarm.UDF_ALARM
                    )
        builder.LoadDatabase()
        if self._security is not None:
            from epicscorelibs.ioc import dbCore

            dbCore.asSetFilename(self._security.encode())
        self._dispatcher = asyncio_dispatcher.AsyncioDispatcher()
        softioc.iocInit(self._dispatcher)
        if not _running():
            raise RuntimeError(
                "the IOC did not start (EPICS said why above: an access-security file it "
                "cannot read?); nothing is served"
            )
        self._started = True
        atexit.register(self.stop)
        for served in self._served:  # nothing read yet: no value to trust
            for pv in served.inputs:
                served.show(pv.name, None, alarm.INVALID_ALARM, alarm.UDF_ALARM)
        lines: dict[int, list[_Served]] = {}
        for served in self._served:
            lines.setdefault(id(served.device.bus), []).append(served)
        for on_line in lines.values():
            poller = threading.Thread(
                target=self._poll, args=(on_line,), name="benchbus-ioc-poller", daemon=True
            )
            self._pollers.append(poller)
            poller.start()

    def _record(self, builder: Any, served: _Served, pv: Pv) -> Any:
        """The softioc record of ``pv``: an output record checks a put (softioc's
        ``validate``) and hands it to its line's writer; the put completes (a client's
        put-callback returns) once the write is over. Every put is written, also one of
        the value the record shows."""
        make: Callable[..., Any] = getattr(builder, pv.kind)
        fields = {k: v for k, v in pv.fields.items() if v not in (None, "")}
        if not pv.output:
            return make(pv.name, *pv.states, **fields)
        writer = self._writers[id(served.device.bus)]

        def write(value: Any) -> None:
            with self._writes:
                served.write(pv, value, self._alarm)

        async def put(value: Any) -> None:
            import asyncio

            try:
                await asyncio.get_running_loop().run_in_executor(writer, write, value)
            except RuntimeError:  # the writer has shut down: the IOC is stopping
                served.refuse(pv, value, Cancelled("the IOC is stopping"), self._alarm)

        if pv.kind == "Action":
            return make(pv.name, on_update=put, blocking=True, initial_value=0)
        return make(
            pv.name,
            *pv.states,
            validate=lambda _record, value: served.check(pv, value),
            on_update=put,
            blocking=True,
            always_update=True,
            **fields,
        )

    def _poll(self, served: list[_Served]) -> None:
        """One line's poller: each device read on its own absolute deadlines."""
        with self._reads:
            self._poll_on_line(served)

    def _poll_on_line(self, served: list[_Served]) -> None:
        """:meth:`_poll`'s loop, under the pollers' token."""
        start = time.monotonic()
        due = {id(s): start for s in served}
        while not self._stopping.is_set():
            device = min(served, key=lambda s: due[id(s)])
            wait = due[id(device)] - time.monotonic()
            if wait > 0 and self._stopping.wait(wait):
                return
            try:
                device.poll(self._alarm)
            except Exception:  # a poller must outlive any one read
                log.exception("%s: reading the device failed", device.prefix)
            now = time.monotonic()
            due[id(device)] += device.period * max(
                1, math.ceil((now - due[id(device)]) / device.period)
            )

    def stop(self) -> None:
        """Refuse further puts, finish the writes on the wire, stop the motors served (as a
        ``with`` block does), stop the pollers and close the devices' ports. The records
        stay served until the process ends (EPICS cannot stop an IOC), their input records
        INVALID with DISABLE status (no longer read); idempotent."""
        if self._stopped:
            return
        self._stopped = True
        self._stopping.set()  # puts are refused from now on
        self._reads.cancel()  # no read starts an attempt now
        self._writes.cancel()  # nor a write; the one on the wire ends before the stops
        for writer in self._writers.values():
            writer.shutdown(wait=True)  # the puts queued are refused, each at once
        for served in self._served:
            if isinstance(served.device, MotorDevice):
                try:
                    served.device._stop_on_exit(urgent=True)
                except Exception as exc:
                    log.error("%s: could not stop the motor: %s", served.prefix, exc)
        deadline = time.monotonic() + 1.5
        for poller in self._pollers:
            poller.join(max(0.0, deadline - time.monotonic()))
        for served in self._served:
            try:
                served.device.bus.close()
            except _LINE_FAILURES as exc:
                log.debug("closing %s: %s", served.prefix, exc)
            for pv in served.inputs:  # no longer read: no value to trust
                served.show(pv.name, None, self._alarm.INVALID_ALARM, self._alarm.DISABLE_ALARM)

    def run(self, *, shell: bool = False) -> NoReturn:
        """Start (if not started) and serve until SIGINT or SIGTERM, then :meth:`stop` and end
        the process (EPICS ends it: Python's own clean-up does not run, so the stop
        happens here). ``shell``: an interactive Python shell with EPICS's commands
        (``dbl()``...) and ``ioc`` meanwhile; leaving it ends the IOC. From the main
        thread."""
        if not self._started:
            self.start()
        from softioc import softioc

        quit = threading.Event()

        def on_signal(signum: int, _frame: Any) -> None:
            if shell:
                self.stop()
                softioc.safeEpicsExit(0)
            quit.set()

        signal.signal(signal.SIGTERM, on_signal)
        try:
            if shell:
                softioc.interactive_ioc({"ioc": self}, call_exit=False)
            else:
                signal.signal(signal.SIGINT, on_signal)
                quit.wait()
        except SystemExit:  # exit() in the shell
            pass
        finally:
            self.stop()
            softioc.safeEpicsExit(0)
        raise SystemExit(0)  # not reached: EPICS has ended the process
