"""The simulator itself, driven by a raw pseudo-terminal client with its own CRC.

Nothing here goes through the compiled core or the simulator's own framing helpers: the
client writes request bytes and reads reply bytes, and the CRC is computed bit by bit below,
so a bug in either side's CRC or framing cannot hide behind the other.
"""

from __future__ import annotations

import os
import threading
import time
import tty
from collections.abc import Iterator

import pytest

from benchbus.sim import RegisterDevice, SimDevice, SimException, Simulator
from conftest import crc, read_up_to
from conftest import rtu as frame

#: How long a test waits to conclude that no reply is coming.
QUIET = 0.3


def crc_valid(data: bytes) -> bool:
    return len(data) >= 4 and crc(data[:-2]) == data[-2:]


class Client:
    """The library's end of the line, opened raw, without the library."""

    def __init__(self, port: str) -> None:
        self.fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)

    def close(self) -> None:
        os.close(self.fd)

    def send(self, request: bytes) -> None:
        os.write(self.fd, request)

    def recv(self, n: int, timeout: float = 2.0) -> bytes:
        """Up to ``n`` bytes, whatever has come within ``timeout``."""
        return read_up_to(self.fd, n, timeout)

    def transact(self, request: bytes, reply_len: int) -> bytes:
        self.send(request)
        reply = self.recv(reply_len)
        assert self.recv(1, 0.05) == b"", "more bytes than the expected reply"
        return reply

    def assert_quiet(self, timeout: float = QUIET) -> None:
        assert self.recv(1, timeout) == b""


@pytest.fixture
def rig() -> Iterator[tuple[Simulator[RegisterDevice], Client]]:
    devices = {
        1: RegisterDevice({0x3006: 1450, 0x3007: 0xFFFF, 0x0005: 250}, max_read=20, max_write=4),
        2: RegisterDevice(
            {0x0010: 0x2222},
            identity={0: "ACME LABS", 1: "BB-42", 2: "1.07"},
            readonly={0x0002},
        ),
    }
    with Simulator(devices) as sim:
        client = Client(sim.port)
        try:
            yield sim, client
        finally:
            client.close()


def wait_for(condition: object, timeout: float = 2.0) -> bool:
    assert callable(condition)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return bool(condition())


# ---- RegisterDevice through the line: exact frames -------------------------------------------


