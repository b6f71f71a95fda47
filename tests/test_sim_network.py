"""The network simulator (``Simulator(network="tcp" | "rtu+tcp")``), driven by raw sockets.

Nothing here goes through the library or the simulator's own framing helpers: the client
builds MBAP headers and RTU frames itself (CRC bit by bit), so a bug in either side's framing
cannot hide behind the other. Loopback only; every wait is bounded.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from urllib.parse import urlsplit

import pytest

from benchbus.sim import DriveDevice, Faults, RegisterDevice, SimDevice, SimException, Simulator
from conftest import crc, rtu

#: How long a test waits to conclude that no reply is coming.
QUIET = 0.3
#: Bound on any wait for something that should come.
WAIT = 3.0


def mbap(tid: int, unit: int, pdu_hex: str) -> bytes:
    """An MBAP frame: transaction ``tid``, protocol 0, length, ``unit``, the PDU."""
    pdu = bytes.fromhex(pdu_hex)
    return (
        tid.to_bytes(2, "big") + b"\0\0" + (len(pdu) + 1).to_bytes(2, "big") + bytes([unit]) + pdu
    )


def address(sim: Simulator[SimDevice]) -> tuple[str, int]:
    url = urlsplit(sim.port)
    assert url.hostname == "127.0.0.1"
    assert url.port is not None
    return url.hostname, url.port


class Client:
    """One TCP connection to the simulator, without the library."""

    def __init__(self, sim: Simulator[SimDevice]) -> None:
        self.sock = socket.create_connection(address(sim), timeout=WAIT)

    def close(self) -> None:
        self.sock.close()

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def recv(self, n: int, timeout: float = WAIT) -> bytes:
        """Up to ``n`` bytes: whatever came within ``timeout`` (less at an end of stream)."""
        deadline = time.monotonic() + timeout
        data = b""
        while len(data) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(n - len(data))
            except socket.timeout:
                break
            if not chunk:
                break
            data += chunk
        return data

    def transact(self, request: bytes, reply_len: int) -> bytes:
        self.send(request)
        reply = self.recv(reply_len)
        assert self.recv(1, 0.05) == b"", "more bytes than the expected reply"
        return reply

    def assert_quiet(self, timeout: float = QUIET) -> None:
        assert self.recv(1, timeout) == b""


@pytest.fixture
def tcp() -> Iterator[tuple[Simulator[SimDevice], Client]]:
    devices: dict[int, SimDevice] = {
        1: RegisterDevice({0x3006: 1450, 0x0005: 250}),
        2: RegisterDevice({0x0010: 0x2222}, identity={0: "ACME LABS", 1: "BB-42", 2: "1.07"}),
    }
    with Simulator(devices, network="tcp") as sim:
        client = Client(sim)
        try:
            yield sim, client
        finally:
            client.close()


@pytest.fixture
def rtu_tcp() -> Iterator[tuple[Simulator[SimDevice], Client]]:
    devices: dict[int, SimDevice] = {1: RegisterDevice({0x3006: 1450}), 2: RegisterDevice()}
    with Simulator(devices, network="rtu+tcp") as sim:
        client = Client(sim)
        try:
            yield sim, client
        finally:
            client.close()


# ---- plain traffic ---------------------------------------------------------------------------


def test_tcp_golden_read(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = tcp
    assert sim.port.startswith("tcp://127.0.0.1:")
    request = bytes.fromhex("00 01 00 00 00 06 01 03 30 06 00 01")
    reply = client.transact(request, 11)
    assert reply == bytes.fromhex("00 01 00 00 00 05 01 03 02 05 AA")
    assert sim.requests == [request]
    assert sim.replies == [reply]
    assert len(sim.request_times) == 1


def test_tcp_transaction_id_is_echoed(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    _, client = tcp
    for tid in (0x0000, 0xBEEF, 0xFFFF):
        reply = client.transact(mbap(tid, 1, "03 00 05 00 01"), 11)
        assert reply == mbap(tid, 1, "03 02 00 FA")


def test_tcp_pipelined_requests_get_replies_in_order(
    tcp: tuple[Simulator[SimDevice], Client],
) -> None:
    _, client = tcp
    client.send(mbap(7, 1, "03 30 06 00 01") + mbap(8, 2, "03 00 10 00 01"))
    assert client.recv(22) == mbap(7, 1, "03 02 05 AA") + mbap(8, 2, "03 02 22 22")


def test_tcp_write_reaches_the_device(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = tcp
    assert client.transact(mbap(3, 1, "06 00 07 12 34"), 12) == mbap(3, 1, "06 00 07 12 34")
    request = mbap(4, 1, "10 00 20 00 02 04 00 01 00 02")
    assert client.transact(request, 12) == mbap(4, 1, "10 00 20 00 02")
    assert sim.peek(1, 0x0007) == [0x1234]
    assert sim.peek(1, 0x0020, 2) == [1, 2]


def test_tcp_drive_speed_setpoint() -> None:
    with Simulator({1: DriveDevice("BLD2")}, network="tcp") as sim:
        client = Client(sim)
        try:
            # 0x2001 = 1500 rpm
            assert client.transact(mbap(0x11, 1, "06 20 01 05 DC"), 12) == mbap(
                0x11, 1, "06 20 01 05 DC"
            )
            assert sim.peek(1, 0x2001) == [1500]
            assert client.transact(mbap(0x12, 1, "03 20 01 00 01"), 11) == mbap(
                0x12, 1, "03 02 05 DC"
            )
            # Out of range (0..3000): the drive's own exception 3.
            assert client.transact(mbap(0x13, 1, "06 20 01 0F A1"), 9) == mbap(0x13, 1, "86 03")
            assert sim.peek(1, 0x2001) == [1500]
        finally:
            client.close()


def test_tcp_read_device_identification(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    _, client = tcp
    client.send(mbap(9, 2, "2B 0E 01 00"))
    header = client.recv(7)
    assert header[:4] == bytes.fromhex("00 09 00 00")
    assert header[6] == 2
    body = client.recv(int.from_bytes(header[4:6], "big") - 1)
    assert body[:3] == bytes.fromhex("2B 0E 01")
    assert b"ACME LABS" in body and b"BB-42" in body and b"1.07" in body


def test_tcp_device_exception_codes(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    class Failing(SimDevice):
        def read_holding(self, address: int, count: int) -> list[int]:
            raise SimException(0x21)  # a code pymodbus has no name for

    sim, client = tcp
    sim.devices[1] = Failing()
    assert client.transact(mbap(5, 1, "03 00 00 00 01"), 9) == mbap(5, 1, "83 21")
    # Unit 2 on the same server: its own reply, not the rewritten code.
    assert client.transact(mbap(6, 2, "03 00 10 00 01"), 11) == mbap(6, 2, "03 02 22 22")
    # Functions the units do not speak (0x41, a vendor's), and a bad count.
    assert client.transact(mbap(7, 2, "41 00 10 00 01"), 9) == mbap(7, 2, "C1 01")
    assert client.transact(mbap(8, 2, "03 00 10 00 00"), 9) == mbap(8, 2, "83 03")


def test_tcp_unknown_unit_gets_gateway_exception(
    tcp: tuple[Simulator[SimDevice], Client],
) -> None:
    sim, client = tcp
    assert client.transact(mbap(0x42, 9, "03 00 00 00 01"), 9) == mbap(0x42, 9, "83 0B")
    assert sim.requests == [mbap(0x42, 9, "03 00 00 00 01")]


def test_tcp_broadcast_reaches_every_unit_without_reply(
    tcp: tuple[Simulator[SimDevice], Client],
) -> None:
    sim, client = tcp
    client.send(mbap(1, 0, "06 00 30 00 63"))
    client.assert_quiet()
    assert sim.peek(1, 0x0030) == [0x63]
    assert sim.peek(2, 0x0030) == [0x63]
    assert sim.replies == []


def test_tcp_bad_mbap_header_closes_the_connection(
    tcp: tuple[Simulator[SimDevice], Client],
) -> None:
    sim, client = tcp
    client.send(bytes.fromhex("00 01 00 07 00 06 01 03 30 06 00 01"))  # protocol id 7
    assert client.recv(1) == b""  # end of stream
    again = Client(sim)
    try:
        assert again.transact(mbap(1, 1, "03 30 06 00 01"), 11) == mbap(1, 1, "03 02 05 AA")
    finally:
        again.close()


def test_rtu_tcp_golden_read(rtu_tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = rtu_tcp
    assert sim.port.startswith("rtu+tcp://127.0.0.1:")
    reply = client.transact(rtu("01 03 30 06 00 01"), 7)
    assert reply == rtu("01 03 02 05 AA")
    assert reply[-2:] == crc(reply[:-2])
    assert sim.requests == [rtu("01 03 30 06 00 01")]
    assert sim.replies == [reply]


def test_rtu_tcp_write_bad_crc_and_unknown_unit(
    rtu_tcp: tuple[Simulator[SimDevice], Client],
) -> None:
    sim, client = rtu_tcp
    assert client.transact(rtu("02 06 00 01 AB CD"), 8) == rtu("02 06 00 01 AB CD")
    assert sim.peek(2, 0x0001) == [0xABCD]
    bad = bytearray(rtu("01 03 30 06 00 01"))
    bad[-1] ^= 0xFF
    client.send(bytes(bad))
    client.assert_quiet()
    client.send(rtu("09 03 00 00 00 01"))  # a transparent converter: nobody answers
    client.assert_quiet()
    assert len(sim.requests) == 3


def test_two_clients_at_once(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, first = tcp
    second = Client(sim)
    try:
        first.send(mbap(0x0101, 1, "03 30 06 00 01"))
        second.send(mbap(0x0202, 2, "03 00 10 00 01"))
        assert second.recv(11) == mbap(0x0202, 2, "03 02 22 22")
        assert first.recv(11) == mbap(0x0101, 1, "03 02 05 AA")
        assert sim.connections == 2

        errors: list[BaseException] = []

        def hammer(client: Client, unit: int, expect: str) -> None:
            try:
                for tid in range(40):
                    reply = client.transact(mbap(tid, unit, "03 00 10 00 01"), 11)
                    assert reply == mbap(tid, unit, expect)
            except BaseException as exc:
                errors.append(exc)

        sim.devices[1].write_holding(0x0010, [0x1111])
        threads = [
            threading.Thread(target=hammer, args=(first, 1, "03 02 11 11")),
            threading.Thread(target=hammer, args=(second, 2, "03 02 22 22")),
        ]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(30)
        assert not errors
        assert len(sim.requests) == 82
    finally:
        second.close()


# ---- faults ----------------------------------------------------------------------------------


def test_reply_delay_holds_the_reply(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = tcp
    sim.reply_delay = 0.3
    start = time.monotonic()
    assert client.transact(mbap(1, 1, "03 30 06 00 01"), 11) == mbap(1, 1, "03 02 05 AA")
    elapsed = time.monotonic() - start
    assert 0.25 <= elapsed < 2.0
    sim.reply_delay = 0.0
    start = time.monotonic()
    client.transact(mbap(2, 1, "03 30 06 00 01"), 11)
    assert time.monotonic() - start < 0.25


@pytest.mark.parametrize("network", ["tcp", "rtu+tcp"])
def test_silent_unit_gets_no_reply(network: str) -> None:
    with Simulator({1: RegisterDevice({0x3006: 1450})}, network=network) as sim:
        client = Client(sim)
        try:
            request = mbap(1, 1, "06 00 01 00 05") if network == "tcp" else rtu("01 06 00 01 00 05")
            sim.set_silent(1)
            client.send(request)
            client.assert_quiet()
            assert sim.requests == [request]
            assert sim.peek(1, 0x0001) == [0]  # no action either
            sim.set_silent(1, False)
            assert client.transact(request, len(request)) == request
        finally:
            client.close()


def test_answer_exception(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = tcp
    sim.answer_exception(0x0B, n=1, unit=1)
    assert client.transact(mbap(0x77, 1, "06 00 01 00 05"), 9) == mbap(0x77, 1, "86 0B")
    assert sim.peek(1, 0x0001) == [0]  # the device did not see it
    assert client.transact(mbap(0x78, 1, "06 00 01 00 05"), 12) == mbap(0x78, 1, "06 00 01 00 05")


def test_answer_exception_rtu(rtu_tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = rtu_tcp
    sim.answer_exception(0x06, n=2)
    assert client.transact(rtu("01 03 30 06 00 01"), 5) == rtu("01 83 06")
    assert client.transact(rtu("02 03 00 00 00 01"), 5) == rtu("02 83 06")
    assert client.transact(rtu("01 03 30 06 00 01"), 7) == rtu("01 03 02 05 AA")


def test_corrupt_next(rtu_tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = rtu_tcp
    sim.corrupt_next()
    reply = client.transact(rtu("01 03 30 06 00 01"), 7)
    assert reply[:-2] == bytes.fromhex("01 03 02 05 AA")
    assert reply[-2:] != crc(reply[:-2])
    assert client.transact(rtu("01 03 30 06 00 01"), 7) == rtu("01 03 02 05 AA")


def test_rtu_tcp_random_faults(rtu_tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = rtu_tcp
    sim.faults = Faults(rate=1.0, kinds={"duplicate"}, limit=1)
    client.send(rtu("01 03 30 06 00 01"))
    assert client.recv(14) == rtu("01 03 02 05 AA") * 2
    assert sim.fault_counts["duplicate"] == 1
    assert client.transact(rtu("01 03 30 06 00 01"), 7) == rtu("01 03 02 05 AA")


@pytest.mark.parametrize("network", ["tcp", "rtu+tcp"])
def test_reset_next_cuts_the_reply_and_resets(network: str) -> None:
    with Simulator({1: RegisterDevice({0x3006: 1450})}, network=network) as sim:
        client = Client(sim)
        try:
            if network == "tcp":
                request, whole = mbap(5, 1, "03 30 06 00 01"), mbap(5, 1, "03 02 05 AA")
            else:
                request, whole = rtu("01 03 30 06 00 01"), rtu("01 03 02 05 AA")
            sim.reset_next()
            client.send(request)
            half = client.recv(len(whole) // 2)
            assert half == whole[: len(whole) // 2]
            with pytest.raises(ConnectionResetError):  # a reset, not an end of stream
                client.recv(len(whole))
            assert sim.replies == [half]
            deadline = time.monotonic() + WAIT
            while sim.connections and time.monotonic() < deadline:
                time.sleep(0.01)
            assert sim.connections == 0
        finally:
            client.close()
        again = Client(sim)  # the client reconnects: a whole reply again
        try:
            assert again.transact(request, len(whole)) == whole
            assert sim.accepted == 2
        finally:
            again.close()


def test_refuse_connections(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = tcp
    sim.refuse_connections(True)
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(address(sim), timeout=WAIT).close()
    # A connection already open stays.
    assert client.transact(mbap(1, 1, "03 30 06 00 01"), 11) == mbap(1, 1, "03 02 05 AA")
    sim.refuse_connections(False)
    again = Client(sim)
    try:
        assert again.transact(mbap(2, 1, "03 30 06 00 01"), 11) == mbap(2, 1, "03 02 05 AA")
    finally:
        again.close()


def test_refuse_before_start_and_clear_faults() -> None:
    sim = Simulator(RegisterDevice({0x3006: 1450}), network="tcp")
    sim.refuse_connections()
    with sim:
        with pytest.raises(ConnectionRefusedError):
            socket.create_connection(address(sim), timeout=WAIT).close()
        sim.clear_faults()
        client = Client(sim)
        try:
            assert client.transact(mbap(1, 1, "03 30 06 00 01"), 11) == mbap(1, 1, "03 02 05 AA")
        finally:
            client.close()


@pytest.mark.parametrize("reset", [False, True])
def test_drop_connections(tcp: tuple[Simulator[SimDevice], Client], reset: bool) -> None:
    sim, client = tcp
    client.transact(mbap(1, 1, "03 30 06 00 01"), 11)
    sim.drop_connections(reset=reset)
    assert sim.connections == 0
    if reset:
        with pytest.raises(ConnectionResetError):
            client.recv(1)
    else:
        assert client.recv(1) == b""
    again = Client(sim)
    try:
        assert again.transact(mbap(2, 1, "03 30 06 00 01"), 11) == mbap(2, 1, "03 02 05 AA")
        assert sim.accepted == 2
    finally:
        again.close()


def test_inject_raw_goes_to_the_client(tcp: tuple[Simulator[SimDevice], Client]) -> None:
    sim, client = tcp
    client.transact(mbap(1, 1, "03 30 06 00 01"), 11)  # connected and served
    sim.inject_raw(b"\x55\xaa")
    assert client.recv(2) == b"\x55\xaa"
    assert len(sim.replies) == 1


# ---- what a network simulator refuses, and its lifecycle ---------------------------------------


def test_refusals() -> None:
    device = RegisterDevice()
    with pytest.raises(ValueError, match="network"):
        Simulator(device, network="udp")
    with pytest.raises(ValueError, match="echo"):
        Simulator(device, network="rtu+tcp", echo=True)
    with pytest.raises(ValueError, match="faults"):
        Simulator(device, network="tcp", faults=Faults())
    sim = Simulator(device, network="tcp")
    with pytest.raises(ValueError, match="CRC"):
        sim.corrupt_next()
    with pytest.raises(ValueError, match="collide"):
        sim.collide_next()
    serial = Simulator(device)
    for call in (serial.reset_next, serial.refuse_connections, serial.drop_connections):
        with pytest.raises(ValueError, match="network"):
            call()


def test_stop_releases_everything() -> None:
    before = {t.name for t in threading.enumerate()}
    sim = Simulator(RegisterDevice({0x3006: 1450}), network="tcp")
    for _ in range(2):  # restartable
        sim.start()
        where = address(sim)
        client = Client(sim)
        try:
            client.transact(mbap(1, 1, "03 30 06 00 01"), 11)
            sim.stop()
            assert client.recv(1) == b""  # its connection closed
        finally:
            client.close()
        with pytest.raises(ConnectionRefusedError):
            socket.create_connection(where, timeout=WAIT).close()
    assert not sim.running
    leftover = {t.name for t in threading.enumerate()} - before
    assert not {name for name in leftover if name.startswith("benchbus-sim")}
