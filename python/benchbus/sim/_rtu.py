"""Modbus RTU framing helpers for the simulator's line (pure Python, no pymodbus).

The forwarder between the library and the pymodbus server uses these to cut the byte stream
into frames: it knows the length of the requests and replies of the functions the simulated
devices speak, and falls back to a silent gap for anything else.
"""

from __future__ import annotations

__all__ = [
    "crc16",
    "crc_ok",
    "end_of_frame_silence",
    "exception_frame",
    "reply_length",
    "request_length",
    "t3_5",
    "with_crc",
]


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16/MODBUS of ``data`` (polynomial 0xA001 reflected, initial value 0xFFFF)."""
    crc = 0xFFFF
    for byte in data:
        crc = (crc >> 8) ^ _TABLE[(crc ^ byte) & 0xFF]
    return crc


def with_crc(data: bytes) -> bytes:
    """``data`` followed by its CRC, low byte first, as sent on the wire."""
    return data + crc16(data).to_bytes(2, "little")


def crc_ok(frame: bytes) -> bool:
    """Whether ``frame`` (at least unit + function + CRC) ends with its correct CRC."""
    return len(frame) >= 4 and crc16(frame[:-2]).to_bytes(2, "little") == frame[-2:]


def exception_frame(unit: int, function: int, code: int) -> bytes:
    """The exception reply ``unit, function | 0x80, code, CRC``."""
    return with_crc(bytes([unit, (function | 0x80) & 0xFF, code]))


def t3_5(baudrate: int, bits: int = 11) -> float:
    """The silence (seconds) between two frames: 3.5 characters of ``bits`` bits each
    (start + 8 data + parity + stop: 10 for 8N1, 11 for 8E1 or 8N2), fixed at 1.75 ms above
    19200 baud (Modbus over Serial Line V1.02, 2.5.1.1).

    The simulators' own reading of the spec, kept apart from the library's on purpose: they
    judge the library's timing.
    """
    return 0.00175 if baudrate > 19200 else 3.5 * bits / baudrate


def end_of_frame_silence(baudrate: int) -> float:
    """Silence (seconds) that ends a frame of unknown length: t3.5, but at least 5 ms.

    t3.5 is counted with 11-bit characters (the longest 8-bit format, 8E1 or 8N2): the
    simulator does not know the library's parity.

    A pseudo-terminal carries bytes instantly, so the only silences are the writer's own;
    the floor keeps a frame written in pieces by a busy process from being cut in two.

    The library's Bus has the same idea under the same name (``end_of_frame_silence`` in
    ``src/bus.rs``), with its own t3.5 and a 2 ms floor.
    """
    return max(t3_5(baudrate, 11), 0.005)


def request_length(buf: bytes) -> int | None:
    """Length of the request at the start of ``buf``.

    Returns 0 when more bytes are needed to tell, None when the function is not one whose
    length is known (the caller then waits for a silent gap).
    """
    if len(buf) < 2:
        return 0
    function = buf[1]
    if function in (0x07, 0x0B, 0x0C, 0x11):
        return 4
    if function == 0x18:
        return 6
    if function in (0x14, 0x15):
        return 0 if len(buf) < 3 else 5 + buf[2]
    if function in (0x01, 0x02, 0x03, 0x04, 0x05, 0x06):
        return 8
    if function == 0x08:
        # Every Diagnostics sub-function but return query data (any length) carries one
        # word: a request the next one follows closely is not taken together with it.
        if len(buf) < 4:
            return 0
        return None if buf[2:4] == b"\x00\x00" else 8
    if function == 0x16:
        return 10
    if function in (0x0F, 0x10):
        return 0 if len(buf) < 7 else 9 + buf[6]
    if function == 0x17:
        return 0 if len(buf) < 11 else 13 + buf[10]
    if function == 0x2B:
        if len(buf) < 3:
            return 0
        return 7 if buf[2] == 0x0E else None
    return None


def reply_length(buf: bytes) -> int | None:
    """Length of the reply at the start of ``buf``: 0 = need more bytes, None = unknown."""
    if len(buf) < 2:
        return 0
    function = buf[1]
    if function & 0x80:
        return 5
    if function == 0x07:
        return 5
    if function in (0x01, 0x02, 0x03, 0x04, 0x0C, 0x11, 0x14, 0x15, 0x17):
        return 0 if len(buf) < 3 else 5 + buf[2]
    if function in (0x05, 0x06, 0x0B, 0x0F, 0x10):
        return 8
    if function == 0x18:
        return 0 if len(buf) < 4 else 6 + int.from_bytes(buf[2:4], "big")
    if function == 0x16:
        return 10
    if function == 0x2B:
        return _device_identification_length(buf)
    return None


def _device_identification_length(buf: bytes) -> int | None:
    # unit 2B 0E read-code conformity more-follows next-object count {id len value}* crc crc
    if len(buf) < 3:
        return 0
    if buf[2] != 0x0E:
        return None
    if len(buf) < 8:
        return 0
    pos = 8
    for _ in range(buf[7]):
        if len(buf) < pos + 2:
            return 0
        pos += 2 + buf[pos + 1]
    return pos + 2


def count_echo(reply: bytes) -> bytes:
    """``reply`` as a unit that answers a 0x06 write with the address and a register count
    of 1 in place of the value sends it (a PBL drive); any other reply as it is."""
    if len(reply) != 8 or reply[1] != 0x06:
        return reply
    return with_crc(reply[:4] + b"\x00\x01")
