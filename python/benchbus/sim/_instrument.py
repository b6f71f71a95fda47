"""Simulated instruments of the Taisong Modbus-RTU v2.1 manual (pure Python, no pymodbus).

The manual describes two things: the Taisong panel instrument itself (a measured value at
0x0000, its setpoint at 0x0005, at most 37 registers a read and 20 a write) and, copied
into it, the Modbus section of an Altivar ATV31 drive's manual (its registers W3102..W3105,
W9001, W4043..W4044, at most 29 words, and Read Device Identification, 0x2B / MEI 0x0E).
:class:`TaisongDevice` simulates the first, :class:`Atv31Device` the second.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from types import MappingProxyType

from benchbus.sim._device import BASIC_FUNCTIONS, ClockedModel, RegisterDevice, pace_write
from benchbus.sim._rtu import with_crc

__all__ = ["Atv31Device", "TaisongDevice"]

_INT16_LOW, _INT16_HIGH = -0x8000, 0x7FFF


def _to_signed(word: int) -> int:
    return word - 0x10000 if word & 0x8000 else word


def _finite(name: str, value: float, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"{name} must be a number, not {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise ValueError(f"{name} must be {'> 0' if positive else '>= 0'}, not {value}")
    return value


def _count(value: float) -> int:
    """A measured value as the register holds it: rounded, limited to a signed word."""
    return min(max(round(value), _INT16_LOW), _INT16_HIGH)


class TaisongDevice(ClockedModel, RegisterDevice):
    """A Taisong panel instrument as its Modbus-RTU v2.1 manual describes it.

    ::

        meter = TaisongDevice(clock=clock)  # PV rises from 0 toward SV = 1000
        meter.hold(1000)  # the manual's first example reads 03 E8
        with Simulator({1: meter}, baudrate=TaisongDevice.BAUDRATE) as sim:
            ...

    **Line.** 9600 8N1 at the factory (2400..19200 can be set): :attr:`BAUDRATE`, for the
    Simulator's end-of-frame silence. Functions 0x03, 0x06 and 0x10; a read of more than
    :attr:`MAX_READ` (37) registers or a write of more than :attr:`MAX_WRITE` (20)
    answers exception 3 (illegal data value: the manual gives the limits but not the code
    given for a request over them; 3 is its "value not allowed"), a block past 0xFFFF
    exception 2. No Read
    Device Identification: 0x2B answers exception 1 (illegal function).

    **Registers.** The manual gives only its examples (the full map is in a per-series
    address table it does not include), so:

    - 0x0000 :attr:`PV`, the measured value, read-only: a signed 16-bit count (two's
      complement; the manual's examples read 1000 = 03 E8 and 256 = 01 00 and say nothing
      of decimals or sign). It approaches SV as a first-order process with time constant
      ``tau`` seconds, plus a deterministic wobble of ``wobble`` counts (a sine of
      ``period`` seconds), evaluated lazily from ``clock`` x ``speedup`` (plus
      :meth:`advance`): ``PV(t) = SV + (PV0 - SV) exp(-t / tau) + wobble sin(2 pi t /
      period)``, rounded and limited to -32768..32767, restarting from the value reached
      whenever SV changes. :meth:`hold` freezes what the register shows (like a panel
      meter's HOLD input) while the process goes on behind it.
    - 0x0001 :attr:`STATUS`, read-only (a choice: the manual's third example reads
      0x0000..0x0001 without saying what the second word is): bit 0
      (:attr:`STATUS_ALARM`) = PV >= SV, as an alarm output driven by the setpoint would
      be; bit 1 (:attr:`STATUS_HOLD`) = the display is held (:meth:`hold`). Other bits 0.
    - 0x0005 :attr:`SV`, the setpoint, a signed 16-bit count, any value writable (the
      manual's fourth example writes 100).
    - Everything else, 0x0008..0x0009 included (the manual's fifth example writes 100 and
      200 there), is a plain table of 65536 words as in :class:`RegisterDevice`, all 0
      unless given: a test can keep 32-bit integers, floats or text anywhere in it.

    A write touching 0x0000 or 0x0001 answers exception 2 and writes nothing;
    ``registers[0]`` and ``registers[1]`` are not used (read :attr:`pv` and
    :attr:`status`). ``registers[5]`` is SV: setting it directly is a change of SV taking
    effect at the next access.

    **Write pacing** (optional; the manual asks for none). With ``min_write_interval`` > 0
    a write request (0x06 or 0x10) that comes sooner than that many real seconds after the
    previous one answers exception 6 (server device busy) and writes nothing; every
    arrival goes to :attr:`write_times` and every too-short gap to
    :attr:`write_violations`, as for :class:`J2Device`.
    """

    #: The manual's functions: 0x03, 0x06 and 0x10 (any other answers exception 1).
    functions = BASIC_FUNCTIONS
    #: The factory baud rate (the manual: 2400, 4800, 9600 or 19200, 8N1).
    BAUDRATE = 9600
    #: Most registers one read (0x03) may ask for.
    MAX_READ = 37
    #: Most registers one write (0x06 / 0x10) may carry.
    MAX_WRITE = 20
    #: The measured value's address.
    PV = 0x0000
    #: The status word's address.
    STATUS = 0x0001
    #: The setpoint's address.
    SV = 0x0005
    #: Status bit 0: the measured value is at or above the setpoint.
    STATUS_ALARM = 0x0001
    #: Status bit 1: the measured value is held (:meth:`hold`).
    STATUS_HOLD = 0x0002

    def __init__(
        self,
        registers: Mapping[int, int] | None = None,
        *,
        setpoint: int = 1000,
        initial: float = 0.0,
        tau: float = 10.0,
        wobble: float = 2.0,
        period: float = 5.0,
        speedup: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
        min_write_interval: float = 0.0,
    ) -> None:
        """A meter at power-up: PV at ``initial``, rising (or falling) toward ``setpoint``.

        ``registers`` (``{address: word}``) fills the plain table; it may not set 0x0000,
        0x0001 or 0x0005 (use ``setpoint``, -32768..32767). ``tau`` (> 0) and ``period``
        (> 0) are model seconds, ``wobble`` (>= 0) counts. ``clock`` gives the time in
        seconds (a test may pass a fake one and move it, or call :meth:`advance`); the model
        runs ``speedup`` times faster. ``min_write_interval`` is the shortest time between
        write requests, real seconds (0: no pacing).
        """
        registers = dict(registers or {})
        for address in (self.PV, self.STATUS, self.SV):
            if address in registers:
                raise ValueError(f"register {address:#06x} is the model's: not in registers")
        if isinstance(setpoint, bool) or not isinstance(setpoint, int):
            raise TypeError(f"setpoint must be an int, not {type(setpoint).__name__}")
        if not _INT16_LOW <= setpoint <= _INT16_HIGH:
            raise ValueError(f"setpoint must be -32768..32767, not {setpoint}")
        if isinstance(initial, bool) or not isinstance(initial, (int, float)):
            raise TypeError(f"initial must be a number, not {type(initial).__name__}")
        if not math.isfinite(initial):
            raise ValueError(f"initial must be finite, not {initial}")
        super().__init__(
            {**registers, self.SV: setpoint & 0xFFFF},
            max_read=self.MAX_READ,
            max_write=self.MAX_WRITE,
            readonly=(self.PV, self.STATUS),
        )
        #: The process's time constant, model seconds.
        self.tau: float = _finite("tau", tau, positive=True)
        #: The wobble's amplitude, counts.
        self.wobble: float = _finite("wobble", wobble)
        #: The wobble's period, model seconds.
        self.period: float = _finite("period", period, positive=True)
        #: How many times faster than ``clock`` the model runs.
        self.speedup: float = _finite("speedup", speedup, positive=True)
        #: Shortest time between two write requests, real seconds; sooner: exception 6.
        self.min_write_interval: float = _finite("min_write_interval", min_write_interval)
        #: ``time.monotonic()`` at the arrival of each write request, refused or not.
        self.write_times: list[float] = []
        #: Each too-short interval between two write requests, seconds (answered with 6).
        self.write_violations: list[float] = []
        self._start_clock(clock)
        self._t0 = self._now()  # the process is x0 at t0 and heads for target
        self._x0 = float(initial)
        self._target = float(setpoint)
        self._held: int | None = None

    # ---- Modbus handlers ----------------------------------------------------------------------

    def _arrive(self, write: bool) -> None:
        if write:
            pace_write(self.write_times, self.write_violations, self.min_write_interval)
        self._update()

    def _live(self, address: int) -> int:
        """The live PV and status at 0x0000 and 0x0001, the table's words elsewhere."""
        if address in (self.PV, self.STATUS):
            return (self._pv() if address == self.PV else self._status()) & 0xFFFF
        return super()._live(address)

    def _store(self, address: int, value: int) -> None:
        super()._store(address, value)
        self._update()  # a new SV: the process heads for it from now

    # ---- test access ----------------------------------------------------------------------

    @property
    def pv(self) -> int:
        """The measured value the register shows now (signed)."""
        with self._lock:
            return self._pv()

    @property
    def process(self) -> float:
        """The process value now, unrounded, without the wobble, whether held or not."""
        with self._up_to_now():
            return self._x0

    @property
    def status(self) -> int:
        """The status word the register shows now."""
        with self._lock:
            return self._status()

    @property
    def sv(self) -> int:
        """The setpoint (register 0x0005, signed)."""
        return _to_signed(self.registers[self.SV])

    @sv.setter
    def sv(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError(f"a setpoint is an int, not {type(value).__name__}")
        if not _INT16_LOW <= value <= _INT16_HIGH:
            raise ValueError(f"a setpoint is -32768..32767, not {value}")
        with self._up_to_now():
            self.registers[self.SV] = value & 0xFFFF
            self._update()

    @property
    def held(self) -> int | None:
        """The value the measured value is held at, or None."""
        return self._held

    def hold(self, value: float | None) -> None:
        """Show ``value`` (rounded, -32768..32767) at 0x0000 from now on; None: the live value.

        The process goes on behind a held display, as behind a panel meter's HOLD input.
        """
        if value is not None:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"a held value is a number, not {type(value).__name__}")
            if not (math.isfinite(value) and _INT16_LOW <= round(value) <= _INT16_HIGH):
                raise ValueError(f"a held value is -32768..32767, not {value}")
            value = round(value)
        with self._lock:
            self._held = value

    def __repr__(self) -> str:
        """PV, SV and whether PV is held."""
        with self._lock:
            held = " held" if self._held is not None else ""
            return f"<TaisongDevice PV={self._pv()}{held} SV={self.sv}>"

    # ---- the model ----------------------------------------------------------------------------

    def _update(self) -> None:
        """Move the process to now; from there it heads for the SV now in the register."""
        now = self._now()
        decay = math.exp(-(now - self._t0) / self.tau)
        self._x0 = self._target + (self._x0 - self._target) * decay
        self._t0 = now
        self._target = float(self.sv)

    def _pv(self) -> int:
        self._update()
        if self._held is not None:
            return self._held
        wobble = self.wobble * math.sin(2.0 * math.pi * self._t0 / self.period)
        return _count(self._x0 + wobble)

    def _status(self) -> int:
        status = self.STATUS_ALARM if self._pv() >= self.sv else 0
        return status | (self.STATUS_HOLD if self._held is not None else 0)


class Atv31Device(RegisterDevice):
    """The ATV31 drive of the Taisong manual's Modbus section, with its identification.

    ::

        drive = Atv31Device(identity_page_size=1)  # one object per identification reply
        with Simulator({2: drive}, baudrate=19200) as sim:
            ...

    **Registers.** A plain table of 65536 words (see :class:`RegisterDevice`), all
    writable, with the manual's values (:attr:`REGISTERS`): W3102..W3105 at
    0x0C1E..0x0C21 = 0x0028, 0x0258, 0x01F4, 0x0000 (SFr switching frequency 4 kHz, tFr
    maximum frequency 60 Hz, HSP high speed 50 Hz, LSP low speed 0 Hz), W9001 at 0x2329
    (ACC, 3 at power-up; the manual writes 13) and W4043..W4044 at 0x0FCB..0x0FCC (ACC and
    DEC, 3 each; the manual writes 20 and 30); every other word 0 unless given. At most
    :attr:`MAX_WORDS` (29) words a read or a write, as the manual's table says; more
    answer exception 3.

    **Read Device Identification** (0x2B / MEI 0x0E), built by the Modbus spec: objects 0
    "TELEMECANIQUE" (the bytes of the manual's reply; its text says "Telemecanique"),
    1 "ATV31HU09M3S232", 2 "0201" (:attr:`IDENTITY`), plus ``extra_objects`` (regular
    objects 3..6, private 0x80..0xFF). Read codes 1 (basic: objects 0..2), 2 (regular:
    0..6) and 3 (extended: 0..6 and 0x80..0xFF) stream from the requested object id (an
    id the stream does not hold restarts at 0), 4 reads one object. The conformity byte
    is :attr:`conformity`, or when that is None, 0x02 (what the manual's reply sends) or
    0x03 once there are private objects; read code 4 is answered whatever it says.

    With :attr:`identity_page_size` N, a stream reply carries at most N objects: if more
    are left it says "more follows" (0xFF) and the next object's id, and the master asks
    again from that id. The manual's ATV31 sends its three objects in one reply.

    Errors: read code 0 or > 4 answers exception 3, an object id read code 4 cannot find
    exception 2, an MEI type other than 0x0E exception 1 (standard 5-byte replies
    ``unit, 0xAB, code, CRC``). With :attr:`mei_exceptions` they take the form the
    manual's "abnormal response" shows, 6 bytes ``unit, 0xAB, 0x0E, error, CRC``: error 1
    for a bad read code or MEI type, 2 for a bad object id. With :attr:`identity` None the
    function is not supported: exception 1 in the standard form either way.
    """

    #: The manual's functions: 0x03, 0x06, 0x10 and 0x2B (any other answers exception 1).
    functions = BASIC_FUNCTIONS
    #: The manual's identification objects (read-only mapping).
    IDENTITY: Mapping[int, str] = MappingProxyType(
        {0: "TELEMECANIQUE", 1: "ATV31HU09M3S232", 2: "0201"}
    )
    #: The registers at power-up that are not 0 (read-only mapping).
    REGISTERS: Mapping[int, int] = MappingProxyType(
        {
            0x0C1E: 0x0028,  # W3102 SFr = 4 kHz
            0x0C1F: 0x0258,  # W3103 tFr = 60 Hz
            0x0C20: 0x01F4,  # W3104 HSP = 50 Hz
            0x0C21: 0x0000,  # W3105 LSP = 0 Hz
            0x0FCB: 3,  # W4043 ACC
            0x0FCC: 3,  # W4044 DEC
            0x2329: 3,  # W9001 ACC
        }
    )
    #: Most words one read or write may carry.
    MAX_WORDS = 29
    #: Longest object text, bytes: one object alone fills a reply.
    MAX_OBJECT_LENGTH = 244

    def __init__(
        self,
        registers: Mapping[int, int] | None = None,
        *,
        extra_objects: Mapping[int, str] | None = None,
        identity_page_size: int | None = None,
        mei_exceptions: bool = False,
        conformity: int | None = None,
    ) -> None:
        """The manual's drive; ``registers`` (``{address: word}``) change its table.

        ``extra_objects`` (``{object id: ASCII text}``, ids 3..6 or 0x80..0xFF, 1 to
        :attr:`MAX_OBJECT_LENGTH` characters) add to :attr:`IDENTITY`.
        """
        identity = dict(self.IDENTITY)
        for object_id, text in (extra_objects or {}).items():
            _check_object(object_id, text)
            identity[object_id] = text
        super().__init__(
            {**self.REGISTERS, **(registers or {})},
            identity=identity,
            max_read=self.MAX_WORDS,
            max_write=self.MAX_WORDS,
        )
        if identity_page_size is not None and (
            isinstance(identity_page_size, bool)
            or not isinstance(identity_page_size, int)
            or identity_page_size < 1
        ):
            raise ValueError(f"identity_page_size must be None or >= 1, not {identity_page_size}")
        if conformity is not None and (
            isinstance(conformity, bool) or not isinstance(conformity, int)
        ):
            raise TypeError(f"conformity must be None or an int, not {type(conformity).__name__}")
        if conformity is not None and conformity not in (0x01, 0x02, 0x03, 0x81, 0x82, 0x83):
            raise ValueError(f"conformity must be 0x01..0x03 or 0x81..0x83, not {conformity:#x}")
        #: Most objects one identification reply carries (None: as many as fit).
        self.identity_page_size: int | None = identity_page_size
        #: Whether identification errors take the manual's 6-byte form.
        self.mei_exceptions: bool = bool(mei_exceptions)
        #: The conformity byte of identification replies (None: from the objects).
        self.conformity: int | None = conformity

    def shape_reply(self, request: bytes, reply: bytes) -> bytes:
        """Identification replies: the conformity, the paging, the manual's error form."""
        if len(request) < 5 or request[1] != 0x2B or len(reply) < 5:
            return reply
        identity = self.identity
        if identity is None:
            return reply
        if reply[1] == 0xAB:
            error = {0x01: 1, 0x03: 1, 0x02: 2}.get(reply[2])
            if not self.mei_exceptions or len(reply) != 5 or error is None:
                return reply
            return with_crc(bytes([reply[0], 0xAB, 0x0E, error]))
        if reply[1:3] != b"\x2b\x0e" or len(reply) < 10:
            return reply
        objects = _objects(reply)
        more, next_id = reply[5], reply[6]
        page = self.identity_page_size
        if page is not None and reply[3] in (1, 2, 3) and len(objects) > page:
            more, next_id = 0xFF, objects[page][0]
            objects = objects[:page]
        conformity = self.conformity
        if conformity is None:
            conformity = 0x03 if any(i >= 0x80 for i in identity) else 0x02
        body = b"".join(bytes([i, len(text)]) + text for i, text in objects)
        head = bytes([reply[0], 0x2B, 0x0E, reply[3], conformity, more, next_id, len(objects)])
        return with_crc(head + body)


def _objects(reply: bytes) -> list[tuple[int, bytes]]:
    """The objects of an identification reply ``unit 2B 0E code conf more next n {id len
    text}* CRC``."""
    objects, pos = [], 8
    for _ in range(reply[7]):
        length = reply[pos + 1]
        objects.append((reply[pos], reply[pos + 2 : pos + 2 + length]))
        pos += 2 + length
    return objects


def _check_object(object_id: int, text: str) -> None:
    if isinstance(object_id, bool) or not isinstance(object_id, int):
        raise TypeError(f"an object id is an int, not {type(object_id).__name__}")
    if not (3 <= object_id <= 6 or 0x80 <= object_id <= 0xFF):
        raise ValueError(f"an extra object id is 3..6 or 0x80..0xFF, not {object_id:#x}")
    if not isinstance(text, str):
        raise TypeError(f"an object is text, not {type(text).__name__}")
    if not (text.isascii() and 1 <= len(text) <= Atv31Device.MAX_OBJECT_LENGTH):
        raise ValueError(
            f"object {object_id:#x} must be 1..{Atv31Device.MAX_OBJECT_LENGTH} ASCII"
            f" characters, not {text!r}"
        )
