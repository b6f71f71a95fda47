"""Modbus ASCII: the Bus's ``framing="ascii"``, the simulator's ASCII line, and third-party
peers (pymodbus's ASCII client and server).

The frames are the specification's examples in the serial line spec's ASCII framing
(``tests/vectors/ascii.json``), sent to the simulator as printed, without the library; then
the library's Bus in ASCII against the simulator and against pymodbus's server, and
pymodbus's client against the simulator.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
from pymodbus.client import ModbusSerialClient
from pymodbus.framer import FramerType
from pymodbus_peer import COILS, HOLDING, INPUT, pymodbus_server
from test_sim import Client
from test_sim_functions import EXAMPLES

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator

ALL_VECTORS = json.loads((Path(__file__).parent / "vectors" / "ascii.json").read_text("utf-8"))[
    "vectors"
]
VECTORS = {v["id"]: v for v in ALL_VECTORS}

#: The examples a RegisterDevice answers as printed, and its registers for them (the spec's
#: read example reads 0x022B, 0, 0x64 at 0x006B..0x006D).
SERVED = [
    "read-holding",
    "write-single",
    "write-multiple",
    "broadcast-write",
    "read-coils",
    "read-input",
]
REGISTERS = {0x6B: 0x022B, 0x6C: 0, 0x6D: 0x64}
#: The specification's state for the coil and input-register examples (from its text, as
#: test_sim_functions reads it): set up on the device before the request.
PRESETS = {
    "read-coils": EXAMPLES["0x01 read coils"],
    "read-input": EXAMPLES["0x04 read input registers"],
}


def ascii_reply(client: Client, timeout: float = 2.0) -> bytes:
    """The characters the simulator sends, up to the CR LF that ends a frame."""
    got = b""
    end = time.monotonic() + timeout
    while not got.endswith(b"\r\n") and time.monotonic() < end:
        got += client.recv(1, max(0.0, end - time.monotonic()))
    return got


def test_the_examples_cover_what_the_simulator_serves() -> None:
    assert set(SERVED) <= set(VECTORS)


@pytest.mark.parametrize("vector_id", SERVED)
def test_the_simulator_answers_the_specifications_example(vector_id: str) -> None:
    vector: dict[str, Any] = VECTORS[vector_id]
    unit = vector["unit"] or 0x11
    device = RegisterDevice(REGISTERS)
    if vector_id in PRESETS:
        PRESETS[vector_id].preset(device)
    with Simulator({unit: device}, framing="ascii") as sim:
        client = Client(sim.port)
        try:
            client.send(vector["request"]["frame"].encode())
            if "reply" in vector:
                assert ascii_reply(client) == vector["reply"]["frame"].encode()
            client.assert_quiet(0.1)
        finally:
            client.close()
    if vector_id == "write-single":
        assert device.registers[1] == 3
    if vector_id == "write-multiple":
        assert device.registers[1:3] == [0x000A, 0x0102]
    if vector_id == "broadcast-write":
        assert device.registers[1] == 3


def test_the_simulator_answers_an_exception_in_ascii() -> None:
    vector = VECTORS["read-exception"]
    with Simulator({vector["unit"]: RegisterDevice()}, framing="ascii") as sim:
        sim.answer_exception(2)
        client = Client(sim.port)
        try:
            client.send(vector["request"]["frame"].encode())
            assert ascii_reply(client) == vector["reply"]["frame"].encode()
        finally:
            client.close()


def test_the_simulator_drops_bad_frames_noise_and_a_frame_left_for_over_a_second() -> None:
    read = VECTORS["read-holding"]["request"]["frame"].encode()
    reply = VECTORS["read-holding"]["reply"]["frame"].encode()
    with Simulator({0x11: RegisterDevice(REGISTERS)}, framing="ascii") as sim:
        client = Client(sim.port)
        try:
            # A bad LRC, a character that is no hex digit: no reply (serial line spec 2.5.2).
            client.send(read.replace(b"7E\r", b"7F\r"))
            client.send(read.replace(b"6B", b"6G"))
            client.assert_quiet(0.2)
            # Noise, then a frame cut off by a new ':', then the frame: answered once.
            client.send(b"\x00\xff:1103" + read)
            assert ascii_reply(client) == reply
            # Split by a pause within the second the spec allows: answered.
            client.send(read[:7])
            time.sleep(0.3)
            client.send(read[7:])
            assert ascii_reply(client) == reply
            # Left for over a second: given up, its rest is no frame.
            client.send(read[:7])
            time.sleep(1.2)
            client.send(read[7:])
            client.assert_quiet(0.2)
            assert sim.request_count == 2
        finally:
            client.close()


@pytest.fixture
def ascii_sim() -> Any:
    devices = {
        1: RegisterDevice(
            {0: 5, 1: 6, 0x10: 0x2222}, identity={0: "ACME LABS", 1: "BB-42", 2: "1.07"}
        )
    }
    with Simulator(devices, framing="ascii") as sim:
        yield sim


def test_the_bus_reads_and_writes_in_ascii_against_the_simulator(ascii_sim: Any) -> None:
    sim = ascii_sim
    with bb.Bus(sim.port, framing="ascii", timeout=0.5) as bus:
        assert bus.read_holding_registers(1, 0, 2) == [5, 6]
        bus.write_register(1, 0x20, 7)
        bus.write_registers(1, 0x21, [8, 9])
        assert sim.devices[1].registers[0x20:0x23] == [7, 8, 9]
        # The longest write: 123 registers, a 511-character frame.
        values = list(range(1000, 1123))
        bus.write_registers(1, 0x100, values)
        assert sim.devices[1].registers[0x100 : 0x100 + 123] == values
        assert bus.read_holding_registers(1, 0x100, 125)[:123] == values
        ident = bus.read_device_identification(1)
        assert ident[0] == "ACME LABS"
        # A raw request without a reply length is read to its CR LF (no silence to wait).
        start = time.monotonic()
        raw = bus.request(1, 0x03, bytes([0, 0x10, 0, 1]))
        assert raw == bytes([2, 0x22, 0x22])
        assert time.monotonic() - start < 0.5
        bus.broadcast_write_registers(0x30, [4])
        assert sim.devices[1].registers[0x30] == 4
        assert bus.stats.transactions >= 8
        assert bus.stats.crc_errors == bus.stats.frame_errors == 0
    # What crossed the line: every request an ASCII frame, logged as its RTU twin.
    assert sim.requests[0] == bytes.fromhex("01 03 00 00 00 02 c4 0b")


def test_the_bus_in_ascii_gets_exceptions_and_retries_bad_lrcs(ascii_sim: Any) -> None:
    sim = ascii_sim
    with bb.Bus(sim.port, framing="ascii", timeout=0.3, retries=1) as bus:
        sim.answer_exception(2)
        with pytest.raises(bb.ModbusException) as caught:
            bus.read_holding_registers(1, 0, 2)
        assert (caught.value.unit, caught.value.function, caught.value.code) == (1, 3, 2)
        sim.corrupt_next(1)
        assert bus.read_holding_registers(1, 0, 2) == [5, 6]
        assert (bus.stats.crc_errors, bus.stats.retries) == (1, 1)
        sim.corrupt_next(2)
        with pytest.raises(bb.CrcError) as bad:
            bus.read_holding_registers(1, 0, 2)
        assert "LRC" in str(bad.value)
        # Noise before the reply's ':' is dropped and counted.
        sim.inject_raw(b"\x00\x7f")
        assert bus.read_holding_registers(1, 0, 2) == [5, 6]


def test_an_rtu_bus_gets_nothing_from_an_ascii_line(ascii_sim: Any) -> None:
    with (
        bb.Bus(ascii_sim.port, timeout=0.05, retries=0) as bus,
        pytest.raises(bb.ResponseTimeout),
    ):
        bus.read_holding_registers(1, 0, 2)


def test_pymodbus_ascii_client_against_the_simulator(ascii_sim: Any) -> None:
    # pyserial cannot set parity on a pseudo-terminal: 8N1 carries the 7-bit characters.
    client = ModbusSerialClient(
        port=ascii_sim.port,
        framer=FramerType.ASCII,
        baudrate=19200,
        bytesize=8,
        parity="N",
        stopbits=1,
        timeout=1,
    )
    assert client.connect()
    try:
        assert client.read_holding_registers(0, count=2, device_id=1).registers == [5, 6]
        assert not client.write_registers(0x40, [11, 12], device_id=1).isError()
        assert ascii_sim.devices[1].registers[0x40:0x42] == [11, 12]
        assert not client.write_register(0x42, 13, device_id=1).isError()
        assert ascii_sim.devices[1].registers[0x42] == 13
    finally:
        client.close()


def test_the_bus_in_ascii_against_pymodbus_ascii_server() -> None:
    with (
        pymodbus_server(True, ascii=True) as url,
        bb.Bus(url, framing="ascii", timeout=1.0) as bus,
    ):
        assert bus.read_holding_registers(1, 0, 10) == HOLDING[:10]
        assert bus.read_input_registers(1, 0, 3) == INPUT[:3]
        assert bus.read_coils(1, 0, 10) == [bool(c) for c in COILS[:10]]
        bus.write_registers(1, 100, [7, 8])
        assert bus.read_holding_registers(1, 100, 2) == [7, 8]
        bus.write_coil(1, 5, True)
        assert bus.read_coils(1, 5, 1) == [True]
        assert bus.diagnostics(1, 0, b"\x12\x34") == b"\x12\x34"
        with pytest.raises(bb.ModbusException) as caught:
            bus.read_holding_registers(1, 300, 5)
        assert caught.value.code == 2
        assert bus.stats.frame_errors == bus.stats.crc_errors == 0


def test_line_formats_default_to_the_specs_for_ascii() -> None:
    with Simulator({1: RegisterDevice()}) as sim:
        with bb.Bus(sim.port, framing="ascii") as bus:
            assert (bus.framing, bus.bytesize, bus.parity, bus.stopbits) == ("ascii", 7, "E", 1)
            assert "framing='ascii', bytesize=7" in repr(bus)
        with bb.Bus(sim.port, framing="ascii", parity="N") as bus:
            assert (bus.bytesize, bus.parity, bus.stopbits) == (7, "N", 2)
        with bb.Bus(sim.port, framing="ascii", bytesize=8, parity="N") as bus:
            assert (bus.bytesize, bus.parity, bus.stopbits) == (8, "N", 1)
        with bb.Bus(sim.port) as bus:
            assert (bus.framing, bus.bytesize, bus.parity, bus.stopbits) == ("rtu", 8, "N", 1)
            assert "framing" not in repr(bus)


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"framing": "ascii", "parity": "N", "stopbits": 1}, ValueError, "7N1 is not allowed"),
        ({"bytesize": 7}, ValueError, "RTU takes 8 data bits"),
        ({"framing": "ascii", "bytesize": 9}, ValueError, "bytesize"),
        ({"framing": "ascii", "bytesize": "7"}, TypeError, "bytesize"),
        ({"framing": "modbus"}, ValueError, "'rtu' or 'ascii'"),
        ({"framing": 1}, TypeError, "framing"),
    ],
)
def test_bad_framings_and_line_formats_are_refused(
    kwargs: dict[str, Any], error: type[Exception], words: str
) -> None:
    with Simulator({1: RegisterDevice()}) as sim:
        with pytest.raises(error, match=words):
            bb.Bus(sim.port, **kwargs)
        assert sim.request_count == 0


def test_ascii_over_modbus_tcp_is_refused() -> None:
    with pytest.raises(ValueError, match="tcp://"):
        bb.Bus("tcp://127.0.0.1:1", framing="ascii")


def test_the_simulator_refuses_ascii_on_a_network_and_unknown_framings() -> None:
    with pytest.raises(ValueError, match="line only"):
        Simulator({1: RegisterDevice()}, network="tcp", framing="ascii")
    with pytest.raises(ValueError, match="framing"):
        Simulator({1: RegisterDevice()}, framing="binary")
    assert Simulator({1: RegisterDevice()}, framing="ascii").framing == "ascii"


# ---- the command line ------------------------------------------------------------------------


def test_the_cli_reads_writes_and_scans_in_ascii() -> None:
    from test_cli import ok, one_line_error, run

    device = RegisterDevice({0x10: 0xFFFB, 0x11: 1234})
    with Simulator({7: device}, framing="ascii") as sim:
        port = ["--port", sim.port, "--unit", "7"]
        assert ok(run("read", *port, "0x10", "2", "--framing", "ascii")) == [
            "0x0010 (16) = 65531",
            "0x0011 (17) = 1234",
        ]
        ok(run("write", *port, "0x20", "5", "6", "--framing", "ASCII", "--parity", "N"))
        assert device.registers[0x20:0x22] == [5, 6]
        # 7N2 came from --parity N; the requests went out as ASCII frames (logged as RTU).
        assert sim.requests[-1][1] == 0x10
        found = ok(run("scan", "--port", sim.port, "--units", "6-8", "--framing", "ascii"))
        assert found[1].split()[:4] == ["7", "0x07", "19200", "7E1"]
        # Without --framing the command speaks RTU, which the ASCII line does not answer.
        silent = run("read", *port, "0x10", "--timeout", "0.05", "--retries", "0")
        assert "no complete reply" in one_line_error(silent, 1)
        # 7N1 is refused before anything is sent.
        sim.clear_log()
        bad = run("read", *port, "0x10", "--framing", "ascii", "--parity", "N", "--stopbits", "1")
        assert "7N1 is not allowed" in one_line_error(bad, 2)
        assert sim.request_count == 0


def test_the_cli_simulator_serves_ascii_and_doctor_takes_no_framing() -> None:
    import signal

    from test_cli import ok, readline, run, start, stop

    proc = start("sim", "drive", "--framing", "ascii", "--seconds", "20")
    try:
        port = readline(proc.stdout).strip()
        assert "Modbus ASCII" in readline(proc.stderr)
        lines = ok(run("read", "--port", port, "0x3006", "--framing", "ascii"))
        assert len(lines) == 1 and lines[0].startswith("0x3006")
    finally:
        stop(proc, signal.SIGTERM)
    doctor = run("doctor", "--port", "/dev/null", "--framing", "ascii")
    assert doctor.returncode == 2 and "--framing" in doctor.stderr


def test_the_gateway_serves_modbus_tcp_clients_from_an_ascii_line(ascii_sim: Any) -> None:
    from pymodbus.client import ModbusTcpClient

    with (
        bb.Bus(ascii_sim.port, framing="ascii", timeout=0.5) as line,
        bb.Gateway(line, "127.0.0.1:0") as gw,
    ):
        host, port = gw.address
        client = ModbusTcpClient(host, port=port, timeout=2)
        assert client.connect()
        try:
            assert client.read_holding_registers(0, count=2, device_id=1).registers == [5, 6]
            assert not client.write_registers(0x50, [3, 4], device_id=1).isError()
        finally:
            client.close()
    assert ascii_sim.devices[1].registers[0x50:0x52] == [3, 4]


def test_an_echoing_adapter_on_an_ascii_line() -> None:
    with (
        Simulator({1: RegisterDevice({0: 5, 1: 6})}, framing="ascii", echo=True) as sim,
        bb.Bus(sim.port, framing="ascii", echo=True, timeout=0.5) as bus,
    ):
        assert bus.read_holding_registers(1, 0, 2) == [5, 6]
        bus.write_registers(1, 0x100, list(range(123)))  # the longest frame echoed
        assert sim.devices[1].registers[0x100 : 0x100 + 123] == list(range(123))
        sim.collide_next(1)
        assert bus.read_holding_registers(1, 0, 2) == [5, 6]
        assert bus.stats.frame_errors == 1 and bus.stats.retries == 1
