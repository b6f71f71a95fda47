"""The Bus's functions beyond holding registers: coils, discrete inputs, input registers,
0x16, 0x17, 0x07, 0x08, 0x11, raw requests and coil broadcasts.

Against a third-party server (pymodbus's own, over ``tcp://``, ``rtu+tcp://`` and Modbus
ASCII over TCP), and on a
pseudo-terminal against scripted replies where the test needs a reply the peer does not
give (bursts with a gap, a wrong echo, silence).
"""

from __future__ import annotations

import logging
import os
import socket
import struct
import threading
import time
from collections.abc import Iterator

import pytest
from pymodbus_peer import COILS, DISCRETE, INPUT, pymodbus_server

import benchbus as bb
from conftest import ScriptedSlave, read_up_to, rtu


@pytest.fixture(params=["tcp", "rtu+tcp", "ascii"])
def peer(request: pytest.FixtureRequest) -> Iterator[bb.Bus]:
    """A Bus on a pymodbus server, over Modbus TCP, RTU over TCP and Modbus ASCII over TCP."""
    ascii = request.param == "ascii"
    with (
        pymodbus_server(rtu=request.param != "tcp", ascii=ascii) as url,
        bb.Bus(url, timeout=1.0, framing="ascii" if ascii else "rtu") as bus,
    ):
        yield bus


def bits(values: list[int]) -> list[bool]:
    return [bool(v) for v in values]


# ---- against pymodbus ----


def test_every_table_reads_at_the_specifications_limits(peer: bb.Bus) -> None:
    assert peer.read_coils(1, 0, 10) == bits(COILS[:10])
    assert peer.read_coils(1, 0, 2000) == bits(COILS)
    assert peer.read_discrete_inputs(1, 3, 5) == bits(DISCRETE[3:8])
    assert peer.read_discrete_inputs(1, 0, 2000) == bits(DISCRETE)
    assert peer.read_input_registers(1, 0, 125) == INPUT[:125]
    assert peer.read_input_registers(1, 7, 1) == [1007]
    # Holding registers and input registers are two tables.
    assert peer.read_holding_registers(1, 7, 1) == [7]
    assert peer.stats.transactions == 7


def test_writes_change_what_is_read_back(peer: bb.Bus) -> None:
    peer.write_coil(1, 20, True)
    assert peer.read_coils(1, 19, 3) == [False, True, False]
    peer.write_coil(1, 20, False)
    assert peer.read_coils(1, 20, 1) == [False]
    pattern = [True, False, True, True, False, False, True, True, True, False, True]
    peer.write_coils(1, 30, pattern)
    assert peer.read_coils(1, 30, 11) == pattern
    # The specification's mask write (6.16): 0x12 AND 0xF2 OR (0x25 AND NOT 0xF2) = 0x17.
    peer.write_register(1, 50, 0x12)
    peer.mask_write_register(1, 50, 0xF2, 0x25)
    assert peer.read_holding_registers(1, 50, 1) == [0x17]
    # 0x17 writes first, then reads: the values written come back.
    assert peer.read_write_registers(1, 60, 4, 61, [7, 8, 9]) == [60, 7, 8, 9]
    assert peer.read_holding_registers(1, 61, 3) == [7, 8, 9]


def test_serial_line_functions_reach_the_unit_over_the_network(peer: bb.Bus) -> None:
    # pymodbus answers 0x07, 0x08/00 and 0x11 itself (its server id "Pymodbus", run
    # indicator ON).
    assert peer.read_exception_status(1) == 0
    assert peer.diagnostics(1, 0, b"\xa5\x37") == b"\xa5\x37"
    assert peer.diagnostics(1, 0) == b"\x00\x00"
    assert peer.report_server_id(1) == b"Pymodbus\xff"


