"""Bad input (issue 9, item 5): every public method and property of Bus, Poll, Drive,
PblDrive, J2Controller and Instrument refuses wrong types, out-of-range values, NaN and
infinities, huge ints, negative units, empty lists and unknown names with a ValueError or
TypeError whose message names the argument, and sends nothing: the simulator's request log
is the same after the call as before it.

The cases are one table. Three kinds are made from the classes themselves, so that a new
property or method cannot be forgotten: every register-backed property is set to junk and to
just outside the range in the device's own register table; every method without arguments is
called with one (TypeError); every read-only property is assigned (AttributeError, which is
what Python raises for that). The rest are written out below, and
``test_every_public_name_is_covered`` checks that together they reach every public name that
``dir()`` lists but an explicit allow-list.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import re
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus._device import MeasuredProperty, RegisterProperty
from benchbus.sim import (
    DriveDevice,
    J2Device,
    PblDevice,
    ProfileDevice,
    SimDevice,
    Simulator,
    TaisongDevice,
)

NAN, INF = math.nan, math.inf
#: An int far too big for any register, a u64, or PyO3's conversions.
HUGE = 2**70
#: A profile with every kind of value: floats in two orders, enums, strings, 64-bit values.
CONTROLLER = str(
    Path(__file__).resolve().parent.parent / "examples" / "profiles" / "flow_controller.toml"
)


class _Placeholder:
    """An argument filled in when the case runs (the test's Bus, a register's range...)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return self.name


BUS = _Placeholder("bus")  # the module's Bus
PORT = _Placeholder("port")  # its port, held open by that Bus
BELOW = _Placeholder("below")  # the property's register's lowest value, minus 1
ABOVE = _Placeholder("above")  # its highest value, plus 1

#: The classes under test; "C20" is a Drive made for the C20 family (BLD-only things refused).
OWNERS: dict[str, type] = {
    "Bus": bb.Bus,
    "Poll": bb.Poll,
    "Drive": bb.Drive,
    "C20": bb.Drive,
    "PblDrive": bb.PblDrive,
    "J2Controller": bb.J2Controller,
    "Instrument": bb.Instrument,
    "Device": bb.Device,
}

#: Public names that take no input at all, so have nothing to refuse.
ALLOWED: dict[str, str] = {
    "LINE_DEFAULTS": "a class constant: the family's line format, not an input",
    "SAMPLE_FIELDS": "a class constant: the names sample() gives, not an input",
    "IDENTITY": "a class constant: the family the device checks its unit is of, not an input",
}


def _show(value: Any) -> str:
    if type(value) is int and abs(value) == HUGE:
        return "-2**70" if value < 0 else "2**70"
    if type(value) is int and value > 2**100:
        return f"2**{value.bit_length() - 1}"
    return repr(value)


@dataclasses.dataclass(frozen=True)
class Case:
    """One bad call: ``owner.member(*args, **kwargs)`` (or ``owner.member = args[0]``)."""

    owner: str
    member: str  # "__init__" for the constructor
    args: tuple[Any, ...]
    kwargs: Mapping[str, Any]
    exc: type[Exception]
    names: str  # a regex the message (notes included) must match: what it is about
    assign: bool = False

    @property
    def id(self) -> str:
        if self.assign:
            return f"{self.owner}.{self.member}={_show(self.args[0])}"
        shown = [_show(a) for a in self.args]
        shown += [f"{k}={_show(v)}" for k, v in self.kwargs.items()]
        return f"{self.owner}.{self.member}({', '.join(shown)})"