def test_read_holding_exact_frames(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    request = frame("01 03 30 06 00 02")
    reply = client.transact(request, 9)
    assert reply == frame("01 03 04 05 AA FF FF")
    assert sim.requests == [request]
    assert sim.replies == [reply]


def test_write_single_echo_and_store(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    # The temperature controller manual's own frame: write SV (0x0005) = 100.
    request = bytes.fromhex("01 06 00 05 00 64 98 20")
    assert client.transact(request, 8) == request
    assert sim.devices[1].registers[0x0005] == 100
    assert client.transact(frame("01 03 00 05 00 01"), 7) == frame("01 03 02 00 64")


def test_write_multiple_reply_and_store(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    request = frame("01 10 20 00 00 03 06 00 01 0B B8 FF FF")
    assert client.transact(request, 8) == frame("01 10 20 00 00 03")
    assert sim.devices[1].registers[0x2000:0x2003] == [1, 3000, 0xFFFF]


def test_count_limits_answer_exception_3(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    assert client.transact(frame("01 03 00 00 00 14"), 45)[:3] == bytes.fromhex("01 03 28")
    assert client.transact(frame("01 03 00 00 00 15"), 5) == frame("01 83 03")
    # A count the protocol forbids outright is answered too, not dropped.
    assert client.transact(frame("01 03 00 00 00 00"), 5) == frame("01 83 03")
    assert client.transact(frame("01 03 00 00 00 7E"), 5) == frame("01 83 03")
    write5 = frame("01 10 00 00 00 05 0A 00 01 00 02 00 03 00 04 00 05")
    assert client.transact(write5, 5) == frame("01 90 03")
    assert sim.devices[1].registers[0:5] == [0, 0, 0, 0, 0]


def test_past_the_last_address_answers_exception_2(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    assert client.transact(frame("01 03 FF FF 00 02"), 5) == frame("01 83 02")
    assert client.transact(frame("01 03 FF FF 00 01"), 7) == frame("01 03 02 00 00")
    assert client.transact(frame("01 10 FF FF 00 02 04 00 07 00 08"), 5) == frame("01 90 02")
    assert sim.devices[1].registers[0xFFFF] == 0


def test_readonly_write_is_all_or_nothing(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    assert client.transact(frame("02 10 00 01 00 03 06 00 0A 00 0B 00 0C"), 5) == frame("02 90 02")
    assert sim.devices[2].registers[1:4] == [0, 0, 0]
    assert client.transact(frame("02 06 00 02 00 09"), 5) == frame("02 86 02")
    assert client.transact(frame("02 06 00 03 00 09"), 8) == frame("02 06 00 03 00 09")
    assert sim.devices[2].registers[1:4] == [0, 0, 9]


class Locked(RegisterDevice):
    readonly_code = 0x08


def test_readonly_code_is_a_class_setting() -> None:
    with Simulator(Locked(readonly={7})) as sim:
        client = Client(sim.port)
        try:
            assert client.transact(frame("01 06 00 07 00 01"), 5) == frame("01 86 08")
        finally:
            client.close()


# ---- custom devices: exception codes and failures --------------------------------------------


class Scripted(SimDevice):
    """Raises whatever the test puts in ``raise_next``."""

    def __init__(self) -> None:
        self.raise_next: BaseException | None = None
        self.read_result: list[int] = [0x1234]

    def read_holding(self, address: int, count: int) -> list[int]:
        if self.raise_next is not None:
            raise self.raise_next
        return self.read_result

    def write_holding(self, address: int, values: list[int]) -> None:
        if self.raise_next is not None:
            raise self.raise_next


@pytest.fixture
def scripted() -> Iterator[tuple[Simulator[Scripted], Client, Scripted]]:
    device = Scripted()
    with Simulator(device) as sim:
        client = Client(sim.port)
        try:
            yield sim, client, device
        finally:
            client.close()


@pytest.mark.parametrize("code", [0x01, 0x06, 0x08, 0x09, 0x21, 0xFF])
def test_sim_exception_codes_reach_the_wire(
    scripted: tuple[Simulator[Scripted], Client, Scripted], code: int
) -> None:
    sim, client, device = scripted
    device.raise_next = SimException(code)
    assert client.transact(frame("01 03 00 00 00 01"), 5) == frame(f"01 83 {code:02X}")
    assert client.transact(frame("01 06 00 00 00 01"), 5) == frame(f"01 86 {code:02X}")
    # The rewrite of a code pymodbus lacks does not stick to the next reply.
    device.raise_next = None
    assert client.transact(frame("01 03 00 00 00 01"), 7) == frame("01 03 02 12 34")
    device.raise_next = SimException(0x03)
    assert client.transact(frame("01 03 00 00 00 01"), 5) == frame("01 83 03")
    assert sim.errors == []


def test_a_failing_handler_answers_4_and_is_kept(
    scripted: tuple[Simulator[Scripted], Client, Scripted],
) -> None:
    sim, client, device = scripted
    device.raise_next = RuntimeError("broken simulator")
    assert client.transact(frame("01 03 00 00 00 01"), 5) == frame("01 83 04")
    assert len(sim.errors) == 1 and isinstance(sim.errors[0], RuntimeError)
    device.raise_next = None
    device.read_result = [1, 2]  # two values for a one-register read
    assert client.transact(frame("01 03 00 00 00 01"), 5) == frame("01 83 04")
    device.read_result = [0x10000]
    assert client.transact(frame("01 03 00 00 00 01"), 5) == frame("01 83 04")
    assert [type(e) for e in sim.errors] == [RuntimeError, ValueError, ValueError]


def test_base_device_has_no_registers() -> None:
    with Simulator(SimDevice()) as sim:
        client = Client(sim.port)
        try:
            assert client.transact(frame("01 03 00 00 00 01"), 5) == frame("01 83 02")
            assert client.transact(frame("01 06 00 00 00 01"), 5) == frame("01 86 02")
            assert client.transact(frame("01 2B 0E 01 00"), 5) == frame("01 AB 01")
        finally:
            client.close()


@pytest.mark.parametrize("function", [0x01, 0x04, 0x05, 0x0F, 0x08])
def test_other_functions_answer_illegal_function(function: int) -> None:
    # A device that declares only the basic functions (as the families' manuals do); a
    # RegisterDevice serves these (tests/test_sim_functions.py).
    request = {
        0x0F: frame("01 0F 00 00 00 08 01 FF"),
    }.get(function, frame(f"01 {function:02X} 00 00 00 01"))
    with Simulator(SimDevice()) as sim:
        client = Client(sim.port)
        try:
            assert client.transact(request, 5) == frame(f"01 {function | 0x80:02X} 01")
        finally:
            client.close()


# ---- Read Device Identification ---------------------------------------------------------------


def decode_identification(reply: bytes) -> dict[int, str]:
    assert crc_valid(reply)
    assert reply[1:3] == bytes([0x2B, 0x0E])
    count, pos, objects = reply[7], 8, {}
    for _ in range(count):
        object_id, length = reply[pos], reply[pos + 1]
        objects[object_id] = reply[pos + 2 : pos + 2 + length].decode("ascii")
        pos += 2 + length
    assert pos == len(reply) - 2
    return objects


def test_identification_is_per_unit(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    _, client = rig
    client.send(frame("02 2B 0E 01 00"))
    reply = client.recv(64, 1.0)
    assert reply[:4] == bytes.fromhex("02 2B 0E 01")
    assert reply[5:7] == b"\x00\x00"  # no more follows
    assert decode_identification(reply) == {0: "ACME LABS", 1: "BB-42", 2: "1.07"}
    # Unit 1 has no identity: illegal function.
    assert client.transact(frame("01 2B 0E 01 00"), 5) == frame("01 AB 01")
    # One object by id (read code 4); an id the unit lacks is an illegal address.
    client.send(frame("02 2B 0E 04 01"))
    assert decode_identification(client.recv(64, 1.0)) == {1: "BB-42"}
    assert client.transact(frame("02 2B 0E 04 05"), 5) == frame("02 AB 02")


def test_identity_can_change_while_running(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    sim.devices[1].identity = {0: "OTHER", 1: "X", 2: "2"}
    client.send(frame("01 2B 0E 01 00"))
    assert decode_identification(client.recv(64, 1.0)) == {0: "OTHER", 1: "X", 2: "2"}


# ---- what gets no reply -----------------------------------------------------------------------


def test_unknown_unit_and_bad_crc_get_no_reply(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    to_nobody = frame("07 03 00 00 00 01")
    client.send(to_nobody)
    client.assert_quiet()
    bad = bytearray(frame("01 06 00 05 00 07"))
    bad[-1] ^= 0x01
    client.send(bytes(bad))
    client.assert_quiet()
    assert sim.devices[1].registers[0x0005] == 250
    assert sim.requests == [to_nobody, bytes(bad)]
    assert sim.replies == []
    # The line is still in step afterwards.
    assert client.transact(frame("01 03 00 05 00 01"), 7) == frame("01 03 02 00 FA")


def test_broadcast_reaches_every_unit_and_is_not_answered(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    client.send(frame("00 06 00 09 00 2A"))
    client.assert_quiet()
    assert wait_for(lambda: [d.registers[9] for d in sim.devices.values()] == [42, 42])
    assert sim.replies == []


def test_broadcast_off_ignores_unit_0() -> None:
    devices = {1: RegisterDevice(), 2: RegisterDevice()}
    with Simulator(devices, broadcast=False) as sim:
        client = Client(sim.port)
        try:
            client.send(frame("00 06 00 09 00 2A"))
            client.assert_quiet()
            assert client.transact(frame("01 03 00 09 00 01"), 7) == frame("01 03 02 00 00")
            assert [d.registers[9] for d in devices.values()] == [0, 0]
        finally:
            client.close()


class Chatty(RegisterDevice):
    answers_broadcast = True


def test_a_unit_that_answers_broadcasts_uses_its_own_address() -> None:
    devices = {3: Chatty(), 5: RegisterDevice()}
    with Simulator(devices) as sim:
        client = Client(sim.port)
        try:
            client.send(frame("00 06 00 01 00 07"))
            assert client.recv(8) == frame("03 06 00 01 00 07")
            client.assert_quiet()
            assert wait_for(lambda: devices[5].registers[1] == 7)
            assert devices[3].registers[1] == 7
        finally:
            client.close()


# ---- faults -----------------------------------------------------------------------------------


def test_silent_units(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    read1, read2 = frame("01 03 00 05 00 01"), frame("02 03 00 10 00 01")
    sim.set_silent(1)
    client.send(read1)
    client.assert_quiet()
    assert client.transact(read2, 7) == frame("02 03 02 22 22")
    client.send(frame("01 06 00 05 00 01"))  # a silent unit does not act either
    client.assert_quiet()
    assert sim.devices[1].registers[5] == 250
    client.send(frame("00 06 00 06 00 01"))  # nor take part in a broadcast
    assert wait_for(lambda: sim.devices[2].registers[6] == 1)
    assert sim.devices[1].registers[6] == 0
    sim.set_silent(1, False)
    assert client.transact(read1, 7) == frame("01 03 02 00 FA")

    sim.set_silent(None)
    client.send(read2)
    client.assert_quiet()
    sim.set_silent(2)
    sim.set_silent(None, False)  # clears the per-unit setting too
    assert client.transact(read2, 7) == frame("02 03 02 22 22")
    assert client.transact(read1, 7) == frame("01 03 02 00 FA")
    assert len(sim.requests) == 8  # silent requests are still logged


def test_corrupt_next_flips_the_crc_only(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    request, good = frame("01 03 30 06 00 01"), frame("01 03 02 05 AA")
    sim.corrupt_next(2)
    for _ in range(2):
        reply = client.transact(request, 7)
        assert reply[:-2] == good[:-2] and not crc_valid(reply)
    assert client.transact(request, 7) == good
    sim.corrupt_next(0)
    assert client.transact(request, 7) == good
    with pytest.raises(ValueError):
        sim.corrupt_next(-1)


def test_answer_exception_preempts_the_device(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    sim.answer_exception(6, n=2, unit=1)
    write = frame("01 06 00 05 00 01")
    assert client.transact(frame("02 03 00 10 00 01"), 7) == frame("02 03 02 22 22")
    client.send(frame("00 06 00 07 00 01"))  # a broadcast does not use up the count
    client.assert_quiet()
    assert client.transact(write, 5) == frame("01 86 06")
    assert client.transact(frame("01 03 00 05 00 01"), 5) == frame("01 83 06")
    assert sim.devices[1].registers[5] == 250  # the write never reached the device
    assert client.transact(write, 8) == write
    assert sim.devices[1].registers[5] == 1

    sim.answer_exception(0x21)  # any unit, once, a non-standard code
    assert client.transact(frame("02 03 00 10 00 01"), 5) == frame("02 83 21")
    assert client.transact(frame("02 03 00 10 00 01"), 7) == frame("02 03 02 22 22")
    for bad in ({"code": 0}, {"code": 256}, {"code": 2, "n": 0}):
        with pytest.raises(ValueError):
            sim.answer_exception(**bad)


def test_reply_delay(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    request = frame("01 03 30 06 00 01")
    sim.reply_delay = 0.25
    assert sim.reply_delay == 0.25
    start = time.monotonic()
    client.send(request)
    assert client.recv(7, 0.2) == b""
    assert client.recv(7, 2.0) == frame("01 03 02 05 AA")
    assert 0.25 <= time.monotonic() - start < 1.5
    for bad in (-0.1, float("nan")):
        with pytest.raises(ValueError):
            sim.reply_delay = bad
    assert sim.reply_delay == 0.25


class Mute(RegisterDevice):
    answers_writes = False


class Switchable(RegisterDevice):
    """Answers writes while register 1 is 0, and holds replies register 0 milliseconds."""

    @property
    def answers_writes(self) -> bool:  # type: ignore[override]
        return self.registers[1] == 0

    @property
    def reply_delay(self) -> float:  # type: ignore[override]
        return self.registers[0] / 1000


def test_a_unit_that_does_not_answer_writes_still_acts_on_them() -> None:
    devices = {1: Mute(max_write=4), 2: RegisterDevice()}
    with Simulator(devices) as sim:
        client = Client(sim.port)
        try:
            single = frame("01 06 00 05 00 07")
            client.send(single)
            client.assert_quiet()
            assert devices[1].registers[5] == 7
            client.send(frame("01 10 00 00 00 02 04 00 0A 00 0B"))
            client.assert_quiet()
            assert devices[1].registers[0:2] == [10, 11]
            # An exception reply to a write is kept off the line too.
            client.send(frame("01 10 00 00 00 05 0A 00 01 00 02 00 03 00 04 00 05"))
            client.assert_quiet()
            # Reads are answered, and so are other units' writes.
            assert client.transact(frame("01 03 00 05 00 01"), 7) == frame("01 03 02 00 07")
            assert client.transact(frame("02 06 00 01 00 02"), 8) == frame("02 06 00 01 00 02")
            # A fault forced by the simulator is not the unit's reply: it is delivered.
            sim.answer_exception(6, unit=1)
            assert client.transact(single, 5) == frame("01 86 06")
            assert sim.requests.count(single) == 2 and len(sim.requests) == 6
            assert len(sim.replies) == 3
        finally:
            client.close()


def test_answers_writes_is_read_per_request() -> None:
    device = Switchable()
    with Simulator(device) as sim:
        client = Client(sim.port)
        try:
            # Asked before the unit handles the request: this write is still answered ...
            mute = frame("01 06 00 01 00 01")
            assert client.transact(mute, 8) == mute
            # ... and from then on writes are not, including the one that undoes it.
            client.send(frame("01 06 00 02 00 05"))
            client.assert_quiet()
            client.send(frame("01 06 00 01 00 00"))
            client.assert_quiet()
            assert device.registers[1:3] == [0, 5]
            speak = frame("01 06 00 02 00 06")
            assert client.transact(speak, 8) == speak
            assert sim.errors == []
        finally:
            client.close()


def test_a_unit_reply_delay_is_read_per_request_and_maxed_with_the_line() -> None:
    device = Switchable({0: 200})
    devices = {1: device, 2: RegisterDevice({0: 0x0102})}
    with Simulator(devices) as sim:
        client = Client(sim.port)
        try:
            read1, read2 = frame("01 03 00 00 00 01"), frame("02 03 00 00 00 01")
            start = time.monotonic()
            client.send(read1)
            assert client.recv(7, 0.15) == b""
            assert client.recv(7) == frame("01 03 02 00 C8")
            assert 0.2 <= time.monotonic() - start < 1.0
            # Other units are not held.
            start = time.monotonic()
            assert client.transact(read2, 7) == frame("02 03 02 01 02")
            assert time.monotonic() - start < 0.15
            # The line's own delay and the unit's: the larger one applies, not the sum.
            sim.reply_delay = 0.3
            start = time.monotonic()
            client.send(read1)
            assert client.recv(7) == frame("01 03 02 00 C8")
            assert 0.3 <= time.monotonic() - start < 0.45
            sim.reply_delay = 0.0
            # The write that clears the delay is itself still held; the next reply is not.
            start = time.monotonic()
            client.send(frame("01 06 00 00 00 00"))
            assert client.recv(8) == frame("01 06 00 00 00 00")
            assert time.monotonic() - start >= 0.2
            start = time.monotonic()
            assert client.transact(read1, 7) == frame("01 03 02 00 00")
            assert time.monotonic() - start < 0.15
        finally:
            client.close()


class Counted(RegisterDevice):
    """Answers 0x06 with a register count of 1 instead of the echo (as a PBL drive does).

    Records every ``(request, reply)`` the line shows it; ``fail`` makes the hook raise and
    ``result`` makes it return that instead.
    """

    def __init__(self, *, answers_broadcast: bool = False, answers_writes: bool = True) -> None:
        super().__init__(readonly={0x0002})
        self.answers_broadcast = answers_broadcast
        self.answers_writes = answers_writes
        self.seen: list[tuple[bytes, bytes]] = []
        self.fail: BaseException | None = None
        self.result: object = None

    def shape_reply(self, request: bytes, reply: bytes) -> bytes:
        self.seen.append((request, reply))
        if self.fail is not None:
            raise self.fail
        if self.result is not None:
            return self.result  # type: ignore[return-value]
        if reply[1] == 0x06:
            return frame(reply[:4].hex() + "0001")
        return reply


@pytest.fixture
def counted() -> Iterator[tuple[Simulator[Counted], Client, Counted]]:
    device = Counted()
    with Simulator({1: device, 2: RegisterDevice()}) as sim:
        client = Client(sim.port)
        try:
            yield sim, client, device
        finally:
            client.close()


def test_shape_reply_gives_the_units_own_reply(
    counted: tuple[Simulator[Counted], Client, Counted],
) -> None:
    sim, client, device = counted
    write = frame("01 06 00 05 00 07")
    assert client.transact(write, 8) == frame("01 06 00 05 00 01")
    assert device.registers[5] == 7  # the write itself is the server's business
    assert device.seen == [(write, write)]  # the request and the server's standard echo
    assert sim.replies == [frame("01 06 00 05 00 01")]
    # Other replies go through the hook too, and come out as they went in.
    read = frame("01 03 00 05 00 01")
    assert client.transact(read, 7) == frame("01 03 02 00 07")
    refused = frame("01 06 00 02 00 01")
    assert client.transact(refused, 5) == frame("01 86 02")
    multiple = frame("01 10 00 00 00 02 04 00 0A 00 0B")
    assert client.transact(multiple, 8) == frame("01 10 00 00 00 02")
    assert device.seen[1:] == [
        (read, frame("01 03 02 00 07")),
        (refused, frame("01 86 02")),
        (multiple, frame("01 10 00 00 00 02")),
    ]
    # The other unit keeps the default: the standard echo.
    other = frame("02 06 00 05 00 07")
    assert client.transact(other, 8) == other
    assert len(device.seen) == 4
    assert sim.errors == []


def test_shape_reply_comes_before_the_faults(
    counted: tuple[Simulator[Counted], Client, Counted],
) -> None:
    sim, client, _ = counted
    shaped = frame("01 06 00 05 00 01")
    sim.corrupt_next()
    reply = client.transact(frame("01 06 00 05 00 07"), 8)
    assert reply[:-2] == shaped[:-2] and not crc_valid(reply)
    assert reply[-2:] == bytes(b ^ 0xFF for b in shaped[-2:])
    assert sim.replies == [reply]
    sim.reply_delay = 0.2
    start = time.monotonic()
    assert client.transact(frame("01 06 00 05 00 08"), 8) == shaped
    assert time.monotonic() - start >= 0.2


def test_shape_reply_only_sees_the_units_replies_on_the_line(
    counted: tuple[Simulator[Counted], Client, Counted],
) -> None:
    sim, client, device = counted
    # Replies the simulator makes itself.
    sim.answer_exception(6, unit=1)
    assert client.transact(frame("01 06 00 05 00 07"), 5) == frame("01 86 06")
    # (0x41, a vendor's function: one a RegisterDevice does not serve.)
    assert client.transact(frame("01 41 00 00 00 01"), 5) == frame("01 C1 01")
    # A broadcast this unit does not answer.
    client.send(frame("00 06 00 05 00 09"))
    client.assert_quiet()
    assert device.registers[5] == 9
    # (Nor the simulator's start-up probe, which went to this unit too.)
    assert device.seen == []


def test_shape_reply_is_skipped_for_replies_kept_off_the_line() -> None:
    device = Counted(answers_writes=False)
    with Simulator(device) as sim:
        client = Client(sim.port)
        try:
            client.send(frame("01 06 00 05 00 07"))
            client.assert_quiet()
            assert device.registers[5] == 7 and device.seen == []
            read = frame("01 03 00 05 00 01")
            assert client.transact(read, 7) == frame("01 03 02 00 07")
            assert device.seen == [(read, frame("01 03 02 00 07"))]
            assert sim.errors == []
        finally:
            client.close()


def test_shape_reply_of_a_broadcast_sees_the_units_own_address() -> None:
    devices = {3: Counted(answers_broadcast=True), 5: Counted(answers_broadcast=True)}
    with Simulator(devices) as sim:
        client = Client(sim.port)
        try:
            client.send(frame("00 06 00 01 00 07"))
            assert client.recv(16) == frame("03 06 00 01 00 01") + frame("05 06 00 01 00 01")
            client.assert_quiet()
            for unit, device in devices.items():
                own = frame(f"{unit:02X} 06 00 01 00 07")
                assert device.seen == [(own, own)]
                assert device.registers[1] == 7
            assert sim.requests == [frame("00 06 00 01 00 07")]
        finally:
            client.close()


@pytest.mark.parametrize(
    ("fail", "result", "error"),
    [
        (RuntimeError("broken hook"), None, RuntimeError),
        (None, b"\x01\x06\x00", TypeError),
        (None, "01 06 00 05 00 01", TypeError),
        (None, 42, TypeError),
    ],
)
def test_a_failing_shape_reply_keeps_the_servers_reply(
    counted: tuple[Simulator[Counted], Client, Counted],
    caplog: pytest.LogCaptureFixture,
    fail: BaseException | None,
    result: object,
    error: type[BaseException],
) -> None:
    sim, client, device = counted
    device.fail, device.result = fail, result
    write = frame("01 06 00 05 00 07")
    assert client.transact(write, 8) == write
    assert device.registers[5] == 7
    assert [type(e) for e in sim.errors] == [error]
    assert "shape_reply" in caplog.text
    # The line is still in step, and a working hook is used again.
    device.fail = device.result = None
    assert client.transact(write, 8) == frame("01 06 00 05 00 01")


def test_inject_raw_is_not_logged_as_a_reply(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    sim.inject_raw(b"\x01\x03\x99")
    assert client.recv(3) == b"\x01\x03\x99"
    assert sim.replies == [] and sim.requests == []


def test_clear_log_and_clear_faults(rig: tuple[Simulator[RegisterDevice], Client]) -> None:
    sim, client = rig
    request = frame("01 03 30 06 00 01")
    assert client.transact(request, 7) == frame("01 03 02 05 AA")
    sim.clear_log()
    assert sim.requests == [] and sim.replies == []
    sim.reply_delay = 5.0
    sim.set_silent(None)
    sim.set_silent(1)
    sim.corrupt_next(3)
    sim.answer_exception(4, n=3)
    sim.clear_faults()
    assert sim.reply_delay == 0.0
    assert client.transact(request, 7) == frame("01 03 02 05 AA")
    assert sim.requests == [request]


def test_a_device_can_be_replaced_while_running(
    rig: tuple[Simulator[RegisterDevice], Client],
) -> None:
    sim, client = rig
    sim.devices[1] = RegisterDevice({0x3006: 7})
    assert client.transact(frame("01 03 30 06 00 01"), 7) == frame("01 03 02 00 07")


# ---- construction and lifecycle ---------------------------------------------------------------


def test_a_single_device_is_unit_1() -> None:
    device = RegisterDevice({0: 5})
    sim = Simulator(device)
    assert sim.devices == {1: device}


@pytest.mark.parametrize("unit", [0, 256, -1, True, "1", 1.0])
def test_bad_unit_addresses(unit: object) -> None:
    with pytest.raises(ValueError, match=r"1\.\.255"):
        Simulator({unit: RegisterDevice()})  # type: ignore[dict-item]


def test_bad_constructor_arguments() -> None:
    with pytest.raises(TypeError, match="not a SimDevice"):
        Simulator({1: object()})  # type: ignore[type-var]
    for baudrate in (0, -9600, True, 9600.0):
        with pytest.raises(ValueError, match="baudrate"):
            Simulator(RegisterDevice(), baudrate=baudrate)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_read"):
        RegisterDevice(max_read=126)
    with pytest.raises(ValueError, match="max_write"):
        RegisterDevice(max_write=0)
    with pytest.raises(ValueError, match=r"0\.\.0xFFFF"):
        RegisterDevice({0x10000: 1})
    with pytest.raises(ValueError, match=r"0\.\.0xFFFF"):
        RegisterDevice({0: 0x10000})
    with pytest.raises(TypeError):
        RegisterDevice({0: "1"})  # type: ignore[dict-item]
    with pytest.raises(ValueError):
        RegisterDevice(readonly={-1})
    for code in (0, 256, True, "3"):
        with pytest.raises(ValueError, match=r"1\.\.255"):
            SimException(code)  # type: ignore[arg-type]


def test_lifecycle() -> None:
    sim = Simulator(RegisterDevice({0: 0x0102}))
    assert not sim.running
    with pytest.raises(RuntimeError, match="start"):
        _ = sim.port
    with pytest.raises(RuntimeError, match="start"):
        sim.inject_raw(b"\x00")
    sim.stop()  # stopping a simulator never started is harmless
    assert sim.start() is sim
    port = sim.port
    assert sim.start() is sim and sim.port == port  # already running: nothing changes
    assert "port=" in repr(sim)
    sim.stop()
    sim.stop()
    assert not sim.running and "stopped" in repr(sim)
    with pytest.raises(RuntimeError):
        _ = sim.port
    with sim:  # and it starts again
        client = Client(sim.port)
        try:
            assert client.transact(frame("01 03 00 00 00 01"), 7) == frame("01 03 02 01 02")
        finally:
            client.close()


def test_stop_releases_threads_and_descriptors() -> None:
    def fds() -> int:
        return len(os.listdir("/proc/self/fd"))

    # One run first, so that lazily created process-wide objects are not counted.
    with Simulator(RegisterDevice()):
        pass
    before_fds, before_threads = fds(), threading.active_count()
    for _ in range(3):
        with Simulator({1: RegisterDevice(), 2: RegisterDevice()}) as sim:
            client = Client(sim.port)
            client.transact(frame("02 03 00 00 00 01"), 7)
            client.close()
            assert threading.active_count() >= before_threads + 2
    assert fds() == before_fds
    assert wait_for(lambda: threading.active_count() == before_threads)
