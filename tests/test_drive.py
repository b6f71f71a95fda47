"""benchbus.Drive through the real serial path against the simulated BLD2 / BLD3H / C20 drive.

The frames of the manuals' "常用命令举例" tables are checked on the simulator's side of the
line, byte for byte, for the Python call that makes each of them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import re
import time
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus._core import DriveCore
from benchbus._device import RegisterProperty
from benchbus.sim import DriveDevice, SimException, Simulator
from conftest import FakeClock


def h(text: str) -> bytes:
    return bytes.fromhex(text)


Rig = tuple[bb.Drive, Simulator[DriveDevice], DriveDevice]


@contextlib.contextmanager
def open_drive(model: str = "BLD2", **options: object) -> Iterator[Rig]:
    """A simulated drive of ``model`` and a Drive on its line (family from the model)."""
    device = DriveDevice(model, **options)  # type: ignore[arg-type]
    family = "C20" if model == "C20" else "BLD"
    with Simulator(device) as sim, bb.Drive(sim.port, family=family) as drive:
        drive.verify_identity()  # its reads out of the way of the frames a test counts
        sim.clear_log()
        yield drive, sim, device


@pytest.fixture(params=["BLD2", "C20"])
def any_family(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """Both families, on drives that take one register per read, as the manuals describe."""
    with open_drive(request.param, single_register_reads=True) as line:
        yield line


@pytest.fixture
def bld() -> Iterator[Rig]:
    with open_drive("BLD2") as line:
        yield line


@pytest.fixture
def c20() -> Iterator[Rig]:
    with open_drive("C20") as line:
        yield line


def exchanged(sim: Simulator[DriveDevice], request: str, reply: str) -> bool:
    """Whether ``request`` went out and ``reply`` answered that very request.

    Every request in these tests is answered, so the n-th reply answers the n-th request.
    """
    assert len(sim.requests) == len(sim.replies)
    return (h(request), h(reply)) in zip(sim.requests, sim.replies)


# ---- the manuals' common commands, byte for byte ------------------------------------------


def test_manual_command_frames(any_family: Rig) -> None:
    drive, sim, device = any_family
    drive.forward()
    assert exchanged(sim, "01 06 20 00 00 01 43 CA", "01 06 20 00 00 01 43 CA")
    assert device.state == bb.DriveState.FORWARD
    drive.reverse()
    assert exchanged(sim, "01 06 20 00 00 02 03 CB", "01 06 20 00 00 02 03 CB")
    drive.stop()
    assert exchanged(sim, "01 06 20 00 00 05 42 09", "01 06 20 00 00 05 42 09")
    drive.reset_fault()
    assert exchanged(sim, "01 06 20 00 00 07 C3 C8", "01 06 20 00 00 07 C3 C8")
    drive.speed_setpoint = 3000
    assert exchanged(sim, "01 06 20 01 0B B8 D4 88", "01 06 20 01 0B B8 D4 88")
    assert device.commands == [1, 2, 5, 7]


def test_every_command_of_the_table_is_a_method_that_sends_its_code(bld: Rig) -> None:
    """The command codes are declared once, in the core's table; each is a Drive method."""
    drive, _sim, device = bld
    table = DriveCore.commands()
    assert [code for _name, code in table] == list(range(1, 10))
    for name, code in table:
        method = getattr(drive, name)
        assert f"(command {code})" in (method.__doc__ or "")
        method()
        assert device.commands[-1] == code
    # Each is a method of the compiled base, made from its row, with nothing in Python
    # between; a name that is not a row is no command at all.
    for name, _code in table:
        assert name in vars(DriveCore) and name not in vars(bb.Drive), name
    with pytest.raises(AttributeError, match="Forward"):
        drive.Forward  # type: ignore[attr-defined]  # noqa: B018