def test_a_raw_request_by_length_and_by_silence(peer: bb.Bus) -> None:
    # A 0x03 of two registers as a raw PDU: byte count 4, then the registers 0 and 1.
    expected = bytes([4, 0, 0, 0, 1])
    assert peer.request(1, 0x03, bytes([0, 0, 0, 2]), reply_length=5) == expected
    assert peer.request(1, 0x03, bytearray([0, 0, 0, 2])) == expected
    # Registers the peer does not have: its exception reply, known at its 5 bytes.
    with pytest.raises(bb.ModbusException) as e:
        peer.request(1, 0x03, bytes([0x0F, 0xFF, 0, 2]))
    assert (e.value.unit, e.value.function, e.value.code) == (1, 0x03, 2)


def test_an_exception_reply_carries_unit_function_and_frame(peer: bb.Bus) -> None:
    # The peer has 2000 coils: past them, illegal data address.
    with pytest.raises(bb.ModbusException) as e:
        peer.read_coils(1, 1990, 20)
    assert (e.value.unit, e.value.function, e.value.code) == (1, 0x01, 2)
    assert e.value.frame is not None
    if peer.framing == "ascii":  # the frame's characters, in hex
        assert bytes.fromhex(e.value.frame) == b":0181027C\r\n"
    else:
        assert "81 02" in e.value.frame
    assert peer.stats.exceptions == 1


def test_threads_share_the_bus_for_every_table(peer: bb.Bus) -> None:
    errors: list[BaseException] = []

    def work(i: int) -> None:
        try:
            for _ in range(10):
                assert peer.read_coils(1, i, 8) == bits(COILS[i : i + 8])
                assert peer.read_input_registers(1, i, 2) == INPUT[i : i + 2]
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert errors == []
    assert peer.stats.transactions == 80


def test_the_wire_log_shows_a_coil_read(peer: bb.Bus, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.DEBUG, logger="benchbus.wire"):
        bb.refresh_logging()
        peer.read_coils(1, 0, 3)
    sent = [r.getMessage() for r in caplog.records if r.getMessage().startswith("->")]
    # Over tcp:// behind an MBAP header, over rtu+tcp:// before the CRC; in ASCII as text.
    if peer.framing == "ascii":
        assert sent == ["-> :010100000003FB\\r\\n"], sent
        received = [r.getMessage() for r in caplog.records if r.getMessage().startswith("<-")]
        assert received == ["<- :01010105F8\\r\\n"], received
    else:
        assert sent and "01 01 00 00 00 03" in sent[-1], sent


# ---- on a pseudo-terminal, scripted ----


def serve(slave: ScriptedSlave, request_len: int, *bursts: bytes, gap: float = 0.0) -> None:
    """In the background: read a request of ``request_len`` bytes, then write ``bursts``
    with ``gap`` seconds between them."""

    def run() -> None:
        slave.received.append(read_up_to(slave.master, request_len, 2.0))
        for i, burst in enumerate(bursts):
            if i:
                time.sleep(gap)
            os.write(slave.master, burst)

    slave._thread = threading.Thread(target=run, daemon=True)
    slave._thread.start()


def test_silence_reads_a_reply_delivered_in_bursts_whole(slave: ScriptedSlave) -> None:
    reply = rtu("01 41 0A 0B 0C 0D 0E 0F")
    with bb.Bus(slave.port, timeout=0.5, retries=0, silence=0.1) as bus:
        assert bus.silence == 0.1
        assert repr(bus).endswith(", retries=0, silence=0.1)")
        serve(slave, 4, reply[:4], reply[4:], gap=0.03)
        start = time.monotonic()
        assert bus.request(1, 0x41, b"") == bytes.fromhex("0A 0B 0C 0D 0E 0F")
        # The reply's end was known only after the quiet gap.
        assert time.monotonic() - start >= 0.1
        slave.join()
    assert slave.received == [rtu("01 41")]


