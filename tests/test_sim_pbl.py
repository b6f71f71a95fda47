"""The simulated PBL-series drive, driven by the raw pseudo-terminal client.

Requests are bytes with a CRC computed bit by bit in test_sim.py, and the manual's example
frames are written out literally, so the tests do not lean on the package's own framing.
The manual's examples talk to unit 0x11, and so do these tests. The motor runs on a clock
that stands still; the tests move it with ``advance``.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from test_sim import Client, crc_valid, frame

from benchbus.sim import PblDevice, Simulator

UNIT = 0x11

# Parameter addresses used below.
CONTROL, CONTROL_HIGH, STATUS, STATUS_HIGH, ALARMS_LOW, ALARMS_HIGH = range(6)
HALL, POSITION, SPEED, CURRENT, BUS_VOLTAGE = 6, 7, 8, 9, 13
CONTROL_MODE, BRAKE_MODE, MIN_SPEED, MAX_SPEED = 100, 114, 123, 124
INTERNAL_SPEED, SPEED_SOURCE, DIRECTION, START_SOURCE, POLE_PAIRS = 201, 202, 203, 204, 205
ACCEL, DECEL, RESTORE, ADDRESS = 209, 210, 214, 215
START, REVERSE = 0x1, 0x2


class Rig:
    """One simulated PBL drive and a raw client that sends it 0x03, 0x06 and 0x10."""

    def __init__(self, sim: Simulator[PblDevice], client: Client, drive: PblDevice) -> None:
        self.sim, self.client, self.drive = sim, client, drive

    def exchange(self, request: bytes, reply_len: int) -> bytes:
        self.client.send(request)
        return self.client.recv(reply_len)

    def read(self, address: int, count: int = 1) -> list[int]:
        """``count`` parameters, in reads of at most 61 (the manual's frame)."""
        if count > PblDevice.max_read:
            head = self.read(address, PblDevice.max_read)
            return head + self.read(address + PblDevice.max_read, count - PblDevice.max_read)
        reply = self.exchange(frame(f"11 03 {address:04X} {count:04X}"), 5 + 2 * count)
        assert crc_valid(reply) and reply[:3] == bytes([UNIT, 3, 2 * count]), reply.hex(" ")
        data = reply[3:-2]
        return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]

    def read_fails(self, address: int, count: int = 1) -> int:
        reply = self.exchange(frame(f"11 03 {address:04X} {count:04X}"), 5)
        assert crc_valid(reply) and reply[:2] == b"\x11\x83", reply.hex(" ")
        return reply[2]

    def write(self, address: int, value: int) -> None:
        """0x06, answered as the manual shows: the address and a register count of 1."""
        reply = self.exchange(frame(f"11 06 {address:04X} {value:04X}"), 8)
        assert reply == frame(f"11 06 {address:04X} 0001"), reply.hex(" ")

    def write_fails(self, address: int, value: int) -> int:
        reply = self.exchange(frame(f"11 06 {address:04X} {value:04X}"), 5)
        assert crc_valid(reply) and reply[:2] == b"\x11\x86", reply.hex(" ")
        return reply[2]

    def _many(self, address: int, values: list[int]) -> bytes:
        data = "".join(f"{v:04X}" for v in values)
        return frame(f"11 10 {address:04X} {len(values):04X} {2 * len(values):02X} {data}")

    def write_many(self, address: int, values: list[int]) -> None:
        """0x10, in writes of at most 59 (the manual's frame)."""
        if len(values) > PblDevice.max_write:
            self.write_many(address, values[: PblDevice.max_write])
            self.write_many(address + PblDevice.max_write, values[PblDevice.max_write :])
            return
        reply = self.exchange(self._many(address, values), 8)
        assert reply == frame(f"11 10 {address:04X} {len(values):04X}"), reply.hex(" ")

    def write_many_fails(self, address: int, values: list[int]) -> int:
        reply = self.exchange(self._many(address, values), 5)
        assert crc_valid(reply) and reply[:2] == b"\x11\x90", reply.hex(" ")
        return reply[2]


@contextmanager
def open_rig(**options: Any) -> Iterator[Rig]:
    options.setdefault("clock", lambda: 0.0)  # time moves only by advance()
    drive = PblDevice(**options)
    with Simulator({UNIT: drive}, baudrate=115200) as sim:
        client = Client(sim.port)
        try:
            yield Rig(sim, client, drive)
            assert sim.errors == []
        finally:
            client.close()