def test_property_docs_say_what_the_register_table_says(bld: Rig) -> None:
    """The address, range and "stopped only" in each property's docstring are the table's."""

    def number(text: str) -> float:
        return float(int(text, 16) if text.startswith("0x") else text)

    drive, _sim, _device = bld
    table = {row[0]: row for row in drive.registers()}
    checked = 0
    for attribute in vars(bb.Drive).values():
        if not isinstance(attribute, RegisterProperty):
            continue
        _name, address, _scale, _unit, access, low, high = table[attribute.register]
        doc = attribute.__doc__ or ""
        assert f"(0x{address:04X}" in doc, doc
        assert ("stopped only" in doc) == (access == "W/R*"), doc
        span = re.search(r"(\S+)\.\.(\S+?)[ )]", doc)
        if span is not None:
            assert (number(span[1]), number(span[2])) == (low, high), doc
        checked += 1
    assert checked == 10


def test_manual_parameter_frames(any_family: Rig) -> None:
    drive, sim, device = any_family
    # 读功能码: F00.10 reads 50.00 Hz (0x1388).
    assert drive.read_parameter("F00.10") == 0x1388
    assert sim.requests[-1] == h("01 03 00 0A 00 01 A4 08")
    assert sim.replies[-1] == h("01 03 02 13 88 B5 12")
    # 写功能码: F00.10 = 25.00 Hz, with 0x200E enabled around it. Putting the enable back to
    # 0 is the frame the manual labels "使能功能码可写" (its erratum: it writes 0).
    drive.write_parameter("F00.10", 0x09C4)
    assert exchanged(sim, "01 06 00 0A 09 C4 AE 0B", "01 06 00 0A 09 C4 AE 0B")
    assert sim.requests[-1] == h("01 06 20 0E 00 00 E3 C9")
    assert sim.replies[-1] == h("01 06 20 0E 00 00 E3 C9")
    assert device.params[0x000A] == 0x09C4
    assert device.peek(0x200E) == 0
    # 读失败: F00.50 does not exist.
    with pytest.raises(bb.ModbusException) as e:
        drive.read_parameter("F00.50")
    assert (e.value.code, e.value.frame) == (2, "01 83 02 C0 F1")
    assert sim.requests[-1] == h("01 03 00 32 00 01 25 C5")
    # 写失败: F00.00 = 5 is out of range.
    with pytest.raises(bb.ModbusException) as e:
        drive.write_parameter("F00.00", 5)
    assert (e.value.code, e.value.frame) == (3, "01 86 03 02 61")
    assert "F00.00 = 5" in str(e.value)
    assert h("01 06 00 00 00 05 49 C9") in sim.requests
    assert device.peek(0x200E) == 0  # put back after the refusal too


def test_manual_status_frames(any_family: Rig) -> None:
    drive, sim, device = any_family
    # 读状态字 2, read singly by status(): 0x0041 is bus voltage up, communication control
    # and bit 4 clear, which is "not overloaded" on the BLD and "overloaded" by the C20's
    # text (its example was printed with the BLD's value; a healthy C20 reads 0x0051).
    c20 = drive.family == "C20"
    device.overloaded = c20
    status = drive.status()
    assert exchanged(sim, "01 03 21 01 00 01 DF F6", "01 03 02 00 41 78 74")
    assert status.bus_voltage_ready and status.overloaded == c20
    assert status.keypad_connected is (None if c20 else False)
    device.overloaded = False
    assert not drive.status().overloaded
    assert device.peek(0x2101) == (0x51 if c20 else 0x41)
    assert status.control_source == bb.CommandSource.COMMUNICATION
    assert status.state == bb.DriveState.STOPPED and status.fault is None
    # 读故障码: 0x0A undervoltage.
    device.inject_fault(0x0A)
    fault = drive.fault
    assert fault == bb.Fault(0x0A, "undervoltage")
    assert exchanged(sim, "01 03 21 02 00 01 2F F6", "01 03 02 00 0A 38 43")
    assert drive.state == bb.DriveState.FAULT
    drive.reset_fault()
    assert drive.fault is None
    # 读状态字 1: the OFF state.
    device.power_off()
    assert drive.state == bb.DriveState.OFF
    assert sim.requests[-1] == h("01 03 21 00 00 01 8E 36")
    assert sim.replies[-1] == h("01 03 02 00 05 78 47")
    assert drive.block_reads is False