def test_without_silence_a_reply_in_bursts_is_cut_at_the_gap(slave: ScriptedSlave) -> None:
    reply = rtu("01 41 0A 0B 0C 0D 0E 0F")
    with bb.Bus(slave.port, timeout=0.5, retries=0) as bus:
        assert bus.silence == 0.0
        assert "silence" not in repr(bus)
        serve(slave, 4, reply[:4], reply[4:], gap=0.05)
        with pytest.raises(bb.FrameError) as e:
            bus.request(1, 0x41, b"")
        assert e.value.unit == 1 and e.value.function == 0x41
        assert e.value.frame == reply[:4].hex(" ").upper()
        slave.join()


def test_a_reply_length_does_not_wait_for_silence(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.5, retries=0, silence=0.5) as bus:
        slave.expect(4, rtu("01 41 0A 0B"))
        start = time.monotonic()
        assert bus.request(1, 0x41, b"", reply_length=2) == b"\x0a\x0b"
        assert time.monotonic() - start < 0.3
        slave.join()


def test_force_listen_only_is_sent_once_and_not_awaited(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=2) as bus:
        slave.expect(8, None)
        start = time.monotonic()
        assert bus.diagnostics(1, 4) == b""
        assert time.monotonic() - start < 0.2
        slave.join()
        # Exactly one frame went out: nothing more is waiting on the line.
        assert read_up_to(slave.master, 64, 0.3) == b""
        assert (bus.stats.retries, bus.stats.timeouts, bus.stats.transactions) == (0, 0, 1)
    assert slave.received == [rtu("01 08 00 04 00 00")]


def test_a_coil_echo_that_differs_is_a_frame_error(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=0) as bus:
        slave.expect(8, rtu("01 05 00 AC 00 00"))
        with pytest.raises(bb.FrameError, match="not echoed") as e:
            bus.write_coil(1, 172, True)
        assert (e.value.unit, e.value.function) == (1, 5)
        slave.join()
    assert slave.received == [rtu("01 05 00 AC FF 00")]


def test_return_query_data_that_differs_is_a_frame_error(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=0) as bus:
        slave.expect(8, rtu("01 08 00 00 A5 00"))
        with pytest.raises(bb.FrameError, match="not echoed"):
            bus.diagnostics(1, 0, b"\xa5\x37")
        slave.join()


def test_a_raw_exception_reply_is_known_at_five_bytes(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=0, silence=1.0) as bus:
        slave.expect(5, rtu("01 C1 01"))
        start = time.monotonic()
        with pytest.raises(bb.ModbusException) as e:
            bus.request(1, 0x41, b"\x01")
        # Not read by silence: its length is known.
        assert time.monotonic() - start < 0.5
        assert (e.value.unit, e.value.function, e.value.code) == (1, 0x41, 1)
        slave.join()


def test_report_server_id_returns_the_data_field_as_sent(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=0) as bus:
        slave.expect(4, rtu("01 11 05 2A FF 41 42 43"))
        assert bus.report_server_id(1) == b"\x2a\xffABC"
        slave.join()


def test_a_corrupt_coil_reply_is_retried(slave: ScriptedSlave) -> None:
    good = rtu("01 01 01 05")
    bad = good[:-1] + bytes([good[-1] ^ 1])
    with bb.Bus(slave.port, timeout=0.3, retries=1) as bus:

        def run() -> None:
            for reply in (bad, good):
                slave.received.append(read_up_to(slave.master, 8, 2.0))
                os.write(slave.master, reply)

        slave._thread = threading.Thread(target=run, daemon=True)
        slave._thread.start()
        assert bus.read_coils(1, 0, 3) == [True, False, True]
        slave.join()
        assert (bus.stats.crc_errors, bus.stats.retries) == (1, 1)
    assert slave.received == [rtu("01 01 00 00 00 03")] * 2


