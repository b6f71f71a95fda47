"""Each simulator's register map, held against the library's table (the compiled core's).

The simulators are independent readings of the manuals: they declare their registers in
their own form, and the library's tables are not imported into them. This holds the two
readings together where both speak (address, access, range, scale), asking each simulator
through its Modbus handlers (``read_holding`` / ``write_holding``: the exception codes a
unit answers) rather than through its internals, so that a register added to one side only,
a range typed differently or a scale that disagrees fails here. Where the two disagreed,
the manual decided (see the comments in the Rust tables and the CHANGELOG).
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

import benchbus as bb
from benchbus._core import J2Core, PblCore
from benchbus.sim import (
    DriveDevice,
    J2Device,
    PblDevice,
    SimDevice,
    SimException,
    Simulator,
    TaisongDevice,
)

Row = tuple[str, int, float, str, str, float, float]

#: The drive families' address blocks (manual 000 / 001, B.3): settings, status, telemetry.
DRIVE_BLOCKS = (range(0x2000, 0x2020), range(0x2100, 0x2110), range(0x3000, 0x3020))
COMMAND = 0x2000  # the command register: an action, not in the table of either side


class Clock:
    """A clock that moves only when told (the models are evaluated from it)."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def answer(action: Callable[[], object]) -> int:
    """0 when the unit accepts, else the exception code it answers."""
    try:
        action()
    except SimException as exc:
        return int(exc.code)
    return 0


def write(device: SimDevice, address: int, value: int) -> int:
    """0 when ``device`` takes ``value`` at ``address``, else the exception code it answers."""
    return answer(lambda: device.write_holding(address, [value]))


def drive_table(model: str) -> list[Row]:
    family = "C20" if model == "C20" else "BLD"
    with Simulator({1: DriveDevice(model)}) as sim, bb.Drive(sim.port, family=family) as drive:
        return drive.registers()


@pytest.fixture(scope="module", params=["BLD2", "BLD3H", "C20"])
def drive_model(request: pytest.FixtureRequest) -> tuple[str, list[Row]]:
    return request.param, drive_table(request.param)


def raw(value: float, scale: float) -> int:
    return round(value / scale)


def test_drive_addresses_are_the_same(drive_model: tuple[str, list[Row]]) -> None:
    model, rows = drive_model
    device = DriveDevice(model)
    answered = {
        address
        for block in DRIVE_BLOCKS
        for address in block
        if answer(lambda a=address: device.read_holding(a, 1)) != SimException.ILLEGAL_DATA_ADDRESS
    }
    assert answered - {COMMAND} == {row[1] for row in rows}


def test_drive_access_and_ranges_are_the_same(drive_model: tuple[str, list[Row]]) -> None:
    model, rows = drive_model
    wrong = []
    for name, address, scale, _, access, low, high in rows:
        device = DriveDevice(model)
        if access == "R":
            code = write(device, address, 0)
            if code != 0x07:  # parameter is read-only
                wrong.append(f"{name}: read-only in the table, the simulator answers {code}")
            continue
        lo, hi = raw(low, scale), raw(high, scale)
        for value, expected in ((lo, 0), (hi, 0), (lo - 1, 3), (hi + 1, 3)):
            if 0 <= value <= 0xFFFF:
                code = write(device, address, value)
                if code != expected:
                    wrong.append(f"{name} = {value} (table {lo}..{hi}): answered {code}")
        running = running_drive(model)
        code = write(running, address, lo)
        expected = 0x08 if access == "W/R*" else 0  # W/R*: not changeable while running
        if code != expected:
            wrong.append(f"{name} ({access}) written while running: answered {code}")
    assert wrong == []


def running_drive(model: str) -> DriveDevice:
    device = DriveDevice(model, clock=Clock())
    device.write_holding(0x2001, [1000])
    device.write_holding(COMMAND, [1])  # forward
    device.advance(0.5)
    assert device.speed > 0
    return device


def test_drive_scales_are_the_same() -> None:
    """The library's readings (raw x its table's scale) are the simulated drive's own
    quantities in their units (rpm, V, degC, Hz)."""
    device = DriveDevice("BLD2", clock=Clock())
    device.analog_inputs = [1.23, 4.56, 9.87]
    device.temperature = 30.0
    with Simulator({1: device}) as sim, bb.Drive(sim.port) as drive:
        drive.speed_setpoint = 1500
        drive.accel_time = 0.1
        drive.forward()
        device.advance(10.0)
        t = drive.telemetry()
        pole_pairs = device.peek(0x2002)
    assert t.speed == pytest.approx(device.speed) == 1500
    hertz = 1500 * pole_pairs / 60
    assert t.set_frequency == pytest.approx(hertz)
    assert t.output_frequency == pytest.approx(hertz)
    assert t.bus_voltage == pytest.approx(DriveDevice.BUS_VOLTAGE / 10)  # the sim's 0.1 V
    assert t.software_version == pytest.approx(DriveDevice.SOFTWARE_VERSION / 100)
    assert [t.ai1_voltage, t.ai2_voltage, t.ai3_voltage] == pytest.approx(device.analog_inputs)
    # The heat sink warms with the current: 0.5 degC per ampere in the model.
    assert t.temperature == pytest.approx(30.0 + 0.5 * t.output_current, abs=0.05)