def test_bld_status_word_2_is_the_manuals_example(bld: Rig) -> None:
    drive, sim, _ = bld
    assert drive.get("status_word") == 0x41
    assert sim.requests[-1] == h("01 03 21 01 00 01 DF F6")
    assert sim.replies[-1] == h("01 03 02 00 41 78 74")
    # Its fields by name, from the same reply (bit 0, bits 5..6 = 2, bit 7), and as
    # status() gives them.
    before = len(sim.requests)
    fields = drive.get_many(["bus_voltage_ready", "control_source", "keypad_connected"])
    assert fields == {"bus_voltage_ready": True, "control_source": 2, "keypad_connected": False}
    assert [type(v) for v in fields.values()] == [bool, int, bool]
    assert sim.requests[before:] == [h("01 03 21 01 00 01 DF F6")]
    status = drive.status()
    assert (status.bus_voltage_ready, status.keypad_connected) == (True, False)
    assert status.control_source == bb.CommandSource.COMMUNICATION
    assert status.overloaded is False


# ---- properties -------------------------------------------------------------------------------


BOTH: list[tuple[str, object, int, int]] = [
    ("speed_setpoint", 1500, 0x2001, 1500),
    ("pole_pairs", 4, 0x2002, 4),
    ("accel_time", 2.5, 0x2003, 25),
    ("decel_time", 600.0, 0x2004, 6000),
    ("command_source", bb.CommandSource.TERMINAL, 0x2006, 1),
    ("speed_source", bb.SpeedSource.SIMPLE_PLC, 0x2007, 6),
    ("virtual_inputs", 0x1FF, 0x200A, 0x1FF),
    ("virtual_outputs", 0x0F, 0x200B, 0x0F),
]


def round_trip(
    drive: bb.Drive, device: DriveDevice, cases: list[tuple[str, object, int, int]]
) -> None:
    """Set each property, see the raw word in the drive, and read the same value back."""
    for name, value, address, raw in cases:
        setattr(drive, name, value)
        assert device.peek(address) == raw, name
        got = getattr(drive, name)
        assert got == value and type(got) is type(value), name


def test_c20_settings_round_trip(c20: Rig) -> None:
    drive, _, device = c20
    cases = [*BOTH, ("control_mode", bb.C20ControlMode.CLOSED_LOOP, 0x2005, 2)]
    round_trip(drive, device, cases)


def test_settings_round_trip(bld: Rig) -> None:
    drive, _, device = bld
    cases = [
        *BOTH,
        ("control_mode", bb.ControlMode.SENSORLESS_VECTOR, 0x2005, 4),
        ("speed_source", bb.SpeedSource.CAN, 0x2007, 8),  # 7, 8: BLD only
        ("stop_mode", bb.StopMode.COAST, 0x2012, 1),
    ]
    round_trip(drive, device, cases)
    drive.accel_time = 0.1
    assert drive.accel_time == 0.1


def test_c20_enums_and_ranges(c20: Rig) -> None:
    drive, sim, device = c20
    drive.control_mode = bb.C20ControlMode.DIP_SWITCH
    assert drive.control_mode is bb.C20ControlMode.DIP_SWITCH
    drive.command_source = bb.CommandSource.DIP_SWITCH
    assert drive.command_source is bb.CommandSource.DIP_SWITCH
    drive.set_station_address(200)
    assert device.peek(0x2008) == 200 and drive.station_address == 200
    sent = len(sim.requests)
    with pytest.raises(ValueError):
        drive.control_mode = bb.ControlMode.SENSORLESS_VECTOR  # 4: BLD only
    with pytest.raises(ValueError):
        drive.speed_source = bb.SpeedSource.PULSE  # 7: BLD only
    with pytest.raises(ValueError, match="BLD drives only"):
        drive.brake()
    with pytest.raises(ValueError, match="BLD drives only"):
        drive.stop_mode = bb.StopMode.COAST
    with pytest.raises(ValueError, match="BLD drives only"):
        drive.clear_hall_count()
    with pytest.raises(ValueError):
        drive.set_baud_rate(115200)
    assert len(sim.requests) == sent


