"""Every device family is built through one path: the same checks of the unit, the device's
own timeout and retries, with the same messages, before anything is sent."""

from __future__ import annotations

import inspect
import os
import select

import pytest

import benchbus as bb
from conftest import ScriptedSlave

FAMILIES = {
    "PblDrive": lambda bus, **kw: bb.PblDrive(bus, **kw),
    "J2Controller": lambda bus, **kw: bb.J2Controller(bus, **kw),
    "Instrument": lambda bus, **kw: bb.Instrument(bus, **kw),
}


def nothing_sent(slave: ScriptedSlave) -> bool:
    """Whether the line carried no byte."""
    return not select.select([slave.master], [], [], 0.05)[0] or not os.read(slave.master, 256)


@pytest.mark.parametrize("family", sorted(FAMILIES))
@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"unit": 256}, ValueError, r"^unit must be 1 to 255, got 256$"),
        ({"unit": "1"}, TypeError, r"unit must be an int"),
        ({"unit": 1, "timeout": -1}, ValueError, r"timeout"),
        ({"unit": 1, "retries": 101}, ValueError, r"^retries must be 0 to 100, got 101$"),
        ({"unit": 1, "retries": True}, TypeError, r"retries"),
    ],
)
def test_bad_station_arguments_are_refused_alike(
    slave: ScriptedSlave,
    family: str,
    kwargs: dict[str, object],
    error: type[Exception],
    message: str,
) -> None:
    with (
        bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus,
        pytest.raises(error, match=message),
    ):
        FAMILIES[family](bus, **kwargs)
    assert nothing_sent(slave)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_every_family_stands_on_the_bus_and_unit_given(slave: ScriptedSlave, family: str) -> None:
    with bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus:
        device = FAMILIES[family](bus, unit=9, timeout=0.2, retries=0)
        assert device.bus is bus
        assert device.unit == 9


def test_the_pbl_drive_is_its_compiled_class_with_nothing_forwarded() -> None:
    from benchbus._core import PblCore

    assert issubclass(bb.PblDrive, PblCore)
    for name in ("start", "stop", "read_parameter", "write_parameter", "read_parameters"):
        assert name not in vars(bb.PblDrive), name
    for name in ("parameters", "table", "sample", "units", "running", "alarms", "alarm_word"):
        assert name not in vars(bb.PblDrive), name
    # The sample block is the Rust table's, and what sample() reads.
    assert bb.PblDrive.SAMPLE_FIELDS == (
        "speed",
        "bus_voltage",
        "analog_speed_input",
        "current",
        "power",
    )


