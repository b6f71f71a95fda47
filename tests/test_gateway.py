"""The gateway: a Modbus TCP server that owns one serial port and serialises its clients
onto it. Checked with raw MBAP frames from sockets, against a simulator on the serial side
(which sees every frame the gateway puts on the line); and with a third-party client
(pymodbus's) against a third-party serial device (pymodbus's serial server) or a scripted
one for a vendor's function.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ModbusPDU
from pymodbus_peer import COILS, DISCRETE, HOLDING, INPUT, pymodbus_serial_server

import benchbus as bb
from benchbus.sim import Atv31Device, J2Device, RegisterDevice, Simulator
from conftest import ScriptedSlave, gateway_command, read_up_to, rtu

TIMEOUT = 0.3  # generous: a loaded machine must not turn a reply into a 0x0B
IDENTITY = {0: "Müller & Söhne €", 1: "RB-1", 2: "1.0"}


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice | J2Device]]:
    devices: dict[int, RegisterDevice | J2Device] = {
        1: RegisterDevice({0x3006: 1450, 0x3007: 7}, identity=IDENTITY),
        2: RegisterDevice({0: 0}),
        5: J2Device(),
    }
    with Simulator(devices) as s:
        yield s


@pytest.fixture
def gateway(sim: Simulator[RegisterDevice | J2Device]) -> Iterator[bb.Gateway]:
    with (
        bb.Bus(sim.port, timeout=TIMEOUT, retries=1) as bus,
        bb.Gateway(bus, "127.0.0.1:0") as gw,
    ):
        yield gw


def connect(gw: bb.Gateway) -> socket.socket:
    client = socket.create_connection(gw.address, timeout=2.0)
    client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return client


def ask(client: socket.socket, unit: int, pdu: bytes, tid: int = 1) -> bytes:
    """Send one MBAP request; the reply's PDU (its header checked)."""
    client.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
    header = recv(client, 7)
    got_tid, pid, length, got_unit = struct.unpack(">HHHB", header)
    assert (got_tid, pid, got_unit) == (tid, 0, unit)
    return recv(client, length - 1)


def recv(client: socket.socket, n: int) -> bytes:
    buf = b""
    while len(buf) < n:
        chunk = client.recv(n - len(buf))
        assert chunk, "connection closed"
        buf += chunk
    return buf