def test_coil_broadcasts_go_to_unit_zero(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, turnaround=0.01) as bus:
        slave.expect(8, None)
        bus.broadcast_write_coil(172, True)
        slave.join()
        slave.expect(11, None)
        bus.broadcast_write_coils(19, [True, False, True, True, False, False, True, True, True])
        slave.join()
        assert bus.stats.broadcasts == 2
    assert slave.received == [rtu("00 05 00 AC FF 00"), rtu("00 0F 00 13 00 09 02 CD 01")]


# ---- a Modbus TCP gateway that does not forward the serial line functions ----


@pytest.fixture
def refusing_gateway() -> Iterator[str]:
    """A Modbus TCP endpoint that answers every request with exception 1 (illegal
    function), as a gateway does for functions it does not forward."""
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]

    def run() -> None:
        conn, _ = server.accept()
        with conn:
            while True:
                header = conn.recv(7)
                if len(header) < 7:
                    return
                tid, _, length, unit = struct.unpack(">HHHB", header)
                pdu = conn.recv(length - 1)
                conn.sendall(struct.pack(">HHHBBB", tid, 0, 3, unit, pdu[0] | 0x80, 1))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{port}"
    server.close()


def test_a_gateway_that_does_not_forward_answers_exception_1(refusing_gateway: str) -> None:
    with bb.Bus(refusing_gateway, timeout=0.5, retries=0) as bus:
        for call, function in (
            (lambda: bus.read_exception_status(1), 0x07),
            (lambda: bus.diagnostics(1, 0), 0x08),
            (lambda: bus.report_server_id(1), 0x11),
            (lambda: bus.request(1, 0x0B, b""), 0x0B),
            (lambda: bus.request(1, 0x0C, b""), 0x0C),
        ):
            with pytest.raises(bb.ModbusException) as e:
                call()
            assert (e.value.function, e.value.code) == (function, 1)
        assert bus.stats.exceptions == 5


def test_the_gil_is_released_while_a_new_function_waits(slave: ScriptedSlave) -> None:
    """A Python thread runs on while read_coils waits for a silent unit and request() for
    the line's silence."""
    ticks = 0
    stop = threading.Event()

    def count() -> None:
        nonlocal ticks
        while not stop.is_set():
            ticks += 1
            time.sleep(0.001)

    counter = threading.Thread(target=count)
    with bb.Bus(slave.port, timeout=0.3, retries=0, silence=0.2) as bus:
        counter.start()
        try:
            slave.expect(8, None)
            with pytest.raises(bb.ResponseTimeout):
                bus.read_coils(1, 0, 8)
            slave.join()
            during_read = ticks
            # Another unit: the silent one's late reply is not waited for first.
            slave.expect(4, rtu("02 41 01"))
            assert bus.request(2, 0x41, b"") == b"\x01"
            slave.join()
        finally:
            stop.set()
            counter.join()
    # About 300 and 200 ticks of 1 ms: the GIL held would give none.
    assert during_read > 50
    assert ticks - during_read > 30


# ---- comm event counter and log, file records, FIFO queue (0x0B, 0x0C, 0x14, 0x15, 0x18) ----