def test_a_pbl_drive_keeps_no_core_and_refuses_unknown_attributes(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus:
        pbl = bb.PblDrive(bus, unit=3)
        assert "core" not in vars(pbl)
        assert repr(pbl).startswith("<PblDrive unit=3 on ")
        with pytest.raises(AttributeError, match="speed_setpoint"):
            pbl.speed_setpoin = 5  # type: ignore[attr-defined]
    assert nothing_sent(slave)


def test_the_instrument_is_its_compiled_class_with_nothing_forwarded() -> None:
    from benchbus._core import InstrumentCore

    assert issubclass(bb.Instrument, InstrumentCore)
    for name in ("read_register", "write_register", "read_registers", "write_registers"):
        assert name not in vars(bb.Instrument), name
    for name in ("read_long", "write_long", "read_float", "write_float", "read_string"):
        assert name not in vars(bb.Instrument), name
    for name in ("write_string", "identify", "max_read", "max_write", "min_write_interval"):
        assert name not in vars(bb.Instrument), name
    # The compiled methods keep the defaults users see.
    assert "order='ABCD'" in str(inspect.signature(bb.Instrument.read_long))
    assert "*, function=6" in str(inspect.signature(bb.Instrument.write_register))
    assert "level='basic'" in str(inspect.signature(bb.Instrument.identify))


def test_an_instrument_keeps_no_core_and_identifies_typed() -> None:
    from benchbus.sim import Atv31Device, Simulator

    with Simulator({2: Atv31Device()}) as sim, bb.Bus(sim.port) as bus:
        meter = bb.Instrument(bus, unit=2, max_read=29)
        assert "core" not in vars(meter)
        assert repr(meter).startswith("<Instrument unit=2 on ")
        assert (meter.max_read, meter.max_write) == (29, 20)
        ident = meter.identify("regular")
        assert type(ident) is bb.Identification
        assert ident.vendor == "TELEMECANIQUE" and ident.objects[1] == "ATV31HU09M3S232"
        assert sim.requests[-1][:5] == bytes.fromhex("02 2B 0E 02 00")
        with pytest.raises(AttributeError, match="max_read"):
            meter.max_reed = 5  # type: ignore[attr-defined]


def test_the_j2_controller_is_its_compiled_class_with_the_groups_from_the_table() -> None:
    from benchbus._core import J2Core

    assert issubclass(bb.J2Controller, J2Core)
    for name in ("read", "write", "read_many", "write_many", "parameters", "table", "units"):
        assert name not in vars(bb.J2Controller), name
    for name in ("sample", "set_output", "start_ramp", "stop_ramp"):
        assert name not in vars(bb.J2Controller), name
    # The groups' results come typed from the compiled class itself.
    for name in ("status", "pid", "pid2", "limits"):
        assert name not in vars(bb.J2Controller), name
        assert name in vars(J2Core), name
    assert bb.J2Controller.SAMPLE_FIELDS == ("pv", "sv", "mv")


def test_the_tables_rows_are_named_tuples_that_still_unpack() -> None:
    pbl = bb.PblDrive.table()
    assert all(isinstance(row, bb.PblParameter) for row in pbl)
    number, name, unit, access, low, high = pbl[50]
    assert (
        (pbl[50].number, pbl[50].name, pbl[50].unit) == (number, name, unit) == (50, "speed", "rpm")
    )
    assert (pbl[50].access, pbl[50].low, pbl[50].high) == (access, low, high)
    j2 = {row.name: row for row in bb.J2Controller.table()}
    assert all(isinstance(row, bb.J2Parameter) for row in j2.values())
    sv = j2["SV"]
    assert sv.within_limits and sv.signed and sv.writable
    assert sv == (sv.name, sv.address, sv.signed, sv.writable, sv.low, sv.high, True)
    assert not j2["PV"].writable


def test_the_drive_is_its_compiled_class_with_nothing_forwarded() -> None:
    from benchbus._core import DriveCore

    assert issubclass(bb.Drive, DriveCore)
    commands = [name for name, _code in DriveCore.commands()]
    for name in (*commands, "get", "set", "registers", "read_parameter", "write_parameter"):
        assert name not in vars(bb.Drive), name
    for name in ("status", "telemetry", "sample", "units", "baud_rate", "set_baud_rate"):
        assert name not in vars(bb.Drive), name
    assert bb.Drive.SAMPLE_FIELDS is not None and bb.Drive.SAMPLE_FIELDS[-1] == "hall_count"


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        # A drive's units are the standard 1..247, not the 1..255 of the other families.
        ({"unit": 248}, ValueError, r"^unit must be 1 to 247, got 248$"),
        ({"unit": 0}, ValueError, r"^unit must be 1 to 247, got 0$"),
        ({"unit": "1"}, TypeError, r"unit must be an int"),
        ({"unit": 1, "timeout": -1}, ValueError, r"timeout"),
        ({"unit": 1, "retries": 101}, ValueError, r"^retries must be 0 to 100, got 101$"),
        ({"unit": 1, "family": "XYZ"}, ValueError, r"^family must be \"BLD\""),
    ],
)
def test_bad_drive_arguments_are_refused_before_anything_is_sent(
    slave: ScriptedSlave, kwargs: dict[str, object], error: type[Exception], message: str
) -> None:
    with (
        bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus,
        pytest.raises(error, match=message),
    ):
        bb.Drive(bus, **kwargs)  # type: ignore[arg-type]
    assert nothing_sent(slave)