@pytest.fixture
def pbl() -> Iterator[Rig]:
    with open_rig() as rig:
        yield rig


def manual(request: str, reply: str) -> tuple[bytes, bytes]:
    """A request / reply pair as printed; both carry the CRC the manual prints."""
    pair = bytes.fromhex(request), bytes.fromhex(reply)
    assert all(crc_valid(f) for f in pair)
    return pair


# ---- the manual's three examples, byte for byte -------------------------------------------------


def test_manual_read_example(pbl: Rig) -> None:
    # 0x03: parameters 006B..006D of unit 11H read 0x006B, 0x0013, 0x0000.
    pbl.drive.set_param(107, 0x6B)
    pbl.drive.set_param(108, 0x13)
    pbl.drive.set_param(109, 0)
    sent, expected = manual("11 03 00 6B 00 03 76 87", "11 03 06 00 6B 00 13 00 00 38 B9")
    assert pbl.client.transact(sent, len(expected)) == expected


def test_manual_write_single_example(pbl: Rig) -> None:
    # 0x06: parameter 0001H = 0003H. The request is printed with the value 00 01 but the
    # CRC of 00 03 (the value the text names); as printed, its CRC is wrong: no reply.
    printed = bytes.fromhex("11 06 00 01 00 01 9A 9B")
    assert not crc_valid(printed)
    pbl.client.send(printed)
    pbl.client.assert_quiet()
    assert pbl.drive.peek(CONTROL_HIGH) == 0
    # Corrected, it is answered with a register count of 1 instead of the echo.
    sent, expected = manual("11 06 00 01 00 03 9A 9B", "11 06 00 01 00 01 1B 5A")
    assert pbl.client.transact(sent, len(expected)) == expected
    assert pbl.drive.peek(CONTROL_HIGH) == 3


def test_echo_writes_gives_the_standard_echo() -> None:
    with open_rig(echo_writes=True) as rig:
        sent = bytes.fromhex("11 06 00 01 00 03 9A 9B")
        assert rig.client.transact(sent, 8) == sent
        assert rig.drive.peek(CONTROL_HIGH) == 3
        rig.drive.echo_writes = False  # a plain attribute, read at each reply
        assert rig.client.transact(sent, 8) == bytes.fromhex("11 06 00 01 00 01 1B 5A")


def test_manual_write_multiple_example(pbl: Rig) -> None:
    # 0x10: 0001H = 000AH and 0002H = 0102H. Parameter 2 is the motor status: the write is
    # answered, and the status stays what the motor says.
    sent, expected = manual("11 10 00 01 00 02 04 00 0A 01 02 C6 F0", "11 10 00 01 00 02 12 98")
    assert pbl.client.transact(sent, len(expected)) == expected
    assert pbl.read(CONTROL, 3) == [0, 0x0A, 0]


# ---- exceptions ---------------------------------------------------------------------------------


def test_past_222_answers_2(pbl: Rig) -> None:
    assert pbl.read(222) == [100]
    assert len(pbl.read(162, 61)) == 61  # up to 222, in the most one read may ask for
    for address in (223, 224, 0x1000, 0xFFFF):
        assert pbl.read_fails(address) == 0x02
        assert pbl.write_fails(address, 0) == 0x02
    assert pbl.read_fails(220, 4) == 0x02  # a block that runs past 222
    assert pbl.write_many_fails(221, [5, 5, 5]) == 0x02
    assert pbl.drive.params[221] == 3200  # nothing written


@pytest.mark.parametrize(
    ("address", "bad", "good"),
    [
        (CONTROL_MODE, 3, 2),
        (101, 2, 1),
        (112, 2, 1),
        (BRAKE_MODE, 2, 1),
        (121, 2, 1),
        (139, 2, 0),
        (150, 2, 0),
        (151, 3, 2),
        (152, 2, 0),
        (158, 2, 1),
        (161, 1000, 999),
        (162, 1000, 999),
        (180, 2, 1),
        (189, 2, 1),
        (191, 2, 1),
        (195, 2, 0),
        (197, 2, 1),
        (DIRECTION, 2, 1),
        (START_SOURCE, 3, 1),
        (212, 3300, 3299),
        (113, 4, 3),
        (ADDRESS, 0, 255),
        (ADDRESS, 256, 2),
        (217, 3, 2),
        (221, 3300, 0),
        (222, 3300, 3299),
    ],
)
def test_out_of_range_answers_3(pbl: Rig, address: int, bad: int, good: int) -> None:
    before = pbl.drive.params[address]
    assert pbl.write_fails(address, bad) == 0x03
    assert pbl.drive.params[address] == before
    pbl.write(address, good)
    assert pbl.read(address) == [good]


