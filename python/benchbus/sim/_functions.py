"""The public function codes a simulated unit answers besides 0x03, 0x06, 0x10 and 0x2B.

Written from the Modbus Application Protocol Specification V1.1b3 (section 6 and its
exception state diagrams) alone: coils (0x01, 0x05, 0x0F), discrete inputs (0x02), input
registers (0x04), Mask Write Register (0x16), Read/Write Multiple registers (0x17), and the
serial line's Read Exception Status (0x07), Diagnostics (0x08: return query data 0x0000 and
restart communications 0x0001; the listen only mode, 0x0004, is the router's, which keeps
the requests from the unit), Get Comm Event Counter (0x0B), Get Comm Event Log (0x0C),
Report Server ID (0x11), Read / Write File Record (0x14, 0x15) and Read FIFO Queue (0x18).
:func:`serve` turns a request PDU's data into the reply PDU's data by calling the unit's
:class:`~benchbus.sim.SimDevice` handlers, and raises :class:`~benchbus.sim.SimException`
for an exception reply. The checks come in the spec's order: the quantity (and the byte
count, and a coil's value) first, exception 3, and the device's own limit on it
(``too_many_code``); then the addresses, exception 2; then the device's own refusals. Pure
Python, no pymodbus."""

from __future__ import annotations

from collections.abc import Callable

from benchbus.sim._device import SimDevice, SimException

__all__ = [
    "DIAGNOSTICS",
    "FORCE_LISTEN_ONLY",
    "FUNCTIONS",
    "RESTART_COMMUNICATIONS",
    "pack_bits",
    "serve",
    "took",
]

#: The spec's quantity limits: bits a read (0x01, 0x02) and a write (0x0F) may carry,
#: registers a read (0x04, 0x17) and a 0x17 write may carry.
READ_BITS, WRITE_BITS, READ_REGISTERS, READ_WRITE_WRITE = 2000, 1968, 125, 121
#: A coil's ON and OFF in a 0x05 request.
COIL_ON, COIL_OFF = 0xFF00, 0x0000
#: Diagnostics, and its sub-functions 0x0000 return query data, 0x0001 restart
#: communications and 0x0004 force listen only mode (the listen only mode is the router's,
#: ``benchbus.sim._router``: it keeps the requests from the unit).
DIAGNOSTICS = 0x08
#: Get Comm Event Counter (6.9): the one request that succeeds without counting an event.
GET_COMM_EVENT_COUNTER = 0x0B
RETURN_QUERY_DATA, RESTART_COMMUNICATIONS, FORCE_LISTEN_ONLY = 0x0000, 0x0001, 0x0004
#: Most bytes a Report Server ID reply's data may take (a PDU is at most 253 bytes).
MAX_SERVER_ID_DATA = 251
#: The reference type of a file record group (6.14, 6.15), the highest record number, and
#: the request byte counts allowed: 0x07..0xF5 a read, 0x09..0xFB a write.
FILE_REFERENCE, LAST_RECORD = 6, 0x270F
READ_FILE_BYTES, WRITE_FILE_BYTES = range(0x07, 0xF6), range(0x09, 0xFC)
#: Most values a FIFO queue holds (6.18), most events a comm event log carries (6.10).
MAX_FIFO, MAX_EVENTS = 31, 64
#: The status word of 0x0B and 0x0C: a program command still being processed, or not.
BUSY, READY = 0xFFFF, 0x0000
#: The comm event log's bytes (6.10): a receive event (bit 7), with bit 6 for a broadcast
#: and bit 5 for the listen only mode; a send event (bit 6), with bit 0 for a read
#: exception sent (codes 1..3), bit 1 a server abort (4), bit 2 a busy exception (5, 6),
#: bit 3 a program NAK (7) and bit 5 the listen only mode; a communications restart; the
#: listen only mode entered (04 by the event bytes' definitions; the spec's example of 6.10
#: calls its 20 hex that, which is the listen only flag of a send event).
RECEIVED, RECEIVED_BROADCAST, SENT, IN_LISTEN_ONLY = 0x80, 0x40, 0x40, 0x20
RESTARTED, ENTERED_LISTEN_ONLY = 0x00, 0x04
_SENT_EXCEPTION = {1: 0x01, 2: 0x01, 3: 0x01, 4: 0x02, 5: 0x04, 6: 0x04, 7: 0x08}