def test_configuration_methods() -> None:
    clock = FakeClock()
    with open_drive("BLD2", clock=clock) as (drive, _, device):
        configure(drive, device, clock)


def configure(drive: bb.Drive, device: DriveDevice, clock: FakeClock) -> None:
    assert drive.baud_rate == 19200
    drive.set_baud_rate(9600)
    assert device.peek(0x2009) == 3 and drive.baud_rate == 9600
    with pytest.raises(ValueError):
        drive.set_baud_rate(14400)
    with pytest.raises(ValueError):
        drive.set_station_address(200)  # BLD: 1..127
    drive.write_parameter("F08.03", 20)
    assert device.params[0x0803] == 20
    drive.restore_defaults()
    assert device.params[0x0803] == 5
    drive.speed_setpoint = 600
    drive.forward()
    clock.now += 10.0
    assert drive.telemetry().hall_count
    drive.coast()
    drive.clear_hall_count()
    assert drive.telemetry().hall_count == 0


def test_model() -> None:
    for model, family, expected in [
        ("BLD2", "BLD", bb.Model.BLD2),
        ("BLD3H", "BLD", bb.Model.BLD3H),
        ("C20", "C20", bb.Model.C20),
    ]:
        with Simulator(DriveDevice(model)) as sim, bb.Drive(sim.port, family=family) as drive:
            assert drive.model is expected


def test_the_model_enum_is_the_cores_model_table(caplog: pytest.LogCaptureFixture) -> None:
    """Each model is declared once, in the core: name, code, family; the enum follows it."""
    table = DriveCore.models()
    assert [name for name, _id, _family in table] == [m.value for m in bb.Model]
    for name, code, family in table:
        assert DriveCore.model_from_id(family, code) == name
        with (
            Simulator(DriveDevice(name)) as sim,
            bb.Drive(sim.port, family=family) as drive,
            caplog.at_level("WARNING", logger="benchbus.drive"),
        ):
            assert drive.model is bb.Model(name)
    assert caplog.text == ""  # each model on its own family: nothing to report


# ---- errors -----------------------------------------------------------------------------------


def test_errors_in_their_cases(bld: Rig) -> None:
    drive, sim, device = bld
    sent = len(sim.requests)
    for name, value in [
        ("speed_setpoint", 3001),
        ("speed_setpoint", -1),
        ("pole_pairs", 0),
        ("pole_pairs", 21),
        ("accel_time", 0.05),
        ("accel_time", 2.55),
        ("decel_time", 600.1),
        ("virtual_inputs", 0x200),
        ("speed_setpoint", float("nan")),
    ]:
        with pytest.raises(ValueError):
            setattr(drive, name, value)
    with pytest.raises(TypeError):
        drive.speed_setpoint = "1500"  # type: ignore[assignment]
    with pytest.raises(AttributeError):
        drive.speed = 5  # type: ignore[misc]
    with pytest.raises(ValueError):
        drive.read_parameter("F11.00")
    with pytest.raises(ValueError):
        drive.write_parameter("F00.10", 0x10000)
    assert len(sim.requests) == sent  # nothing went out

    drive.forward()
    with pytest.raises(bb.ModbusException) as e:
        drive.pole_pairs = 3  # W/R*: only while stopped
    assert e.value.code == 8 and e.value.meaning == "not changeable while running"
    with pytest.raises(bb.ModbusException) as e:
        drive.write_parameter("F08.03", 10)
    assert e.value.code == 8 and "F08.03 = 10" in str(e.value)
    drive.coast()
    with pytest.raises(bb.ModbusException) as e:
        drive.bus.write_register(1, 0x2100, 1)  # read-only on this family: 0x07
    assert e.value.code == 7
    device.inject_fault(0x0A)
    with pytest.raises(bb.ModbusException) as e:
        drive.forward()  # the drive refuses to run while faulted
    assert e.value.code == 1
    assert e.value.unit == 1 and e.value.function == 0x06


