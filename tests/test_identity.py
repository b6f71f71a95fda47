"""A device object checks that its unit is of its family before its first exchange, and a
value its enum does not list reads as that enum's UNKNOWN value, in every family.

The simulators are the families' own (:mod:`benchbus.sim`); the check reads what ``benchbus
scan`` reads, so a drive object on a J2 controller's unit must raise ``WrongDevice`` before
any write, and send nothing after."""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable, Iterator
from enum import IntEnum
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, J2Device, PblDevice, RegisterDevice, Simulator


@pytest.fixture(scope="module")
def line() -> Iterator[tuple[Simulator[Any], bb.Bus]]:
    """A drive at unit 1, a PBL at unit 2, a J2 at unit 3."""
    devices = {1: DriveDevice("BLD2"), 2: PblDevice(), 3: J2Device(speedup=50)}
    with Simulator(devices) as sim, bb.Bus(sim.port, timeout=0.15, retries=0) as bus:
        yield sim, bus


UNITS = {"drive": 1, "pbl": 2, "j2": 3}
NAMES = {"drive": "a BLD drive", "pbl": "a PBL drive", "j2": "a J2 controller"}
MADE: dict[str, Callable[..., Any]] = {
    "drive": bb.Drive,
    "pbl": bb.PblDrive,
    "j2": bb.J2Controller,
}
#: A read and a write of each family (a write the family's own unit takes).
READ: dict[str, Callable[[Any], object]] = {
    "drive": lambda d: d.speed,
    "pbl": lambda d: d.status(),
    "j2": lambda d: d.pv,
}
WRITE: dict[str, Callable[[Any], object]] = {
    "drive": lambda d: setattr(d, "speed_setpoint", 600),
    "pbl": lambda d: d.start(),
    "j2": lambda d: setattr(d, "sv", 60.0),
}
WRITES = {0x05, 0x06, 0x0F, 0x10, 0x16, 0x17}


def functions_sent(sim: Simulator[Any], since: int) -> list[int]:
    """The function codes of the requests the simulator saw from request ``since`` on."""
    return [frame[1] for frame in sim.requests[since:]]


PAIRS = [(made, other) for made in UNITS for other in UNITS if made != other]


@pytest.mark.parametrize(("made", "other"), PAIRS)
def test_a_unit_of_another_family_raises_wrong_device_before_any_write(
    line: tuple[Simulator[Any], bb.Bus], made: str, other: str
) -> None:
    sim, bus = line
    device = MADE[made](bus, UNITS[other])
    sent = sim.request_count
    with pytest.raises(bb.WrongDevice) as raised:
        WRITE[made](device)
    error = raised.value
    assert isinstance(error, bb.BenchbusError)
    assert (error.unit, error.expected, error.looks_like) == (UNITS[other], made, other)
    assert f"is not {NAMES[made]}: it looks like {NAMES[other]}" in str(error)
    assert "check_identity=False" in str(error)
    assert not WRITES & set(functions_sent(sim, sent)), "the check only reads"
    # Every later call raises it again, with nothing sent.
    checked = sim.request_count
    for call in (READ[made], WRITE[made], type(device).verify_identity):
        with pytest.raises(bb.WrongDevice, match="looks like"):
            call(device)
    assert sim.request_count == checked


@pytest.mark.parametrize("made", ["drive", "pbl"])
@pytest.mark.parametrize("leaving", ["normally", "by an exception"])
def test_leaving_the_block_of_a_wrong_device_writes_nothing(
    line: tuple[Simulator[Any], bb.Bus], made: str, leaving: str
) -> None:
    sim, bus = line
    sent = sim.request_count
    with pytest.raises(bb.WrongDevice), MADE[made](bus, UNITS["j2"]) as device:
        if leaving == "normally":
            pass  # the stop on leaving is the first exchange: checked, refused
        else:
            READ[made](device)
    assert not WRITES & set(functions_sent(sim, sent))
    assert not bus.closed  # a shared Bus stays open


