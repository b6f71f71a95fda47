"""Networks: the full device APIs over ``tcp://`` (Modbus TCP to a gateway) and
``rtu+tcp://`` (RTU frames to a serial device server), against pymodbus TCP servers with the
device simulators behind them; refused, reset and slow gateways; and the benchbus gateway
shared by several client processes at once.
"""

from __future__ import annotations

import logging
import socket
import struct
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, J2Device, RegisterDevice, Simulator
from conftest import gateway_command

NETWORKS = ("tcp", "rtu+tcp")


@pytest.fixture(params=NETWORKS)
def network(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def sim(network: str) -> Iterator[Simulator[RegisterDevice | DriveDevice | J2Device]]:
    devices: dict[int, RegisterDevice | DriveDevice | J2Device] = {
        1: DriveDevice("BLD2"),
        2: RegisterDevice({0x3006: 1450}),
        5: J2Device(),
    }
    with Simulator(devices, network=network) as s:
        yield s


def pdus(sim: Simulator[RegisterDevice | DriveDevice | J2Device]) -> list[bytes]:
    """Each logged request as unit + PDU, whatever its framing on the socket."""
    if sim.network == "tcp":
        return [frame[6:] for frame in sim.requests]
    return [frame[:-2] for frame in sim.requests]


def test_the_drive_api_over_the_network(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    device = sim.devices[1]
    assert isinstance(device, DriveDevice)
    with bb.Bus(sim.port, timeout=0.5) as bus:
        drive = bb.Drive(bus, unit=1)
        drive.verify_identity()  # a BLD2 over the network too
        sim.clear_log()
        drive.speed_setpoint = 1500
        drive.accel_time = 2.5
        assert device.peek(0x2001) == 1500
        assert drive.speed_setpoint == 1500
        assert drive.accel_time == pytest.approx(2.5)
        drive.forward()
        assert device.state == bb.DriveState.FORWARD
        assert drive.state == bb.DriveState.FORWARD
        drive.stop()
        assert device.commands == [1, 5]  # forward, stop
        # A refusal from the drive is the drive's exception, through the network as on a line.
        sim.answer_exception(3, unit=1)
        with pytest.raises(bb.ModbusException) as info:
            drive.speed_setpoint = 1000
        assert (info.value.unit, info.value.code) == (1, 3)
        assert not isinstance(info.value, bb.GatewayError)
        assert device.peek(0x2001) == 1500
        assert bus.stats.timeouts == 0
    assert tuple(pdus(sim)[0][:4]) == (1, 0x06, 0x20, 0x01)


def test_the_j2_api_over_the_network_keeps_pacing_and_chunking(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    device = sim.devices[5]
    assert isinstance(device, J2Device)
    with bb.Bus(sim.port, timeout=0.5) as bus:
        j2 = bb.J2Controller(bus, 5)
        for sv in (50.0, 60.0, 70.0):
            j2.sv = sv
        assert device.value("SV") == 70.0
        assert j2.sv == 70.0
        everything = j2.parameters()
        assert everything["SV"] == 70.0
    # The controller's 150 ms between writes and 16 registers a request hold over TCP too.
    assert device.write_violations == []
    reads = [p for p in pdus(sim) if p[:2] == bytes([5, 0x03])]
    assert reads and max(struct.unpack(">H", p[4:6])[0] for p in reads) <= 16


def test_a_refused_connection_is_a_port_error(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    sim.refuse_connections(True)
    start = time.monotonic()
    with pytest.raises(bb.PortError, match="refused"):
        bb.Bus(sim.port)
    assert time.monotonic() - start < 2.0
    sim.refuse_connections(False)
    with bb.Bus(sim.port) as bus:
        assert bus.read_holding_registers(2, 0x3006, 1) == [1450]


def test_a_reset_mid_reply_is_a_lost_port_and_reopen_brings_it_back(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    with bb.Bus(sim.port, timeout=0.5, retries=2) as bus:
        sim.reset_next()
        start = time.monotonic()
        with pytest.raises(bb.PortError, match="lost"):
            bus.read_holding_registers(2, 0x3006, 1)
        assert time.monotonic() - start < 0.5, "at once, not after a timeout"
        with pytest.raises(bb.PortError):
            bus.read_holding_registers(2, 0x3006, 1)
        bus.reopen()
        assert bus.read_holding_registers(2, 0x3006, 1) == [1450]
        assert bus.stats.reopens == 1


def test_reconnect_survives_a_gateway_that_drops_idle_connections(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    with bb.Bus(sim.port, timeout=0.5, reconnect=True) as bus:
        drive = bb.Drive(bus, unit=1)
        drive.speed_setpoint = 1200
        sim.drop_connections()
        time.sleep(0.05)
        # The closed connection is found before the request is written: no error at all.
        drive.speed_setpoint = 1300
        assert drive.speed_setpoint == 1300
        assert bus.stats.reopens == 1


def test_a_slow_gateway_times_out_and_its_late_reply_is_never_taken(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    with bb.Bus(sim.port, timeout=0.1, retries=0) as bus:
        # Late by one timeout: it comes during the next call, whose request went out at once;
        # its transaction id is the last call's, so it is dropped (and counted).
        sim.reply_delay = 0.2
        with pytest.raises(bb.ResponseTimeout):
            bus.read_holding_registers(2, 0x3006, 1)
        sim.reply_delay = 0.0
        bus.write_register(2, 0x3006, 7)
        assert bus.stats.stale_bytes > 0, "the late reply came, and was dropped"
        # Whichever reply came late, each call gets its own.
        assert bus.read_holding_registers(2, 0x3006, 1) == [7]
        assert bus.read_holding_registers(1, 0x2001, 1) == sim.peek(1, 0x2001)


def test_gateway_exceptions_over_modbus_tcp() -> None:
    with Simulator({2: RegisterDevice({0: 1})}, network="tcp") as sim, bb.Bus(sim.port) as bus:
        # A unit the gateway cannot reach: 0x0B, raised at once (the gateway timed out).
        with pytest.raises(bb.GatewayError) as info:
            bus.read_holding_registers(9, 0, 1)
        assert (info.value.unit, info.value.code) == (9, 0x0B)
        assert "failed to respond" in info.value.meaning
        assert bus.stats.retries == 0
        sim.answer_exception(0x0A, unit=2)
        with pytest.raises(bb.GatewayError, match="path unavailable"):
            bus.read_holding_registers(2, 0, 1)


def test_over_modbus_tcp_the_log_and_errors_show_the_bytes_on_the_network(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The wire log and an exception's ``.frame`` show the MBAP frames (transaction id,
    protocol 0, length, unit, PDU) that crossed the socket, so they match a capture: the
    requests as the server received them, the reply with the request's transaction id."""
    caplog.set_level(logging.DEBUG, logger="benchbus.wire")
    with Simulator({2: RegisterDevice({0: 1})}, network="tcp") as sim, bb.Bus(sim.port) as bus:
        assert bus.read_holding_registers(2, 0, 1) == [1]
        sim.answer_exception(0x02, unit=2)
        with pytest.raises(bb.ModbusException) as info:
            bus.read_holding_registers(2, 0, 1)
        received = list(sim.requests)
    sent = [m[3:] for m in (r.getMessage() for r in caplog.records) if m.startswith("-> ")]
    assert [bytes.fromhex(h) for h in sent] == received
    assert received[1][:2] == b"\x00\x02"  # the second transaction
    assert info.value.frame == "00 02 00 00 00 03 02 83 02"
    replies = [m[3:] for m in (r.getMessage() for r in caplog.records) if m.startswith("<- ")]
    assert replies == ["00 01 00 00 00 05 02 03 02 00 01", "00 02 00 00 00 03 02 83 02"]


def hostile_server(replies: list[bytes]) -> tuple[int, threading.Thread, list[bytes]]:
    """A one-connection Modbus TCP server on 127.0.0.1 that answers each request it reads
    with the next of ``replies`` (its transaction id put in the first two bytes): its port,
    its thread, and the requests it read. Every wait is bounded (2 s)."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(2.0)
    requests: list[bytes] = []

    def serve() -> None:
        with server, server.accept()[0] as conn:
            conn.settimeout(2.0)
            for reply in replies:
                request = b""
                while len(request) < 12:  # a read of holding registers: 12 bytes
                    chunk = conn.recv(12 - len(request))
                    if not chunk:
                        return
                    request += chunk
                requests.append(request)
                conn.sendall(request[:2] + reply[2:])
            conn.recv(1)  # until the client closes (or 2 s)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return server.getsockname()[1], thread, requests


def test_a_reply_whose_length_counts_extra_bytes_is_a_frame_error_and_the_next_is_read() -> None:
    port, thread, requests = hostile_server(
        [
            # length 7: unit 01 | 03 02 12 34, then two bytes the reply does not have.
            bytes.fromhex("0000 0000 0007 01 03 02 1234 5678"),
            bytes.fromhex("0000 0000 0005 01 03 02 0042"),
        ]
    )
    with bb.Bus(f"tcp://127.0.0.1:{port}", timeout=1.0, retries=0) as bus:
        with pytest.raises(bb.FrameError, match="MBAP length 7 counts 2 bytes more") as info:
            bus.read_holding_registers(1, 0, 1)
        assert not isinstance(info.value, bb.CrcError)
        # The whole frame as it came, the extra bytes with it.
        assert info.value.frame == "00 01 00 00 00 07 01 03 02 12 34 56 78"
        # They went with their frame: the next call, on the same connection, reads its own.
        assert bus.read_holding_registers(1, 0, 1) == [0x42]
        stats = bus.stats
        assert (stats.frame_errors, stats.stale_bytes, stats.transactions) == (1, 0, 1)
    thread.join(5.0)
    assert [r[:2] for r in requests] == [b"\x00\x01", b"\x00\x02"]


def test_scan_and_identification_over_the_network(
    sim: Simulator[RegisterDevice | DriveDevice | J2Device],
) -> None:
    with bb.Bus(sim.port) as bus:
        found = bus.scan(range(1, 8), timeout=0.1)
    # Over tcp:// the simulated gateway answers 0x0B for absent units: an answer, but not
    # a unit, so a scan through a gateway finds exactly the units behind it.
    assert found == [1, 2, 5]


# ---- the benchbus gateway, shared by processes -----------------------------------------------

CLIENT = textwrap.dedent(
    """
    import sys
    import benchbus as bb

    url, index = sys.argv[1], int(sys.argv[2])
    with bb.Bus(url, timeout=5.0, retries=0) as bus:
        for n in range(60):
            value = index * 1000 + n
            bus.write_register(index, 0x10, value)
            got = bus.read_holding_registers(index, 0x10, 1)[0]
            if got != value:
                sys.exit(f"client {index}: wrote {value}, read {got}")
        j2 = bb.J2Controller(bus, 5)
        for n in range(3):
            j2.alarm1 = 10.0 * index + n
    print("ok", index)
    """
)


@pytest.mark.timing  # each client's writes to the paced J2 wait behind the others' (5 s allowed)
def test_several_processes_share_one_line_through_the_gateway() -> None:
    devices: dict[int, RegisterDevice | J2Device] = {
        u: RegisterDevice({0x10: 0}) for u in (1, 2, 3)
    }
    devices[5] = J2Device()
    with (
        Simulator(devices) as sim,
        gateway_command(sim.port, "--timeout", "0.1", "--write-interval", "5=0.15") as (url, gw),
    ):
        clients = [
            subprocess.Popen(
                [sys.executable, "-c", CLIENT, url, str(index)],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            for index in (1, 2, 3)
        ]
        results = [c.communicate(timeout=120) for c in clients]
        for index, (client, (out, err)) in enumerate(zip(clients, results, strict=True), 1):
            assert client.returncode == 0, err
            assert out.strip() == f"ok {index}"
        # On the line: every frame whole (no interleaving), 3 x 120 register requests plus
        # the controller's, and the controller never written to faster than it allows.
        assert all(bb.crc16(f[:-2]).to_bytes(2, "little") == f[-2:] for f in sim.requests)
        register_requests = [f for f in sim.requests if f[0] in (1, 2, 3)]
        assert len(register_requests) == 360
        device = sim.devices[5]
        assert isinstance(device, J2Device)
        assert len(device.write_times) == 9
        assert device.write_violations == []
        assert [sim.peek(u, 0x10) for u in (1, 2, 3)] == [[1059], [2059], [3059]]
    assert gw.returncode == 0, gw.stderr_text  # type: ignore[attr-defined]


def test_a_network_simulator_needs_no_terminal_support() -> None:
    """Windows has no termios (so no tty module): a TCP simulator and a read through it work
    without them, as on a Windows test machine."""
    code = textwrap.dedent(
        """
        import sys
        sys.modules["tty"] = None  # importing tty now fails, as on Windows
        import benchbus as bb
        from benchbus.sim import RegisterDevice, Simulator
        with Simulator({3: RegisterDevice({0x10: 1234})}, network="tcp") as sim:
            with bb.Bus(sim.port, timeout=1) as bus:
                print(bus.read_holding_registers(3, 0x10, 1))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[1234]"