def test_parameter_write_refused_without_enable_on_the_raw_bus(
    bld: Rig,
) -> None:
    drive, _, device = bld
    with pytest.raises(bb.ModbusException) as e:
        drive.bus.write_register(1, 0x000A, 100)
    assert e.value.code == 4
    assert device.params[0x000A] == 5000


# ---- reads, writes and timing options -----------------------------------------------------


def test_block_reads_are_used_when_allowed() -> None:
    with open_drive("BLD2", single_register_reads=False) as (drive, sim, _):
        sim.clear_log()
        snapshot = drive.telemetry()
        assert len(sim.requests) == 1 and sim.requests[0][:6] == h("01 03 30 00 00 15")
        assert drive.block_reads is True
        assert isinstance(snapshot.hall_count, int)


def test_the_default_simulated_drive_reads_one_register_a_request() -> None:
    with open_drive("BLD2") as (drive, sim, _):
        sim.clear_log()
        drive.telemetry()
        assert sim.replies[0][:3] == h("01 83 03")  # the block read refused: exception 3
        assert drive.block_reads is False


def test_single_register_drive_falls_back_once() -> None:
    with open_drive("C20", single_register_reads=True) as (drive, sim, _):
        sim.clear_log()
        first = drive.telemetry()
        assert len(sim.requests) == 1 + 18
        sim.clear_log()
        drive.telemetry()
        assert len(sim.requests) == 18  # remembered: no block attempt
        assert first.hall_count is None


def test_telemetry_is_consistent() -> None:
    clock = FakeClock()
    with open_drive("BLD2", clock=clock) as (drive, _, _):
        drive.pole_pairs = 4
        drive.accel_time = 2.0
        drive.speed_setpoint = 3000
        drive.forward()
        clock.now += 1.0
        t = drive.telemetry()
        assert t.speed == 1500
        assert t.output_frequency == pytest.approx(1500 * 4 / 60, abs=0.02)
        assert t.set_frequency == pytest.approx(3000 * 4 / 60, abs=0.02)
        assert t.output_current > 0 and 0 < t.bus_voltage < 2000
        assert t.speed_reference == 3000
        clock.now += 5.0
        assert drive.speed == 3000
        assert drive.telemetry().output_current > t.output_current


def test_unanswered_writes() -> None:
    with open_drive("BLD2") as (drive, sim, device):
        device.set_param(0x0806, 1)  # set on the keypad: the drive answers no write
        assert device.params[0x0806] == 1
        with pytest.raises(bb.ResponseTimeout):
            drive.speed_setpoint = 1000  # this drive still waits for a reply
        quiet = bb.Drive(drive.bus, write_ack=False)
        # After a timeout the Bus first listens for a late reply (up to two timeouts): a
        # read takes that wait, so the writes below are timed on their own.
        assert quiet.state == bb.DriveState.STOPPED
        start = time.monotonic()
        replies = len(sim.replies)
        quiet.speed_setpoint = 1200
        quiet.forward()
        assert time.monotonic() - start < 0.2  # no timeout waited
        assert len(sim.replies) == replies
        # The read comes after the writes, answered once the simulator has taken them: only
        # then is the register looked at (the writes wait for nothing).
        assert quiet.state == bb.DriveState.FORWARD
        assert device.peek(0x2001) == 1200
        quiet.coast()  # F08.06 is W/R*: stopped only
        quiet.write_parameter("F08.06", 0)  # answered again, so the stop on exit is too
        assert device.params[0x0806] == 0