def test_wide_settings_take_any_value(pbl: Rig) -> None:
    for address in (102, 122, MAX_SPEED, 171, INTERNAL_SPEED, ACCEL, RESTORE, 218):
        pbl.write(address, 0xFFFF)
        pbl.write(address, 0)
    pbl.write_many(CONTROL, [0xFFFF, 0xFFFF])  # the control word too


def test_a_write_of_several_is_all_or_nothing(pbl: Rig) -> None:
    assert pbl.write_many_fails(INTERNAL_SPEED, [1500, 0, 0, 5]) == 0x03  # 204 = 5
    assert pbl.read(INTERNAL_SPEED, 4) == [0, 0, 0, 2]
    pbl.write_many(INTERNAL_SPEED, [1500, 1, 1, 2])
    assert pbl.read(INTERNAL_SPEED, 4) == [1500, 1, 1, 2]
    # A control word in the same write as a bad value is not applied either.
    assert pbl.write_many_fails(CONTROL, [START, *[0] * 99, 3]) == 0x03
    assert pbl.read(CONTROL) == [0] and not pbl.drive.running


def test_status_writes_are_answered_and_ignored(pbl: Rig) -> None:
    pbl.write(POLE_PAIRS, 4)
    pbl.write(INTERNAL_SPEED, 1000)
    pbl.write(CONTROL, START)
    pbl.drive.advance(2.0)
    live = pbl.read(STATUS, 98)
    pbl.write_many(STATUS, [0x1234] * 98)
    pbl.write(SPEED, 0)
    pbl.write(30, 7)  # reserved
    assert pbl.read(STATUS, 98) == live
    assert live[STATUS - 2] == 1 and live[SPEED - 2] == 1000
    assert pbl.read(22, 28) == [0] * 28  # reserved 22..49


# ---- the motor ----------------------------------------------------------------------------------