class A:
    """The arguments of one call: ``A(1, 0, count=2)``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


def calls(owner: str, member: str, exc: type[Exception], names: str, *each: A) -> list[Case]:
    """Cases calling ``owner.member`` with each of the arguments ``each``, all raising
    ``exc`` with a message that matches ``names``."""
    return [Case(owner, member, a.args, a.kwargs, exc, names) for a in each]


def sets(owner: str, member: str, exc: type[Exception], names: str, *values: Any) -> list[Case]:
    """Cases setting ``owner.member`` to each of ``values``, all raising ``exc`` with a
    message that matches ``names``."""
    return [Case(owner, member, (v,), {}, exc, names, assign=True) for v in values]


# ---- the cases written out: methods with arguments, constructors, properties with setters ----

EXPLICIT: list[Case] = [
    # -- Bus: arguments are checked before the port is opened (it is held: PortError if not)
    *calls("Bus", "__init__", TypeError, "port", A(5), A(None)),
    *calls("Bus", "__init__", ValueError, "port", A("")),
    *calls("Bus", "__init__", ValueError, "baudrate", A(PORT, HUGE), A(PORT, 0), A(PORT, -9600)),
    *calls("Bus", "__init__", TypeError, "baudrate", A(PORT, "19200"), A(PORT, 19200.0)),
    *calls("Bus", "__init__", ValueError, "parity", A(PORT, parity="X"), A(PORT, parity="")),
    *calls("Bus", "__init__", TypeError, "parity", A(PORT, parity=1)),
    *calls("Bus", "__init__", ValueError, "stopbits", A(PORT, stopbits=3), A(PORT, stopbits=0)),
    *calls("Bus", "__init__", TypeError, "stopbits", A(PORT, stopbits="1")),
    *calls(
        "Bus",
        "__init__",
        ValueError,
        "timeout",
        *(A(PORT, timeout=t) for t in (0, -1, NAN, INF, HUGE, 2**1100)),
    ),
    *calls("Bus", "__init__", TypeError, "timeout", A(PORT, timeout="fast")),
    *calls("Bus", "__init__", ValueError, "retries", A(PORT, retries=-1), A(PORT, retries=HUGE)),
    *calls("Bus", "__init__", TypeError, "retries", A(PORT, retries=1.5)),
    *sets("Bus", "timeout", ValueError, "timeout", 0, -1, NAN, INF, 3601, HUGE),
    *sets("Bus", "timeout", TypeError, "timeout", "1", None, True, [1]),
    *sets("Bus", "retries", ValueError, "retries", -1, 101, HUGE),
    *sets("Bus", "retries", TypeError, "retries", 1.5, "2", None, True, NAN),
    *calls(
        "Bus", "__init__", ValueError, "turnaround", A(PORT, turnaround=-1), A(PORT, turnaround=NAN)
    ),
    *calls("Bus", "__init__", TypeError, "reconnect", A(PORT, reconnect="yes")),
    *calls("Bus", "__init__", TypeError, "echo", A(PORT, echo=1), A(PORT, echo="yes")),
    *calls("Bus", "__init__", TypeError, "baud", A(PORT, baud=9600)),  # unknown keyword
    *calls(
        "Bus",
        "read_holding_registers",
        ValueError,
        "unit",
        *(A(u, 0, 1) for u in (-1, 0, 256, HUGE, -HUGE)),
    ),
    *calls(
        "Bus",
        "read_holding_registers",
        TypeError,
        "unit",
        *(A(u, 0, 1) for u in ("1", 1.0, None, True)),
    ),
    *calls("Bus", "read_holding_registers", ValueError, "address", A(1, -1, 1), A(1, 0x10000, 1)),
    *calls("Bus", "read_holding_registers", ValueError, "address", A(1, HUGE, 1), A(1, 0xFFFF, 2)),
    *calls("Bus", "read_holding_registers", TypeError, "address", A(1, NAN, 1), A(1, "0", 1)),
    *calls("Bus", "read_holding_registers", ValueError, "count", A(1, 0, 0), A(1, 0, 126)),
    *calls("Bus", "read_holding_registers", ValueError, "count", A(1, 0, HUGE), A(1, 0, -1)),
    *calls("Bus", "read_holding_registers", TypeError, "count", A(1, 0, 1.0), A(1, 0, True)),
    *calls("Bus", "write_register", ValueError, "unit", A(-1, 0, 0), A(HUGE, 0, 0)),
    *calls("Bus", "write_register", ValueError, "address", A(1, -1, 0), A(1, HUGE, 0)),
    *calls("Bus", "write_register", ValueError, "value", A(1, 0, -1), A(1, 0, 0x10000)),
    *calls("Bus", "write_register", ValueError, "value", A(1, 0, HUGE), A(1, 0, -HUGE)),
    *calls(
        "Bus",
        "write_register",
        TypeError,
        "value",
        *(A(1, 0, v) for v in (NAN, INF, 1.5, "1", None, b"\x01")),
    ),
    *calls(
        "Bus",
        "write_register",
        TypeError,
        "accept_count_echo",
        A(1, 0, 0, accept_count_echo="yes"),
        A(1, 0, 0, accept_count_echo=1),
    ),
    *calls("Bus", "write_registers", ValueError, "unit", A(-1, 0, [1]), A(0, 0, [1])),
    *calls("Bus", "write_registers", ValueError, "values", A(1, 0, []), A(1, 0, [0] * 124)),
    *calls("Bus", "write_registers", ValueError, "value", A(1, 0, [HUGE]), A(1, 0, [1, -1])),
    *calls("Bus", "write_registers", TypeError, "value", A(1, 0, [NAN]), A(1, 0, [1, None])),
    *calls(
        "Bus",
        "write_registers",
        TypeError,
        "values",
        *(A(1, 0, v) for v in ("12", b"12", None, 5)),
    ),
    *calls("Bus", "write_registers", ValueError, "address", A(1, 0xFFFF, [1, 2])),
    *calls(
        "Bus",
        "write_register",
        ValueError,
        "write_interval",
        A(1, 0, 0, write_interval=-0.1),
        A(1, 0, 0, write_interval=61),
        A(1, 0, 0, write_interval=NAN),
    ),
    *calls("Bus", "write_registers", TypeError, "write_interval", A(1, 0, [1], write_interval="x")),
    *calls("Bus", "write_registers", ValueError, "timeout", A(1, 0, [1], timeout=0)),
    *calls("Bus", "write_registers", TypeError, "retries", A(1, 0, [1], retries=1.5)),
    *calls(
        "Bus",
        "write_register",
        ValueError,
        "timeout",
        A(1, 0, 1, timeout=-1),
        A(1, 0, 1, timeout=NAN),
    ),
    *calls("Bus", "write_register", TypeError, "timeout", A(1, 0, 1, timeout="1")),
    *calls("Bus", "write_register", ValueError, "retries", A(1, 0, 1, retries=101)),
    *calls("Bus", "write_register", TypeError, "retries", A(1, 0, 1, retries=True)),
    *calls("Bus", "request", ValueError, "timeout", A(1, 3, b"\0\0\0\1", timeout=3601)),
    *calls("Bus", "request", ValueError, "retries", A(1, 3, b"\0\0\0\1", retries=-1)),
    *calls("Bus", "request", ValueError, "write_interval", A(1, 6, bytes(4), write_interval=61)),
    *calls("Bus", "request", TypeError, "write_interval", A(1, 6, bytes(4), write_interval="1")),
    *calls("Bus", "read_device_identification", ValueError, "unit", A(-1), A(256)),
    *calls("Bus", "read_device_identification", ValueError, "read_code", A(1, 0), A(1, 5)),
    *calls("Bus", "read_device_identification", ValueError, "read_code", A(1, HUGE)),
    *calls("Bus", "read_device_identification", TypeError, "read_code", A(1, "1"), A(1, 1.0)),
    *calls("Bus", "read_device_identification", ValueError, "object_id", A(1, 1, -1)),
    *calls("Bus", "read_device_identification", ValueError, "object_id", A(1, 1, 256)),
    *calls("Bus", "broadcast_write_register", ValueError, "address", A(-1, 0), A(HUGE, 0)),
    *calls("Bus", "broadcast_write_register", ValueError, "value", A(0, 0x10000), A(0, HUGE)),
    *calls("Bus", "broadcast_write_register", TypeError, "value", A(0, NAN), A(0, "0")),
    *calls(
        "Bus", "broadcast_write_registers", ValueError, "address", A(-1, [1]), A(0xFFFF, [1, 2])
    ),
    *calls("Bus", "broadcast_write_registers", ValueError, "values", A(0, []), A(0, [0] * 124)),
    *calls("Bus", "broadcast_write_registers", ValueError, "value", A(0, [HUGE]), A(0, [1, -1])),
    *calls("Bus", "broadcast_write_registers", TypeError, "value", A(0, [NAN]), A(0, [1, None])),
    *calls(
        "Bus",
        "broadcast_write_registers",
        TypeError,
        "values",
        *(A(0, v) for v in ("12", b"12", None, 5)),
    ),
    # -- Bus: the functions beyond holding registers (the specification's limits)
    *calls("Bus", "__init__", ValueError, "silence", A(PORT, silence=-1), A(PORT, silence=NAN)),
    *calls("Bus", "__init__", ValueError, "silence", A(PORT, silence=INF), A(PORT, silence=HUGE)),
    *calls("Bus", "__init__", TypeError, "silence", A(PORT, silence="0.1")),
    *(
        case
        for name in ("read_coils", "read_discrete_inputs")
        for case in (
            *calls("Bus", name, ValueError, "unit", A(0, 0, 1), A(256, 0, 1), A(HUGE, 0, 1)),
            *calls("Bus", name, TypeError, "unit", A("1", 0, 1), A(None, 0, 1)),
            *calls("Bus", name, ValueError, "address", A(1, -1, 1), A(1, 0x10000, 1)),
            *calls("Bus", name, ValueError, "address", A(1, 0xFFFF, 2), A(1, 0xF831, 2000)),
            *calls("Bus", name, TypeError, "address", A(1, "0", 1), A(1, NAN, 1)),
            *calls("Bus", name, ValueError, "count", A(1, 0, 0), A(1, 0, 2001), A(1, 0, HUGE)),
            *calls("Bus", name, TypeError, "count", A(1, 0, 1.0), A(1, 0, True)),
        )
    ),
    *calls("Bus", "read_input_registers", ValueError, "unit", A(0, 0, 1), A(-1, 0, 1)),
    *calls("Bus", "read_input_registers", TypeError, "unit", A(1.0, 0, 1)),
    *calls("Bus", "read_input_registers", ValueError, "address", A(1, -1, 1), A(1, 0xFFFF, 2)),
    *calls("Bus", "read_input_registers", TypeError, "address", A(1, None, 1)),
    *calls("Bus", "read_input_registers", ValueError, "count", A(1, 0, 0), A(1, 0, 126)),
    *calls("Bus", "read_input_registers", TypeError, "count", A(1, 0, "1")),
    *calls("Bus", "write_coil", ValueError, "unit", A(0, 0, True), A(HUGE, 0, True)),
    *calls("Bus", "write_coil", ValueError, "address", A(1, -1, True), A(1, 0x10000, True)),
    # A coil is True or False: not 1, not 0xFF00, not "on".
    *calls(
        "Bus",
        "write_coil",
        TypeError,
        "value",
        *(A(1, 0, v) for v in (1, 0, 0xFF00, "on", None, 1.0, NAN)),
    ),
    *calls("Bus", "write_coils", ValueError, "unit", A(0, 0, [True]), A(-1, 0, [True])),
    *calls("Bus", "write_coils", ValueError, "values", A(1, 0, []), A(1, 0, [True] * 1969)),
    *calls("Bus", "write_coils", ValueError, "address", A(1, 0xFFFF, [True, False])),
    *calls("Bus", "write_coils", TypeError, "value", A(1, 0, [1]), A(1, 0, [True, None])),
    *calls(
        "Bus", "write_coils", TypeError, "values", *(A(1, 0, v) for v in ("10", b"\x01", None, 5))
    ),
    *calls("Bus", "mask_write_register", ValueError, "unit", A(0, 0, 0, 0)),
    *calls("Bus", "mask_write_register", ValueError, "address", A(1, -1, 0, 0)),
    *calls("Bus", "mask_write_register", ValueError, "and_mask", A(1, 0, 0x10000, 0)),
    *calls("Bus", "mask_write_register", ValueError, "and_mask", A(1, 0, -1, 0)),
    *calls("Bus", "mask_write_register", TypeError, "and_mask", A(1, 0, NAN, 0)),
    *calls("Bus", "mask_write_register", ValueError, "or_mask", A(1, 0, 0, HUGE)),
    *calls("Bus", "mask_write_register", TypeError, "or_mask", A(1, 0, 0, "1")),
    *calls("Bus", "read_write_registers", ValueError, "unit", A(0, 0, 1, 0, [1])),
    *calls(
        "Bus",
        "read_write_registers",
        ValueError,
        "read_count",
        A(1, 0, 0, 0, [1]),
        A(1, 0, 126, 0, [1]),
    ),
    *calls("Bus", "read_write_registers", TypeError, "read_count", A(1, 0, 1.5, 0, [1])),
    *calls("Bus", "read_write_registers", ValueError, "read_address", A(1, -1, 1, 0, [1])),
    *calls("Bus", "read_write_registers", ValueError, "address", A(1, 0xFFFF, 2, 0, [1])),
    *calls("Bus", "read_write_registers", ValueError, "write_address", A(1, 0, 1, HUGE, [1])),
    *calls("Bus", "read_write_registers", ValueError, "address", A(1, 0, 1, 0xFFFF, [1, 2])),
    *calls(
        "Bus",
        "read_write_registers",
        ValueError,
        "values",
        A(1, 0, 1, 0, []),
        A(1, 0, 1, 0, [0] * 122),
    ),
    *calls("Bus", "read_write_registers", ValueError, "value", A(1, 0, 1, 0, [0x10000])),
    *calls("Bus", "read_write_registers", TypeError, "values", A(1, 0, 1, 0, "12")),
    *calls("Bus", "read_exception_status", ValueError, "unit", A(0), A(256), A(HUGE)),
    *calls("Bus", "read_exception_status", TypeError, "unit", A("1"), A(None)),
    *calls("Bus", "report_server_id", ValueError, "unit", A(0), A(-1)),
    *calls("Bus", "report_server_id", TypeError, "unit", A(1.0)),
    *calls("Bus", "get_comm_event_counter", ValueError, "unit", A(0), A(-1), A(HUGE)),
    *calls("Bus", "get_comm_event_counter", TypeError, "unit", A("1"), A(None)),
    *calls("Bus", "get_comm_event_log", ValueError, "unit", A(0), A(256)),
    *calls("Bus", "get_comm_event_log", TypeError, "unit", A(1.0)),
    *calls("Bus", "read_file_record", ValueError, "unit", A(-1, [(1, 0, 1)])),
    *calls("Bus", "read_file_record", ValueError, "file", A(1, [(0, 0, 1)]), A(1, [(HUGE, 0, 1)])),
    *calls("Bus", "read_file_record", ValueError, "record", A(1, [(1, 0x2710, 1)])),
    *calls("Bus", "read_file_record", ValueError, "record", A(1, [(1, -1, 1)])),
    *calls("Bus", "read_file_record", ValueError, "length", A(1, [(1, 0, 0)])),
    *calls("Bus", "read_file_record", ValueError, "record 9999", A(1, [(1, 0x270F, 2)])),
    *calls("Bus", "read_file_record", ValueError, "group", A(1, [])),
    *calls("Bus", "read_file_record", ValueError, "request", A(1, [(1, 0, 1)] * 36)),
    *calls("Bus", "read_file_record", ValueError, "reply", A(1, [(1, 0, 125)])),
    *calls("Bus", "read_file_record", TypeError, "groups", A(1, "x"), A(1, 5), A(1, [(1, 0)])),
    *calls("Bus", "read_file_record", TypeError, "file", A(1, [(1.0, 0, 1)])),
    *calls("Bus", "read_file_record", TypeError, "length", A(1, [(1, 0, None)])),
    *calls("Bus", "write_file_record", ValueError, "unit", A(0, [(1, 0, [1])])),
    *calls("Bus", "write_file_record", ValueError, "file", A(1, [(0, 0, [1])])),
    *calls("Bus", "write_file_record", ValueError, "record", A(1, [(1, 0x2710, [1])])),
    *calls("Bus", "write_file_record", ValueError, "values", A(1, [(1, 0, [])])),
    *calls("Bus", "write_file_record", ValueError, "value", A(1, [(1, 0, [0x10000])])),
    *calls("Bus", "write_file_record", ValueError, "group", A(1, [])),
    *calls("Bus", "write_file_record", ValueError, "request", A(1, [(1, 0, [0] * 123)])),
    *calls("Bus", "write_file_record", TypeError, "groups", A(1, b"x"), A(1, [(1, 0, 1, 2)])),
    *calls("Bus", "write_file_record", TypeError, "values", A(1, [(1, 0, "12")])),
    *calls("Bus", "read_fifo_queue", ValueError, "unit", A(256, 0)),
    *calls("Bus", "read_fifo_queue", ValueError, "address", A(1, -1), A(1, 0x10000)),
    *calls("Bus", "read_fifo_queue", TypeError, "address", A(1, "0"), A(1, NAN)),
    *calls("Bus", "diagnostics", ValueError, "unit", A(0, 0), A(256, 0)),
    *calls("Bus", "diagnostics", ValueError, "sub_function", A(1, -1), A(1, 0x10000)),
    *calls("Bus", "diagnostics", TypeError, "sub_function", A(1, "0"), A(1, None)),
    *calls("Bus", "diagnostics", TypeError, "data", *(A(1, 0, d) for d in ("AB", [0, 0], 5, None))),
    *calls("Bus", "diagnostics", ValueError, "data", A(1, 0, bytes(251))),
    *calls("Bus", "request", ValueError, "unit", A(0, 0x41, b""), A(HUGE, 0x41, b"")),
    # 0 and 0x80 up are not requests' function codes (0x80 | f is an exception reply).
    *calls(
        "Bus",
        "request",
        ValueError,
        "function",
        *(A(1, f, b"") for f in (0, 0x80, 0xC1, 0xFF, 256, -1, HUGE)),
    ),
    *calls("Bus", "request", TypeError, "function", A(1, "0x41", b""), A(1, 65.0, b"")),
    *calls(
        "Bus", "request", TypeError, "data", A(1, 0x41, "AB"), A(1, 0x41, [1]), A(1, 0x41, None)
    ),
    *calls("Bus", "request", ValueError, "data", A(1, 0x41, bytes(253))),
    *calls(
        "Bus",
        "request",
        ValueError,
        "reply_length",
        A(1, 0x41, b"", reply_length=-1),
        A(1, 0x41, b"", reply_length=253),
    ),
    *calls("Bus", "request", TypeError, "reply_length", A(1, 0x41, b"", reply_length=1.0)),
    *calls("Bus", "broadcast_write_coil", ValueError, "address", A(-1, True), A(HUGE, True)),
    *calls("Bus", "broadcast_write_coil", TypeError, "value", A(0, 1), A(0, "on")),
    *calls("Bus", "broadcast_write_coils", ValueError, "values", A(0, []), A(0, [True] * 1969)),
    *calls("Bus", "broadcast_write_coils", ValueError, "address", A(0xFFFF, [True, True])),
    *calls("Bus", "broadcast_write_coils", TypeError, "value", A(0, [0])),
    *calls("Bus", "broadcast_write_coils", TypeError, "values", A(0, "1"), A(0, None)),
    # A bad unit anywhere in the list is refused before the first probe.
    *calls("Bus", "scan", ValueError, "unit", A([0]), A([-1]), A([HUGE]), A([1, 2, 0])),
    *calls("Bus", "scan", TypeError, "unit", A(["1"]), A([1, None])),
    *calls("Bus", "scan", TypeError, "units", A(5)),
    *calls(
        "Bus",
        "scan",
        ValueError,
        "timeout",
        *(A([1], timeout=t) for t in (0, -1, NAN, INF, 2**1100)),
    ),
    *calls("Bus", "scan", TypeError, "timeout", A([1], timeout="x")),
    *calls("Bus", "scan", ValueError, "address", A([1], address=-1), A([1], address=HUGE)),
    *calls("Bus", "poll", ValueError, "unit", A(-1, 0, interval=0.1), A(HUGE, 0, interval=0.1)),
    *calls(
        "Bus", "poll", ValueError, "address", A(1, -1, interval=0.1), A(1, 0xFFFF, 2, interval=0.1)
    ),
    *calls(
        "Bus",
        "poll",
        ValueError,
        "count",
        *(A(1, 0, c, interval=0.1) for c in (0, 126, HUGE)),
    ),
    *calls(
        "Bus",
        "poll",
        ValueError,
        "interval",
        *(A(1, 0, interval=i) for i in (0, -1, NAN, INF, HUGE, 2**1100)),
    ),
    *calls("Bus", "poll", TypeError, "interval", A(1, 0, interval="x"), A(1, 0, interval=None)),
    *calls("Bus", "poll", TypeError, "interval", A(1, 0)),  # interval has no default
    *calls(
        "Bus",
        "poll",
        ValueError,
        "duration",
        *(A(1, 0, interval=0.1, duration=d) for d in (-1, NAN, INF, 2**1100)),
    ),
    *calls("Bus", "poll", TypeError, "duration", A(1, 0, interval=0.1, duration="x")),
    # -- Poll: made by Bus.poll only
    *calls("Poll", "__init__", TypeError, "Poll", A()),
    # -- Drive
    *calls("Drive", "__init__", ValueError, "unit", *(A(BUS, u) for u in (-1, 0, 248, HUGE))),
    *calls("Drive", "__init__", TypeError, "unit", A(BUS, "1"), A(BUS, 1.0), A(BUS, None)),
    *calls("Drive", "__init__", ValueError, "family", A(BUS, family="XYZ"), A(BUS, family="")),
    *calls("Drive", "__init__", TypeError, "family", A(BUS, family=5)),
    *calls("Drive", "__init__", TypeError, "write_ack", A(BUS, write_ack="yes")),
    *calls("Drive", "__init__", TypeError, "check_identity", A(BUS, check_identity="no")),
    *calls("Drive", "__init__", ValueError, "timeout", A(BUS, timeout=NAN), A(BUS, timeout=-1)),
    *calls("Drive", "__init__", ValueError, "retries", A(BUS, retries=HUGE), A(BUS, retries=-1)),
    *calls("Drive", "__init__", TypeError, "retries", A(BUS, retries=1.5)),
    *calls("Drive", "__init__", TypeError, "port", A(5), A(None)),
    *calls("Drive", "__init__", TypeError, "units", A(BUS, units=1)),  # unknown keyword
    *calls("Drive", "wait_for_speed", TypeError, "rpm", A("x"), A(None), A(True)),
    *calls(
        "Drive", "wait_for_speed", ValueError, "rpm", *(A(r) for r in (NAN, INF, -1, 3001, HUGE))
    ),
    *calls("Drive", "wait_for_speed", ValueError, "tolerance", A(100, -1), A(100, NAN)),
    *calls("Drive", "wait_for_speed", TypeError, "tolerance", A(100, "5")),
    *calls(
        "Drive",
        "wait_for_speed",
        ValueError,
        "timeout",
        *(A(100, timeout=t) for t in (0, -1, NAN, INF)),
    ),
    *calls("Drive", "wait_for_speed", TypeError, "timeout", A(100, timeout="x")),
    *calls(
        "Drive",
        "wait_for_speed",
        ValueError,
        "interval",
        *(A(100, interval=i) for i in (0, 11, NAN, HUGE)),
    ),
    *calls("Drive", "wait_for_speed", TypeError, "interval", A(100, interval="x")),
    *calls(
        "Drive",
        "set_station_address",
        ValueError,
        "station_address",
        *(A(a) for a in (0, 128, -1, HUGE, NAN, INF, 1.5)),
    ),
    *calls("Drive", "set_station_address", TypeError, "station_address", A("1"), A(None)),
    *calls("C20", "set_station_address", ValueError, "station_address", A(248)),
    *calls("Drive", "set_baud_rate", ValueError, "baud rate", A(12345), A(-1), A(HUGE), A(0)),
    *calls("Drive", "set_baud_rate", TypeError, "baud rate", A(9600.0), A("9600")),
    *calls("C20", "set_baud_rate", ValueError, "baud rate", A(115200)),  # the C20 stops at 57600
    *calls(
        "Drive",
        "read_parameter",
        ValueError,
        "parameter",
        *(A(c) for c in ("F99.99", "X", "", "F00.1", "F11.00")),
    ),
    *calls("Drive", "read_parameter", TypeError, "code", A(5), A(None)),
    *calls("Drive", "write_parameter", ValueError, "parameter", A("nope", 1), A("", 1)),
    *calls("Drive", "write_parameter", TypeError, "code", A(5, 1)),
    *calls(
        "Drive",
        "write_parameter",
        ValueError,
        "value",
        *(A("F00.10", v) for v in (-1, 0x10000, HUGE)),
    ),
    *calls(
        "Drive", "write_parameter", TypeError, "value", *(A("F00.10", v) for v in (NAN, "1", 1.5))
    ),
    *calls("Drive", "get", ValueError, "nope", A("nope")),  # unknown register names
    *calls("Drive", "get", ValueError, "register", A("")),
    *calls("Drive", "get", TypeError, "name", A(5), A(None)),
    *calls("C20", "get", ValueError, "stop_mode", A("stop_mode")),  # BLD only
    *calls("Drive", "set", ValueError, "nope", A("nope", 1)),
    *calls("Drive", "set", ValueError, "speed", A("speed", 1)),  # read-only
    *calls("Drive", "set", ValueError, "speed_setpoint", A("speed_setpoint", NAN)),
    *calls("Drive", "set", TypeError, "speed_setpoint", A("speed_setpoint", "x")),
    *calls("Drive", "set", TypeError, "name", A(5, 1)),
    # Several: every value checked before the first is sent (the first here is good).
    *calls("Drive", "get_many", TypeError, "names", A("speed"), A(5), A(None)),
    *calls("Drive", "get_many", TypeError, "named by a str", A(["speed", 5])),
    *calls("Drive", "get_many", ValueError, "nope", A(["speed", "nope"])),
    *calls("Drive", "set_many", TypeError, "values", A(5), A("speed_setpoint"), A([5])),
    *calls("Drive", "set_many", ValueError, "values", A([("speed_setpoint",)])),
    *calls(
        "Drive",
        "set_many",
        ValueError,
        "speed_setpoint",
        A({"accel_time": 1.0, "speed_setpoint": NAN}),
    ),
    *calls(
        "Drive", "set_many", ValueError, r"\bspeed\b", A([("speed_setpoint", 100), ("speed", 1)])
    ),
    *calls("Drive", "set_many", ValueError, "nope", A({"speed_setpoint": 100, "nope": 1})),
    *calls("C20", "brake", ValueError, "brake", A()),  # BLD only
    *calls("C20", "clear_hall_count", ValueError, "hall_count", A()),  # BLD only
    *sets("C20", "stop_mode", ValueError, "stop_mode", bb.StopMode.COAST),  # BLD only
    *calls("Drive", "record", ValueError, "duration", *(A(d, 0.1) for d in (NAN, INF, 0, -1))),
    *calls("Drive", "record", TypeError, "duration", A("1", 0.1), A(None, 0.1)),
    *calls("Drive", "record", ValueError, "interval", A(1, 0), A(1, INF), A(1, -0.1)),
    *calls("Drive", "record", TypeError, "interval", A(1, "0.1")),
    *calls(
        "Drive", "record", TypeError, "columns", A(1, 0.1, columns="speed"), A(1, 0.1, columns=5)
    ),
    *calls("Drive", "record", ValueError, "columns", A(1, 0.1, columns=[])),
    *calls("Drive", "record", ValueError, "columns", A(1, 0.1, columns=["speed", "speed"])),
    *calls("Drive", "record", ValueError, "nope", A(1, 0.1, columns=["speed", "nope"])),
    *calls("Drive", "record", TypeError, "column", A(1, 0.1, columns=[5])),
    *calls("Drive", "record", TypeError, "clock", A(1, 0.1, clock="x")),
    *calls("Drive", "record", TypeError, "sleep", A(1, 0.1, sleep=0.1)),
    *sets(
        "Drive",
        "comm_loss_timeout",
        ValueError,
        "comm_loss_timeout",
        *(-1, 0.05, 60.1, NAN, INF, -INF, HUGE, -HUGE, 2**1100),
    ),
    *sets("Drive", "comm_loss_timeout", TypeError, "comm_loss_timeout", "1", None, True, [1]),
    *sets("C20", "comm_loss_timeout", ValueError, "F08.04", 1.0),  # BLD only
    *calls("Drive", "keepalive", ValueError, "interval", *(A(i) for i in (0, -1, NAN, INF, HUGE))),
    *calls("Drive", "keepalive", ValueError, "interval", A(0.001), A(61)),
    *calls("Drive", "keepalive", TypeError, "interval", A("1"), A(None), A(True)),
    *calls("Drive", "read_setting", ValueError, "setting", A("nope"), A("")),
    *calls("Drive", "read_setting", TypeError, "name", A(5), A(None)),
    *calls("C20", "read_setting", ValueError, "F08.04", A("comm_loss_timeout")),  # BLD only
    *calls("Drive", "write_setting", ValueError, "nope", A("nope", 1)),
    *calls(
        "Drive",
        "write_setting",
        ValueError,
        "comm_loss_timeout",
        *(A("comm_loss_timeout", v) for v in (-1, 0.05, 60.1, NAN, INF, HUGE)),
    ),
    *calls("Drive", "write_setting", TypeError, "comm_loss_timeout", A("comm_loss_timeout", "1")),
    *calls("Drive", "write_setting", TypeError, "name", A(5, 1)),
    *calls("Drive", "model_from_id", ValueError, "family", A("ABC", 0x20), A("", 0x20)),
    *calls("Drive", "model_from_id", TypeError, "family", A(5, 0x20)),
    *calls("Drive", "model_from_id", ValueError, "id", A("BLD", 0x10000), A("BLD", -1)),
    *calls("Drive", "model_from_id", TypeError, "id", A("BLD", "0x20"), A("BLD", 1.0)),
    # -- PblDrive
    *calls("PblDrive", "__init__", ValueError, "unit", *(A(BUS, u) for u in (-1, 0, 256, HUGE))),
    *calls("PblDrive", "__init__", TypeError, "unit", A(BUS, "1"), A(BUS, 17.0)),
    *calls("PblDrive", "__init__", TypeError, "check_identity", A(BUS, check_identity=0)),
    *calls("PblDrive", "__init__", ValueError, "timeout", A(BUS, timeout=INF), A(BUS, timeout=0)),
    *calls("PblDrive", "__init__", TypeError, "timeout", A(BUS, timeout="x")),
    *calls("PblDrive", "__init__", ValueError, "retries", A(BUS, retries=-1)),
    *sets("PblDrive", "direction", ValueError, "direction", 2, -1, HUGE),
    *sets("PblDrive", "direction", TypeError, "direction", "x", True, NAN, None),
    *calls("PblDrive", "read_parameter", ValueError, "parameter", *(A(k) for k in (-1, 223, HUGE))),
    *calls("PblDrive", "read_parameter", ValueError, "parameter", A("nope"), A("")),
    *calls(
        "PblDrive", "read_parameter", TypeError, "parameter", *(A(k) for k in (1.5, None, True))
    ),
    *calls("PblDrive", "write_parameter", ValueError, "speed", A(50, 1)),  # read-only
    *calls(
        "PblDrive", "write_parameter", ValueError, "control_mode", A(100, 3), A("control_mode", 3)
    ),
    *calls("PblDrive", "write_parameter", ValueError, "value", A(100, -1), A(100, HUGE)),
    *calls("PblDrive", "write_parameter", TypeError, "value", A(100, NAN), A(100, "1")),
    *calls("PblDrive", "write_parameter", ValueError, "parameter", A("nope", 1), A(223, 1)),
    *calls("PblDrive", "read_parameters", ValueError, "count", *(A(0, c) for c in (0, 224, HUGE))),
    *calls("PblDrive", "read_parameters", ValueError, "parameters", A(200, 50)),
    *calls("PblDrive", "read_parameters", ValueError, "parameter", A("nope", 1), A(-1, 1)),
    *calls("PblDrive", "read_parameters", TypeError, "count", A(0, 1.0), A(0, "1")),
    *calls("PblDrive", "get", ValueError, "nope", A("nope")),
    *calls("PblDrive", "get", TypeError, "name", A(50), A(None)),
    *calls("PblDrive", "set", ValueError, "speed", A("speed", 1)),  # read-only
    *calls("PblDrive", "set", ValueError, "control_mode", A("control_mode", 3)),
    *calls("PblDrive", "set", ValueError, "nope", A("nope", 1)),
    *calls("PblDrive", "set", TypeError, "control_mode", A("control_mode", "1")),
    *calls("PblDrive", "get_many", TypeError, "names", A("speed"), A(None)),
    *calls("PblDrive", "get_many", ValueError, "nope", A(["speed", "nope"])),
    *calls("PblDrive", "set_many", TypeError, "values", A(5), A([5])),
    *calls(
        "PblDrive", "set_many", ValueError, "control_mode", A({"pole_pairs": 2, "control_mode": 3})
    ),
    *calls(
        "PblDrive",
        "set_many",
        TypeError,
        "control_mode",
        A([("pole_pairs", 2), ("control_mode", "1")]),
    ),
    *calls("PblDrive", "record", ValueError, "duration", A(NAN, 0.1)),
    *calls("PblDrive", "record", ValueError, "nope", A(1, 0.1, columns=["nope"])),
    # -- J2Controller
    *calls(
        "J2Controller", "__init__", ValueError, "unit", *(A(BUS, u) for u in (-1, 0, 256, HUGE))
    ),
    *calls("J2Controller", "__init__", TypeError, "unit", A(BUS, "3")),
    *calls("J2Controller", "__init__", TypeError, "check_identity", A(BUS, check_identity=None)),
    *calls("J2Controller", "__init__", ValueError, "baudrate", A(BUS, 3, 4800), A(BUS, 3, HUGE)),
    *calls("J2Controller", "__init__", TypeError, "baudrate", A(BUS, 3, "9600")),
    *calls("J2Controller", "__init__", ValueError, "timeout", A(BUS, 3, timeout=-1)),
    *calls("J2Controller", "__init__", ValueError, "retries", A(BUS, 3, retries=HUGE)),
    *sets("J2Controller", "mv", ValueError, "MV", NAN, INF, 150, -1, HUGE),
    *sets("J2Controller", "mv", TypeError, "MV", "x", None, True),
    *sets("J2Controller", "autotune", ValueError, "autotune", 2, -1, HUGE),
    *sets("J2Controller", "autotune", TypeError, "autotune", "x", 1.5, None, NAN),
    *sets("J2Controller", "limits", ValueError, "limits", (1,), (1, 2, 3), (), (100, 10)),
    *sets("J2Controller", "limits", TypeError, "limits", 5, "ab", None),
    *sets("J2Controller", "limits", ValueError, "LSP", (NAN, 10), (-3000, 10), (-HUGE, 10)),
    *sets("J2Controller", "limits", ValueError, "USP", (0, INF), (0, HUGE)),
    *sets("J2Controller", "limits", TypeError, "LSP", ("a", "b"), (None, 10)),
    *sets("J2Controller", "pid", ValueError, "PID", (1, 2), (1, 2, 3, 4), ()),
    *sets("J2Controller", "pid", TypeError, "PID", 5, "abc", None),
    *sets("J2Controller", "pid", ValueError, r"\bP\b", (NAN, 1, 1), (0, 1, 1), (HUGE, 1, 1)),
    *sets("J2Controller", "pid", ValueError, r"\bI\b", (1, INF, 1), (1, -1, 1)),
    *sets("J2Controller", "pid", TypeError, r"\bP\b", ("a", 1, 1)),
    *sets("J2Controller", "pid2", ValueError, "PID", (1, 2, 3, 4)),
    *sets("J2Controller", "pid2", TypeError, "PID", 5),
    *sets("J2Controller", "pid2", ValueError, r"\bD1\b", (1, 1, NAN)),
    *calls("J2Controller", "get", TypeError, "named by a str", A(5), A(None)),
    *calls("J2Controller", "get", ValueError, "parameter", A("NOPE")),
    *calls("J2Controller", "set", ValueError, r"\bPV\b", A("PV", 10)),  # read-only
    *calls("J2Controller", "set", ValueError, r"\bSV\b", A("SV", NAN)),
    *calls("J2Controller", "set", TypeError, r"\bSV\b", A("SV", "x")),
    *calls("J2Controller", "set", TypeError, "named by a str", A(5, 10)),
    *calls("J2Controller", "get_many", TypeError, "names", A("SV"), A(None)),
    *calls("J2Controller", "get_many", ValueError, "NOPE", A(["SV", "NOPE"])),
    *calls("J2Controller", "set_many", TypeError, "values", A(5), A([5])),
    *calls("J2Controller", "set_many", ValueError, r"\bAL2\b", A({"AL1": 10, "AL2": NAN})),
    *calls("J2Controller", "set_many", ValueError, r"\bPV\b", A([("AL1", 10), ("PV", 1)])),
    *calls("J2Controller", "read", TypeError, "named by a str", A(5), A(None)),
    *calls("J2Controller", "read", ValueError, "parameter", A("NOPE"), A("")),
    *calls("J2Controller", "write", ValueError, "function", A("SV", 10, function=3)),
    *calls("J2Controller", "write", TypeError, "function", A("SV", 10, function="6")),
    *calls("J2Controller", "write", ValueError, r"\bSV\b", *(A("SV", v) for v in (NAN, INF, HUGE))),
    *calls("J2Controller", "write", TypeError, r"\bSV\b", A("SV", "x"), A("SV", None)),
    *calls("J2Controller", "write", ValueError, r"\bPV\b", A("PV", 10)),  # read-only
    *calls("J2Controller", "write", TypeError, "named by a str", A(5, 10)),
    *calls("J2Controller", "write", ValueError, "NOPE", A("NOPE", 10)),
    *calls("J2Controller", "read_many", TypeError, "names", A("SV"), A(5), A(None)),
    *calls("J2Controller", "read_many", TypeError, "named by a str", A([5]), A(["SV", None])),
    *calls("J2Controller", "read_many", ValueError, "NOPE", A(["SV", "NOPE"])),
    *calls("J2Controller", "write_many", TypeError, "values", A(5), A("SV"), A([5]), A(["SV"])),
    *calls("J2Controller", "write_many", ValueError, "values", A([("SV",)]), A([("SV", 1, 2)])),
    *calls("J2Controller", "write_many", ValueError, "NOPE", A({"NOPE": 1})),
    # Every fixed range is checked before the first write: AL1 = 10 is not sent either.
    *calls("J2Controller", "write_many", ValueError, r"\bAL2\b", A({"AL1": 10, "AL2": NAN})),
    *calls("J2Controller", "write_many", TypeError, r"\bAL2\b", A([("AL1", 10), ("AL2", "x")])),
    *calls("J2Controller", "set_output", ValueError, "MV", A(NAN), A(150), A(-1), A(HUGE)),
    *calls("J2Controller", "set_output", TypeError, "MV", A("x"), A(None)),
    *calls(
        "J2Controller",
        "set_output",
        TypeError,
        "switch_to_manual",
        A(10, switch_to_manual="no"),
        A(10, switch_to_manual=1),
        A(10, switch_to_manual=None),
    ),
    *calls("J2Controller", "record", ValueError, "nope", A(1, 0.1, columns=["pv", "nope"])),
    *calls("J2Controller", "record", ValueError, "interval", A(1, NAN)),
    # -- Instrument
    *calls("Instrument", "__init__", ValueError, "unit", *(A(BUS, u) for u in (-1, 0, 256, HUGE))),
    *calls("Instrument", "__init__", TypeError, "unit", A(BUS, "4")),
    *calls(
        "Instrument", "__init__", ValueError, "max_read", *(A(BUS, 4, m) for m in (0, 126, HUGE))
    ),
    *calls("Instrument", "__init__", TypeError, "max_read", A(BUS, 4, 1.0)),
    *calls("Instrument", "__init__", ValueError, "max_write", A(BUS, 4, 37, 0), A(BUS, 4, 37, 124)),
    *calls(
        "Instrument",
        "__init__",
        ValueError,
        "min_write_interval",
        *(A(BUS, 4, min_write_interval=i) for i in (-1, NAN, INF, HUGE)),
    ),
    *calls(
        "Instrument", "__init__", TypeError, "min_write_interval", A(BUS, 4, min_write_interval="x")
    ),
    *calls("Instrument", "__init__", ValueError, "baudrate", A(BUS, 4, baudrate=1234)),
    *calls("Instrument", "__init__", TypeError, "baudrate", A(BUS, 4, baudrate="9600")),
    *calls("Instrument", "__init__", ValueError, "timeout", A(BUS, 4, timeout=NAN)),
    *calls("Instrument", "read_register", ValueError, "address", A(-1), A(HUGE), A(0x10000)),
    *calls("Instrument", "read_register", TypeError, "address", A("0"), A(NAN)),
    *calls("Instrument", "read_register", ValueError, "decimals", A(0, -1), A(0, 10), A(0, HUGE)),
    *calls("Instrument", "read_register", TypeError, "decimals", A(0, 1.5)),
    *calls("Instrument", "read_register", TypeError, "signed", A(0, 0, "yes")),
    *calls("Instrument", "read_register", TypeError, "decimal", A(0, decimal=1)),  # unknown keyword
    *calls(
        "Instrument",
        "write_register",
        ValueError,
        "value",
        *(A(0, v) for v in (NAN, INF, -INF, HUGE, -1, 70000, 1.5)),
        A(0, 1.55, 1),
        A(0, -40000, signed=True),
        A(0, 6553.6, 1),
    ),
    *calls("Instrument", "write_register", TypeError, "value", A(0, "x"), A(0, None)),
    *calls("Instrument", "write_register", ValueError, "address", A(-1, 0), A(HUGE, 0)),
    *calls("Instrument", "write_register", ValueError, "decimals", A(0, 0, -1)),
    *calls("Instrument", "write_register", ValueError, "function", A(0, 1, function=3)),
    *calls("Instrument", "write_register", TypeError, "function", A(0, 1, function="6")),
    *calls("Instrument", "write_register", TypeError, "signed", A(0, 1, signed=1)),
    *calls("Instrument", "read_registers", ValueError, "count", *(A(0, c) for c in (0, -1, HUGE))),
    *calls("Instrument", "read_registers", ValueError, "count", A(0xFFFF, 2)),
    *calls("Instrument", "read_registers", TypeError, "count", A(0, "1"), A(0, 1.0)),
    *calls("Instrument", "read_registers", ValueError, "function", A(0, 1, function=6)),
    *calls("Instrument", "read_registers", TypeError, "function", A(0, 1, function="4")),
    *calls("Instrument", "read_register", ValueError, "function", A(0, function=16)),
    *calls("Instrument", "read_string", ValueError, "function", A(0, 1, function=1)),
    *calls("Instrument", "read_float", ValueError, "function", A(0, function=2)),
    *calls("Instrument", "read_coil", ValueError, "address", A(-1), A(0x10000), A(HUGE)),
    *calls("Instrument", "read_coil", TypeError, "address", A("0"), A(1.0)),
    *calls("Instrument", "read_discrete_input", ValueError, "address", A(-1), A(0x10000)),
    *calls("Instrument", "read_discrete_input", TypeError, "address", A(None)),
    *calls("Instrument", "read_coils", ValueError, "count", *(A(0, c) for c in (0, -1, HUGE))),
    *calls("Instrument", "read_coils", ValueError, "count", A(0xFFFF, 2)),
    *calls("Instrument", "read_coils", TypeError, "count", A(0, 1.0)),
    *calls("Instrument", "read_discrete_inputs", ValueError, "count", A(0, 0), A(0xFFFE, 3)),
    *calls("Instrument", "read_discrete_inputs", ValueError, "address", A(-1, 1)),
    *calls("Instrument", "write_coil", TypeError, "coil", *(A(0, v) for v in (1, 0, None, "x"))),
    *calls("Instrument", "write_coil", ValueError, "address", A(0x10000, True)),
    *calls("Instrument", "write_coils", TypeError, "coil", A(0, [True, 1]), A(0, [None])),
    *calls("Instrument", "write_coils", TypeError, "values", A(0, "10"), A(0, 5), A(0, None)),
    *calls("Instrument", "write_coils", ValueError, "values", A(0, []), A(0xFFFF, [True] * 2)),
    *calls("Instrument", "read_registers", ValueError, "address", A(-1, 1), A(HUGE, 1)),
    *calls("Instrument", "write_registers", ValueError, "values", A(0, []), A(0xFFFF, [1, 2])),
    *calls(
        "Instrument", "write_registers", TypeError, "values", *(A(0, v) for v in ("ab", None, 5))
    ),
    *calls("Instrument", "write_registers", ValueError, "value", A(0, [HUGE]), A(0, [-1])),
    *calls("Instrument", "write_registers", TypeError, "value", A(0, [NAN]), A(0, [1, "2"])),
    *calls("Instrument", "write_registers", ValueError, "address", A(-1, [1])),
    *calls("Instrument", "read_long", ValueError, "word_order", A(0, word_order="middle")),
    *calls("Instrument", "read_long", TypeError, "word_order", A(0, word_order=5)),
    *calls("Instrument", "read_long", ValueError, "address", A(0xFFFF), A(-1)),
    *calls("Instrument", "read_long", TypeError, "signed", A(0, "x")),
    *calls("Instrument", "read_long", ValueError, "byte_order", A(0, byte_order="middle")),
    *calls("Instrument", "read_long", TypeError, "byte_order", A(0, byte_order=5)),
    *calls("Instrument", "read_long", ValueError, "order", A(0, order="ABDC")),
    *calls("Instrument", "read_long", TypeError, "order", A(0, order=5)),
    *calls("Instrument", "read_long", TypeError, "not both", A(0, False, "little", order="CDAB")),
    *calls(
        "Instrument",
        "write_float",
        TypeError,
        "not both",
        A(0, 1.0, byte_order="big", order="ABCD"),
    ),
    *calls("Instrument", "read_long", ValueError, "bits", A(0, bits=16), A(0, bits=HUGE)),
    *calls("Instrument", "read_long", TypeError, "bits", A(0, bits="64"), A(0, bits=64.0)),
    *calls("Instrument", "read_long", ValueError, "address", A(0xFFFD, bits=64)),
    *calls("Instrument", "write_long", ValueError, "value", A(0, 2**64, bits=64)),
    *calls("Instrument", "write_long", ValueError, "value", A(0, 2**63, True, bits=64)),
    *calls("Instrument", "write_float", ValueError, "value", A(0, NAN, bits=64)),
    *calls("Instrument", "read_float", TypeError, "bits", A(0, bits=32.5)),
    *calls("Instrument", "write_long", ValueError, "value", A(0, 2**32), A(0, -1), A(0, HUGE)),
    *calls(
        "Instrument", "write_long", ValueError, "value", A(0, 2**31, True), A(0, -(2**31) - 1, True)
    ),
    *calls("Instrument", "write_long", TypeError, "value", A(0, NAN), A(0, "x"), A(0, 1.0)),
    *calls("Instrument", "write_long", ValueError, "address", A(0xFFFF, 1)),
    *calls("Instrument", "write_long", ValueError, "word_order", A(0, 1, word_order="x")),
    *calls("Instrument", "read_float", ValueError, "word_order", A(0, "x")),
    *calls("Instrument", "read_float", ValueError, "address", A(0xFFFF), A(HUGE)),
    *calls(
        "Instrument",
        "write_float",
        ValueError,
        "value",
        *(A(0, v) for v in (NAN, INF, -INF, 1e39, 2**200, 2**1100)),
    ),
    *calls("Instrument", "write_float", TypeError, "value", A(0, "x"), A(0, None)),
    *calls("Instrument", "write_float", ValueError, "address", A(0xFFFF, 1.0)),
    *calls("Instrument", "write_float", TypeError, "word_order", A(0, 1.0, 5)),
    *calls("Instrument", "read_string", ValueError, "count", *(A(0, c) for c in (0, -1, HUGE))),
    *calls("Instrument", "read_string", TypeError, "count", A(0, "2")),
    *calls("Instrument", "read_string", ValueError, "address", A(-1, 1)),
    *calls("Instrument", "write_string", TypeError, "text", A(0, 5, 2), A(0, b"ab", 2)),
    *calls("Instrument", "write_string", ValueError, "text", A(0, "\u20ac", 2), A(0, "abcde", 2)),
    *calls("Instrument", "write_string", ValueError, "count", A(0, "ab", 0), A(0, "ab", HUGE)),
    *calls("Instrument", "identify", ValueError, "level", A("full"), A("")),
    *calls("Instrument", "identify", TypeError, "level", A(5), A([]), A(None)),
    *calls("Instrument", "read_file_record", ValueError, "file", A([(0, 0, 1)])),
    *calls("Instrument", "read_file_record", ValueError, "record", A([(1, 0x2710, 1)])),
    *calls("Instrument", "read_file_record", ValueError, "group", A([])),
    *calls("Instrument", "read_file_record", TypeError, "groups", A("x"), A([(1, 0)])),
    *calls("Instrument", "write_file_record", ValueError, "values", A([(1, 0, [])])),
    *calls("Instrument", "write_file_record", ValueError, "request", A([(1, 0, [0] * 123)])),
    *calls("Instrument", "write_file_record", TypeError, "groups", A(None), A([(1, 0)])),
    *calls("Instrument", "write_file_record", TypeError, "values", A([(1, 0, 1)])),
    *calls("Instrument", "read_fifo_queue", ValueError, "address", A(-1), A(HUGE)),
    *calls("Instrument", "read_fifo_queue", TypeError, "address", A(None), A(1.5)),
    *calls("Instrument", "record", ValueError, "duration", A(NAN, 0.1)),
    # An instrument has no fixed measurements: refused at the first sample, before any read.
    *calls("Instrument", "record", TypeError, "measurements", A(1, 0.1)),
    # -- Device (the flow controller's profile: floats, enums, strings, 64-bit values)
    *calls("Device", "__init__", TypeError, "path", A(5, BUS), A(None, BUS)),
    *calls(
        "Device",
        "__init__",
        ValueError,
        "unit",
        *(A(CONTROLLER, BUS, u) for u in (-1, 0, 256, HUGE)),
    ),
    *calls("Device", "__init__", TypeError, "unit", A(CONTROLLER, BUS, "4")),
    *calls("Device", "__init__", ValueError, "timeout", A(CONTROLLER, BUS, 5, timeout=NAN)),
    *calls("Device", "from_profile", TypeError, "path", A(5, BUS)),
    *calls("Device", "from_profile", ValueError, "unit", A(CONTROLLER, BUS, -1)),
    *calls("Device", "from_profile", ValueError, "retries", A(CONTROLLER, BUS, 5, retries=-1)),
    *calls("Device", "read", ValueError, "nope", A("nope")),
    *calls("Device", "read", ValueError, "register ''", A("")),
    *calls("Device", "read", ValueError, "reset_total", A("reset_total")),  # write-only
    *calls("Device", "get", ValueError, "NOPE", A("NOPE")),
    *calls("Device", "read_many", ValueError, "nope", A(["flow", "nope"])),
    *calls("Device", "read_many", TypeError, "int", A(5)),
    *calls(
        "Device",
        "write",
        ValueError,
        "setpoint",
        *(A("setpoint", v) for v in (-0.5, 200.5, NAN, INF, -INF, HUGE, -HUGE)),
    ),
    *calls("Device", "write", TypeError, "setpoint", A("setpoint", "x"), A("setpoint", None)),
    *calls("Device", "write", TypeError, "setpoint", A("setpoint", True), A("setpoint", [1])),
    *calls("Device", "write", ValueError, "flow", A("flow", 1.0)),  # read-only
    *calls("Device", "write", ValueError, "mode", A("mode", "heat"), A("mode", 9), A("mode", -1)),
    *calls("Device", "write", TypeError, "mode", A("mode", 1.0), A("mode", False)),
    *calls("Device", "write", ValueError, "zero_offset", A("zero_offset", 10**6 + 1)),
    *calls("Device", "write", ValueError, "zero_offset", A("zero_offset", 2**64)),
    *calls("Device", "write", ValueError, "device_name", A("device_name", "x" * 17)),
    *calls("Device", "write", ValueError, "device_name", A("device_name", "\u20ac")),
    *calls("Device", "write", TypeError, "device_name", A("device_name", 5)),
    *calls("Device", "write", ValueError, "nope", A("nope", 1)),
    *calls("Device", "set", ValueError, "gain", A("gain", 0.4), A("gain", NAN)),
    *calls("Device", "set", ValueError, "NOPE", A("NOPE", 1)),
    *calls("Device", "get_many", ValueError, "nope", A(["flow", "nope"])),
    *calls("Device", "get_many", TypeError, "int", A(5)),
    *calls("Device", "set_many", TypeError, "values", A(5), A([5])),
    *calls("Device", "set_many", ValueError, "gain", A({"setpoint": 1, "gain": 0.4})),
    *calls("Device", "set_many", ValueError, "flow", A([("setpoint", 1), ("flow", 1.0)])),
    *calls("Device", "set_many", ValueError, "nope", A({"setpoint": 1, "nope": 1})),
    *calls("Device", "record", ValueError, "duration", A(NAN, 0.1)),
    *calls("Device", "record", ValueError, "nope", A(1, 0.1, columns=["nope"])),
]


# ---- the cases made from the classes -----------------------------------------------------------


def _compiled_setters() -> set[tuple[str, str]]:
    """``(class, property)`` of each compiled property that takes a value, as the stubs of
    the compiled module declare them (a compiled descriptor does not say it has a setter)."""
    stubs = ast.parse((Path(bb.__file__).parent / "_core.pyi").read_text(encoding="utf-8"))
    return {
        (klass.name, item.name)
        for klass in stubs.body
        if isinstance(klass, ast.ClassDef)
        for item in klass.body
        if isinstance(item, ast.FunctionDef)
        for decorator in item.decorator_list
        if isinstance(decorator, ast.Attribute) and decorator.attr == "setter"
    }


COMPILED_SETTERS = _compiled_setters()


def kind(cls: type, name: str) -> str:
    """What the public attribute ``name`` of ``cls`` is, for the cases made from it."""
    attr = inspect.getattr_static(cls, name)
    if isinstance(attr, RegisterProperty):
        return "register"
    if isinstance(attr, MeasuredProperty):
        return "read-only"
    if isinstance(attr, property):
        return "read-only" if attr.fset is None else "setter"
    if type(attr).__name__ == "getset_descriptor":  # a compiled property
        return "setter" if (attr.__objclass__.__name__, name) in COMPILED_SETTERS else "read-only"
    if callable(attr) or isinstance(attr, staticmethod):
        parameters = inspect.signature(getattr(cls, name)).parameters
        return "method" if [p for p in parameters if p != "self"] else "no-arguments"
    return "constant"


def made_cases(owner: str) -> list[Case]:
    cls = OWNERS[owner]
    cases = []
    for name in sorted(n for n in dir(cls) if not n.startswith("_")):
        what = kind(cls, name)
        if what == "register":
            register = inspect.getattr_static(cls, name).register
            about = rf"\b({name}|{register})\b"
            cases += sets(owner, name, TypeError, about, "x", None, True, b"1", [1])
            cases += sets(owner, name, ValueError, about, NAN, INF, -INF, HUGE, -HUGE, BELOW, ABOVE)
        elif what == "read-only":
            attr = inspect.getattr_static(cls, name)
            register = getattr(attr, "register", name)
            cases += sets(owner, name, AttributeError, rf"\b({name}|{register})\b", 0)
        elif what == "no-arguments":
            cases += calls(owner, name, TypeError, rf"\b{name}\(\)", A(HUGE))
    return cases


CASES = EXPLICIT + [c for owner in OWNERS if owner != "C20" for c in made_cases(owner)]


# ---- running them ------------------------------------------------------------------------------


@dataclasses.dataclass
class Env:
    sim: Simulator[Any]
    objects: dict[str, Any]
    ranges: dict[str, dict[str, tuple[float, float]]]


@pytest.fixture(scope="module")
def env() -> Iterator[Env]:
    devices: dict[int, SimDevice] = {
        1: DriveDevice(),
        3: J2Device(),
        4: TaisongDevice(),
        0x11: PblDevice(),
        5: ProfileDevice(CONTROLLER),
    }
    with Simulator(devices) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        drive = bb.Drive(bus, 1)
        objects = {
            "Bus": bus,
            "Poll": bus.poll(1, 0x3006, interval=0.1),  # not started: nothing sent yet
            "Drive": drive,
            "C20": bb.Drive(bus, 1, family="C20"),
            "PblDrive": bb.PblDrive(bus, 0x11),
            "J2Controller": bb.J2Controller(bus, 3),
            "Instrument": bb.Instrument(bus, 4),
            "Device": bb.Device.from_profile(CONTROLLER, bus, 5),
        }
        ranges = {
            "Drive": {r[0]: (r[5], r[6]) for r in drive.registers()},
            "PblDrive": {r[1]: (r[4], r[5]) for r in bb.PblDrive.table()},
            "J2Controller": {r[0]: (r[4], r[5]) for r in bb.J2Controller.table()},
        }
        yield Env(sim, objects, ranges)
        assert not sim.errors


def run(case: Case, env: Env) -> object:
    """Make the call ``case`` describes."""

    def fill(value: Any) -> Any:
        if value is BUS:
            return env.objects["Bus"]
        if value is PORT:
            return env.sim.port
        if value is BELOW or value is ABOVE:
            register = inspect.getattr_static(OWNERS[case.owner], case.member).register
            low, high = env.ranges[case.owner][register]
            return low - 1 if value is BELOW else high + 1
        return value

    args = [fill(a) for a in case.args]
    kwargs = {k: fill(v) for k, v in case.kwargs.items()}
    if case.member == "__init__":
        return OWNERS[case.owner](*args, **kwargs)
    target = env.objects[case.owner]
    if case.assign:
        setattr(target, case.member, args[0])
        return None
    return getattr(target, case.member)(*args, **kwargs)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_refused_before_anything_is_sent(env: Env, case: Case) -> None:
    bus = env.objects["Bus"]
    sent, stats = len(env.sim.requests), bus.stats
    with pytest.raises(case.exc) as info:
        run(case, env)
    assert not isinstance(info.value, bb.BenchbusError)
    text = "\n".join([str(info.value), *getattr(info.value, "__notes__", [])])
    assert re.search(case.names, text), f"the message does not name {case.names!r}: {text!r}"
    assert env.sim.requests[sent:] == []
    assert bus.stats == stats
    assert not bus.closed


def test_every_public_name_is_covered() -> None:
    """The table reaches every public name of every class, but the allow-list."""
    for cls in set(OWNERS.values()):
        public = {n for n in dir(cls) if not n.startswith("_")}
        covered = {c.member for c in CASES if OWNERS[c.owner] is cls}
        assert "__init__" in covered, f"{cls.__name__}: no constructor case"
        assert public - covered == public & set(ALLOWED), f"{cls.__name__}: not covered"
        assert covered - public == {"__init__"}, f"{cls.__name__}: cases for unknown names"
        for name in public & set(ALLOWED):
            assert kind(cls, name) == "constant", f"{cls.__name__}.{name} is not a constant"


def test_each_kind_of_bad_input_is_tried() -> None:
    """The issue's list: wrong types, out of range, NaN / inf, huge ints, negative units,
    empty lists and unknown names each appear among the cases."""
    values = [v for c in CASES for v in (*c.args, *c.kwargs.values())]
    flat = values + [x for v in values if isinstance(v, (list, tuple)) for x in v]
    assert any(isinstance(v, float) and math.isnan(v) for v in flat)
    assert INF in flat and -INF in flat and HUGE in flat and -HUGE in flat
    assert [] in values and "" in values
    negative_units = [c for c in CASES if c.names == "unit" and -1 in c.args]
    assert {OWNERS[c.owner] for c in negative_units} >= {
        bb.Bus,
        bb.Drive,
        bb.PblDrive,
        bb.J2Controller,
        bb.Instrument,
    }
    assert any(c.exc is TypeError for c in CASES) and any(c.exc is ValueError for c in CASES)
    assert any("nope" in map(str, c.args) or "NOPE" in map(str, c.args) for c in CASES)
    assert len(CASES) > 400, len(CASES)


def test_asking_for_nothing_sends_nothing(env: Env) -> None:
    """Empty lists where an empty answer makes sense are not errors: nothing is asked, nothing
    is sent, and the answer is empty. The bus still works after all the refusals."""
    bus, j2 = env.objects["Bus"], env.objects["J2Controller"]
    sent = len(env.sim.requests)
    assert bus.scan([]) == []
    assert j2.read_many([]) == []
    assert j2.write_many({}) is None
    assert j2.write_many([]) is None
    assert env.sim.requests[sent:] == []
    assert bus.read_holding_registers(0x11, 201, 1) == [PblDevice.DEFAULTS[201]]
    assert len(env.sim.requests) == sent + 1
