"""The simulated BLD2 / BLD3H / ZBLD.C20 drive, driven by the raw pseudo-terminal client.

Requests are bytes with a CRC computed bit by bit in test_sim.py, and the manuals' example
frames are written out literally, so the tests do not lean on the package's own framing.
The motor runs on a clock that stands still; the tests move it with ``advance``.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from test_sim import Client, crc_valid, frame

from benchbus.sim import DriveDevice, Simulator

# Register addresses used below.
COMMAND, SETPOINT, POLE_PAIRS, ACCEL, DECEL = 0x2000, 0x2001, 0x2002, 0x2003, 0x2004
STATE, STATUS2, FAULT_CODE, MODEL_ID = 0x2100, 0x2101, 0x2102, 0x2103
WRITE_ENABLE, RESTORE, STOP_MODE = 0x200E, 0x200F, 0x2012
F00_00, F00_10, F08_03, F08_06 = 0x0000, 0x000A, 0x0803, 0x0806
FORWARD, REVERSE, JOG_FORWARD, JOG_REVERSE, STOP, COAST, RESET, JOG_STOP, BRAKE = range(1, 10)


class Rig:
    """One simulated drive at unit 1 and a raw client that sends it 0x03, 0x06 and 0x10."""

    def __init__(self, sim: Simulator[DriveDevice], client: Client, drive: DriveDevice) -> None:
        self.sim, self.client, self.drive = sim, client, drive

    def exchange(self, request: bytes, reply_len: int) -> bytes:
        self.client.send(request)
        return self.client.recv(reply_len)

    def read(self, address: int, count: int = 1) -> list[int]:
        reply = self.exchange(frame(f"01 03 {address:04X} {count:04X}"), 5 + 2 * count)
        assert crc_valid(reply) and reply[:3] == bytes([1, 3, 2 * count]), reply.hex(" ")
        data = reply[3:-2]
        return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]

    def read_fails(self, address: int, count: int = 1) -> int:
        reply = self.exchange(frame(f"01 03 {address:04X} {count:04X}"), 5)
        assert crc_valid(reply) and reply[:2] == b"\x01\x83", reply.hex(" ")
        return reply[2]

    def write(self, address: int, value: int) -> None:
        request = frame(f"01 06 {address:04X} {value:04X}")
        assert self.exchange(request, 8) == request

    def write_fails(self, address: int, value: int) -> int:
        reply = self.exchange(frame(f"01 06 {address:04X} {value:04X}"), 5)
        assert crc_valid(reply) and reply[:2] == b"\x01\x86", reply.hex(" ")
        return reply[2]

    def _many(self, address: int, values: list[int]) -> bytes:
        data = "".join(f"{v:04X}" for v in values)
        return frame(f"01 10 {address:04X} {len(values):04X} {2 * len(values):02X} {data}")

    def write_many(self, address: int, values: list[int]) -> None:
        reply = self.exchange(self._many(address, values), 8)
        assert reply == frame(f"01 10 {address:04X} {len(values):04X}")

    def write_many_fails(self, address: int, values: list[int]) -> int:
        reply = self.exchange(self._many(address, values), 5)
        assert crc_valid(reply) and reply[:2] == b"\x01\x90", reply.hex(" ")
        return reply[2]

    def enable_parameter_writes(self) -> None:
        self.write(WRITE_ENABLE, 1)


@contextmanager
def open_rig(model: str = "BLD2", **options: Any) -> Iterator[Rig]:
    options.setdefault("clock", lambda: 0.0)  # time moves only by advance()
    # Block reads, to check many registers at once; the default refusal has its own test.
    options.setdefault("single_register_reads", False)
    drive = DriveDevice(model, **options)
    with Simulator(drive) as sim:
        client = Client(sim.port)
        try:
            yield Rig(sim, client, drive)
            assert sim.errors == []
        finally:
            client.close()


@pytest.fixture
def bld() -> Iterator[Rig]:
    with open_rig("BLD2") as rig:
        yield rig


@pytest.fixture
def c20() -> Iterator[Rig]:
    with open_rig("C20") as rig:
        yield rig


@pytest.fixture(params=DriveDevice.MODELS)
def any_model(request: pytest.FixtureRequest) -> Iterator[Rig]:
    with open_rig(request.param) as rig:
        yield rig


# ---- the manuals' "common commands" table, byte for byte ------------------------------------


def manual(request: str, reply: str) -> tuple[bytes, bytes]:
    """A request / reply pair as printed; both carry the CRC the manual prints."""
    pair = bytes.fromhex(request), bytes.fromhex(reply)
    assert all(crc_valid(f) for f in pair)
    return pair


def test_common_commands_table(any_model: Rig) -> None:
    rig, drive = any_model, any_model.drive
    client = rig.client

    def check(request: str, reply: str) -> None:
        sent, expected = manual(request, reply)
        assert client.transact(sent, len(expected)) == expected

    check("01 06 20 00 00 01 43 CA", "01 06 20 00 00 01 43 CA")  # forward
    assert drive.state == DriveDevice.FORWARD
    check("01 06 20 00 00 02 03 CB", "01 06 20 00 00 02 03 CB")  # reverse
    assert drive.state == DriveDevice.REVERSE
    check("01 06 20 00 00 05 42 09", "01 06 20 00 00 05 42 09")  # stop
    check("01 06 20 00 00 07 C3 C8", "01 06 20 00 00 07 C3 C8")  # fault reset
    assert drive.state == DriveDevice.STOPPED
    assert drive.commands == [FORWARD, REVERSE, STOP, RESET]
    check("01 06 20 01 0B B8 D4 88", "01 06 20 01 0B B8 D4 88")  # setpoint 3000 rpm
    assert drive.peek(SETPOINT) == 3000

    # "Enable parameter writes": the frame writes 0 to 0x200E (the text says 0x200F = 1),
    # so parameter writes stay disabled.
    check("01 06 20 0E 00 00 E3 C9", "01 06 20 0E 00 00 E3 C9")
    assert drive.peek(WRITE_ENABLE) == 0
    assert rig.write_fails(F00_10, 0x09C4) == 0x04
    check("01 03 00 0A 00 01 A4 08", "01 03 02 13 88 B5 12")  # F00.10 = 50.00 Hz
    rig.enable_parameter_writes()
    check("01 06 00 0A 09 C4 AE 0B", "01 06 00 0A 09 C4 AE 0B")  # F00.10 = 25.00 Hz
    assert drive.params[F00_10] == 2500

    drive.power_off()
    check("01 03 21 00 00 01 8E 36", "01 03 02 00 05 78 47")  # state 5: off
    drive.power_on()
    if drive.model == "C20":
        drive.overloaded = True  # the C20 text: bit 4 = 0 means overloaded
    check("01 03 21 01 00 01 DF F6", "01 03 02 00 41 78 74")  # status word 2
    drive.inject_fault(0x0A)
    check("01 03 21 02 00 01 2F F6", "01 03 02 00 0A 38 43")  # fault 0x0A, undervoltage
    check("01 03 00 32 00 01 25 C5", "01 83 02 C0 F1")  # F00.50 does not exist
    check("01 06 00 00 00 05 49 C9", "01 86 03 02 61")  # F00.00 = 5 is out of range
    assert drive.params[F00_00] == 0


def test_function_format_examples(bld: Rig) -> None:
    # The 0x06 and 0x03 format examples (0x2001 = 1, read back), and the 0x10 example
    # writing 0x2000 and 0x2001 together.
    bld.write(SETPOINT, 1)
    assert bld.client.transact(frame("01 03 20 01 00 01"), 7) == frame("01 03 02 00 01")
    bld.write_many(COMMAND, [FORWARD, 1500])
    assert bld.drive.state == DriveDevice.FORWARD
    assert bld.read(0x3005) == [1500]


# ---- exception codes ----------------------------------------------------------------------------


def test_unknown_addresses_answer_2(bld: Rig) -> None:
    for address in (0x200C, 0x200D, 0x2013, 0x2104, 0x3015, 0x0032, 0x0003, 0x0807, 0xFFFF):
        assert bld.read_fails(address) == 0x02
        assert bld.write_fails(address, 0) == 0x02
    assert bld.read_fails(0x200A, 4) == 0x02  # a block that runs into 0x200C
    assert bld.write_many_fails(0x200B, [1, 0]) == 0x02
    assert bld.drive.peek(0x200B) == 0  # all or nothing


def test_read_only_registers_answer_7(bld: Rig) -> None:
    for address in (STATE, STATUS2, FAULT_CODE, MODEL_ID, 0x3000, 0x3006, 0x3014):
        assert bld.write_fails(address, 0) == 0x07
    assert bld.write_many_fails(0x2102, [0, 0]) == 0x07


def test_out_of_range_values_answer_3(bld: Rig) -> None:
    bld.enable_parameter_writes()
    for address, value in [
        (COMMAND, 0),
        (COMMAND, 10),
        (SETPOINT, 3001),
        (POLE_PAIRS, 0),
        (POLE_PAIRS, 21),
        (ACCEL, 0),
        (DECEL, 6001),
        (0x2006, 4),
        (0x200A, 0x200),
        (0x200B, 0x10),
        (WRITE_ENABLE, 2),
        (RESTORE, 2),
        (STOP_MODE, 2),
        (F00_00, 3),
        (F00_10, 99),
        (F00_10, 40001),
        (F08_03, 201),
        (0x0805, 1),
    ]:
        assert bld.write_fails(address, value) == 0x03, hex(address)
    assert bld.drive.commands == []
    # A 0x10 write is checked register by register and applies nothing if one fails.
    assert bld.write_many_fails(SETPOINT, [1000, 4, 0]) == 0x03
    assert bld.read(SETPOINT, 4) == [0, 2, 50, 50]
    bld.write_many(SETPOINT, [1000, 4, 30])
    assert bld.read(SETPOINT, 4) == [1000, 4, 30, 50]


def test_parameter_writes_need_0x200e_and_answer_4(bld: Rig) -> None:
    drive = bld.drive
    assert bld.read(F00_10) == [5000]  # always readable
    assert bld.write_fails(F00_10, 2500) == 0x04
    assert bld.write_fails(F08_03, 10) == 0x04
    bld.write(WRITE_ENABLE, 1)
    bld.write(F00_10, 2500)
    bld.write_many(0x0800, [9, 3])  # F08.00 station address, F08.01 baud code
    bld.write(WRITE_ENABLE, 0)
    assert bld.write_fails(F00_10, 3000) == 0x04
    assert drive.params[F00_10] == 2500
    # 0x2008 and 0x2009 are the same settings as F08.00 and F08.01.
    assert bld.read(0x2008, 2) == [9, 3]


def test_not_while_running_answers_8(bld: Rig) -> None:
    drive = bld.drive
    bld.enable_parameter_writes()
    bld.write(SETPOINT, 1000)
    bld.write(COMMAND, FORWARD)
    drive.advance(0.5)
    for address, value in [
        (POLE_PAIRS, 4),
        (0x2005, 1),
        (0x2008, 2),
        (0x2009, 3),
        (RESTORE, 1),
        (0x0005, 1),
        (0x0800, 2),
        (F08_03, 10),
        (F08_06, 1),
    ]:
        assert bld.write_fails(address, value) == 0x08, hex(address)
    # W/R registers stay writable while running.
    bld.write(SETPOINT, 1200)
    bld.write(ACCEL, 20)
    bld.write(F00_10, 6000)
    # A 0x10 write is applied in order: the run command comes first, so the pole pairs
    # that follow are refused, and the whole write with them.
    bld.write(COMMAND, STOP)
    drive.advance(10)
    assert drive.state == DriveDevice.STOPPED
    assert bld.write_many_fails(COMMAND, [FORWARD, 1000, 4]) == 0x08
    assert drive.state == DriveDevice.STOPPED
    assert drive.commands == [FORWARD, STOP]
    bld.write(POLE_PAIRS, 4)  # stopped: fine


def test_run_commands_in_fault_or_off_answer_1(bld: Rig) -> None:
    drive = bld.drive
    bld.write(SETPOINT, 1000)
    bld.write(COMMAND, FORWARD)
    drive.advance(1)
    drive.inject_fault(0x0A)
    assert drive.state == DriveDevice.FAULT and drive.speed == 0
    for command in (FORWARD, REVERSE, JOG_FORWARD, JOG_REVERSE):
        assert bld.write_fails(COMMAND, command) == 0x01
    bld.write(COMMAND, STOP)  # other commands are taken
    assert bld.read(FAULT_CODE) == [0x0A]
    bld.write(COMMAND, RESET)
    assert bld.read(STATE) + bld.read(FAULT_CODE) + bld.read(0x300B) == [3, 0, 0x0A]
    bld.write(COMMAND, FORWARD)
    assert drive.commands == [FORWARD, STOP, RESET, FORWARD]
    assert bld.read(COMMAND) == [FORWARD]

    drive.power_off()
    assert drive.state == DriveDevice.OFF and drive.speed == 0
    assert bld.write_fails(COMMAND, FORWARD) == 0x01
    drive.power_on()
    assert drive.state == DriveDevice.STOPPED
    drive.inject_fault(0x21)
    drive.power_off()
    drive.power_on()
    assert drive.state == DriveDevice.FAULT and drive.fault == 0x21


# ---- block reads ---------------------------------------------------------------------------------


def test_block_reads(bld: Rig) -> None:
    assert bld.read(COMMAND, 12) == [0, 0, 2, 50, 50, 2, 2, 3, 1, 4, 0, 0]
    assert bld.read(WRITE_ENABLE, 5) == [0, 0, 0, 0, 0]
    assert bld.read(STATE, 4) == [3, 0x41, 0, 0x20]
    assert len(bld.read(0x3000, 0x15)) == 0x15
    assert bld.read(0x0800, 7) == [1, 4, 0, 5, 0, 0, 0]
    assert bld.read_fails(0x3010, 6) == 0x02  # past 0x3014


def test_single_register_reads() -> None:
    # The default: the manuals' 0x03 format reads one register ("count 0x0001").
    assert DriveDevice().single_register_reads and DriveDevice("C20").max_read == 1
    with open_rig(single_register_reads=DriveDevice().single_register_reads) as rig:
        assert rig.read(MODEL_ID) == [0x20]
        assert rig.read_fails(COMMAND, 2) == 0x03
        assert rig.read_fails(0x3000, 0x12) == 0x03
        rig.write_many(SETPOINT, [100, 3])  # writes of several registers still work
        assert rig.read(POLE_PAIRS) == [3]


# ---- the motor -----------------------------------------------------------------------------------


def test_ramp_up_retarget_and_stop(bld: Rig) -> None:
    drive = bld.drive
    bld.write_many(SETPOINT, [3000, 2, 20, 40])  # accel 2.0 s, decel 4.0 s per 3000 rpm
    bld.write(COMMAND, FORWARD)
    assert bld.read(STATE) == [1] and bld.read(0x3006) == [0]
    drive.advance(1.0)
    assert drive.speed == 1500 and bld.read(0x3006) == [1500]
    drive.advance(1.0)
    assert drive.speed == 3000
    drive.advance(5.0)
    assert drive.speed == 3000
    bld.write(SETPOINT, 1500)  # retarget while running: slows at the decel rate
    drive.advance(1.0)
    assert drive.speed == 2250
    drive.advance(1.0)
    assert drive.speed == 1500
    bld.write(SETPOINT, 2250)  # and speeds up at the accel rate
    drive.advance(0.5)
    assert drive.speed == 2250
    bld.write(COMMAND, STOP)
    drive.advance(1.5)
    assert drive.speed == 1125 and bld.read(STATE) == [1]
    drive.advance(1.5)
    assert drive.speed == 0 and bld.read(STATE) == [3]
    assert bld.read(0x3001, 6) == [0, 0, 0, 0, 2250, 0]


def test_reversing_ramps_through_zero(bld: Rig) -> None:
    drive = bld.drive
    bld.write_many(SETPOINT, [3000, 2, 20, 40])
    bld.write(COMMAND, FORWARD)
    drive.advance(2.0)
    bld.write(COMMAND, REVERSE)
    assert bld.read(STATE) == [2]  # the commanded direction
    drive.advance(2.0)
    assert drive.speed == 1500 and bld.read(0x3006) == [1500]
    drive.advance(2.0)
    assert drive.speed == 0
    drive.advance(1.0)
    assert drive.speed == -1500 and bld.read(0x3006) == [1500]
    drive.advance(5.0)
    assert drive.speed == -3000 and bld.read(STATE) == [2]


def test_jog(bld: Rig) -> None:
    drive = bld.drive
    bld.write_many(ACCEL, [20, 40])
    bld.write(COMMAND, JOG_FORWARD)
    drive.advance(0.1)
    assert drive.speed == 150 and drive.state == DriveDevice.FORWARD
    drive.advance(1.0)
    assert drive.speed == DriveDevice.JOG_SPEED == 300
    bld.write(COMMAND, JOG_STOP)
    drive.advance(0.2)
    assert drive.speed == 150 and drive.state == DriveDevice.FORWARD
    drive.advance(0.2)
    assert drive.speed == 0 and drive.state == DriveDevice.STOPPED
    bld.write(COMMAND, JOG_REVERSE)
    drive.advance(1.0)
    assert drive.speed == -300 and drive.state == DriveDevice.REVERSE
    bld.write(COMMAND, JOG_STOP)
    drive.advance(1.0)
    assert drive.state == DriveDevice.STOPPED
    # Jog stop does not stop a normal run.
    bld.write(SETPOINT, 600)
    bld.write(COMMAND, FORWARD)
    drive.advance(1.0)
    bld.write(COMMAND, JOG_STOP)
    drive.advance(1.0)
    assert drive.speed == 600 and drive.state == DriveDevice.FORWARD


def test_coast_brake_and_stop_mode(bld: Rig) -> None:
    drive = bld.drive
    bld.write_many(SETPOINT, [3000, 2, 20, 40])
    bld.write(COMMAND, FORWARD)
    drive.advance(2.0)
    bld.write(COMMAND, COAST)
    assert drive.speed == 0 and bld.read(STATE) == [3]

    bld.write(COMMAND, FORWARD)
    drive.advance(2.0)
    bld.write(COMMAND, BRAKE)  # 10x the decel rate: 3000 rpm in 0.4 s
    assert bld.read(STATE) == [6]
    drive.advance(0.2)
    assert drive.speed == 1500 and bld.read(STATE) == [6]
    assert bld.write_fails(POLE_PAIRS, 3) == 0x08  # still turning
    drive.advance(0.2)
    assert drive.speed == 0 and bld.read(STATE) == [3]

    bld.write(STOP_MODE, 1)  # stop now coasts
    bld.write(COMMAND, FORWARD)
    drive.advance(2.0)
    bld.write(COMMAND, STOP)
    assert drive.speed == 0 and bld.read(STATE) == [3]


def test_a_real_clock_is_followed() -> None:
    now = [100.0]
    with open_rig(clock=lambda: now[0]) as rig:
        rig.write_many(SETPOINT, [3000, 2, 10])
        rig.write(COMMAND, FORWARD)
        now[0] += 0.5
        assert rig.read(0x3006) == [1500]
        rig.drive.advance(0.25)
        now[0] += 0.25
        assert rig.read(0x3006) == [3000]


# ---- C20 against BLD -----------------------------------------------------------------------------


def test_model_ids() -> None:
    for model, ident in (("BLD2", 0x20), ("BLD3H", 0x30), ("C20", 0x20)):
        assert DriveDevice(model).peek(MODEL_ID) == ident
    with pytest.raises(ValueError, match="BLD2"):
        DriveDevice("BLD4")


def test_c20_lacks_the_bld_extras(c20: Rig, bld: Rig) -> None:
    for rig in (bld, c20):
        rig.write(SETPOINT, 1000)
        rig.write(COMMAND, FORWARD)
        rig.drive.advance(1)
    assert c20.write_fails(COMMAND, BRAKE) == 0x03
    bld.write(COMMAND, BRAKE)
    for address in (0x2010, 0x2011, 0x2012):
        assert c20.read_fails(address) == 0x02
        assert c20.write_fails(address, 0) == 0x02
    for address in (0x3012, 0x3013, 0x3014):
        assert c20.read_fails(address) == 0x02
        assert c20.write_fails(address, 0) == 0x02
        assert bld.write_fails(address, 0) == 0x07
    assert c20.read_fails(0x3000, 0x15) == 0x02
    assert len(c20.read(0x3000, 0x12)) == 0x12
    assert bld.read(0x2010, 3) == [0, 0, 0]


def test_status_word_2(c20: Rig, bld: Rig) -> None:
    # Bit 0 bus voltage, bit 4 overload (BLD 1 = overloaded, C20 0 = overloaded), bits 5-6
    # the command source, bit 7 keypad (BLD only).
    assert bld.read(STATUS2) == [0x41]
    assert c20.read(STATUS2) == [0x51]
    for rig in (bld, c20):
        rig.drive.overloaded = True
        rig.drive.keypad_connected = True
    assert bld.read(STATUS2) == [0xD1]
    assert c20.read(STATUS2) == [0x41]
    bld.drive.overloaded = False
    for source, bits in ((0, 0x00), (1, 0x20), (2, 0x40)):
        bld.write(0x2006, source)
        assert bld.read(STATUS2) == [0x81 | bits]
    bld.drive.power_off()
    assert bld.read(STATUS2) == [0x80 | 0x40]


def test_model_ranges(c20: Rig, bld: Rig) -> None:
    for address, value in ((0x2005, 5), (0x2007, 8), (0x2009, 7)):
        bld.write(address, value)
        assert c20.write_fails(address, value) == 0x03
        c20.write(address, value - 2)
    assert bld.write_fails(0x2008, 128) == 0x03
    c20.write(0x2008, 247)
    assert c20.read(0x2005, 5) == [3, 2, 6, 247, 5]


# ---- line behaviour from F08.06 and F08.03 ---------------------------------------------------


def test_f08_06_writes_get_no_reply_but_are_applied(bld: Rig) -> None:
    drive, client = bld.drive, bld.client
    bld.enable_parameter_writes()
    bld.write(F08_06, 1)  # this write's own reply still comes
    assert not drive.answers_writes
    client.send(frame("01 06 20 01 03 E8"))
    client.assert_quiet()
    assert drive.peek(SETPOINT) == 1000
    client.send(frame("01 10 20 03 00 02 04 00 0A 00 14"))
    client.assert_quiet()
    client.send(frame("01 06 21 00 00 01"))  # not even an exception reply
    client.assert_quiet()
    assert bld.read(ACCEL, 2) == [10, 20]  # reads are answered
    client.send(frame("01 06 08 06 00 00"))  # switching it back is not answered either
    client.assert_quiet()
    assert drive.answers_writes
    bld.write(SETPOINT, 1500)
    assert len(bld.sim.requests) == 8 and len(bld.sim.replies) == 4
    # Set from the keypad (F08.06 is W/R*: only while stopped).
    drive.set_param(F08_06, 1)
    assert not drive.answers_writes


def test_f08_03_reply_delay(bld: Rig) -> None:
    drive, client = bld.drive, bld.client
    assert drive.reply_delay == 0.005  # the default, 5 ms
    request = frame("01 03 21 00 00 01")
    start = time.monotonic()
    assert client.transact(request, 7) == frame("01 03 02 00 03")
    assert time.monotonic() - start >= 0.005
    bld.enable_parameter_writes()
    bld.write(F08_03, 200)
    assert drive.reply_delay == 0.2
    start = time.monotonic()
    client.send(request)
    assert client.recv(7, 0.15) == b""
    assert client.recv(7) == frame("01 03 02 00 03")
    assert 0.2 <= time.monotonic() - start < 1.0
    # Restoring the defaults brings back 5 ms.
    bld.write(RESTORE, 1)
    assert drive.params[F08_03] == 5
    start = time.monotonic()
    assert client.transact(request, 7) == frame("01 03 02 00 03")
    assert time.monotonic() - start < 0.15


def test_restore_defaults(bld: Rig) -> None:
    drive = bld.drive
    bld.enable_parameter_writes()
    bld.write(F00_10, 2500)
    bld.write(0x2006, 0)  # the same setting as F00.01
    bld.write(SETPOINT, 700)
    assert drive.params[0x0001] == 0
    bld.write(RESTORE, 1)
    assert bld.read(RESTORE) == [0]
    assert drive.params == {
        0x0000: 0,
        0x0001: 2,
        0x0002: 3,
        0x0005: 0,
        0x000A: 5000,
        0x0800: 1,
        0x0801: 4,
        0x0802: 0,
        0x0803: 5,
        0x0804: 0,
        0x0805: 0,
        0x0806: 0,
    }
    assert bld.read(0x2006) == [2]
    assert bld.read(SETPOINT) == [700]  # not a function-code parameter
    assert bld.read(WRITE_ENABLE) == [1]
    bld.write(RESTORE, 0)  # no operation


# ---- telemetry -----------------------------------------------------------------------------------


def test_telemetry_is_consistent(bld: Rig) -> None:
    drive = bld.drive
    bld.write_many(SETPOINT, [1234, 4, 1])
    bld.write_many(0x200A, [0x1A5, 0x0C])
    drive.analog_inputs[:] = [1.5, 10.0, 12.0]
    idle = bld.read(0x3000, 0x15)
    assert idle[0] == round(1234 * 4 * 100 / 60)  # set frequency even when stopped
    assert idle[1:5] == [0, 0, 0, 0]  # no output, no current
    assert idle[5:8] == [1234, 0, 0]
    assert idle[8] == 3110 and idle[10] == 101 and idle[12] == 250
    assert idle[13:17] == [0x1A5, 0x0C, 150, 1000]
    assert idle[17:] == [1000, 0, 0, 0]

    bld.write(COMMAND, FORWARD)
    drive.advance(1.0)
    t = bld.read(0x3000, 0x15)
    rpm = t[6]
    assert rpm == 1234
    for frequency in t[0:3]:  # 0.01 Hz = rpm x pole pairs / 60
        assert abs(frequency - rpm * 4 * 100 / 60) <= 1
    volts, amps, watts, bus = t[3] / 10, t[4] / 100, t[7], t[8] / 10
    assert 0 < volts <= bus == 311.0
    assert 0.3 < amps < 3.0
    assert abs(watts - volts * amps) <= 1 and watts <= 2200
    assert 250 < t[12] < 270  # warmer with current
    # Faster means more voltage, current and power.
    bld.write(SETPOINT, 3000)
    drive.advance(1.0)
    fast = bld.read(0x3003, 5)
    assert fast[0] > t[3] and fast[1] > t[4] and fast[4] > t[7]
    assert fast[3] == 3000


def test_temperature_is_signed() -> None:
    drive = DriveDevice("BLD3H")
    drive.temperature = -5.0
    assert drive.peek(0x300C) == 0xFFCE
    drive.temperature = 119.9
    assert drive.peek(0x300C) == 1199


def test_hall_value_steps_through_six_states(bld: Rig) -> None:
    drive = bld.drive
    bld.write(ACCEL, 1)
    bld.write(COMMAND, JOG_FORWARD)  # 300 rpm x 2 pole pairs x 6 = 60 hall edges a second
    drive.advance(1.0 + 1 / 120)  # steady, and half-way between two edges
    seen = []
    for _ in range(13):
        seen.append(bld.read(0x3009)[0])
        drive.advance(1 / 60)
    assert set(seen) == {1, 2, 3, 4, 5, 6}
    assert all(a != b for a, b in zip(seen, seen[1:]))
    assert seen[6:12] == seen[0:6]
    assert all(bin(a ^ b).count("1") == 1 for a, b in zip(seen, seen[1:]))  # one sensor flips
    drive.set_param(F08_03, 0)  # (just fewer milliseconds per read below)
    bld.write(COMMAND, JOG_REVERSE)
    drive.advance(2.0)
    backward = []
    for _ in range(7):
        backward.append(bld.read(0x3009)[0])
        drive.advance(1 / 60)
    assert backward[::-1][:6] in [seen[i : i + 6] for i in range(7)]


def test_hall_count(bld: Rig) -> None:
    drive = bld.drive
    bld.write_many(SETPOINT, [3000, 2, 10])  # 0 -> 3000 rpm in 1.0 s
    bld.write(COMMAND, FORWARD)
    drive.advance(2.0)  # 25 + 50 revolutions, x 2 pole pairs x 6
    assert bld.read(0x3013, 2) == [0, 900]
    assert drive.hall_count == 900
    drive.hall_count = 2**32 - 10
    drive.advance(1 / 128)  # 0.390625 revolutions: 4.6875 edges
    assert bld.read(0x3013, 2) == [0xFFFF, 0xFFFA]
    drive.advance(1 / 64)  # 9.375 edges more: past 2**32
    assert bld.read(0x3013, 2) == [0, 4]
    bld.write(0x2011, 1)  # clear
    assert bld.read(0x2011) == [0]
    assert bld.read(0x3013, 2) == [0, 0]
    bld.write(COMMAND, REVERSE)  # counts up in either direction
    drive.advance(2.0)
    assert drive.hall_count > 0


# ---- the Python side -----------------------------------------------------------------------------


def test_python_access_and_errors() -> None:
    drive = DriveDevice("C20", clock=lambda: 0.0)
    assert "C20" in repr(drive) and "state=3" in repr(drive)
    assert drive.state == DriveDevice.STOPPED and drive.speed == 0 and drive.fault == 0
    assert drive.commands == [] and drive.params[F00_10] == 5000
    assert drive.answers_writes and drive.reply_delay == 0.005
    with pytest.raises(KeyError):
        drive.peek(0x2010)
    with pytest.raises(KeyError):
        drive.set_param(0x0032, 1)
    with pytest.raises(ValueError):
        drive.set_param(F08_03, 201)
    with pytest.raises(ValueError):
        drive.advance(-1)
    with pytest.raises(ValueError):
        drive.inject_fault(0)
    with pytest.raises(ValueError):
        drive.hall_count = 2**32
    with pytest.raises(TypeError):
        DriveDevice(clock=5)  # type: ignore[arg-type]
    drive.inject_fault()
    assert drive.fault == 0x0A and drive.peek(0x300B) == 0x0A
    assert "fault=0x0a" in repr(drive)