_SPACE = 0x10000
_ILLEGAL_FUNCTION = SimException.ILLEGAL_FUNCTION
_ILLEGAL_ADDRESS = SimException.ILLEGAL_DATA_ADDRESS
_ILLEGAL_VALUE = SimException.ILLEGAL_DATA_VALUE


def pack_bits(bits: list[bool]) -> bytes:
    """``bits`` packed eight a byte, the first in the low bit of the first byte, the last
    byte padded with zeros (the spec's coil and input status bytes)."""
    out = bytearray((len(bits) + 7) // 8)
    for i, bit in enumerate(bits):
        if bit:
            out[i // 8] |= 1 << (i % 8)
    return bytes(out)


def _unpack_bits(data: bytes, count: int) -> list[bool]:
    return [bool(data[i // 8] >> (i % 8) & 1) for i in range(count)]


def _word(data: bytes, at: int) -> int:
    return int.from_bytes(data[at : at + 2], "big")


def _need(condition: bool, code: int) -> None:
    if not condition:
        raise SimException(code)


def _quantity(quantity: int, spec_limit: int, device_limit: int, too_many_code: int) -> None:
    """The spec's range first (exception 3), then the device's own limit."""
    _need(1 <= quantity <= spec_limit, _ILLEGAL_VALUE)
    _need(quantity <= device_limit, too_many_code)


def _span(address: int, quantity: int) -> None:
    """Exception 2 for a block that runs past address 0xFFFF."""
    _need(address + quantity <= _SPACE, _ILLEGAL_ADDRESS)


def _checked(name: str, values: object, count: int, bits: bool) -> list[int]:
    """A handler's result, checked: ``count`` bits (bools, or 0 and 1) or words."""
    top = 1 if bits else 0xFFFF
    if not (
        isinstance(values, list)
        and len(values) == count
        and all(isinstance(v, int) and 0 <= v <= top for v in values)
    ):
        kind = "bools" if bits else "ints 0..0xFFFF"
        raise ValueError(f"{name} returned {values!r}: expected {count} {kind}")
    return [int(v) for v in values]


def _read_bits(
    device: SimDevice, data: bytes, read: Callable[[int, int], list[bool]], name: str
) -> bytes:
    _need(len(data) == 4, _ILLEGAL_VALUE)
    address, count = _word(data, 0), _word(data, 2)
    _quantity(count, READ_BITS, device.max_read_bits, device.too_many_code)
    _span(address, count)
    bits = _checked(f"{type(device).__name__}.{name}", read(address, count), count, bits=True)
    packed = pack_bits([bool(b) for b in bits])
    return bytes([len(packed)]) + packed


def _words(values: list[int]) -> bytes:
    return b"".join(v.to_bytes(2, "big") for v in values)


def _read_holding(device: SimDevice, address: int, count: int) -> bytes:
    values = device.read_holding(address, count)
    name = f"{type(device).__name__}.read_holding"
    return _words(_checked(name, values, count, bits=False))


def _read_coils(device: SimDevice, data: bytes) -> bytes:
    return _read_bits(device, data, device.read_coils, "read_coils")


def _read_discrete_inputs(device: SimDevice, data: bytes) -> bytes:
    return _read_bits(device, data, device.read_discrete_inputs, "read_discrete_inputs")


def _read_input_registers(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) == 4, _ILLEGAL_VALUE)
    address, count = _word(data, 0), _word(data, 2)
    _quantity(count, READ_REGISTERS, device.max_read, device.too_many_code)
    _span(address, count)
    values = device.read_input_registers(address, count)
    name = f"{type(device).__name__}.read_input_registers"
    return bytes([2 * count]) + _words(_checked(name, values, count, bits=False))


def _write_coil(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) == 4 and _word(data, 2) in (COIL_ON, COIL_OFF), _ILLEGAL_VALUE)
    device.write_coils(_word(data, 0), [_word(data, 2) == COIL_ON])
    return data


def _write_coils(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) >= 5, _ILLEGAL_VALUE)
    address, count, byte_count = _word(data, 0), _word(data, 2), data[4]
    _need(1 <= count <= WRITE_BITS, _ILLEGAL_VALUE)
    _need(byte_count == (count + 7) // 8 == len(data) - 5, _ILLEGAL_VALUE)
    _need(count <= device.max_write_bits, device.too_many_code)
    _span(address, count)
    device.write_coils(address, _unpack_bits(data[5:], count))
    return data[:4]


def _mask_write_register(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) == 6, _ILLEGAL_VALUE)
    address, and_mask, or_mask = _word(data, 0), _word(data, 2), _word(data, 4)
    (current,) = _checked(
        f"{type(device).__name__}.read_holding", device.read_holding(address, 1), 1, bits=False
    )
    device.write_holding(address, [(current & and_mask) | (or_mask & ~and_mask & 0xFFFF)])
    return data


def _read_write_registers(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) >= 9, _ILLEGAL_VALUE)
    read_address, read_count = _word(data, 0), _word(data, 2)
    write_address, write_count, byte_count = _word(data, 4), _word(data, 6), data[8]
    _need(1 <= read_count <= READ_REGISTERS, _ILLEGAL_VALUE)
    _need(1 <= write_count <= READ_WRITE_WRITE, _ILLEGAL_VALUE)
    _need(byte_count == 2 * write_count == len(data) - 9, _ILLEGAL_VALUE)
    _need(read_count <= device.max_read and write_count <= device.max_write, device.too_many_code)
    _span(read_address, read_count)
    _span(write_address, write_count)
    values = [_word(data, 9 + 2 * i) for i in range(write_count)]
    device.write_holding(write_address, values)  # the spec: the write before the read
    return bytes([2 * read_count]) + _read_holding(device, read_address, read_count)


def _read_exception_status(device: SimDevice, data: bytes) -> bytes:
    _need(not data, _ILLEGAL_VALUE)
    status = device.exception_status
    if isinstance(status, bool) or not isinstance(status, int) or not 0 <= status <= 0xFF:
        raise ValueError(f"{type(device).__name__}.exception_status is {status!r}: not 0..255")
    return bytes([status])


def _diagnostics(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) >= 2, _ILLEGAL_VALUE)
    sub_function = _word(data, 0)
    _need(sub_function in (RETURN_QUERY_DATA, RESTART_COMMUNICATIONS), _ILLEGAL_FUNCTION)
    if sub_function == RESTART_COMMUNICATIONS:
        # Out of the listen only mode (the router's business): the echo, then a restart,
        # which clears the counters (and with 0xFF00 the event log: see took()).
        _need(len(data) == 4 and _word(data, 2) in (0x0000, 0xFF00), _ILLEGAL_VALUE)
    return data  # the query data, echoed