def test_reply_delay_within_the_drive_timeout() -> None:
    device = DriveDevice()
    with Simulator(device) as sim:
        with bb.Drive(sim.port) as drive:
            drive.write_parameter("F08.03", 150)
            start = time.monotonic()
            assert drive.speed == 0  # the drive's own Bus waits 0.25 s: enough
            assert time.monotonic() - start >= 0.15
        assert device.params[0x0803] == 150
        impatient = bb.Drive(sim.port, timeout=0.1, retries=0)
        with pytest.raises(bb.ResponseTimeout):
            _ = impatient.speed
        impatient.close()


def test_shared_bus_and_arguments() -> None:
    with (
        Simulator({1: DriveDevice(), 2: DriveDevice("BLD3H")}) as sim,
        bb.Bus(sim.port, timeout=0.25) as bus,
    ):
        one, two = bb.Drive(bus, 1), bb.Drive(bus, unit=2)
        assert one.bus is bus and two.unit == 2
        assert (one.model, two.model) == (bb.Model.BLD2, bb.Model.BLD3H)
        one.close()
        assert not bus.closed  # a shared Bus stays open
        with pytest.raises(ValueError):
            bb.Drive(bus, 248)
        with pytest.raises(ValueError):
            bb.Drive(bus, 1, family="XYZ")


# ---- the context manager and waiting ------------------------------------------------------------


def test_leaving_the_block_stops_the_motor() -> None:
    device = DriveDevice()
    with Simulator(device) as sim:
        with bb.Drive(sim.port) as drive:
            drive.speed_setpoint = 500
            drive.forward()
        assert device.commands == [1, 5]
        assert drive.bus.closed
        for error in (RuntimeError("bench failed"), KeyboardInterrupt()):
            with pytest.raises(type(error)), bb.Drive(sim.port) as drive:
                drive.forward()
                raise error
            assert device.commands[-2:] == [1, 5]


def test_wait_for_speed() -> None:
    with open_drive("BLD2") as (drive, _, _):
        drive.accel_time = 0.5
        drive.speed_setpoint = 1500
        with pytest.raises(TimeoutError, match="not within"):
            drive.wait_for_speed(1500, tolerance=10, timeout=0.2)
        drive.forward()
        reached = drive.wait_for_speed(1500, tolerance=30, timeout=5)
        assert abs(reached - 1500) <= 30
        with pytest.raises(ValueError):
            drive.wait_for_speed(-5)


def test_a_drive_on_a_shared_bus_can_wait_longer_than_the_bus() -> None:
    device = DriveDevice()
    device.set_param(0x0803, 150)  # F08.03: reply after 150 ms
    with Simulator(device) as sim, bb.Bus(sim.port, timeout=0.1, retries=0) as bus:
        with pytest.raises(bb.ResponseTimeout):
            bus.read_holding_registers(1, 0x3006, 1)
        patient = bb.Drive(bus, timeout=0.3)
        assert (patient.timeout, patient.retries) == (0.3, 0)
        assert patient.speed == 0
        assert bus.timeout == 0.1  # the Bus keeps its own


def test_parameter_write_still_refused_after_the_enable() -> None:
    class Locked(DriveDevice):
        """Refuses F00.10 with 0x04 even with 0x200E = 1 (a locked parameter)."""

        def write_holding(self, address: int, values: list[int]) -> None:
            if address == 0x000A:
                raise SimException(0x04)
            super().write_holding(address, values)

    device = Locked()
    with Simulator(device) as sim, bb.Drive(sim.port) as drive:
        with pytest.raises(bb.ModbusException) as e:
            drive.write_parameter("F00.10", 2500)
        assert e.value.code == 4
        assert "operation failed" in str(e.value) and "F00.10 = 2500" in str(e.value)
        assert device.params[0x000A] == 5000
        assert device.peek(0x200E) == 0  # put back


def test_firmware_without_hall_registers() -> None:
    with open_drive("BLD2", hall_registers=False, single_register_reads=False) as (drive, sim, _):
        first = drive.telemetry()
        sim.clear_log()
        second = drive.telemetry()
        assert first.hall_count is None and second.hall_count is None
        assert sim.requests == [h("01 03 30 00 00 12 ca c7")]  # 18 registers, one request
        assert first.units["output_current"] == "A" and first.units["temperature"] == "°C"


