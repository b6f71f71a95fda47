"""The Bus through the real serial path (a pseudo-terminal) against the pymodbus simulator."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import RegisterDevice, SimException, Simulator
from conftest import ScriptedSlave


@pytest.fixture
def sim() -> Iterator[Simulator]:
    devices = {
        1: RegisterDevice({0x0000: 1000, 0x0005: 250, 0x3006: 1450}),
        2: RegisterDevice(
            {0x0010: 0x2222},
            identity={0: "TELEMECANIQUE", 1: "ATV31HU09M3S232", 2: "0201"},
        ),
    }
    with Simulator(devices, baudrate=19200) as s:
        yield s


def crc_ok(frame: bytes) -> bool:
    return len(frame) >= 4 and bb.crc16(frame[:-2]).to_bytes(2, "little") == frame[-2:]


def test_read_write_round_trip(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.2) as bus:
        assert bus.read_holding_registers(1, 0x0000, 1) == [1000]
        bus.write_register(1, 0x0005, 100)
        assert sim.devices[1].registers[0x0005] == 100
        bus.write_registers(1, 0x0008, [100, 200, 0xFFFF])
        assert bus.read_holding_registers(1, 0x0008, 3) == [100, 200, 0xFFFF]
        assert bus.read_holding_registers(1, 0x0000, 125)[5] == 100
        assert bus.stats.transactions == 5
    # The manual's frames for the same requests (004: write SV=100, write 0x0008..0x0009).
    assert bytes.fromhex("01 06 00 05 00 64 98 20") in sim.requests
    assert sim.requests[0] == bytes.fromhex("01 03 00 00 00 01 84 0A")


def test_read_device_identification(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.2) as bus:
        ident = bus.read_device_identification(2)
        assert ident[0] == "TELEMECANIQUE"
        assert ident[1] == "ATV31HU09M3S232"
        assert ident[2] == "0201"
        with pytest.raises(bb.ModbusException) as e:
            bus.read_device_identification(1)  # unit 1 has no identity
        assert e.value.code == 1
        assert e.value.function == 0x2B
    assert sim.requests[0] == bytes.fromhex("02 2B 0E 01 00 34 77")


def test_broadcast_reaches_every_unit_and_waits_no_reply(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.5, turnaround=0.05) as bus:
        start = time.monotonic()
        bus.broadcast_write_register(0x2000, 5)
        took = time.monotonic() - start
        assert 0.05 <= took < 0.3
        time.sleep(0.05)
        assert sim.devices[1].registers[0x2000] == 5
        assert sim.devices[2].registers[0x2000] == 5
        assert bus.stats.broadcasts == 1
        assert bus.read_holding_registers(1, 0x2000, 1) == [5]
    assert sim.requests[0][0] == 0


def test_scan_finds_the_units_that_answer(sim: Simulator) -> None:
    with bb.Bus(sim.port) as bus:
        assert bus.scan(range(1, 6), timeout=0.03) == [1, 2]
        sim.answer_exception(2, n=1, unit=2)  # an exception reply still means "present"
        assert bus.scan([2, 3], timeout=0.03) == [2]


def test_corrupted_reply_is_retried(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.2, retries=2) as bus:
        sim.corrupt_next(1)
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        s = bus.stats
        assert (s.crc_errors, s.retries, s.transactions) == (1, 1, 1)
    assert sim.requests.count(sim.requests[0]) == 2


def test_crc_error_raised_when_retries_run_out(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.2, retries=1) as bus:
        sim.corrupt_next(2)
        with pytest.raises(bb.CrcError) as e:
            bus.read_holding_registers(1, 0x3006, 1)
        assert e.value.unit == 1
        assert e.value.function == 3
        assert e.value.frame is not None
        assert not crc_ok(bytes.fromhex(e.value.frame))
        assert isinstance(e.value, bb.FrameError)


def test_silent_unit_times_out_after_all_attempts(sim: Simulator) -> None:
    sim.set_silent(1)
    with bb.Bus(sim.port, timeout=0.1, retries=2) as bus:
        start = time.monotonic()
        with pytest.raises(bb.ResponseTimeout) as e:
            bus.read_holding_registers(1, 0, 1)
        took = time.monotonic() - start
    assert 0.3 <= took < 0.4, took
    assert isinstance(e.value, TimeoutError)
    assert e.value.unit == 1
    assert len(sim.requests) == 3


def test_exception_reply_is_raised_at_once(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=1.0, retries=2) as bus:
        sim.answer_exception(2)
        start = time.monotonic()
        with pytest.raises(bb.ModbusException) as e:
            bus.read_holding_registers(1, 0x0032, 1)
        took = time.monotonic() - start
        assert took < 0.25, took
        assert (e.value.unit, e.value.function, e.value.code) == (1, 3, 2)
        assert e.value.meaning == "illegal data address"
        assert e.value.frame is not None
        assert bus.stats.exceptions == 1
        assert bus.stats.retries == 0
    assert len(sim.requests) == 1


@pytest.mark.parametrize(
    ("code", "meaning"),
    [(0x0A, "gateway path unavailable"), (0x0B, "gateway target device failed to respond")],
)
def test_gateway_exceptions_are_gateway_errors(sim: Simulator, code: int, meaning: str) -> None:
    with bb.Bus(sim.port, timeout=1.0, retries=2) as bus:
        sim.answer_exception(code)
        with pytest.raises(bb.GatewayError) as e:
            bus.read_holding_registers(1, 0x0032, 1)
        assert isinstance(e.value, bb.ModbusException)
        assert (e.value.unit, e.value.code, e.value.meaning) == (1, code, meaning)
        assert bus.stats.retries == 0
        # Any other code stays a plain ModbusException.
        sim.answer_exception(2)
        with pytest.raises(bb.ModbusException) as other:
            bus.read_holding_registers(1, 0x0032, 1)
        assert type(other.value) is bb.ModbusException


def test_write_interval_spaces_writes_to_a_unit(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.5) as bus:
        bus.write_register(1, 0x10, 1, write_interval=0.3)
        bus.write_registers(1, 0x10, [2, 3], write_interval=0.3)
        bus.read_holding_registers(1, 0x10, 1)  # a read is not paced
        bus.write_register(1, 0x10, 4)  # nor a write that asks for no interval
    t = sim.request_times
    assert t[1] - t[0] >= 0.3
    assert t[3] - t[1] < 0.3
    assert sim.peek(1, 0x10, 2) == [4, 3]


class BusyAt0x100(RegisterDevice):
    """A device whose register 0x0100 answers "server device failure" (code 4)."""

    def read_holding(self, address: int, count: int) -> list[int]:
        if address <= 0x100 < address + count:
            raise SimException(4)
        return super().read_holding(address, count)


def test_device_exception_from_its_handler() -> None:
    with (
        Simulator({1: BusyAt0x100({0x0FF: 9}, max_read=37)}) as sim,
        bb.Bus(sim.port, timeout=0.5) as bus,
    ):
        with pytest.raises(bb.ModbusException) as e:
            bus.read_holding_registers(1, 0x00F0, 17)
        assert e.value.code == 4
        assert e.value.meaning == "server device failure"
        with pytest.raises(bb.ModbusException) as e:
            bus.read_holding_registers(1, 0, 38)  # over the device's 37-register limit
        assert e.value.code == 3
        assert bus.read_holding_registers(1, 0x00FF, 1) == [9]


def test_stale_bytes_are_dropped_before_a_request(sim: Simulator) -> None:
    with bb.Bus(sim.port, timeout=0.2) as bus:
        sim.inject_raw(b"\xaa\xbb\xcc")
        time.sleep(0.05)
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        assert bus.stats.stale_bytes == 3


def test_reply_from_wrong_unit_is_a_frame_error(slave: ScriptedSlave) -> None:
    reply = bytes([2, 3, 2, 0, 7])
    reply += bb.crc16(reply).to_bytes(2, "little")
    with bb.Bus(slave.port, timeout=0.2, retries=0) as bus:
        slave.expect(8, reply)
        with pytest.raises(bb.FrameError) as e:
            bus.read_holding_registers(1, 0, 1)
        assert not isinstance(e.value, bb.CrcError)
        assert "unit 2" in str(e.value)
        assert bus.stats.frame_errors == 1


def test_a_byte_count_that_disagrees_with_the_request_names_both(slave: ScriptedSlave) -> None:
    # A valid frame (its CRC is right over all 7 bytes) with byte count 1, to a one-register
    # read: not a CRC error, but the two counts; nothing of it is left for the next call.
    reply = bytes.fromhex("01 03 01 00 07 09 86")
    with bb.Bus(slave.port, timeout=0.2, retries=0) as bus:
        slave.expect(8, reply)
        with pytest.raises(bb.FrameError) as e:
            bus.read_holding_registers(1, 0, 1)
        assert not isinstance(e.value, bb.CrcError)
        assert "byte count 1" in str(e.value) and "asked for 2 bytes" in str(e.value)
        assert e.value.frame == "01 03 01 00 07 09 86"
        assert (bus.stats.frame_errors, bus.stats.crc_errors, bus.stats.stale_bytes) == (1, 0, 0)


def test_two_threads_share_one_bus_without_interleaving(sim: Simulator) -> None:
    errors: list[BaseException] = []
    with bb.Bus(sim.port, timeout=0.5) as bus:

        def worker(unit: int, address: int, expected: int) -> None:
            try:
                for _ in range(40):
                    assert bus.read_holding_registers(unit, address, 1) == [expected]
            except BaseException as e:
                errors.append(e)

        threads = [
            threading.Thread(target=worker, args=(1, 0x3006, 1450)),
            threading.Thread(target=worker, args=(2, 0x0010, 0x2222)),
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
        assert bus.stats.transactions == 80
    assert not errors, errors
    assert len(sim.requests) == 80
    assert all(len(r) == 8 and crc_ok(r) for r in sim.requests)
    assert all(len(r) == 7 and crc_ok(r) for r in sim.replies)


def test_gil_is_released_while_waiting_for_the_wire(sim: Simulator) -> None:
    sim.reply_delay = 0.3
    with bb.Bus(sim.port, timeout=1.0) as bus:
        t = threading.Thread(target=bus.read_holding_registers, args=(1, 0, 1))
        start = time.monotonic()
        t.start()
        spins = 0
        while t.is_alive() and time.monotonic() - start < 2:
            spins += 1
        t.join()
    # The main thread ran Python code the whole 0.3 s the other waited for its reply.
    assert time.monotonic() - start >= 0.3
    assert spins > 10_000


def test_bad_arguments_are_refused_before_anything_is_sent(sim: Simulator) -> None:
    with bb.Bus(sim.port) as bus:
        bad_calls = [
            (ValueError, lambda: bus.read_holding_registers(0, 0, 1)),
            (ValueError, lambda: bus.read_holding_registers(256, 0, 1)),
            (ValueError, lambda: bus.read_holding_registers(1, 0, 0)),
            (ValueError, lambda: bus.read_holding_registers(1, 0, 126)),
            (ValueError, lambda: bus.read_holding_registers(1, 0x10000, 1)),
            (ValueError, lambda: bus.read_holding_registers(1, 0xFFFF, 2)),
            (ValueError, lambda: bus.read_holding_registers(1, -1, 1)),
            (ValueError, lambda: bus.write_register(1, 0, 0x10000)),
            (ValueError, lambda: bus.write_register(1, 0, 2**100)),
            (ValueError, lambda: bus.write_register(1, 0, -1)),
            (ValueError, lambda: bus.write_registers(1, 0, [])),
            (ValueError, lambda: bus.write_registers(1, 0, [0] * 124)),
            (ValueError, lambda: bus.write_registers(1, 0, [1, 70000])),
            (ValueError, lambda: bus.broadcast_write_register(0, 0x10000)),
            (ValueError, lambda: bus.read_device_identification(1, 5)),
            (ValueError, lambda: bus.scan([0, 1])),
            (TypeError, lambda: bus.read_holding_registers("1", 0, 1)),  # type: ignore[arg-type]
            (TypeError, lambda: bus.write_register(1, 0, 1.5)),  # type: ignore[arg-type]
            (TypeError, lambda: bus.write_registers(1, 0, "12")),
            (TypeError, lambda: bus.write_registers(1, 0, None)),  # type: ignore[arg-type]
        ]
        for exc, call in bad_calls:
            with pytest.raises(exc):
                call()
        assert bus.stats.transactions == 0
    assert sim.requests == []


@pytest.mark.parametrize(
    ("kwargs", "exc"),
    [
        ({"parity": "X"}, ValueError),
        ({"stopbits": 3}, ValueError),
        ({"timeout": 0}, ValueError),
        ({"timeout": -1.0}, ValueError),
        ({"timeout": float("nan")}, ValueError),
        ({"retries": -1}, ValueError),
        ({"baudrate": 0}, ValueError),
        ({"baudrate": 2**64}, ValueError),
        ({"timeout": "fast"}, TypeError),
    ],
)
def test_bad_bus_arguments(sim: Simulator, kwargs: dict[str, object], exc: type) -> None:
    with pytest.raises(exc):
        bb.Bus(sim.port, **kwargs)  # type: ignore[arg-type]


def test_port_errors() -> None:
    with pytest.raises(bb.PortError) as e:
        bb.Bus("/dev/does-not-exist")
    assert isinstance(e.value, OSError)
    with pytest.raises(ValueError, match="foo"):
        bb.Bus("foo://127.0.0.1:502")
    with pytest.raises(ValueError, match="port"):
        bb.Bus("rtu+tcp://127.0.0.1")  # a device server has no standard port


def test_a_file_that_is_not_a_serial_port_is_told_so() -> None:
    with pytest.raises(bb.PortError, match="not a serial port") as e:
        bb.Bus("/dev/null")
    assert "/dev/null" in str(e.value)


@pytest.mark.parametrize("timeout", [0, -1, 3601])
def test_the_timeout_range_reads_as_words(sim: Simulator, timeout: float) -> None:
    message = f"^timeout must be more than 0 and at most 3600 seconds, got {timeout}$"
    with pytest.raises(ValueError, match=message):
        bb.Bus(sim.port, timeout=timeout)


def test_closed_bus_and_exclusive_open(sim: Simulator) -> None:
    bus = bb.Bus(sim.port)
    with pytest.raises(bb.PortError):
        bb.Bus(sim.port)  # the port is held exclusively
    bus.close()
    bus.close()
    assert bus.closed
    with pytest.raises(bb.PortError, match="closed"):
        bus.read_holding_registers(1, 0, 1)
    with bb.Bus(sim.port) as again:  # released on close
        assert again.read_holding_registers(1, 0x3006, 1) == [1450]
    assert again.closed


def test_properties_and_line_timing(sim: Simulator) -> None:
    with bb.Bus(sim.port, baudrate=115200, parity="E", stopbits=1, timeout=0.25, retries=3) as bus:
        assert (bus.port, bus.baudrate, bus.parity, bus.stopbits) == (sim.port, 115200, "E", 1)
        assert (bus.timeout, bus.retries) == (0.25, 3)
        # 8E1: 11 bits a character (times are kept to the nanosecond).
        assert bus.char_time == pytest.approx(11 / 115200, abs=1e-9)
        assert bus.t3_5 == pytest.approx(0.00175)  # fixed above 19200 baud
        # 8E1 on a pseudo-terminal (no parity bit) still works.
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        assert "115200" in repr(bus)
    with bb.Bus(sim.port, baudrate=19200) as bus:
        assert bus.char_time == pytest.approx(10 / 19200, abs=1e-9)
        assert bus.t3_5 == pytest.approx(3.5 * 10 / 19200, abs=1e-9)


def test_silence_before_each_request(sim: Simulator) -> None:
    """Back-to-back requests are at least t3.5 apart on the wire."""
    with bb.Bus(sim.port, baudrate=9600) as bus:
        start = time.monotonic()
        for _ in range(20):
            bus.read_holding_registers(1, 0, 1)
        took = time.monotonic() - start
        assert took >= 20 * bus.t3_5


def test_every_frame_is_logged(sim: Simulator, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG, logger="benchbus.wire")
    with bb.Bus(sim.port, timeout=0.2) as bus:
        bus.read_holding_registers(1, 0, 1)
    wire = [r.getMessage() for r in caplog.records if r.name == "benchbus.wire"]
    assert any("01 03 00 00 00 01 84 0A" in m for m in wire), wire
    assert any("01 03 02 03 E8 B8 FA" in m for m in wire), wire