def test_the_check_reads_once_and_then_the_calls_go_as_before(
    line: tuple[Simulator[Any], bb.Bus],
) -> None:
    sim, bus = line
    sent = sim.request_count
    drive = bb.Drive(bus, UNITS["drive"])
    assert sim.request_count == sent  # making it sends nothing
    drive.speed_setpoint = 900
    checked = sim.request_count - sent
    assert checked >= 2  # the model code, then the write
    assert drive.speed_setpoint == 900
    assert sim.request_count - sent == checked + 1


@pytest.mark.parametrize("made", list(UNITS))
def test_check_identity_false_sends_the_call_alone(
    line: tuple[Simulator[Any], bb.Bus], made: str
) -> None:
    sim, bus = line
    other = next(o for o in UNITS if o != made)
    device = MADE[made](bus, UNITS[other], check_identity=False)
    sent = sim.request_count
    device.verify_identity()  # nothing to check
    assert sim.request_count == sent
    with pytest.raises(bb.BenchbusError) as raised:  # the other unit refuses the register
        WRITE[made](device)
    assert not isinstance(raised.value, bb.WrongDevice)


def test_a_unit_off_at_first_is_checked_when_it_answers(
    line: tuple[Simulator[Any], bb.Bus],
) -> None:
    sim, bus = line
    drive, j2 = bb.Drive(bus, UNITS["j2"]), bb.J2Controller(bus, UNITS["j2"])
    sim.set_silent(UNITS["j2"])
    try:
        with pytest.raises(bb.ResponseTimeout) as raised:
            drive.speed_setpoint = 500
        assert "while checking that unit 3 is a BLD drive" in raised.value.__notes__
        with pytest.raises(bb.ResponseTimeout):
            _ = j2.pv
    finally:
        sim.set_silent(UNITS["j2"], False)
    with pytest.raises(bb.WrongDevice, match="looks like a J2 controller"):
        drive.speed_setpoint = 500
    assert 0 < j2.pv < 1000  # the J2 itself is vouched for now


def test_the_stop_on_leaving_by_an_exception_goes_without_the_check(
    line: tuple[Simulator[Any], bb.Bus],
) -> None:
    sim, bus = line
    sent = sim.request_count
    with pytest.raises(KeyError), bb.Drive(bus, UNITS["drive"]):
        raise KeyError("before any exchange")
    frames = sim.requests[sent:]
    assert [f[1] for f in frames] == [0x06]  # the stop alone: no identity reads first
    assert frames[0][2:6] == bytes([0x20, 0x00, 0x00, 0x05])  # command 5, stop


def test_async_devices_check_too() -> None:
    import asyncio

    async def main(port: str) -> None:
        async with bb.aio.AsyncBus(port, timeout=0.15) as shared:
            drive = bb.aio.Drive(shared, 1)
            with pytest.raises(bb.WrongDevice, match="looks like a PBL drive"):
                await drive.verify_identity()
            with pytest.raises(bb.WrongDevice):
                await drive.speed

    with Simulator({1: PblDevice()}) as sim:
        asyncio.run(main(sim.port))
        assert not WRITES & set(functions_sent(sim, 0))


# ---- values an enum does not list --------------------------------------------------------


def address(rows: Any, name: str) -> int:
    """The address of the row called ``name`` of a family's table (a PBL's by number)."""
    row = next(r for r in rows if r.name == name)
    return int(getattr(row, "address", getattr(row, "number", -1)))


PROFILE = """
[device]
name = "oven"
[[register]]
name = "mode"
address = 0x10
enum = { 0 = "off", 1 = "heat", 2 = "cool" }
access = "rw"
"""