def test_leaving_the_block_ends_a_jog() -> None:
    device = DriveDevice()
    with Simulator(device) as sim:
        with bb.Drive(sim.port) as drive:
            drive.jog_forward()
        assert device.commands == [3, 8, 5]


def test_a_model_of_the_other_family_is_reported(caplog: pytest.LogCaptureFixture) -> None:
    with Simulator(DriveDevice("BLD3H")) as sim, bb.Drive(sim.port, family="C20") as drive:
        with caplog.at_level("WARNING", logger="benchbus.drive"):
            assert drive.model is bb.Model.BLD3H
        assert "family C20" in caplog.text


# ---- the compiled base and the table ------------------------------------------------------------


def test_the_telemetry_fields_are_the_cores_measurement_rows(bld: Rig) -> None:
    """DriveTelemetry is written out for its docs and types; its fields are the table's."""
    drive, _sim, _device = bld
    fields = tuple(f.name for f in dataclasses.fields(bb.DriveTelemetry) if f.name != "units")
    assert fields == DriveCore.SAMPLE_FIELDS == bb.Drive.SAMPLE_FIELDS
    assert "SAMPLE_FIELDS" not in vars(bb.Drive)
    table = {row.name: row for row in drive.registers()}
    for field in dataclasses.fields(bb.DriveTelemetry):
        if field.name in table:
            assert field.type in ("int", "float")
            assert (field.type == "int") == (table[field.name].scale == 1.0), field.name
    assert list(drive.sample()) == list(fields)


class OddStatus(DriveDevice):
    """Reports a state and a control source the manuals do not list."""

    def read_holding(self, address: int, count: int) -> list[int]:
        words = super().read_holding(address, count)
        return [{0x2100: 9, 0x2101: 0x61}.get(address + i, w) for i, w in enumerate(words)]


def test_status_comes_typed_from_the_compiled_base() -> None:
    assert "status" not in vars(bb.Drive) and "telemetry" not in vars(bb.Drive)
    with open_drive("BLD2") as (drive, _sim, device):
        status = drive.status()
        assert type(status) is bb.DriveStatus
        assert type(status.state) is bb.DriveState
        assert type(status.control_source) is bb.CommandSource
        assert status.fault is None
        device.inject_fault(0x1B)
        assert drive.status().fault == bb.Fault(0x1B, "unknown fault 0x1B")
        assert type(drive.telemetry()) is bb.DriveTelemetry
    with Simulator(OddStatus()) as sim, bb.Drive(sim.port) as drive:
        status = drive.status()
        assert (status.state, status.control_source) == (9, 3)
        assert type(status.state) is bb.DriveState and bb.is_unknown(status.state)
        assert type(status.control_source) is bb.CommandSource
        assert drive.state == 9 and str(drive.state) == "DriveState.UNKNOWN(9)"


def test_registers_are_named_rows_that_still_unpack(any_family: Rig) -> None:
    drive, _sim, _device = any_family
    rows = drive.registers()
    assert all(type(row) is bb.DriveRegister for row in rows)
    speed = next(row for row in rows if row.name == "speed_setpoint")
    name, address, scale, unit, access, low, high = speed
    assert (name, address, unit, access, low, high) == (
        "speed_setpoint",
        0x2001,
        "rpm",
        "W/R",
        0,
        3000,
    )
    assert scale == 1.0 and speed.high == speed[6]
    assert " ".join(speed._fields) == "name address scale unit access low high"
    station = next(row for row in rows if row.name == "station_address")
    assert station.high == (247.0 if drive.family == "C20" else 127.0)
    assert ("stop_mode" in {row.name for row in rows}) == (drive.family == "BLD")
    assert rows == DriveCore._table(drive.family)
    assert drive.units() == {row.name: row.unit for row in rows}