def test_golden_read_through_the_gateway(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        client.sendall(bytes.fromhex("00 01 00 00 00 06 01 03 30 06 00 02"))
        assert recv(client, 13) == bytes.fromhex("00 01 00 00 00 07 01 03 04 05 AA 00 07")
    # On the line: the RTU form of the same request.
    rtu = bytes.fromhex("01 03 30 06 00 02")
    assert sim.requests == [rtu + bb.crc16(rtu).to_bytes(2, "little")]
    assert gateway.url == f"tcp://127.0.0.1:{gateway.address[1]}"


def test_writes_reach_the_unit(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        assert ask(client, 2, bytes.fromhex("06 00 00 12 34"), tid=7) == bytes.fromhex(
            "06 00 00 12 34"
        )
        assert sim.peek(2, 0) == [0x1234]
        assert ask(client, 1, bytes.fromhex("10 30 06 00 02 04 00 01 00 02")) == bytes.fromhex(
            "10 30 06 00 02"
        )
        assert sim.peek(1, 0x3006, 2) == [1, 2]
    assert gateway.stats.requests == 2


def test_exceptions_from_the_unit_and_from_the_gateway(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        sim.answer_exception(2, unit=1)
        assert ask(client, 1, bytes.fromhex("03 30 06 00 01")) == bytes([0x83, 0x02])
        # A unit that does not answer: 0x0B, after the Bus's own timeout and retry.
        assert ask(client, 9, bytes.fromhex("03 00 00 00 01")) == bytes([0x83, 0x0B])
        assert [r[0] for r in sim.requests[-2:]] == [9, 9]
        # A function code no request has (0, 0x80 and up): 0x01, and nothing on the line.
        before = len(sim.requests)
        assert ask(client, 1, bytes.fromhex("00 00 00 00 01")) == bytes([0x80, 0x01])
        assert ask(client, 1, bytes.fromhex("84 00 00 00 01")) == bytes([0x84, 0x01])
        # A byte count that does not match: 0x03, nothing on the line.
        assert ask(client, 1, bytes.fromhex("10 00 00 00 02 02 00 01")) == bytes([0x90, 0x03])
        assert ask(client, 1, bytes.fromhex("03 00 00 00 00")) == bytes([0x83, 0x03])
        # A function of the specification with a malformed length, a count past its limits
        # or a byte count that does not match: 0x03 (illegal data value), not 0x01.
        for pdu in (
            *("03 0C 1E 00", "03 00 00 00 01 00", "06 00 01", "10 00 00", "2B", "2B 0E 01"),
            *("01 00 00 07 D1", "02 FF FF 00 02", "04 00 00 00 7E", "05 00 00 12 34"),
            *("0F 00 00 00 0A 01 FF", "0F 00 00 07 B1 F7" + " 00" * 247, "16 00 00 00 F2"),
            *("17 00 00 00 01 00 00 00 01 01 00", "08 00", "07 00", "11 00", "0B 00"),
        ):
            request = bytes.fromhex(pdu)
            assert ask(client, 1, request) == bytes([request[0] | 0x80, 0x03]), pdu
        assert len(sim.requests) == before
        # Any other function goes to the unit, and its answer comes back: here another MEI
        # type of 0x2B, which this unit does not know.
        assert ask(client, 1, bytes.fromhex("2B 0D 01 00")) == bytes([0xAB, 0x01])
        assert sim.requests[-1][:-2] == bytes.fromhex("01 2B 0D 01 00")
    assert gateway.stats.gateway_exceptions == 23


def test_a_lost_line_is_path_unavailable(gateway: bb.Gateway) -> None:
    gateway.bus.close()
    with connect(gateway) as client:
        assert ask(client, 1, bytes.fromhex("03 30 06 00 01")) == bytes([0x83, 0x0A])


def test_device_identification_through_the_gateway(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        reply = ask(client, 1, bytes.fromhex("2B 0E 01 00"))
    # The conformity level is the one the unit sent (pymodbus: 0x83), not the read code.
    (line_reply,) = sim.replies
    assert line_reply[4] == 0x83
    assert reply[:7] == bytes([0x2B, 0x0E, 0x01, 0x83, 0x00, 0x00, 3])
    objects, at = {}, 7
    for _ in range(reply[6]):
        object_id, size = reply[at], reply[at + 1]
        objects[object_id] = reply[at + 2 : at + 2 + size].decode("utf-8")
        at += 2 + size
    assert objects == IDENTITY


def identification_objects(pdu: bytes) -> dict[int, bytes]:
    """The objects of a 0x2B / 0x0E reply PDU, as the bytes it carries."""
    objects, at = {}, 7
    for _ in range(pdu[6]):
        object_id, size = pdu[at], pdu[at + 1]
        objects[object_id] = pdu[at + 2 : at + 2 + size]
        at += 2 + size
    return objects


def test_identification_reads_the_same_through_the_bus_the_instrument_and_the_gateway(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        reply = ask(client, 1, bytes.fromhex("2B 0E 01 00"))
    sent = sim.replies[-1][1:-2]  # the unit's own reply PDU, as it went on the line
    # The gateway forwards the bytes the unit sent, not a re-encoding of them.
    assert reply == sent
    raw = identification_objects(sent)
    assert any(byte >= 0x80 for value in raw.values() for byte in value)
    # The Bus and Instrument.identify read them one way: a character per byte (Latin-1).
    text = {object_id: value.decode("latin-1") for object_id, value in raw.items()}
    assert gateway.bus.read_device_identification(1) == text
    ident = bb.Instrument(gateway.bus, 1).identify()
    assert ident.objects == text
    # Nothing lost: the text gives back the bytes the device sent (UTF-8 from this one).
    assert ident.vendor is not None
    assert ident.vendor.encode("latin-1") == IDENTITY[0].encode("utf-8")


@pytest.mark.parametrize(("conformity", "expected"), [(None, 0x02), (0x81, 0x81)])
def test_identification_keeps_the_conformity_and_bytes_the_unit_sent(
    conformity: int | None, expected: int
) -> None:
    # The ATV31 answers conformity 0x02 whatever the read code (3 here: extended).
    with (
        Simulator({3: Atv31Device(conformity=conformity)}) as sim,
        bb.Bus(sim.port, timeout=TIMEOUT) as bus,
        bb.Gateway(bus, "127.0.0.1:0") as gw,
        connect(gw) as client,
    ):
        direct = bus._device_identification(3, 3, 0)
        assert direct == (expected, {0: b"TELEMECANIQUE", 1: b"ATV31HU09M3S232", 2: b"0201"})
        reply = ask(client, 3, bytes.fromhex("2B 0E 03 00"))
        # Byte for byte the unit's own reply PDU: its conformity, its objects.
        assert reply == sim.replies[-1][1:-2]
        assert reply[3] == expected


def test_a_broadcast_is_sent_and_not_answered(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        client.sendall(bytes.fromhex("00 05 00 00 00 06 00 06 00 00 00 2A"))
        # The next request's reply is the first thing to come back.
        assert ask(client, 2, bytes.fromhex("03 00 00 00 01"), tid=6) == bytes.fromhex(
            "03 02 00 2A"
        )
    assert sim.requests[0][:6] == bytes.fromhex("00 06 00 00 00 2A")
    # Any other broadcast is not forwarded, and not answered either.
    with connect(gateway) as client:
        client.sendall(bytes.fromhex("00 08 00 00 00 06 00 03 00 00 00 01"))
        assert ask(client, 2, bytes.fromhex("03 00 00 00 01"), tid=9) == bytes.fromhex(
            "03 02 00 2A"
        )
    assert [f[0] for f in sim.requests] == [0, 2, 2]


def test_a_multiple_register_broadcast_reaches_every_unit(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        client.sendall(bytes.fromhex("00 05 00 00 00 0B 00 10 30 06 00 02 04 01 02 03 04"))
        # A malformed one (the byte count disagrees) goes nowhere, and is not answered.
        client.sendall(bytes.fromhex("00 06 00 00 00 0B 00 10 30 06 00 02 03 01 02 03 04"))
        assert ask(client, 1, bytes.fromhex("03 30 06 00 02"), tid=7) == bytes.fromhex(
            "03 04 01 02 03 04"
        )
    rtu = bytes.fromhex("00 10 30 06 00 02 04 01 02 03 04")
    assert sim.requests[0] == rtu + bb.crc16(rtu).to_bytes(2, "little")
    assert [f[0] for f in sim.requests] == [0, 1]
    assert sim.peek(1, 0x3006, 2) == [0x0102, 0x0304]


def test_bad_frames_are_dropped(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        # Protocol id 1 is not Modbus: no reply, the connection goes on.
        client.sendall(bytes.fromhex("00 01 00 01 00 06 01 03 30 06 00 01"))
        assert ask(client, 1, bytes.fromhex("03 30 06 00 01"), tid=2) == bytes.fromhex(
            "03 02 05 AA"
        )
        # A length no Modbus frame has: the connection is out of step and is closed.
        client.sendall(bytes.fromhex("00 03 00 00 01 00 01"))
        assert client.recv(16) == b""
    assert gateway.stats.bad_frames == 2
    assert len(sim.requests) == 1


def test_clients_in_threads_get_their_own_replies(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    errors: list[str] = []

    def client_loop(index: int) -> None:
        with connect(gateway) as client:
            for n in range(40):
                value = index * 1000 + n
                tid = (index << 8) | n
                if ask(client, 2, struct.pack(">BHH", 6, index, value), tid) != struct.pack(
                    ">BHH", 6, index, value
                ):
                    errors.append(f"client {index}: write {n}")
                got = ask(client, 2, struct.pack(">BHH", 3, index, 1), tid)
                if got != struct.pack(">BBH", 3, 2, value):
                    errors.append(f"client {index}: read {n} gave {got.hex()}")

    threads = [threading.Thread(target=client_loop, args=(i,)) for i in range(1, 5)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert errors == []
    # Every frame on the line whole: 4 clients x 40 x (write + read).
    assert len(sim.requests) == 320
    assert all(bb.crc16(f[:-2]).to_bytes(2, "little") == f[-2:] for f in sim.requests)


def at_once(gw: bb.Gateway, unit: int, requests: list[list[bytes]]) -> None:
    """Each list of request PDUs for ``unit`` sent in turn by a client of its own, the
    clients at once, each in a thread."""

    def client_loop(pdus: list[bytes]) -> None:
        with connect(gw) as client:
            for pdu in pdus:
                ask(client, unit, pdu)

    threads = [threading.Thread(target=client_loop, args=(pdus,)) for pdus in requests]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)


@pytest.mark.parametrize("paced", [True, False])
def test_write_intervals_hold_across_clients(
    sim: Simulator[RegisterDevice | J2Device], paced: bool
) -> None:
    device = sim.devices[5]
    assert isinstance(device, J2Device)
    intervals = {5: 0.15} if paced else {}
    with (
        bb.Bus(sim.port, timeout=0.2, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0", write_intervals=intervals) as gw,
    ):
        # Two clients at once, each writing AL1 three times.
        at_once(gw, 5, [[struct.pack(">BHH", 6, 8, value)] * 3 for value in (100, 200)])
    assert len(device.write_times) == 6
    if paced:
        assert device.write_violations == []
    else:  # the clients' writes come closer than the controller allows
        assert device.write_violations != []


def test_write_intervals_hold_for_the_gateways_retries(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    device = sim.devices[5]
    assert isinstance(device, J2Device)
    with (
        bb.Bus(sim.port, timeout=0.2, retries=2) as bus,
        bb.Gateway(bus, "127.0.0.1:0", write_intervals={5: 0.15}) as gw,
        connect(gw) as client,
    ):
        ask(client, 5, struct.pack(">BHH", 6, 8, 100))
        sim.corrupt_next(1)  # the next write's reply is lost: the Bus repeats the write
        assert ask(client, 5, struct.pack(">BHH", 6, 8, 200)) == struct.pack(">BHH", 6, 8, 200)
        assert bus.stats.retries == 1
    assert len(device.write_times) == 3
    assert device.write_violations == []


def test_stop_ends_every_thread_and_connection(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with bb.Bus(sim.port, timeout=TIMEOUT) as bus:
        gw = bb.Gateway(bus, "127.0.0.1:0").start()
        clients = [connect(gw) for _ in range(3)]
        assert ask(clients[0], 2, bytes.fromhex("03 00 00 00 01")) == bytes.fromhex("03 02 00 00")
        accepted(gw, 3)  # one still in the listen queue would be reset, not closed
        gw.stop()
        assert [t.name for t in threading.enumerate() if "benchbus-gateway" in t.name] == []
        for client in clients:
            assert client.recv(16) == b""  # closed by the gateway
            client.close()
        with pytest.raises(ConnectionRefusedError):
            socket.create_connection(gw.address, timeout=2.0)
        gw.stop()  # idempotent
        assert not bus.closed


READ = bytes.fromhex("03 00 00 00 01")  # unit 2's register 0


def accepted(gw: bb.Gateway, n: int) -> None:
    """Wait (up to 2 s) until the gateway has accepted ``n`` connections in all: a client's
    connect() returns before the gateway takes the connection."""
    deadline = time.monotonic() + 2.0
    while gw.stats.connections < n:
        assert time.monotonic() < deadline, f"{gw.stats.connections} of {n} accepted"
        time.sleep(0.005)


def closed(client: socket.socket) -> bool:
    """Whether the gateway closed this connection (waits up to the client's timeout)."""
    try:
        return client.recv(16) == b""
    except ConnectionResetError:
        return True


def test_a_new_client_takes_the_place_of_the_longest_idle_one(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with (
        bb.Bus(sim.port, timeout=TIMEOUT) as bus,
        bb.Gateway(bus, "127.0.0.1:0", max_clients=2) as gw,
        connect(gw) as first,
        connect(gw) as second,
    ):
        accepted(gw, 2)
        assert ask(first, 2, READ) == bytes.fromhex("03 02 00 00")  # first: no longer idle
        with connect(gw) as third:
            assert closed(second)
            assert ask(third, 2, READ) == bytes.fromhex("03 02 00 00")
            assert ask(first, 2, READ) == bytes.fromhex("03 02 00 00")
        stats = gw.stats
        assert (stats.connections, stats.idle_closed, stats.refused) == (3, 1, 0)


def test_a_request_that_just_began_is_not_dropped_and_the_newcomer_is_answered_busy(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with (
        bb.Bus(sim.port, timeout=TIMEOUT) as bus,
        bb.Gateway(bus, "127.0.0.1:0", max_clients=1) as gw,
        connect(gw) as first,
    ):
        request = struct.pack(">HHHB", 1, 0, len(READ) + 1, 2) + READ
        first.sendall(request[:3])  # half a header: a request under way, for under 1 s
        with connect(gw) as second:
            assert ask(second, 2, READ, tid=9) == bytes([0x83, 0x06])  # server device busy
            assert closed(second)
        first.sendall(request[3:])
        assert recv(first, 11)[7:] == bytes.fromhex("03 02 00 00")
        stats = gw.stats
        assert (stats.connections, stats.refused, stats.idle_closed, stats.slow_closed) == (
            1,
            1,
            0,
            0,
        )
        assert stats.requests == 1  # the refused request never reached the line
    assert len(sim.requests) == 1


def occupied(
    sim: Simulator[RegisterDevice | J2Device], gw: bb.Gateway, client: socket.socket
) -> None:
    """Make ``client`` busy being served: it asks absent unit 9, which the gateway's Bus
    waits its timeout for; returns once the request is on the line. The client then waits
    up to 5 s for a reply: its answer (0x0B) comes after the gateway Bus's timeout."""
    client.sendall(struct.pack(">HHHB", 1, 0, len(READ) + 1, 9) + READ)
    client.settimeout(5.0)
    deadline = time.monotonic() + 2.0
    while not any(frame[0] == 9 for frame in sim.requests):
        assert time.monotonic() < deadline, "the request did not reach the line"
        time.sleep(0.005)


def test_a_client_beyond_max_clients_gets_server_device_busy_then_the_close(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with (
        bb.Bus(sim.port, timeout=2.0, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0", max_clients=1) as gw,
        connect(gw) as first,
    ):
        occupied(sim, gw, first)  # the only slot, serving a request: never dropped
        for tid, unit, pdu in [(0x0102, 2, READ), (0x0304, 1, bytes.fromhex("06 0000 0001"))]:
            with connect(gw) as newcomer:
                newcomer.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
                # The whole MBAP frame: the request's transaction id and unit, function |
                # 0x80, code 6; then the gateway closes the connection.
                answer = struct.pack(">HHHB", tid, 0, 3, unit) + bytes([pdu[0] | 0x80, 6])
                assert recv(newcomer, len(answer)) == answer
                assert closed(newcomer)
        assert recv(first, 9)[7:] == bytes([0x83, 0x0B])  # served in full meanwhile
        assert (gw.stats.refused, gw.stats.connections) == (2, 1)
    assert [frame[0] for frame in sim.requests] == [9]


def test_benchbus_raises_server_device_busy_saying_the_gateway_is_full(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with (
        bb.Bus(sim.port, timeout=2.0, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0", max_clients=1) as gw,
        connect(gw) as first,
    ):
        occupied(sim, gw, first)
        with bb.Bus(gw.url, timeout=1.0, retries=0) as client:
            with pytest.raises(bb.ModbusException) as info:
                client.read_holding_registers(2, 0, 1)
            assert not isinstance(info.value, bb.GatewayError)
            assert (info.value.unit, info.value.function, info.value.code) == (2, 3, 6)
            assert info.value.meaning.startswith("server device busy (")
            assert "all its client slots are taken" in info.value.meaning
            assert "--max-clients" in str(info.value)
            # Then the gateway closed the connection: a lost port, as after any close.
            with pytest.raises(bb.PortError, match="closed"):
                client.read_holding_registers(2, 0, 1)
        # A device's 0x06 says what its manual says, and the gateway's reading too.
        with bb.Bus(gw.url, timeout=1.0, retries=0) as client:
            with pytest.raises(bb.ModbusException) as info:
                bb.Drive(client, unit=1).speed_setpoint = 1000
            assert info.value.code == 6
            assert info.value.meaning.startswith("frame error (length or CRC) (")
            assert "all its client slots are taken" in info.value.meaning


def gone(client: socket.socket) -> bool:
    """Whether the gateway has closed (or reset) ``client``; does not wait."""
    if not select.select([client], [], [], 0)[0]:
        return False  # nothing waiting, not even the end: still open
    try:
        return client.recv(16) == b""
    except ConnectionResetError:
        return True


def test_slowloris_clients_are_dropped_by_their_frame_deadline_and_a_newcomer_is_served(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    frame_timeout = 0.5
    request = struct.pack(">HHHB", 1, 0, len(READ) + 1, 2) + READ
    with (
        bb.Bus(sim.port, timeout=TIMEOUT) as bus,
        bb.Gateway(bus, "127.0.0.1:0", max_clients=2, frame_timeout=frame_timeout) as gw,
        connect(gw) as slow1,
        connect(gw) as slow2,
    ):
        accepted(gw, 2)
        # One byte every 0.2 s each: never silent for long, never a whole request in time.
        started = time.monotonic()
        dropped_after: dict[int, float] = {}
        for at in range(len(request)):
            for n, slow in enumerate((slow1, slow2)):
                if n not in dropped_after and gone(slow):
                    dropped_after[n] = time.monotonic() - started
            if len(dropped_after) == 2:
                break
            for n, slow in enumerate((slow1, slow2)):
                if n not in dropped_after:
                    slow.sendall(request[at : at + 1])
            time.sleep(0.2)
        assert sorted(dropped_after) == [0, 1], "the slow clients were never dropped"
        # By the deadline counted from each one's first byte (with some latitude).
        late = frame_timeout + 1.0
        assert all(frame_timeout <= t < late for t in dropped_after.values()), dropped_after
        assert gw.stats.slow_closed == 2
        with connect(gw) as newcomer:
            assert ask(newcomer, 2, READ) == bytes.fromhex("03 02 00 00")
        assert (gw.stats.connections, gw.stats.refused) == (3, 0)
    assert len(sim.requests) == 1


def test_when_full_a_client_slow_to_send_its_request_makes_room_for_a_newcomer(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    request = struct.pack(">HHHB", 1, 0, len(READ) + 1, 2) + READ
    with (
        bb.Bus(sim.port, timeout=TIMEOUT) as bus,
        bb.Gateway(bus, "127.0.0.1:0", max_clients=1) as gw,  # frame timeout: 5 s
        connect(gw) as slow,
    ):
        slow.sendall(request[:3])
        time.sleep(1.2)  # arriving for over a second, within its frame timeout
        with connect(gw) as newcomer:
            assert ask(newcomer, 2, READ) == bytes.fromhex("03 02 00 00")
        assert closed(slow)
        stats = gw.stats
        assert (stats.slow_closed, stats.refused, stats.connections) == (1, 0, 2)


def test_thirty_two_silent_connections_do_not_lock_out_the_next(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    silent = [connect(gateway) for _ in range(32)]
    try:
        accepted(gateway, 32)
        with connect(gateway) as client:
            assert ask(client, 2, READ) == bytes.fromhex("03 02 00 00")
        assert closed(silent[0])  # the one idle the longest made room
        assert gateway.stats.idle_closed == 1
    finally:
        for s in silent:
            s.close()


def test_idle_clients_are_closed_after_idle_timeout(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with (
        bb.Bus(sim.port, timeout=TIMEOUT) as bus,
        bb.Gateway(bus, "127.0.0.1:0", idle_timeout=0.3) as gw,
        connect(gw) as idle,
        connect(gw) as busy,
    ):
        started = time.monotonic()
        while time.monotonic() - started < 0.9:  # three idle timeouts, never silent for one
            assert ask(busy, 2, READ) == bytes.fromhex("03 02 00 00")
            time.sleep(0.1)
        assert closed(idle)
        assert ask(busy, 2, READ) == bytes.fromhex("03 02 00 00")
        assert gw.stats.idle_closed == 1


def connect_from(gw: bb.Gateway, source: str) -> socket.socket:
    """A connection to the gateway from the local address ``source``."""
    client = socket.socket(socket.AF_INET6 if ":" in source else socket.AF_INET)
    client.settimeout(2.0)
    client.bind((source, 0))
    client.connect(gw.address)
    return client


def test_allow_limits_who_may_connect(sim: Simulator[RegisterDevice | J2Device]) -> None:
    with bb.Bus(sim.port, timeout=TIMEOUT) as bus:
        with bb.Gateway(bus, "127.0.0.1:0", allow=["127.0.0.1", "10.0.0.0/8"]) as gw:
            with connect_from(gw, "127.0.0.2") as stranger:
                assert closed(stranger)
            with connect_from(gw, "127.0.0.1") as friend:
                assert ask(friend, 2, READ) == bytes.fromhex("03 02 00 00")
            assert (gw.stats.refused, gw.stats.connections) == (1, 1)
        # A network, and IPv6.
        with (
            bb.Gateway(bus, "127.0.0.1:0", allow="127.0.0.0/30") as gw,
            connect_from(gw, "127.0.0.2") as client,
        ):
            assert ask(client, 2, READ) == bytes.fromhex("03 02 00 00")
        with bb.Gateway(bus, "[::1]:0", allow=["::1/128"]) as gw:
            with connect_from(gw, "::1") as client:
                assert ask(client, 2, READ) == bytes.fromhex("03 02 00 00")
            assert gw.stats.refused == 0


def test_listening_beyond_this_machine_warns(
    sim: Simulator[RegisterDevice | J2Device], caplog: pytest.LogCaptureFixture
) -> None:
    with bb.Bus(sim.port) as bus:
        for local in ("127.0.0.1:0", "[::1]:0", "localhost:0"):
            bb.Gateway(bus, local).start().stop()
        assert [r for r in caplog.records if r.levelno >= logging.WARNING] == []
        # 203.0.113.1 (TEST-NET-3) is no address of this machine: warned, then not bound.
        with pytest.raises(OSError):
            bb.Gateway(bus, "203.0.113.1:0").start()
        (warning,) = [r for r in caplog.records if r.levelno >= logging.WARNING]
        assert warning.name == "benchbus.gateway"
        assert "no authentication" in warning.getMessage()
        assert "allow" in warning.getMessage()


def test_gateway_arguments_are_checked(sim: Simulator[RegisterDevice | J2Device]) -> None:
    with bb.Bus(sim.port) as bus:
        with pytest.raises(ValueError, match="HOST:PORT"):
            bb.Gateway(bus, "5020")
        with pytest.raises(ValueError, match=r"0\.\.65535"):
            bb.Gateway(bus, "127.0.0.1:70000")
        with pytest.raises(ValueError, match=r"1\.\.255"):
            bb.Gateway(bus, write_intervals={0: 0.1})
        with pytest.raises(ValueError, match=r"0\.\.60"):
            bb.Gateway(bus, write_intervals={1: -1.0})
        for bad in ("[]:5020", "[::1:5020", "::1:5020", "[127.0.0.1]:5020", "host name:1"):
            with pytest.raises(ValueError, match="HOST:PORT"):
                bb.Gateway(bus, bad)
        with pytest.raises(ValueError, match="port"):
            bb.Gateway(bus, "127.0.0.1:\u0665")  # an Arabic-Indic five
        with pytest.raises(ValueError, match="max_clients"):
            bb.Gateway(bus, max_clients=0)
        for bad_timeout in (0, -1.0, float("nan"), float("inf")):
            with pytest.raises(ValueError, match="idle_timeout"):
                bb.Gateway(bus, idle_timeout=bad_timeout)
        with pytest.raises(TypeError, match="idle_timeout"):
            bb.Gateway(bus, idle_timeout="60")  # type: ignore[arg-type]
        for bad_timeout in (0, -1.0, float("nan"), float("inf")):
            with pytest.raises(ValueError, match="frame_timeout"):
                bb.Gateway(bus, frame_timeout=bad_timeout)
        for wrong in ("5", None, True):
            with pytest.raises(TypeError, match="frame_timeout"):
                bb.Gateway(bus, frame_timeout=wrong)  # type: ignore[arg-type]
        for bad_allow, message in [
            (["10.0.0.1/33"], "ADDR/BITS"),
            (["10.0.0.5/24"], r"host bits set: the network is 10\.0\.0\.0/24"),
            (["nowhere"], "ADDR/BITS"),
            (["::1/129"], "ADDR/BITS"),
            ([], "allow is empty"),
        ]:
            with pytest.raises(ValueError, match=message):
                bb.Gateway(bus, allow=bad_allow)
        with pytest.raises(TypeError, match="allow"):
            bb.Gateway(bus, allow=[0x7F000001])  # type: ignore[list-item]
        assert bb.Gateway(bus, "[::1]:0").start().url.startswith("tcp://[::1]:")
        with pytest.raises(TypeError, match=r"benchbus\.Bus"):
            bb.Gateway("not a bus")  # type: ignore[arg-type]
        taken = bb.Gateway(bus, "127.0.0.1:0").start()
        try:
            with pytest.raises(OSError):
                bb.Gateway(bus, f"127.0.0.1:{taken.address[1]}").start()
        finally:
            taken.stop()
    assert sim.requests == []


def test_the_gateway_command(sim: Simulator[RegisterDevice | J2Device]) -> None:
    with gateway_command(sim.port, "--timeout", "0.05") as (url, proc):
        host, port = url[len("tcp://") :].rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=2.0) as client:
            assert ask(client, 1, bytes.fromhex("03 30 06 00 01")) == bytes.fromhex("03 02 05 AA")
    assert proc.returncode == 0, proc.stderr_text  # type: ignore[attr-defined]
    assert "gateway for" in proc.stderr_text  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--listen", "nowhere"], "HOST:PORT"),
        (["--write-interval", "5"], "UNIT=SECONDS"),
        (["--write-interval", "5=-1"], "0..60"),
        (["--write-interval", "0=0.1"], "UNIT"),
        (["--allow", "10.0.0.5/24"], "host bits set: the network is 10.0.0.0/24"),
        (["--allow", "127.0.0.1", "--allow", "10.0.0.0/40"], "ADDR/BITS"),
        (["--idle-timeout", "0"], "> 0"),
        (["--frame-timeout", "0"], "> 0"),
        (["--max-clients", "0"], "max-clients"),
    ],
)
def test_gateway_command_usage_errors(args: list[str], message: str) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "benchbus", "gateway", "--port", "/dev/null", *args],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 2
    assert message in result.stderr
    assert len(result.stderr.splitlines()) == 1, result.stderr


def test_the_gateway_command_keeps_its_frame_timeout(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    with gateway_command(sim.port, "--frame-timeout", "0.3") as (url, _):
        host, port = url[len("tcp://") :].rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=2.0) as client:
            assert ask(client, 1, bytes.fromhex("03 30 06 00 01")) == bytes.fromhex("03 02 05 AA")
            client.sendall(bytes.fromhex("00 02 00 00"))  # the start of a request, no more
            started = time.monotonic()
            assert closed(client)
            assert 0.25 < time.monotonic() - started < 1.5


def test_the_gateway_command_limits_and_warns(sim: Simulator[RegisterDevice | J2Device]) -> None:
    with gateway_command(sim.port, "--allow", "127.0.0.2", "--idle-timeout", "0.2") as (url, _):
        host, port = url[len("tcp://") :].rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=2.0) as client:
            assert closed(client)  # from 127.0.0.1: not allowed
        with socket.socket() as client:
            client.settimeout(2.0)
            client.bind(("127.0.0.2", 0))
            client.connect((host, int(port)))
            assert ask(client, 1, bytes.fromhex("03 30 06 00 01")) == bytes.fromhex("03 02 05 AA")
            started = time.monotonic()
            assert closed(client)  # idle for 0.2 s
            assert time.monotonic() - started < 1.5
    # Beyond loopback (203.0.113.1, TEST-NET-3, is no address of this machine: not bound).
    result = subprocess.run(
        [
            *(sys.executable, "-m", "benchbus", "gateway", "--port", sim.port),
            *("--listen", "203.0.113.1:0", "--seconds", "1"),
        ],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 1
    warning, error = result.stderr.splitlines()
    assert "203.0.113.1" in warning and "no authentication" in warning and "--allow" in warning
    assert error.startswith("benchbus: cannot listen on 203.0.113.1:0")


# ---- every function, from a third-party client to a third-party serial device ----


@contextlib.contextmanager
def client_of(gw: bb.Gateway) -> Iterator[ModbusTcpClient]:
    """pymodbus's Modbus TCP client, connected to ``gw``."""
    client = ModbusTcpClient(gw.address[0], port=gw.address[1], timeout=2.0, retries=0)
    assert client.connect()
    try:
        yield client
    finally:
        client.close()


@pytest.fixture
def third_party() -> Iterator[ModbusTcpClient]:
    """pymodbus's TCP client, through a Gateway, to pymodbus's serial server (unit 1)."""
    with (
        pymodbus_serial_server() as port,
        bb.Bus(port, timeout=TIMEOUT, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0") as gw,
        client_of(gw) as client,
    ):
        yield client


def bits(values: list[int]) -> list[bool]:
    return [bool(v) for v in values]


def test_a_third_party_client_reads_every_table_through_the_gateway(
    third_party: ModbusTcpClient,
) -> None:
    client = third_party
    assert client.read_coils(0, count=10, device_id=1).bits[:10] == bits(COILS[:10])
    assert client.read_coils(0, count=2000, device_id=1).bits == bits(COILS)
    assert client.read_discrete_inputs(3, count=5, device_id=1).bits[:5] == bits(DISCRETE[3:8])
    assert client.read_discrete_inputs(0, count=2000, device_id=1).bits == bits(DISCRETE)
    assert client.read_input_registers(0, count=125, device_id=1).registers == INPUT[:125]
    assert client.read_input_registers(7, count=1, device_id=1).registers == [1007]
    assert client.read_holding_registers(7, count=2, device_id=1).registers == HOLDING[7:9]


def test_a_third_party_client_writes_through_the_gateway(third_party: ModbusTcpClient) -> None:
    client = third_party
    assert not client.write_coil(20, True, device_id=1).isError()
    assert client.read_coils(19, count=3, device_id=1).bits[:3] == [False, True, False]
    pattern = [True, False, True, True, False, False, True, True, True, False, True]
    assert not client.write_coils(30, pattern, device_id=1).isError()
    assert client.read_coils(30, count=11, device_id=1).bits[:11] == pattern
    # The specification's mask write (6.16): 0x12 AND 0xF2 OR (0x25 AND NOT 0xF2) = 0x17.
    assert not client.write_register(50, 0x12, device_id=1).isError()
    reply = client.mask_write_register(address=50, and_mask=0xF2, or_mask=0x25, device_id=1)
    assert not reply.isError()
    assert client.read_holding_registers(50, count=1, device_id=1).registers == [0x17]
    # 0x17 writes first, then reads: the values written come back.
    reply = client.readwrite_registers(
        read_address=60, read_count=4, write_address=61, values=[7, 8, 9], device_id=1
    )
    assert reply.registers == [60, 7, 8, 9]


def test_serial_line_functions_through_the_gateway(third_party: ModbusTcpClient) -> None:
    client = third_party
    assert client.diag_query_data(b"\xa5\x37", device_id=1).message == b"\xa5\x37"
    server_id = client.report_device_id(device_id=1)
    # pymodbus's server id and its run indicator, ON.
    assert (server_id.identifier, server_id.status) == (b"Pymodbus", True)
    assert client.read_exception_status(device_id=1).status == 0
    # Get comm event counter (0x0B, a reply of fixed length) and log (0x0C, whose reply
    # the gateway reads by its byte count): nothing happened on pymodbus's side.
    counter = client.diag_get_comm_event_counter(device_id=1)
    assert not counter.isError()
    assert (counter.status, counter.count) == (True, 0)
    log = client.diag_get_comm_event_log(device_id=1)
    assert not log.isError()
    assert (log.status, log.event_count, log.events) == (True, 0, [])


def test_an_exception_reply_passes_through(third_party: ModbusTcpClient) -> None:
    # The peer's input registers end at 199: its own exception 2 (illegal data address).
    reply = third_party.read_input_registers(199, count=5, device_id=1)
    assert reply.isError()
    assert (reply.function_code, reply.exception_code) == (0x84, 0x02)


def test_an_absent_unit_is_target_failed_for_a_third_party_client(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with client_of(gateway) as client:
        reply = client.read_coils(0, count=8, device_id=9)
    assert reply.isError()
    assert (reply.function_code, reply.exception_code) == (0x81, 0x0B)
    # The Bus's timeout and retry on the line, then the gateway's answer.
    assert [f[:2] for f in sim.requests] == [bytes([9, 0x01])] * 2


class VendorPDU(ModbusPDU):
    """A vendor's function 0x41 (request and reply alike): bytes of its own after the code."""

    function_code = 0x41

    def __init__(self, payload: bytes = b"", dev_id: int = 0, transaction_id: int = 0) -> None:
        super().__init__(dev_id=dev_id, transaction_id=transaction_id)
        self.payload = payload

    def encode(self) -> bytes:
        return self.payload

    def decode(self, data: bytes) -> None:
        self.payload = data


def test_any_other_function_is_forwarded_transparently(slave: ScriptedSlave) -> None:
    # A reply of the device's own length (11 bytes after the code): read by silence on the
    # line, and given to the client byte for byte.
    vendor_reply = bytes.fromhex("0A 00 01 02 03 04 05 06 07 08 09")
    with (
        bb.Bus(slave.port, timeout=0.5, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0") as gw,
        client_of(gw) as client,
    ):
        client.register(VendorPDU)
        slave.expect(7, rtu("01 41 " + vendor_reply.hex()))
        reply = client.execute(False, VendorPDU(bytes.fromhex("01 02 03"), dev_id=1))
        slave.join()
        assert isinstance(reply, VendorPDU)
        assert reply.payload == vendor_reply
        assert slave.received == [rtu("01 41 01 02 03")]
        # The device's exception reply to it passes through too.
        slave.expect(7, rtu("01 C1 04"))
        reply = client.execute(False, VendorPDU(bytes.fromhex("01 02 03"), dev_id=1))
        slave.join()
        assert reply.isError()
        assert (reply.function_code, reply.exception_code) == (0xC1, 0x04)
        assert gw.stats.gateway_exceptions == 0


def test_an_unknown_reply_ends_by_the_buses_silence(slave: ScriptedSlave) -> None:
    # An adapter that delivers the reply in two bursts 20 ms apart: with silence=0.1 the
    # gateway's Bus waits for the second, and the client gets the reply whole.
    frame = rtu("01 41 06 0A 0B 0C 0D 0E 0F")

    def device() -> None:
        slave.received.append(read_up_to(slave.master, 4, 2.0))
        os.write(slave.master, frame[:4])
        time.sleep(0.02)
        os.write(slave.master, frame[4:])

    with (
        bb.Bus(slave.port, timeout=0.5, retries=0, silence=0.1) as bus,
        bb.Gateway(bus, "127.0.0.1:0") as gw,
        client_of(gw) as client,
    ):
        client.register(VendorPDU)
        answering = threading.Thread(target=device)
        answering.start()
        reply = client.execute(False, VendorPDU(b"", dev_id=1))
        answering.join(5)
    assert slave.received == [rtu("01 41")]
    assert isinstance(reply, VendorPDU)
    assert reply.payload == frame[2:-2]


def test_force_listen_only_is_sent_once_and_not_answered(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        client.sendall(bytes.fromhex("00 05 00 00 00 06 01 08 00 04 00 00"))
        # The next request's reply is the first thing to come back.
        assert ask(client, 2, READ, tid=6) == bytes.fromhex("03 02 00 00")
    assert [f[:-2] for f in sim.requests] == [bytes.fromhex("01 08 00 04 00 00"), rtu_of(2, READ)]


def rtu_of(unit: int, pdu: bytes) -> bytes:
    """The serial line's frame of ``pdu`` for ``unit``, without its CRC."""
    return bytes([unit]) + pdu


def test_coil_broadcasts_reach_every_unit(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    with connect(gateway) as client:
        client.sendall(bytes.fromhex("00 05 00 00 00 06 00 05 00 03 FF 00"))
        client.sendall(bytes.fromhex("00 06 00 00 00 09 00 0F 00 00 00 0A 02 CD 01"))
        # A coil value that is neither on nor off goes nowhere, and is not answered.
        client.sendall(bytes.fromhex("00 07 00 00 00 06 00 05 00 03 12 34"))
        assert ask(client, 2, READ, tid=8) == bytes.fromhex("03 02 00 00")
    assert [f[:-2] for f in sim.requests] == [
        bytes.fromhex("00 05 00 03 FF 00"),
        bytes.fromhex("00 0F 00 00 00 0A 02 CD 01"),
        rtu_of(2, READ),
    ]
    assert gateway.bus.stats.broadcasts == 2


def test_a_mask_write_broadcast_reaches_every_unit(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    # 0x16 is one of the writes the Bus broadcasts (with 0x05, 0x06, 0x0F and 0x10); the
    # units that have it (not the J2 controller) apply it.
    for unit in (1, 2):
        device = sim.devices[unit]
        assert isinstance(device, RegisterDevice)
        device.registers[4] = 0x12
    with connect(gateway) as client:
        # The specification's example (6.16): 0x12 AND 0xF2, OR 0x25 where not kept.
        client.sendall(bytes.fromhex("00 05 00 00 00 08 00 16 00 04 00 F2 00 25"))
        assert ask(client, 2, READ, tid=6) == bytes.fromhex("03 02 00 00")
    assert [f[:-2] for f in sim.requests] == [
        bytes.fromhex("00 16 00 04 00 F2 00 25"),
        rtu_of(2, READ),
    ]
    assert [sim.peek(unit, 4) for unit in (1, 2)] == [[0x17], [0x17]]
    assert gateway.bus.stats.broadcasts == 1


def test_write_intervals_hold_between_broadcasts(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    device = sim.devices[5]
    assert isinstance(device, J2Device)
    with (
        bb.Bus(sim.port, timeout=0.2, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0", write_intervals={5: 0.15}) as gw,
        connect(gw) as client,
    ):
        # Broadcasts only: a write to every unit each, unit 5 never written alone.
        for tid, value in enumerate((100, 200, 300), start=1):
            client.sendall(struct.pack(">HHHBBHH", tid, 0, 6, 0, 6, 8, value))
        assert ask(client, 2, READ, tid=9) == bytes.fromhex("03 02 00 00")
        assert bus.stats.broadcasts == 3
    assert len(device.write_times) == 3
    assert device.write_violations == []


def test_write_intervals_hold_for_the_retries_of_every_write(
    sim: Simulator[RegisterDevice | J2Device],
) -> None:
    mask_write = bytes.fromhex("16 00 04 00 F2 00 25")
    with (
        bb.Bus(sim.port, timeout=0.2, retries=2) as bus,
        bb.Gateway(bus, "127.0.0.1:0", write_intervals={2: 0.15}) as gw,
        connect(gw) as client,
    ):
        sim.corrupt_next(1)  # the write's reply is lost: the Bus repeats the write
        assert ask(client, 2, mask_write) == mask_write
        assert bus.stats.retries == 1
    times = [t for f, t in zip(sim.requests, sim.request_times, strict=True) if f[0] == 2]
    assert len(times) == 2
    assert times[1] - times[0] >= 0.15


@pytest.mark.parametrize("paced", [True, False])
def test_write_intervals_hold_for_every_write_function(
    sim: Simulator[RegisterDevice | J2Device], paced: bool
) -> None:
    # Writes of several functions (0x06, 0x05, a vendor's 0x41) to one unit, from two
    # clients at once.
    intervals = {2: 0.15} if paced else {}
    writes = [bytes.fromhex("06 00 00 00 07"), bytes.fromhex("05 00 01 FF 00"), b"\x41"]
    with (
        bb.Bus(sim.port, timeout=0.2, retries=0) as bus,
        bb.Gateway(bus, "127.0.0.1:0", write_intervals=intervals) as gw,
    ):
        at_once(gw, 2, [writes, writes[1:] + writes[:1]])
    times = [t for f, t in zip(sim.requests, sim.request_times, strict=True) if f[0] == 2]
    assert len(times) == 6
    closest = min(b - a for a, b in zip(times, times[1:]))
    if paced:
        assert closest >= 0.15
    else:  # the clients' writes come closer than the unit allows
        assert closest < 0.15


#: The specification's examples (6.9, 6.10, 6.14, 6.15, 6.18): request PDU, reply PDU.
SPEC_EXAMPLES = [
    ("0B", "0B FF FF 01 08"),
    ("0C", "0C 08 00 00 01 08 01 21 20 00"),
    (
        "15 0D 06 00 04 00 07 00 03 06 AF 04 BE 10 0D",
        "15 0D 06 00 04 00 07 00 03 06 AF 04 BE 10 0D",
    ),
    (
        "14 0E 06 00 04 00 01 00 02 06 00 03 00 09 00 02",
        "14 0C 05 06 0D FE 00 20 05 06 33 CD 00 40",
    ),
    ("18 04 DE", "18 00 06 00 02 01 B8 12 84"),
]


def test_counters_files_and_fifo_through_the_gateway(
    sim: Simulator[RegisterDevice | J2Device], gateway: bb.Gateway
) -> None:
    device = sim.devices[2]
    assert isinstance(device, RegisterDevice)
    device.comm_busy, device.comm_event_count, device.comm_message_count = True, 0x0108, 0x0121
    device.comm_events = b"\x20\x00"
    device.files[4][1:3] = [0x0DFE, 0x0020]
    device.files[3][9:11] = [0x33CD, 0x0040]
    device.registers[0x04DE : 0x04DE + 3] = [2, 0x01B8, 0x1284]
    with connect(gateway) as client:
        for request, reply in SPEC_EXAMPLES:
            if request.startswith("0C"):
                # The example's unit: not busy, and without the 0x0B just counted and logged.
                device.comm_busy, device.comm_message_count = False, 0x0121
                device.comm_events = b"\x20\x00"
            got = ask(client, 2, bytes.fromhex(request))
            assert got.hex(" ") == bytes.fromhex(reply).hex(" "), request
        # Malformed: a byte count that is not the groups', a reference type other than 6, a
        # FIFO address of one byte, data after 0x0C: answered 0x03 and not sent.
        sent = len(sim.requests)
        for bad in ("14 0E 06 00 04 00 01 00 02", "14 07 07 00 04 00 01 00 01", "18 04", "0C 00"):
            pdu = bytes.fromhex(bad)
            assert ask(client, 2, pdu) == bytes([pdu[0] | 0x80, 0x03]), bad
        assert len(sim.requests) == sent
    # Each went on the line once, as the client sent it.
    assert [f[1:-2].hex(" ").upper() for f in sim.requests] == [r for r, _ in SPEC_EXAMPLES]
    # And benchbus's own client, over Modbus TCP, has the typed calls.
    with bb.Bus(gateway.url, timeout=2.0, retries=0) as bus:
        # The unit counted the 0x0C, 0x15, 0x14 and 0x18 since as events, and logged them
        # and this 0x0B (send 40 and receive 80 each, the newest first).
        assert bus.get_comm_event_counter(2) == (0, 0x010C)
        assert bus.get_comm_event_log(2).events == bytes.fromhex("40 80" * 5 + "20 00")
        assert bus.read_file_record(2, [(4, 7, 3)]) == [[0x06AF, 0x04BE, 0x100D]]
        assert bus.read_fifo_queue(2, 0x04DE) == [0x01B8, 0x1284]
        device.registers[0x04DE] = 32  # more than a FIFO holds: the unit's exception 3
        with pytest.raises(bb.ModbusException) as e:
            bus.read_fifo_queue(2, 0x04DE)
        assert e.value.code == 3