@pytest.mark.parametrize("network", [None, "tcp", "rtu+tcp"])
def test_the_counters_files_and_fifo_against_the_simulator(network: str | None) -> None:
    from benchbus.sim import RegisterDevice, Simulator

    device = RegisterDevice({0x04DE: 2, 0x04DF: 0x01B8, 0x04E0: 0x1284})
    device.comm_event_count, device.comm_message_count = 264, 289
    device.comm_events = b"\x20\x00"
    with Simulator(device, network=network) as sim, bb.Bus(sim.port, timeout=1.0) as bus:
        counter = bus.get_comm_event_counter(1)
        assert counter == bb.CommEventCounter(status=0, event_count=264)
        device.comm_busy = True
        assert bus.get_comm_event_counter(1).status == 0xFFFF
        # The unit counted the two 0x0B requests as messages, not events, and logged each.
        log = bus.get_comm_event_log(1)
        assert log == bb.CommEventLog(0xFFFF, 264, 291, bytes.fromhex("40 80 40 80 20 00"))
        assert isinstance(log.events, bytes)
        bus.write_file_record(1, [(4, 7, [0x06AF, 0x04BE, 0x100D]), (3, 0x270F, [9])])
        assert device.files[4][7:10] == [0x06AF, 0x04BE, 0x100D]
        assert bus.read_file_record(1, [(4, 6, 5), (3, 0x270F, 1)]) == [
            [0, 0x06AF, 0x04BE, 0x100D, 0],
            [9],
        ]
        assert bus.read_fifo_queue(1, 0x04DE) == [0x01B8, 0x1284]
        device.registers[0x100] = 31
        device.registers[0x101 : 0x101 + 31] = range(31)
        assert bus.read_fifo_queue(1, 0x100) == list(range(31))
        # Over 31: the unit's exception 3, as the specification has it.
        device.registers[0x100] = 32
        with pytest.raises(bb.ModbusException) as e:
            bus.read_fifo_queue(1, 0x100)
        assert (e.value.function, e.value.code) == (0x18, 3)
        # A reference past the last record: the unit's exception 2.
        with pytest.raises(bb.ModbusException) as e:
            bus.request(1, 0x14, bytes.fromhex("07 06 00 04 27 10 00 01"))
        assert e.value.code == 2


def test_a_fifo_reply_of_more_than_31_values_is_a_frame_error(slave: ScriptedSlave) -> None:
    values = " 00 2A" * 32
    with bb.Bus(slave.port, timeout=0.3, retries=0) as bus:
        slave.expect(6, rtu("01 18 00 42 00 20" + values))
        with pytest.raises(bb.FrameError, match="count 32"):
            bus.read_fifo_queue(1, 0x04DE)
        slave.join()
    assert slave.received[0] == rtu("01 18 04 DE")


def test_a_write_file_record_reply_must_echo_the_request(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=0) as bus:
        slave.expect(14, rtu("01 15 09 06 00 04 00 07 00 01 06 AE"))
        with pytest.raises(bb.FrameError, match="not echoed"):
            bus.write_file_record(1, [(4, 7, [0x06AF])])
        slave.join()


def test_a_read_file_record_reply_must_answer_every_group(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.3, retries=0) as bus:
        # Asked 2 registers of each of two files; the reply's byte count is for one group.
        slave.expect(19, rtu("01 14 06 05 06 0D FE 00 20"))
        with pytest.raises(bb.FrameError):
            bus.read_file_record(1, [(4, 1, 2), (3, 9, 2)])
        slave.join()


def test_file_record_limits_send_nothing(slave: ScriptedSlave) -> None:
    with bb.Bus(slave.port, timeout=0.2, retries=0) as bus:
        for bad in (
            lambda: bus.read_file_record(1, []),
            lambda: bus.read_file_record(1, [(0, 0, 1)]),
            lambda: bus.read_file_record(1, [(1, 0x2710, 1)]),
            lambda: bus.read_file_record(1, [(1, 0, 1)] * 36),
            lambda: bus.read_file_record(1, [(1, 0, 125)]),
            lambda: bus.write_file_record(1, [(1, 0, [0] * 123)]),
            lambda: bus.write_file_record(1, [(0xFFFF, 0x270F, [1, 2])]),
            lambda: bus.read_fifo_queue(1, 0x10000),
        ):
            with pytest.raises(ValueError):
                bad()
        # At the limits: sent (and unanswered here).
        slave.expect(250, None)
        with pytest.raises(bb.ResponseTimeout):
            bus.read_file_record(1, [(1, 0, 1)] * 35)
        assert bus.stats.timeouts == 1
    slave.join()
    # Only the request at the limits went out: 1 + 1 + 1 + 35 * 7 + 2 bytes.
    assert [len(f) for f in slave.received] == [250]
