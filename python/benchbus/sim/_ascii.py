"""Modbus ASCII framing for the simulator's line (pure Python, no pymodbus).

From Modbus over Serial Line V1.02: 2.5.2 (a frame is ``:``, each byte of unit, PDU and
LRC as two hex characters, then CR LF; at most 513 characters; a ``:`` starts a new frame,
dropping the one begun; up to 1 s between two characters) and 6.2.1 (the LRC is the two's
complement of the 8-bit sum of unit and PDU). Written from the spec alone, apart from the
library's codec, so that the simulator judges it.

The line's units speak RTU behind the forwarder: :class:`Receiver` turns the library's
ASCII requests into ``unit | PDU`` and :func:`encode` the units' replies into ASCII frames.
"""

from __future__ import annotations

import logging

__all__ = ["INTER_CHAR_TIMEOUT", "MAX_FRAME", "Receiver", "encode", "lrc"]

log = logging.getLogger("benchbus.sim")

#: Longest frame, in characters (``:`` and CR LF included).
MAX_FRAME = 513
#: The longest gap between two characters of a frame: past it the frame begun is dropped.
INTER_CHAR_TIMEOUT = 1.0

_HEX = b"0123456789ABCDEFabcdef"


def lrc(data: bytes) -> int:
    """The LRC of ``data`` (unit and PDU): the two's complement of its byte sum, mod 256."""
    return -sum(data) & 0xFF


def encode(unit_pdu: bytes, *, bad_lrc: bool = False) -> bytes:
    """The ASCII frame of ``unit_pdu``: ``:``, upper-case hex of the bytes and of their LRC
    (inverted with ``bad_lrc``: a spoiled frame), CR LF."""
    check = lrc(unit_pdu) ^ (0xFF if bad_lrc else 0)
    return b":" + (bytes(unit_pdu) + bytes([check])).hex().upper().encode() + b"\r\n"


def _decode(body: bytes) -> bytes | None:
    """The ``unit | PDU`` of a frame's characters between ``:`` and CR LF, or None if they
    are not hex digit pairs of at least unit, function and LRC, with the right LRC."""
    if len(body) % 2 or len(body) < 6 or any(c not in _HEX for c in body):
        return None
    data = bytes.fromhex(body.decode("ascii"))
    if lrc(data[:-1]) != data[-1]:
        return None
    return data[:-1]


class Receiver:
    """Cuts the characters of the line into ASCII frames as they come."""

    def __init__(self) -> None:
        """Waiting for a ``:``."""
        self._frame: bytearray | None = None  # the characters after the `:` of a frame begun
        self._last = 0.0
        #: Characters that belonged to no good frame (noise, frames dropped or rejected).
        self.dropped = 0

    def feed(self, data: bytes, now: float) -> list[bytes]:
        """Take ``data``, arrived at ``now`` (``time.monotonic()``); the ``unit | PDU`` of
        each good frame it ends. Rejected frames are logged and dropped."""
        if self._frame is not None and now - self._last > INTER_CHAR_TIMEOUT:
            self._drop("frame given up after a gap over 1 s")
        self._last = now
        out = []
        for c in data:
            if c == ord(":"):
                if self._frame is not None:
                    self._drop("frame cut off by a new ':'")
                self._frame = bytearray()
                continue
            if self._frame is None:
                self.dropped += 1
                continue
            self._frame.append(c)
            if self._frame.endswith(b"\r\n"):
                body = bytes(self._frame[:-2])
                unit_pdu = _decode(body)
                if unit_pdu is None:
                    self._drop("bad frame (a character, its length or its LRC)")
                else:
                    out.append(unit_pdu)
                    self._frame = None
            elif len(self._frame) + 1 >= MAX_FRAME:
                self._drop("frame over 513 characters")
        return out

    def _drop(self, why: str) -> None:
        frame = self._frame or bytearray()
        log.debug("simulator: ASCII %s, dropped: %r", why, b":" + bytes(frame))
        self.dropped += 1 + len(frame)
        self._frame = None