def _report_server_id(device: SimDevice, data: bytes) -> bytes:
    _need(not data, _ILLEGAL_VALUE)
    server_id, extra = device.server_id, device.additional_data
    if not isinstance(server_id, bytes) or not server_id or not isinstance(extra, bytes):
        raise ValueError(
            f"{type(device).__name__}: server_id {server_id!r} must be bytes (at least one)"
            f" and additional_data {extra!r} bytes"
        )
    field = server_id + (b"\xff" if device.run_indicator else b"\x00") + extra
    if len(field) > MAX_SERVER_ID_DATA:
        raise ValueError(
            f"{type(device).__name__}: a Report Server ID reply carries at most"
            f" {MAX_SERVER_ID_DATA} bytes, not {len(field)}"
        )
    return bytes([len(field)]) + field


def _counter(device: SimDevice, name: str) -> int:
    value = getattr(device, name)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
        raise ValueError(f"{type(device).__name__}.{name} is {value!r}: not 0..0xFFFF")
    return value


def _status(device: SimDevice) -> bytes:
    return (BUSY if device.comm_busy else READY).to_bytes(2, "big")


def _get_comm_event_counter(device: SimDevice, data: bytes) -> bytes:
    _need(not data, _ILLEGAL_VALUE)
    return _status(device) + _counter(device, "comm_event_count").to_bytes(2, "big")