def test_pbl_parameters_access_and_ranges_are_the_same() -> None:
    table = PblCore.table()
    assert [row[0] for row in table] == list(range(len(table)))
    device = PblDevice(clock=Clock())
    assert answer(lambda: device.read_holding(len(table) - 61, 61)) == 0  # up to the last
    assert answer(lambda: device.read_holding(len(table), 1)) == SimException.ILLEGAL_DATA_ADDRESS
    wrong = []
    for number, name, _, access, low, high in table:
        device = PblDevice(clock=Clock())
        if access == "R":
            # The manual's live values (2..99): a write is taken and ignored.
            before = device.peek(number)
            code = write(device, number, (before + 1) & 0xFFFF)
            if code != 0 or device.peek(number) != before:
                wrong.append(f"{number} {name}: read-only in the table, written in the simulator")
            continue
        lo, hi = int(low), int(high)
        for value, expected in ((lo, 0), (hi, 0), (lo - 1, 3), (hi + 1, 3)):
            if 0 <= value <= 0xFFFF:
                code = write(device, number, value)
                if code != expected:
                    wrong.append(f"{number} {name} = {value} (table {lo}..{hi}): answered {code}")
    assert wrong == []


#: J2 parameters the manual (003, the signed table) gives "LSP~USP" for, which the library
#: checks against the widest range only (a hysteresis or a ramp rate held to the setpoint
#: limits cannot be meant literally; the controller refuses what it does not take), while
#: the simulator, reading the manual literally, holds them to the LSP..USP in effect.
J2_LIMITS_READ_APART = frozenset({"HY1", "HY2", "HYS", "RAP", "TRL", "TRH", "SRT", "TOP"})


def test_j2_parameters_are_the_same() -> None:
    table = {row[0]: row[1:] for row in J2Core.table()}
    assert list(table) == list(J2Device.PARAMETERS)
    wrong = []
    for name, (address, signed, writable, low, high, within_limits) in table.items():
        sim_address, sim_low, sim_high, sim_scale = J2Device.PARAMETERS[name]
        theirs = (sim_address, sim_scale == 10, name not in J2Device.READ_ONLY)
        between = name in J2Device.BETWEEN_LSP_USP
        if name in J2_LIMITS_READ_APART:
            assert (within_limits, between) == (False, True), name  # still read apart
            between = within_limits
        theirs += (sim_low, sim_high, between)
        ours = (address, signed, writable, low, high, within_limits)
        if ours != pytest.approx(theirs):
            wrong.append(f"{name}: table {ours}, simulator {theirs}")
    assert wrong == []
    # Signed values are tenths on the wire in both (the simulator's scale 10).
    assert {J2Device.PARAMETERS[n][3] for n, row in table.items() if row[1]} == {10}
    assert {J2Device.PARAMETERS[n][3] for n, row in table.items() if not row[1]} == {1}


def test_instrument_request_limits_are_the_same() -> None:
    device = TaisongDevice()
    with Simulator({1: device}) as sim, bb.Instrument(sim.port) as inst:
        assert (inst.max_read, inst.max_write) == (device.max_read, device.max_write) == (37, 20)


def _largest_read(sim: Simulator, unit: int) -> int:
    """The most registers one 0x03 request to ``unit`` the simulator heard asked for."""
    return max(int.from_bytes(r[4:6], "big") for r in sim.requests if r[:2] == bytes([unit, 3]))


def test_pbl_and_j2_request_limits_are_the_same() -> None:
    # The library's block reads (its request limits, in the Rust tables) fill each request up
    # to the simulator's limit (its reading of the manual), and no further.
    pbl, j2 = PblDevice(), J2Device()
    with Simulator({0x11: pbl, 1: j2}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        bb.PblDrive(bus, unit=0x11).parameters()
        bb.J2Controller(bus, unit=1).parameters()
        assert _largest_read(sim, 0x11) == pbl.max_read == 61
        # J2 parameters sit on even addresses and a block ends on one: 15 of the 16 allowed.
        assert j2.max_read == 16
        assert _largest_read(sim, 1) == j2.max_read - 1