def test_a_drive_keeps_no_core_and_stands_on_the_bus_and_unit_given(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus:
        drive = bb.Drive(bus, unit=247, family="C20", timeout=0.2, retries=0)
        assert "core" not in vars(drive)
        assert (drive.bus, drive.unit, drive.family) == (bus, 247, "C20")
        assert (drive.timeout, drive.retries, drive.write_ack) == (0.2, 0, True)
        assert drive.block_reads is None
        assert repr(drive).startswith("<Drive unit=247 family=C20 on ")
        with pytest.raises(AttributeError, match="speed_setpoint"):
            drive.speed_setpoin = 5  # type: ignore[attr-defined]
        shared = bb.Drive(bus, 3)
        assert (shared.timeout, shared.retries) == (0.05, bus.retries)
    assert nothing_sent(slave)


class _OnUnit5:
    """A user's subclass whose ``__init__`` takes its own arguments: the unit is its own."""

    def __init__(self, bus: bb.Bus, label: str) -> None:
        super().__init__(bus, 5)  # type: ignore[call-arg]
        self.label = label


@pytest.mark.parametrize("family", [bb.Drive, bb.PblDrive, bb.J2Controller, bb.Instrument])
def test_a_subclass_with_its_own_init_arguments_is_attached_by_its_init(
    slave: ScriptedSlave, family: type[bb.Instrument]
) -> None:
    # The compiled base is made empty and attached by __init__, as any Python class is built,
    # so a subclass's __init__ decides the arguments (here the unit: 5, not the default 1).
    mine = type(f"My{family.__name__}", (_OnUnit5, family), {})
    with bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus:
        device = mine(bus, "left")
        assert (device.unit, device.bus, device.label) == (5, bus, "left")
    assert nothing_sent(slave)


@pytest.mark.parametrize("family", [bb.Drive, bb.PblDrive, bb.J2Controller, bb.Instrument])
def test_a_device_whose_init_did_not_run_says_so_and_is_attached_once(
    slave: ScriptedSlave, family: type[bb.Instrument]
) -> None:
    empty = family.__new__(family, "/dev/not-opened", 3)
    with pytest.raises(RuntimeError, match=r"not attached to a Bus: its class's __init__"):
        _ = empty.unit
    with pytest.raises(RuntimeError, match="not attached to a Bus"):
        _ = empty.bus
    if family is not bb.Instrument:  # a call to the device, as well as its identity
        with pytest.raises(RuntimeError, match="not attached to a Bus"):
            empty.sample()
    with bb.Bus(slave.port, baudrate=19200, timeout=0.05) as bus:
        device = family(bus, 3)
        with pytest.raises(RuntimeError, match="attached to a Bus already"):
            device.__init__(bus, 4)  # type: ignore[misc]
        assert device.unit == 3
    assert nothing_sent(slave)


def test_compiled_methods_do_not_show_self_as_a_parameter() -> None:
    """A bound compiled method's signature lists only what the caller passes: its text
    signature marks the instance as ``$self`` (a plain ``self`` shows up as a parameter,
    in ``help()`` and in the async devices built from the same signatures)."""
    from benchbus import _core

    meter = bb.Instrument.__new__(bb.Instrument)
    for cls in vars(_core).values():
        if not isinstance(cls, type):
            continue
        for name, member in vars(cls).items():
            text = getattr(member, "__text_signature__", None)
            if text is None or name.startswith("__"):
                continue
            assert not text.startswith("(self"), f"{cls.__name__}.{name}: {text}"
    assert "self" not in inspect.signature(meter.read_long).parameters
