"""Modbus TCP framing (MBAP), for the Python servers: :class:`benchbus.Gateway` and the
simulators' network (``benchbus.sim``).

::

    transaction id (2) | protocol id, 0 (2) | length (2) = 1 + len(PDU) | unit (1) | PDU

Big-endian fields (Modbus Messaging on TCP/IP Implementation Guide V1.0b, 3.1.3). A reply
carries its request's transaction id and unit. Pure Python: the simulators use it without
pymodbus, the gateway without the simulators.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

__all__ = [
    "HEADER_SIZE",
    "MAX_LENGTH",
    "MAX_PDU",
    "MIN_LENGTH",
    "Header",
    "frame",
    "frame_length",
]

#: The longest PDU (Modbus application protocol, 4.1).
MAX_PDU = 253
#: Bytes of the header up to and with the unit.
HEADER_SIZE = 7
#: The range of the length field: the unit and a PDU of 1..MAX_PDU bytes.
MIN_LENGTH = 2
MAX_LENGTH = MAX_PDU + 1

_HEADER = struct.Struct(">HHHB")


class Header(NamedTuple):
    """An MBAP header's fields."""

    transaction: int
    protocol: int
    #: The bytes that follow the length field: the unit and the PDU.
    length: int
    unit: int

    @property
    def length_ok(self) -> bool:
        """Whether :attr:`length` is in range (2..254: a unit and a PDU of 1..253 bytes)."""
        return MIN_LENGTH <= self.length <= MAX_LENGTH

    @classmethod
    def parse(cls, data: bytes) -> Header:
        """The header at the start of ``data`` (at least :data:`HEADER_SIZE` bytes)."""
        return cls(*_HEADER.unpack_from(data))


def frame(transaction: int, unit: int, pdu: bytes) -> bytes:
    """The frame carrying ``pdu`` for ``unit`` under ``transaction`` (protocol id 0)."""
    return _HEADER.pack(transaction, 0, len(pdu) + 1, unit) + pdu


def frame_length(buf: bytes) -> int:
    """Length of the frame at the start of ``buf``, told by its length field.

    0 when fewer than 6 bytes came (the length is not known yet); -1 when ``buf`` does not
    start a frame (a protocol id other than 0, or a length out of range).
    """
    if len(buf) < 6:
        return 0
    protocol = int.from_bytes(buf[2:4], "big")
    length = int.from_bytes(buf[4:6], "big")
    if protocol != 0 or not MIN_LENGTH <= length <= MAX_LENGTH:
        return -1
    return 6 + length