def test_ramp_retarget_and_stop(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write(INTERNAL_SPEED, 3000)
    assert not drive.running and pbl.read(STATUS) == [0]
    pbl.write(CONTROL, START)
    assert drive.running and pbl.read(STATUS) == [1]  # starting
    drive.advance(1.5)  # accel 1000 rpm/s
    assert drive.speed == 1500 and pbl.read(SPEED) == [1500] and pbl.read(50) == [1500]
    drive.advance(1.5)
    assert drive.speed == 3000
    drive.advance(5.0)
    assert drive.speed == 3000
    pbl.write(INTERNAL_SPEED, 2000)  # retarget while running: decel 1000 rpm/s
    drive.advance(0.5)
    assert drive.speed == 2500
    drive.advance(1.0)
    assert drive.speed == 2000
    pbl.write_many(ACCEL, [500, 250])
    pbl.write(INTERNAL_SPEED, 2500)
    drive.advance(0.5)
    assert drive.speed == 2250
    pbl.write(CONTROL, 0)  # stop: ramps down at 250 rpm/s
    drive.advance(1.0)
    assert drive.speed == 2000 and pbl.read(STATUS) == [1]
    drive.advance(8.0)
    assert drive.speed == 0 and not drive.running and pbl.read(STATUS) == [0]


def test_max_speed_caps_the_target(pbl: Rig) -> None:
    pbl.write(MAX_SPEED, 1200)
    pbl.write_many(INTERNAL_SPEED, [5000])
    pbl.write(CONTROL, START)
    pbl.drive.advance(10.0)
    assert pbl.drive.speed == 1200
    pbl.write(MAX_SPEED, 3000)
    pbl.drive.advance(10.0)
    assert pbl.drive.speed == 3000


def test_brake_deceleration_is_four_times_faster(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write(INTERNAL_SPEED, 2000)
    pbl.write(CONTROL, START)
    drive.advance(2.0)
    pbl.write(BRAKE_MODE, 1)
    pbl.write(CONTROL, 0)
    drive.advance(0.25)  # 4000 rpm/s
    assert drive.speed == 1000
    drive.advance(0.25)
    assert drive.speed == 0 and not drive.running
    # Slowing down to a lower speed while running is not a stop: the plain rate.
    pbl.write(CONTROL, START)
    drive.advance(2.0)
    pbl.write(INTERNAL_SPEED, 1000)
    drive.advance(0.5)
    assert drive.speed == 1500


def test_direction_and_its_inversion(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write(INTERNAL_SPEED, 1000)
    pbl.write(CONTROL, START | REVERSE)
    assert pbl.read(STATUS) == [0b11]  # starting, reverse
    drive.advance(2.0)
    assert drive.speed == -1000 and pbl.read(STATUS) == [0b11]
    assert pbl.read(SPEED) == [1000]  # a magnitude
    pbl.write(CONTROL, START)  # reversal: through 0
    drive.advance(0.5)
    assert drive.speed == -500 and pbl.read(STATUS) == [0b11]  # still turning in reverse
    drive.advance(1.0)
    assert drive.speed == 500 and pbl.read(STATUS) == [0b01]
    drive.advance(1.0)
    pbl.write(DIRECTION, 1)  # inverted: forward in the control word turns in reverse
    drive.advance(3.0)
    assert drive.speed == -1000 and pbl.read(STATUS) == [0b11]
    pbl.write(CONTROL, START | REVERSE)
    drive.advance(3.0)
    assert drive.speed == 1000 and pbl.read(STATUS) == [0b01]
    pbl.write(CONTROL, REVERSE)  # stop; bit 1 keeps the last direction of motion
    drive.advance(2.0)
    assert drive.speed == 0 and pbl.read(STATUS) == [0b00]


def test_only_communication_control_starts_the_motor(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write(INTERNAL_SPEED, 1000)
    for source in (0, 1):  # keys, external IO
        pbl.write(START_SOURCE, source)
        pbl.write(CONTROL, START)
        drive.advance(2.0)
        assert drive.speed == 0 and not drive.running
        assert pbl.read(CONTROL) == [START]  # stored all the same
        assert pbl.read(STATUS) == [0]
    pbl.write(START_SOURCE, 2)  # the stored control word now runs the motor
    drive.advance(1.0)
    assert drive.speed == 1000
    pbl.write(START_SOURCE, 0)  # taking control away stops it (decel 1000 rpm/s)
    drive.advance(0.5)
    assert drive.speed == 500
    drive.advance(0.5)
    assert drive.speed == 0 and not drive.running


def test_alarms_stop_the_motor(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write(INTERNAL_SPEED, 1500)
    pbl.write(CONTROL, START)
    drive.advance(2.0)
    assert pbl.read(ALARMS_LOW, 2) == [0, 0]
    drive.inject_alarm(0)
    drive.inject_alarm(17)
    assert drive.alarms == 0x0002_0001
    assert pbl.read(ALARMS_LOW, 2) == [0x0001, 0x0002]
    assert drive.speed == 0 and not drive.running  # at once
    assert pbl.read(CONTROL) == [START]  # the control word stays as written
    drive.advance(2.0)
    assert drive.speed == 0 and pbl.read(STATUS, 2) == [0, 0]
    drive.inject_alarm(31)
    assert pbl.read(ALARMS_LOW, 2) == [0x0001, 0x8002]
    drive.clear_alarms()
    assert pbl.read(ALARMS_LOW, 2) == [0, 0] and drive.alarms == 0
    drive.advance(1.0)  # the control word still says start
    assert drive.speed == 1000


# ---- power and defaults -------------------------------------------------------------------------


def test_defaults(pbl: Rig) -> None:
    drive = pbl.drive
    assert pbl.read(ACCEL, 4) == [1000, 1000, 3000, 100]
    assert pbl.read(INTERNAL_SPEED, 5) == [0, 0, 0, 2, 2]
    assert pbl.read(105) == [2] and pbl.read(MIN_SPEED, 2) == [0, 3000]
    assert pbl.read(ADDRESS) == [1] and pbl.read(RESTORE) == [0]
    assert drive.params == dict(PblDevice.DEFAULTS)
    assert sorted(drive.params) == list(range(100, 223))


def test_restore_defaults_at_the_next_power_up(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write_many(INTERNAL_SPEED, [1500, 1, 1])
    pbl.write(ACCEL, 200)
    pbl.write(CONTROL, START)
    pbl.write(CONTROL_HIGH, 7)
    drive.advance(1.0)
    # Without 1511 a power cycle keeps the settings and clears the control word.
    drive.power_cycle()
    assert drive.speed == 0 and not drive.running
    assert pbl.read(CONTROL, 2) == [0, 0]
    assert pbl.read(INTERNAL_SPEED, 3) == [1500, 1, 1] and pbl.read(ACCEL) == [200]
    assert not drive.restore_pending
    pbl.write(RESTORE, 1511)
    assert drive.restore_pending and pbl.read(RESTORE) == [1511]
    assert pbl.read(ACCEL) == [200]  # not before the power-up
    drive.power_cycle()
    assert not drive.restore_pending
    assert drive.params == dict(PblDevice.DEFAULTS)
    assert pbl.read(RESTORE) == [0]
    # Any other value is only stored.
    pbl.write(RESTORE, 1510)
    pbl.write(ACCEL, 300)
    drive.power_cycle()
    assert pbl.read(ACCEL) == [300]


# ---- broadcast ----------------------------------------------------------------------------------


def test_broadcast_is_acted_on_and_answered_by_each_unit() -> None:
    drives = {0x11: PblDevice(clock=lambda: 0.0), 0x12: PblDevice(clock=lambda: 0.0)}
    with Simulator(drives, baudrate=115200) as sim:
        client = Client(sim.port)
        try:
            client.send(frame("00 06 00 C9 03 E8"))  # 201 = 1000 to all
            assert client.recv(16) == frame("11 06 00 C9 00 01") + frame("12 06 00 C9 00 01")
            client.assert_quiet(0.1)
            client.send(frame("00 10 00 00 00 02 04 00 01 00 00"))  # start, all
            assert client.recv(16) == frame("11 10 00 00 00 02") + frame("12 10 00 00 00 02")
            client.send(frame("00 06 00 DF 00 00"))  # 223: each answers its exception
            assert client.recv(10) == frame("11 86 02") + frame("12 86 02")
            client.assert_quiet(0.1)
            for drive in drives.values():
                drive.advance(1.0)
                assert drive.speed == 1000
            assert sim.errors == []
        finally:
            client.close()


def test_answers_broadcast_false_acts_silently() -> None:
    drives = {
        0x11: PblDevice(answers_broadcast=False, clock=lambda: 0.0),
        0x12: PblDevice(answers_broadcast=False, clock=lambda: 0.0),
    }
    with Simulator(drives, baudrate=115200) as sim:
        client = Client(sim.port)
        try:
            client.send(frame("00 06 00 C9 03 E8"))
            client.assert_quiet()
            assert [d.peek(INTERNAL_SPEED) for d in drives.values()] == [1000, 1000]
            assert sim.replies == []
            # Addressed requests are still answered.
            assert client.transact(frame("12 03 00 C9 00 01"), 7) == frame("12 03 02 03 E8")
        finally:
            client.close()


# ---- measurements -------------------------------------------------------------------------------


def test_measurements_follow_the_motor(pbl: Rig) -> None:
    drive = pbl.drive
    idle = pbl.read(STATUS, 98)

    def at(address: int) -> int:
        return idle[address - STATUS]

    assert at(SPEED) == at(CURRENT) == at(50) == at(53) == at(54) == at(58) == 0
    assert at(BUS_VOLTAGE) == at(51) == 48
    assert at(HALL) in range(1, 7) and at(POSITION) == 0
    drive.analog_input_mv = 1650
    assert pbl.read(52) == [1650] and pbl.read(72) == [1650]
    assert pbl.read(61) == [2048]  # half of a 12-bit reading

    pbl.write(INTERNAL_SPEED, 1500)
    pbl.write(CONTROL, START)
    drive.advance(2.0)
    m = pbl.read(50, 50)  # 50..99

    def got(address: int) -> int:
        return m[address - 50]

    rpm, volts, amps, watts = got(50), got(51), got(53), got(54)
    assert rpm == 1500 and pbl.read(SPEED) == [1500] and got(65) == 1500
    assert volts == 48 and 1 <= amps <= 5 and pbl.read(CURRENT) == [amps]
    assert abs(watts - volts * amps) <= volts / 2
    assert 0 < got(58) < 0xFFFF
    assert got(60) & 0x7 == pbl.read(HALL)[0] and got(60) & 0x8
    # 70..99 repeat the values of 50..69 at their own addresses.
    for address in (72, 73, 74, 78, 80, 85):
        assert got(address) == got(address - 20)
    for address in (90, 95):
        assert got(address) == got(address - 30)
    pbl.write(INTERNAL_SPEED, 3000)
    drive.advance(2.0)
    fast = pbl.read(53, 6)
    assert fast[0] > amps and fast[1] > watts and fast[5] > got(58)
    pbl.write(CONTROL, 0)
    drive.advance(5.0)
    assert pbl.read(53, 2) == [0, 0] and pbl.read(SPEED) == [0]
    drive.bus_voltage = 36
    assert pbl.read(BUS_VOLTAGE) == [36] and pbl.read(51) == [36]


def test_hall_state_and_position(pbl: Rig) -> None:
    drive = pbl.drive
    pbl.write_many(ACCEL, [0, 0])  # no ramps: the speed changes at once
    pbl.write(INTERNAL_SPEED, 300)  # 300 rpm x 2 pole pairs x 6 = 60 hall steps a second
    pbl.write(CONTROL, START)
    drive.advance(1 / 120)  # half-way between two steps
    seen = []
    for _ in range(13):
        seen.append(pbl.read(HALL)[0])
        drive.advance(1 / 60)
    assert set(seen) == {1, 2, 3, 4, 5, 6}
    assert all(bin(a ^ b).count("1") == 1 for a, b in zip(seen, seen[1:]))  # one sensor flips
    assert seen[6:12] == seen[0:6]
    assert pbl.read(POSITION) == [13]
    drive.advance(1090.0)  # 65400 steps more: past the 16-bit wrap
    assert pbl.read(POSITION) == [(13 + 65400) & 0xFFFF]
    pbl.write(CONTROL, START | REVERSE)  # counts down in reverse
    drive.advance(1.0)
    assert pbl.read(POSITION) == [(13 + 65400 - 60) & 0xFFFF]
    drive.power_cycle()
    assert pbl.read(POSITION) == [0]


def test_a_real_clock_is_followed() -> None:
    now = [100.0]
    with open_rig(clock=lambda: now[0]) as rig:
        rig.write(INTERNAL_SPEED, 3000)
        rig.write(CONTROL, START)
        now[0] += 0.5
        assert rig.read(SPEED) == [500]
        rig.drive.advance(0.25)
        now[0] += 0.25
        assert rig.read(SPEED) == [1000]


# ---- the Python side ----------------------------------------------------------------------------


def test_python_access_and_errors() -> None:
    drive = PblDevice(clock=lambda: 0.0)
    assert "stopped" in repr(drive) and "speed=0" in repr(drive)
    assert drive.answers_broadcast and not drive.echo_writes
    assert drive.speed == 0 and not drive.running and drive.alarms == 0
    params = drive.params
    params[ACCEL] = 1
    assert drive.params[ACCEL] == 1000  # a copy
    drive.set_param(INTERNAL_SPEED, 800)
    drive.write_holding(CONTROL, [START])
    drive.advance(1.0)
    assert drive.speed == 800 and drive.peek(SPEED) == 800
    assert "running" in repr(drive) and "speed=800" in repr(drive)
    with pytest.raises(KeyError):
        drive.set_param(CONTROL, 1)  # not a setting
    with pytest.raises(KeyError):
        drive.set_param(223, 0)
    with pytest.raises(ValueError, match=r"0\.\.2"):
        drive.set_param(START_SOURCE, 3)
    with pytest.raises(TypeError):
        drive.set_param(ACCEL, 1.5)  # type: ignore[arg-type]
    with pytest.raises(KeyError):
        drive.peek(223)
    with pytest.raises(KeyError):
        drive.peek(-1)
    with pytest.raises(ValueError):
        drive.advance(-1)
    for bit in (-1, 32, True):
        with pytest.raises(ValueError):
            drive.inject_alarm(bit)
    with pytest.raises(TypeError):
        PblDevice(clock=5)  # type: ignore[arg-type]
    drive.inject_alarm(3)
    assert "alarms=0x00000008" in repr(drive)
    assert PblDevice.DEFAULTS[ACCEL] == 1000
    with pytest.raises(TypeError):
        PblDevice.DEFAULTS[ACCEL] = 1  # type: ignore[index]