def _get_comm_event_log(device: SimDevice, data: bytes) -> bytes:
    _need(not data, _ILLEGAL_VALUE)
    events = device.comm_events
    if not isinstance(events, bytes) or len(events) > MAX_EVENTS:
        raise ValueError(
            f"{type(device).__name__}.comm_events is {events!r}: at most {MAX_EVENTS} bytes"
        )
    counters = _words(
        [_counter(device, "comm_event_count"), _counter(device, "comm_message_count")]
    )
    field = _status(device) + counters + events
    return bytes([len(field)]) + field


def _file_groups(data: bytes, sizes: range, values: bool) -> list[tuple[int, int, list[int]]]:
    """The groups of a 0x14 (``values`` False: their lengths as ``[0] * length``) or 0x15
    request: the byte count first (exception 3), then each group's reference type, file
    and records (exception 2)."""
    _need(len(data) >= 1 and data[0] in sizes and data[0] == len(data) - 1, _ILLEGAL_VALUE)
    groups, at = [], 1
    while at < len(data):
        _need(len(data) - at >= 7, _ILLEGAL_VALUE)
        reference, file, record, length = (
            data[at],
            _word(data, at + 1),
            _word(data, at + 3),
            _word(data, at + 5),
        )
        at += 7
        words = []
        if values:
            _need(len(data) - at >= 2 * length, _ILLEGAL_VALUE)
            words = [_word(data, at + 2 * i) for i in range(length)]
            at += 2 * length
        else:
            words = [0] * length
        _need(reference == FILE_REFERENCE and file >= 1, _ILLEGAL_ADDRESS)
        _need(length >= 1 and record + length - 1 <= LAST_RECORD, _ILLEGAL_ADDRESS)
        groups.append((file, record, words))
    return groups


def _read_file_record(device: SimDevice, data: bytes) -> bytes:
    groups = _file_groups(data, READ_FILE_BYTES, values=False)
    # function, byte count, then a length, a reference type and the registers a group.
    _need(2 + sum(2 + 2 * len(g[2]) for g in groups) <= 253, _ILLEGAL_VALUE)
    out = bytearray()
    for file, record, words in groups:
        name = f"{type(device).__name__}.read_file_record"
        got = _checked(name, device.read_file_record(file, record, len(words)), len(words), False)
        out += bytes([1 + 2 * len(got), FILE_REFERENCE]) + _words(got)
    return bytes([len(out)]) + bytes(out)


def _write_file_record(device: SimDevice, data: bytes) -> bytes:
    for file, record, words in _file_groups(data, WRITE_FILE_BYTES, values=True):
        device.write_file_record(file, record, words)
    return data  # the echo


def _read_fifo_queue(device: SimDevice, data: bytes) -> bytes:
    _need(len(data) == 2, _ILLEGAL_VALUE)
    values = device.read_fifo_queue(_word(data, 0))
    name = f"{type(device).__name__}.read_fifo_queue"
    count = len(values) if isinstance(values, list) else 0
    _need(count <= MAX_FIFO, _ILLEGAL_VALUE)
    values = _checked(name, values, count, bits=False)
    return (2 + 2 * count).to_bytes(2, "big") + count.to_bytes(2, "big") + _words(values)


