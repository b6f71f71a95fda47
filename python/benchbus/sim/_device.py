"""Simulated device behaviour: what one Modbus unit answers (pure Python, no pymodbus)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping

__all__ = ["ClockedModel", "RegisterDevice", "SimDevice", "SimException", "pace_write"]

_REGISTER_SPACE = 0x10000


class SimException(Exception):
    """Raise from a device handler to answer with a Modbus exception reply.

    The reply is ``unit, function | 0x80, code, CRC``. Any code 1..255 can be given; the
    class constants name the standard ones (device simulators may give them their vendor
    meanings, e.g. 0x08 "not changeable while running" on a BLD drive).
    """

    ILLEGAL_FUNCTION = 0x01
    ILLEGAL_DATA_ADDRESS = 0x02
    ILLEGAL_DATA_VALUE = 0x03
    SERVER_DEVICE_FAILURE = 0x04
    ACKNOWLEDGE = 0x05
    SERVER_DEVICE_BUSY = 0x06
    NEGATIVE_ACKNOWLEDGE = 0x07
    MEMORY_PARITY_ERROR = 0x08
    GATEWAY_PATH_UNAVAILABLE = 0x0A
    GATEWAY_TARGET_FAILED = 0x0B

    def __init__(self, code: int) -> None:
        """Exception reply with exception ``code`` (1..255)."""
        if isinstance(code, bool) or not isinstance(code, int) or not 1 <= code <= 0xFF:
            raise ValueError(f"a Modbus exception code is 1..255, not {code!r}")
        super().__init__(f"Modbus exception code {code:#04x}")
        self.code: int = code


class SimDevice:
    """The behaviour of ONE simulated unit; device simulators subclass it.

    The simulator calls :meth:`read_holding` for function 0x03 and :meth:`write_holding` for
    0x06 and 0x10 (from its server thread, one request at a time); raising
    :class:`SimException` from either answers with that exception code, and any other
    exception answers code 4 (server device failure) and is kept in ``Simulator.errors``.
    A request for more registers than :attr:`max_read` / :attr:`max_write` is answered
    with :attr:`too_many_code` before either is called. The base class has no registers:
    every access answers exception 2 (illegal data address).
    """

    #: Most registers one read (0x03) may ask for. The protocol allows 125; a device
    #: simulator declares its manual's limit, so that a master which asks a real device for
    #: more than it takes fails against the simulator too. Checked by the simulator before
    #: :meth:`read_holding` is called (a direct call is not limited).
    max_read: int = 125

    #: Most registers one write (0x10) may carry: the protocol allows 123. As
    #: :attr:`max_read`.
    max_write: int = 123

    #: The exception code answered to a request over :attr:`max_read` / :attr:`max_write`:
    #: 3 (illegal data value), as the Modbus specification gives for a quantity out of range.
    too_many_code: int = SimException.ILLEGAL_DATA_VALUE

    #: Read Device Identification (0x2B / MEI 0x0E) objects, ``{object id: text}``: 0 vendor
    #: name, 1 product code, 2 revision, 3 vendor URL, 4 product name, 5 model name,
    #: 6 user application name, 0x80..0xFF private. None: the function is not supported
    #: (answered with exception 1, illegal function).
    identity: dict[int, str] | None = None

    #: Whether this unit answers a broadcast (unit 0) as if it had been addressed itself, with
    #: its own unit address in the reply. Standard Modbus units act on a broadcast silently;
    #: the PBL manual says its drives answer.
    answers_broadcast: bool = False

    #: Whether this unit's replies to writes (0x06, 0x10) go on the line. When False the unit
    #: still acts on each write (and the request is logged) but its reply, normal or
    #: exception, is dropped, as a BLD drive does with F08.06 = 1 (the library's side of it
    #: is ``Drive(write_ack=False)``). Read once per request, before the unit handles it, so
    #: a subclass may make it a property.
    answers_writes: bool = True

    #: Seconds this unit holds each of its replies before it goes on the line (a BLD drive's
    #: F08.03 reply delay). The line uses the larger of this and ``Simulator.reply_delay``.
    #: Read once per request, before the unit handles it, so a subclass may make it a
    #: property.
    reply_delay: float = 0.0

    def read_holding(self, address: int, count: int) -> list[int]:
        """Values of the ``count`` holding registers from ``address`` (each 0..0xFFFF).

        Raise :class:`SimException` to answer with an exception reply instead.
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def write_holding(self, address: int, values: list[int]) -> None:
        """Write ``values`` to the holding registers from ``address`` (0x06 gives one value).

        Raise :class:`SimException` to answer with an exception reply instead (then nothing
        should have been written).
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def shape_reply(self, request: bytes, reply: bytes) -> bytes:
        """The reply that goes on the line for ``request``, given the one the server made.

        For units whose replies differ from the standard ones (a PBL drive answers a 0x06
        write with a register count instead of the echo). Both frames are whole, unit
        address to CRC; an override that changes the reply returns it with its CRC
        recomputed (``benchbus.sim._rtu.with_crc``). The default returns ``reply`` as is.

        Called from the line's thread, not the server's, once for each reply the server
        made that goes on the line (normal or exception), before the line's faults
        (``Simulator.corrupt_next``, the reply delays) apply. Not called for replies the
        simulator makes itself (``Simulator.answer_exception``, illegal function) nor for
        replies that stay off the line (:attr:`answers_writes` False, a broadcast the unit
        does not answer). ``request`` is the request as received, CRC included; for a
        broadcast the unit answers, it carries the unit's own address instead of 0. If
        this raises, or returns anything but a frame of at least 4 bytes, the server's
        reply goes on the line unchanged and the error is kept in ``Simulator.errors``.
        """
        return reply


class ClockedModel:
    """A device model that runs on a clock and is evaluated lazily, on each access.

    A subclass calls :meth:`_start_clock` in its ``__init__`` and defines :meth:`_update`,
    which brings the model up to :meth:`_now` (under ``self._lock``).
    """

    #: How many times faster than its clock the model runs.
    speedup: float = 1.0

    def _start_clock(self, clock: Callable[[], float]) -> None:
        """Run the model on ``clock`` (seconds) from now; also makes ``self._lock``."""
        if not callable(clock):
            raise TypeError("clock must be a callable returning seconds")
        self._clock = clock
        self._clock_start = float(clock())
        self._offset = 0.0
        self._lock = threading.RLock()

    def _now(self) -> float:
        """Model seconds since the start: the clock's, times :attr:`speedup`, plus advances."""
        return (float(self._clock()) - self._clock_start) * self.speedup + self._offset

    def _update(self) -> None:
        """Bring the model up to :meth:`_now` (called with ``self._lock`` held)."""
        raise NotImplementedError

    def advance(self, seconds: float) -> None:
        """Move the model's time forward by ``seconds`` (model seconds) on top of its clock."""
        if not seconds >= 0:
            raise ValueError(f"seconds must be >= 0, not {seconds}")
        with self._lock:
            self._update()
            self._offset += seconds
            self._update()