def unlisted() -> list[tuple[str, Callable[[bb.Bus], Any], int, Callable[[Any], Any], type]]:
    """(what, make the device, address, read, enum) of an enum register of every family."""
    return [
        (
            "drive state",
            lambda bus: bb.Drive(bus, 1, check_identity=False),
            0x2100,
            lambda d: d.state,
            bb.DriveState,
        ),
        (
            "drive status",
            lambda bus: bb.Drive(bus, 1, check_identity=False),
            0x2100,
            lambda d: d.status().state,
            bb.DriveState,
        ),
        (
            "pbl control mode",
            lambda bus: bb.PblDrive(bus, 1, check_identity=False),
            address(bb.PblDrive.table(), "control_mode"),
            lambda d: d.control_mode,
            bb.PblControlMode,
        ),
        (
            "j2 mode",
            lambda bus: bb.J2Controller(bus, 1, check_identity=False),
            address(bb.J2Controller.table(), "AM"),
            lambda d: d.mode,
            bb.J2Mode,
        ),
        # By name, as the attribute reads it.
        (
            "drive get",
            lambda bus: bb.Drive(bus, 1, check_identity=False),
            0x2100,
            lambda d: d.get("state"),
            bb.DriveState,
        ),
        (
            "pbl get_many",
            lambda bus: bb.PblDrive(bus, 1, check_identity=False),
            address(bb.PblDrive.table(), "control_mode"),
            lambda d: d.get_many(["control_mode"])["control_mode"],
            bb.PblControlMode,
        ),
        (
            "j2 read",
            lambda bus: bb.J2Controller(bus, 1, check_identity=False),
            address(bb.J2Controller.table(), "AM"),
            lambda d: d.read("am"),
            bb.J2Mode,
        ),
    ]


@pytest.mark.parametrize(
    ("what", "make", "at", "read", "enum"), unlisted(), ids=[u[0] for u in unlisted()]
)
def test_a_value_its_enum_does_not_list_reads_as_unknown_in_every_family(
    what: str,
    make: Callable[[bb.Bus], Any],
    at: int,
    read: Callable[[Any], Any],
    enum: type[IntEnum],
) -> None:
    model = RegisterDevice({at: 57})
    with Simulator({1: model}) as sim, bb.Bus(sim.port) as bus:
        value = read(make(bus))
    assert type(value) is enum and value == 57
    assert bb.is_unknown(value) and value.name == "UNKNOWN"
    assert str(value) == f"{enum.__name__}.UNKNOWN(57)"
    assert all(value != member for member in enum)
    for again in (pickle.loads(pickle.dumps(value)), copy.deepcopy(value)):
        assert type(again) is enum and again == 57 and bb.is_unknown(again)
    assert not bb.is_unknown(next(iter(enum))) and not bb.is_unknown(57)


def test_get_and_get_many_read_an_enum_register_as_its_attribute_does() -> None:
    with Simulator({1: DriveDevice()}) as sim, bb.Drive(sim.port) as drive:
        state = drive.get("state")
        assert type(state) is bb.DriveState and state is drive.state
        got = drive.get_many(["state", "speed_setpoint", "command_source"])
        assert got == {"state": state, "speed_setpoint": 0, "command_source": 2}
        assert type(got["command_source"]) is bb.CommandSource
        assert type(got["speed_setpoint"]) is int
    with Simulator({1: J2Device()}) as sim, bb.J2Controller(sim.port) as j2:
        mode, sv = j2.read_many(["am", "SV"])
        assert (type(mode), mode) == (bb.J2Mode, j2.mode) and type(sv) is float


def test_a_profile_enum_reads_its_unlisted_value_as_unknown(tmp_path: Path) -> None:
    path = tmp_path / "oven.toml"
    path.write_text(PROFILE)
    model = RegisterDevice({0x10: 7})
    with Simulator({1: model}) as sim, bb.Bus(sim.port) as bus:
        oven = bb.Device.from_profile(path, bus)
        value = oven.mode
        assert type(value) is oven.enums["mode"] and value == 7 and bb.is_unknown(value)
        assert str(value) == "Mode.UNKNOWN(7)"
        model.registers[0x10] = 2
        assert oven.mode is oven.enums["mode"].cool and not bb.is_unknown(oven.mode)