_HANDLERS: dict[int, Callable[[SimDevice, bytes], bytes]] = {
    0x01: _read_coils,
    0x02: _read_discrete_inputs,
    0x04: _read_input_registers,
    0x05: _write_coil,
    0x07: _read_exception_status,
    DIAGNOSTICS: _diagnostics,
    GET_COMM_EVENT_COUNTER: _get_comm_event_counter,
    0x0C: _get_comm_event_log,
    0x0F: _write_coils,
    0x11: _report_server_id,
    0x14: _read_file_record,
    0x15: _write_file_record,
    0x16: _mask_write_register,
    0x17: _read_write_registers,
    0x18: _read_fifo_queue,
}


#: The functions :func:`serve` answers: the standard ones beyond the basic ones.
FUNCTIONS = frozenset(_HANDLERS)


def serve(device: SimDevice, function: int, data: bytes) -> bytes:
    """The reply PDU's data (after the function code) to request ``function`` with ``data``.

    ``function`` is one of :data:`FUNCTIONS` (another raises :class:`SimException` 1).
    Whether the unit serves the function at all (:attr:`SimDevice.functions`) is the
    caller's question. Raises :class:`SimException` for an exception reply (the device's
    own, or the spec's for a bad request), and ValueError for a handler that returned
    something a reply cannot carry.
    """
    handler = _HANDLERS.get(function)
    if handler is None:
        raise SimException(_ILLEGAL_FUNCTION)
    return handler(device, bytes(data))


def took(
    device: SimDevice, pdu: bytes, reply: bytes | None, *, broadcast: bool, listen_only: bool
) -> None:
    """Count the request ``pdu`` that ``device`` took, as the spec's Get Comm Event Counter
    and Get Comm Event Log (6.9, 6.10) and Diagnostics' restart (6.8) say: answered
    ``reply`` (a PDU), or None in the listen only mode (``listen_only``), where it takes no
    action.

    Every request is a message (:attr:`SimDevice.comm_message_count`); one that succeeds
    (not an exception, and not Get Comm Event Counter itself) is an event
    (:attr:`SimDevice.comm_event_count`); each logs its receive and send events
    (:attr:`SimDevice.comm_events`, newest first, 64 at most). Restart communications
    (0x08 / 0x0001) clears the counters, and with data 0xFF00 the log, then logs the
    restart; force listen only mode (0x08 / 0x0004) logs entering it. A request is counted
    once it is answered, so a 0x0B or 0x0C reply gives the counts from before it.
    """
    sub = _word(pdu, 1) if len(pdu) >= 3 and pdu[0] == DIAGNOSTICS else None
    restarted = listen_only if reply is None else reply[:1] == pdu[:1]
    if sub == RESTART_COMMUNICATIONS and restarted:
        device.comm_event_count = device.comm_message_count = 0
        if len(pdu) >= 5 and _word(pdu, 3) == 0xFF00:
            device.comm_events = b""
        _log(device, RESTARTED)
        return
    device.comm_message_count = (_counter(device, "comm_message_count") + 1) % _SPACE
    if sub == FORCE_LISTEN_ONLY and listen_only:
        _log(device, RECEIVED | (RECEIVED_BROADCAST if broadcast else 0))
        _log(device, ENTERED_LISTEN_ONLY)
        return
    mode = IN_LISTEN_ONLY if listen_only else 0
    _log(device, RECEIVED | (RECEIVED_BROADCAST if broadcast else 0) | mode)
    if reply is None:
        return
    exception = reply[1] if len(reply) >= 2 and reply[0] & 0x80 else None
    if exception is None and pdu[:1] != bytes((GET_COMM_EVENT_COUNTER,)):
        device.comm_event_count = (_counter(device, "comm_event_count") + 1) % _SPACE
    _log(device, SENT | _SENT_EXCEPTION.get(exception or 0, 0))


def _log(device: SimDevice, event: int) -> None:
    device.comm_events = (bytes([event]) + bytes(device.comm_events))[:MAX_EVENTS]