class RegisterDevice(SimDevice):
    """A plain table of 65536 holding registers, all 0 unless given.

    ``registers`` is a list of 65536 ints that a test reads and sets directly
    (``dev.registers[0x2000] = 5``). Requests for more than ``max_read`` (0x03) or
    ``max_write`` (0x06 / 0x10) registers answer exception 3 (illegal data value, see
    :attr:`SimDevice.max_read`), requests past address 0xFFFF exception 2 (illegal data
    address), and a write touching a register in ``readonly`` answers
    :attr:`readonly_code` (2, illegal data address, unless a subclass changes it) and writes
    nothing.
    """

    #: Exception code answered to a write that touches a read-only register.
    readonly_code: int = SimException.ILLEGAL_DATA_ADDRESS

    def __init__(
        self,
        registers: Mapping[int, int] | None = None,
        *,
        identity: Mapping[int, str] | None = None,
        max_read: int | None = None,
        max_write: int | None = None,
        readonly: Iterable[int] = (),
    ) -> None:
        """Registers from ``{address: value}``; the others are 0.

        ``max_read`` is at most 125 and ``max_write`` at most 123 (the protocol's limits);
        None keeps the class's (:attr:`SimDevice.max_read`, which a subclass may declare).
        """
        if max_read is not None and not 1 <= max_read <= 125:
            raise ValueError(f"max_read must be 1..125, not {max_read}")
        if max_write is not None and not 1 <= max_write <= 123:
            raise ValueError(f"max_write must be 1..123, not {max_write}")
        self.registers: list[int] = [0] * _REGISTER_SPACE
        for address, value in (registers or {}).items():
            _check_address(address)
            _check_value(value)
            self.registers[address] = value
        self.identity = dict(identity) if identity is not None else None
        if max_read is not None:
            self.max_read = max_read
        if max_write is not None:
            self.max_write = max_write
        self.readonly: set[int] = set(readonly)
        for address in self.readonly:
            _check_address(address)

    def read_holding(self, address: int, count: int) -> list[int]:
        """The registers ``address .. address + count - 1`` from :attr:`registers`."""
        if not 0 <= address <= _REGISTER_SPACE - count:
            raise SimException(SimException.ILLEGAL_DATA_ADDRESS)
        return self.registers[address : address + count]

    def write_holding(self, address: int, values: list[int]) -> None:
        """Store ``values`` from ``address``, all or nothing."""
        count = len(values)
        if not 0 <= address <= _REGISTER_SPACE - count:
            raise SimException(SimException.ILLEGAL_DATA_ADDRESS)
        if any(a in self.readonly for a in range(address, address + count)):
            raise SimException(self.readonly_code)
        for value in values:
            _check_value(value)
        self.registers[address : address + count] = values

    def __repr__(self) -> str:
        """Class name and the registers that are not 0."""
        nonzero = {a: v for a, v in enumerate(self.registers) if v}
        shown = ", ".join(f"{a:#06x}: {v}" for a, v in list(nonzero.items())[:8])
        more = ", ..." if len(nonzero) > 8 else ""
        return f"{type(self).__name__}({{{shown}{more}}})"


def pace_write(times: list[float], violations: list[float], interval: float) -> None:
    """Record a write request's arrival; exception 6 if it came too soon after the last one.

    For devices that want their writes spaced (a J2 controller's 150 ms). Appends
    ``time.monotonic()`` to ``times`` whatever the outcome, so a refused write counts as
    much as an accepted one and a master that retries at once is refused again. When the
    gap since the previous entry is shorter than ``interval`` seconds (real time, never a
    sped-up model clock), appends the gap to ``violations`` and raises
    :class:`SimException` 6 (server device busy): the violations are exactly the gaps
    between consecutive times that are shorter than the interval. ``interval`` 0 refuses
    nothing. Call it first in ``write_holding``, before any other check.
    """
    now = time.monotonic()
    previous = times[-1] if times else None
    times.append(now)
    if previous is not None and now - previous < interval:
        violations.append(now - previous)
        raise SimException(SimException.SERVER_DEVICE_BUSY)


def _check_address(address: int) -> None:
    if isinstance(address, bool) or not isinstance(address, int):
        raise TypeError(f"a register address is an int, not {type(address).__name__}")
    if not 0 <= address < _REGISTER_SPACE:
        raise ValueError(f"a register address is 0..0xFFFF, not {address}")


def _check_value(value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"a register value is an int, not {type(value).__name__}")
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"a register value is 0..0xFFFF, not {value}")
