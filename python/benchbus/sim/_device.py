"""Simulated device behaviour: what one Modbus unit answers (pure Python, no pymodbus)."""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import TypeVar

__all__ = [
    "BASIC_FUNCTIONS",
    "STANDARD_FUNCTIONS",
    "ClockedModel",
    "RegisterDevice",
    "Row",
    "SimDevice",
    "SimException",
    "TableDevice",
    "pace_write",
]

_REGISTER_SPACE = 0x10000

#: What every :class:`SimDevice` may answer: holding registers (0x03, 0x06, 0x10) and Read
#: Device Identification (0x2B, answered exception 1 when the device has no ``identity``).
BASIC_FUNCTIONS = frozenset({0x03, 0x06, 0x10, 0x2B})
#: Every public function a :class:`RegisterDevice` answers: the basic ones, coils (0x01,
#: 0x05, 0x0F), discrete inputs (0x02), input registers (0x04), Mask Write Register (0x16),
#: Read/Write Multiple registers (0x17), Read Exception Status (0x07), Diagnostics (0x08:
#: sub-functions 0x0000, 0x0001 and 0x0004), Get Comm Event Counter (0x0B), Get Comm Event
#: Log (0x0C), Report Server ID (0x11), Read / Write File Record (0x14, 0x15) and Read FIFO
#: Queue (0x18).
STANDARD_FUNCTIONS = BASIC_FUNCTIONS | frozenset(
    {0x01, 0x02, 0x04, 0x05, 0x07, 0x08, 0x0B, 0x0C, 0x0F, 0x11, 0x14, 0x15, 0x16, 0x17, 0x18}
)
#: Records in a file (0x14, 0x15): 0 to 9999 (Modbus application protocol 6.14).
FILE_RECORDS = 10000


class SimException(Exception):
    """Raise from a device handler to answer with a Modbus exception reply.

    The reply is ``unit, function | 0x80, code, CRC``. Any code 1..255 can be given; the
    class constants name the standard ones (device simulators may give them their vendor
    meanings, e.g. 0x08 "not changeable while running" on a BLD drive).
    """

    #: Exception 1: the unit does not answer this function code.
    ILLEGAL_FUNCTION = 0x01
    #: Exception 2: an address the unit does not have.
    ILLEGAL_DATA_ADDRESS = 0x02
    #: Exception 3: a value (or a quantity) the unit refuses.
    ILLEGAL_DATA_VALUE = 0x03
    #: Exception 4: the unit failed while acting on the request.
    SERVER_DEVICE_FAILURE = 0x04
    #: Exception 5: accepted, but it will take long.
    ACKNOWLEDGE = 0x05
    #: Exception 6: busy with a long command; ask again later.
    SERVER_DEVICE_BUSY = 0x06
    #: Exception 7: the unit cannot carry out the request.
    NEGATIVE_ACKNOWLEDGE = 0x07
    #: Exception 8: a parity error in the unit's memory.
    MEMORY_PARITY_ERROR = 0x08
    #: Exception 0x0A: the gateway has no path to the unit.
    GATEWAY_PATH_UNAVAILABLE = 0x0A
    #: Exception 0x0B: the unit behind the gateway did not answer.
    GATEWAY_TARGET_FAILED = 0x0B

    def __init__(self, code: int) -> None:
        """Exception reply with exception ``code`` (1..255)."""
        if isinstance(code, bool) or not isinstance(code, int) or not 1 <= code <= 0xFF:
            raise ValueError(f"a Modbus exception code is 1..255, not {code!r}")
        super().__init__(f"Modbus exception code {code:#04x}")
        #: The exception code the reply carries.
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

    A unit answers the function codes in :attr:`functions` and exception 1 (illegal
    function) to any other. The base class serves 0x03, 0x06, 0x10 and 0x2B, as the
    device manuals of the families do; a device that serves more declares them, and for
    each the simulator calls (as above, in the server thread):

    - 0x01 :meth:`read_coils`, 0x05 and 0x0F :meth:`write_coils` (limits
      :attr:`max_read_bits` / :attr:`max_write_bits`), 0x02 :meth:`read_discrete_inputs`
      (:attr:`max_read_bits`), 0x04 :meth:`read_input_registers` (:attr:`max_read`);
    - 0x16 (mask write) :meth:`read_holding` of the one register, then
      :meth:`write_holding` of ``(current AND and_mask) OR (or_mask AND NOT and_mask)``;
    - 0x17 (read/write multiple) :meth:`write_holding`, then :meth:`read_holding`, as the
      spec orders them (limits :attr:`max_write`, at most 121, and :attr:`max_read`);
    - 0x14 and 0x15 :meth:`read_file_record` / :meth:`write_file_record` (one call a
      group), 0x18 :meth:`read_fifo_queue`;
    - 0x0B and 0x0C read :attr:`comm_busy`, :attr:`comm_event_count`,
      :attr:`comm_message_count` and :attr:`comm_events`, which the unit keeps as the
      specification says (each request counted and logged once it is answered);
    - 0x07 reads :attr:`exception_status`, 0x11 :attr:`server_id`, :attr:`run_indicator`
      and :attr:`additional_data`; 0x08 (Diagnostics) is answered without asking the
      device: sub-function 0x0000 (return query data) echoes the request, 0x0004 (force
      listen only mode) is not answered and puts the unit in the listen only mode, where
      it takes and answers no request until 0x0001 (restart communications, data 0x0000
      or 0xFF00), which ends the mode unanswered (outside it, 0x0001 is echoed); other
      sub-functions answer exception 1.

    A request the Modbus Application Protocol V1.1b3 refuses is answered as it says before
    the device is asked: a quantity out of its range (coils and inputs 1..2000 a read,
    1..1968 a write; registers 1..125 a read, 1..121 a 0x17 write), a byte count that does
    not match, or a 0x05 value other than 0xFF00 / 0x0000 with exception 3; a block past
    address 0xFFFF with exception 2. A quantity within the spec's range but over the
    device's own limit answers :attr:`too_many_code`.
    """

    #: The function codes this unit answers (any other: exception 1, illegal function).
    #: Read once per request, before the unit handles it, so a subclass may make it a
    #: property.
    functions: frozenset[int] = BASIC_FUNCTIONS

    #: Most registers one read (0x03) may ask for. The protocol allows 125; a device
    #: simulator declares its manual's limit, so that a master which asks a real device for
    #: more than it takes fails against the simulator too. Checked by the simulator before
    #: :meth:`read_holding` is called (a direct call is not limited).
    max_read: int = 125

    #: Most registers one write (0x10) may carry: the protocol allows 123. As
    #: :attr:`max_read`.
    max_write: int = 123

    #: Most coils or discrete inputs one read (0x01, 0x02) may ask for: the protocol allows
    #: 2000. As :attr:`max_read`.
    max_read_bits: int = 2000

    #: Most coils one write (0x0F) may carry: the protocol allows 1968. As :attr:`max_read`.
    max_write_bits: int = 1968

    #: The exception code answered to a request over :attr:`max_read` / :attr:`max_write`
    #: (and :attr:`max_read_bits` / :attr:`max_write_bits`):
    #: 3 (illegal data value), as the Modbus specification gives for a quantity out of range.
    too_many_code: int = SimException.ILLEGAL_DATA_VALUE

    #: Read Device Identification (0x2B / MEI 0x0E) objects, ``{object id: text}``: 0 vendor
    #: name, 1 product code, 2 revision, 3 vendor URL, 4 product name, 5 model name,
    #: 6 user application name, 0x80..0xFF private. None: the function is not supported
    #: (answered with exception 1, illegal function).
    identity: dict[int, str] | None = None

    #: The eight bits answered to Read Exception Status (0x07), 0..255: their meaning is the
    #: device's.
    exception_status: int = 0

    #: The server id of a Report Server ID (0x11) reply: one byte or more, their meaning the
    #: device's.
    server_id: bytes = b"\x00"

    #: The run indicator of a Report Server ID (0x11) reply: True ON (0xFF), False OFF (0x00).
    run_indicator: bool = True

    #: The additional data of a Report Server ID (0x11) reply, after the run indicator (the
    #: three fields take at most 251 bytes together).
    additional_data: bytes = b""

    #: The status word of Get Comm Event Counter (0x0B) and Get Comm Event Log (0x0C): True
    #: answers 0xFFFF (a program command still being processed), False 0x0000.
    comm_busy: bool = False

    #: The event counter of 0x0B and 0x0C, 0..0xFFFF: the requests the unit answered
    #: without an exception since the start or a restart of communications (0x08 / 0x0001),
    #: Get Comm Event Counter's own not counted. The unit counts, once each request is
    #: answered; a test may set it (to a device's count under study) between requests.
    comm_event_count: int = 0

    #: The message counter of Get Comm Event Log (0x0C), 0..0xFFFF: every request the unit
    #: took, broadcasts and those of the listen only mode included, since the start or a
    #: restart of communications. Counted and settable as :attr:`comm_event_count`.
    comm_message_count: int = 0

    #: The events of Get Comm Event Log (0x0C), one byte each, the newest first, at most 64:
    #: for each request a receive event (0x80; + 0x40 a broadcast, + 0x20 in the listen only
    #: mode), then once answered a send event (0x40; + 0x01 for exception 1..3, 0x02 for 4,
    #: 0x04 for 5 or 6, 0x08 for 7); 0x00 a restart of communications (0xFF00 clears the log
    #: first), 0x04 the listen only mode entered (after its request's receive event).
    #: Logged and settable as :attr:`comm_event_count`.
    comm_events: bytes = b""

    #: Whether this unit answers a broadcast (unit 0) as if it had been addressed itself, with
    #: its own unit address in the reply. Standard Modbus units act on a broadcast silently;
    #: the PBL manual says its drives answer.
    answers_broadcast: bool = False

    #: Whether this unit's replies to writes (0x05, 0x06, 0x0F, 0x10, 0x16) go on the line.
    #: When False the unit still acts on each write (and the request is logged) but its
    #: reply, normal or exception, is dropped, as a BLD drive does with F08.06 = 1 (the
    #: library's side of it is ``Drive(write_ack=False)``); a 0x17 read/write is answered.
    #: Read once per request, before the unit handles it, so a subclass may make it a
    #: property.
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

    def read_coils(self, address: int, count: int) -> list[bool]:
        """States of the ``count`` coils from ``address`` (function 0x01).

        Raise :class:`SimException` to answer with an exception reply instead.
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def write_coils(self, address: int, values: list[bool]) -> None:
        """Set the coils from ``address`` to ``values`` (0x05 gives one value, 0x0F several).

        Raise :class:`SimException` to answer with an exception reply instead (then nothing
        should have been written).
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def read_discrete_inputs(self, address: int, count: int) -> list[bool]:
        """States of the ``count`` discrete inputs from ``address`` (function 0x02).

        Raise :class:`SimException` to answer with an exception reply instead.
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def read_input_registers(self, address: int, count: int) -> list[int]:
        """Values of the ``count`` input registers from ``address`` (0x04; each 0..0xFFFF).

        Raise :class:`SimException` to answer with an exception reply instead.
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def read_file_record(self, file: int, record: int, length: int) -> list[int]:
        """The ``length`` registers from record ``record`` of file ``file`` (0x14; the
        request's ranges are checked before: file 1..0xFFFF, records within 0..9999).

        Raise :class:`SimException` to answer with an exception reply instead.
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def write_file_record(self, file: int, record: int, values: list[int]) -> None:
        """Write ``values`` from record ``record`` of file ``file`` (0x15, one call a group).

        Raise :class:`SimException` to answer with an exception reply instead.
        """
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)

    def read_fifo_queue(self, address: int) -> list[int]:
        """The values queued in the FIFO whose count register is at ``address`` (0x18),
        oldest first; more than 31 answers exception 3, as the specification says.

        Raise :class:`SimException` to answer with an exception reply instead.
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
        """Run the model on ``clock`` (seconds) from now; makes ``self._lock`` (an RLock)
        unless the device has one (a :class:`TableDevice`'s, which its checks take too)."""
        if not callable(clock):
            raise TypeError("clock must be a callable returning seconds")
        self._clock = clock
        self._clock_start = float(clock())
        self._offset = 0.0
        if not hasattr(self, "_lock"):
            self._lock = threading.RLock()

    def _now(self) -> float:
        """Model seconds since the start: the clock's, times :attr:`speedup`, plus advances."""
        return (float(self._clock()) - self._clock_start) * self.speedup + self._offset

    def _update(self) -> None:
        """Bring the model up to :meth:`_now` (called with ``self._lock`` held)."""
        raise NotImplementedError

    @contextlib.contextmanager
    def _up_to_now(self) -> Iterator[None]:
        """Hold the model's lock, the model brought up to :meth:`_now`."""
        with self._lock:
            self._update()
            yield

    def advance(self, seconds: float) -> None:
        """Move the model's time forward by ``seconds`` (model seconds) on top of its clock."""
        if not seconds >= 0:
            raise ValueError(f"seconds must be >= 0, not {seconds}")
        with self._up_to_now():
            self._offset += seconds
            self._update()


@dataclasses.dataclass(frozen=True)
class Row:
    """One holding register of a unit's table, as its manual gives it: ``access`` holds
    ``"r"`` if a read may take it and ``"w"`` if a write may (``"rw-stopped"``: not while
    :meth:`TableDevice._turning`); a written word is ``low..high`` (two's complement when
    ``signed``); ``default`` is the word kept at power-up, None for a register the model
    computes (:meth:`TableDevice._live`)."""

    access: str = "rw"
    low: int = 0
    high: int = 0xFFFF
    default: int | None = 0
    signed: bool = False


class TableDevice(SimDevice):
    """A unit whose holding registers are :class:`Row` s by address: it keeps their words
    and answers their reads and writes with one set of checks, its family's model coming
    in through the hooks (the methods below ``_row``).

    A read (0x03): exception 2 for an address past 0xFFFF, without a row (but see
    :attr:`_read_gaps`) or whose row lacks ``"r"``. A write (0x06, 0x10), all or nothing:
    its words are ints 0..0xFFFF (else TypeError / ValueError); under the lock
    :meth:`_arrive`; exception 2 for an address past 0xFFFF or without a row, then
    :attr:`_readonly_code` for a row without ``"w"``; for each word :meth:`_refuse`,
    exception 3 outside the row's range and :attr:`_turning_code` for ``"rw-stopped"``
    while :meth:`_turning`; then :meth:`_store`, in address order.
    """

    #: Answered to a write of a row without ``"w"``; None: taken, and the row unchanged.
    _readonly_code: int | None = SimException.ILLEGAL_DATA_ADDRESS
    #: Answered to a write of a ``"rw-stopped"`` row while :meth:`_turning`.
    _turning_code: int = SimException.ILLEGAL_DATA_VALUE
    #: The addresses without a row a read answers 0 for: "none", "all" or "inside" (not
    #: the read's first or last).
    _read_gaps: str = "none"
    #: Whether a write checks and stores each register before it looks at the next (and
    #: puts back what :meth:`_save` kept on a refusal), or checks them all first.
    _writes_in_turn: bool = False

    def __init__(self, rows: Mapping[int, Row]) -> None:
        """Serve ``rows`` (``{address: row}``), each kept word at its default."""
        self._rows = dict(rows)
        self._words = {a: row.default for a, row in self._rows.items() if row.default is not None}
        self._lock = threading.RLock()

    def read_holding(self, address: int, count: int) -> list[int]:
        """The words of the registers ``address .. address + count - 1`` as the unit's
        table and model give them now; exception 2 where the table serves no read."""
        with self._lock:
            self._arrive(write=False)
            return self._read_words(address, count)

    def write_holding(self, address: int, values: list[int]) -> None:
        """Store ``values`` from ``address`` if the unit's table and rules take them all;
        else raise the exception it answers and store nothing."""
        for value in values:
            _check_value(value)
        with self._lock:
            self._arrive(write=True)
            if self._writes_in_turn:
                steps = [(address + i, [value]) for i, value in enumerate(values)]
            else:
                steps = [(address, values)]
            saved = self._save()
            try:
                for start, words in steps:
                    rows = self._writable(self._row, start, len(words))
                    taken = [
                        (a, row, value)
                        for a, row, value in zip(range(start, start + len(words)), rows, words)
                        if "w" in row.access  # else read-only, taken and left as it is
                    ]
                    for a, row, value in taken:
                        self._check_word(a, row, value)
                    for a, _, value in taken:
                        self._store(a, value)
            except BaseException:
                self._restore(saved)
                raise

    def _read_words(self, address: int, count: int) -> list[int]:
        """The words a read of ``count`` from ``address`` answers (no request arrives)."""
        return [
            0 if row is None else self._words[a] if row.default is not None else self._live(a)
            for a, row in self._readable(self._row, address, count)
        ]

    def _readable(
        self, row: Callable[[int], Row | None], address: int, count: int
    ) -> list[tuple[int, Row | None]]:
        """Each address a read takes with its ``row`` (None: a gap, read as 0)."""
        _check_block(address, count)
        taken: list[tuple[int, Row | None]] = []
        for a in range(address, address + count):
            found = row(a)
            gap = found is None and (
                self._read_gaps == "all"
                or (self._read_gaps == "inside" and address < a < address + count - 1)
            )
            if not gap and (found is None or "r" not in found.access):
                raise SimException(SimException.ILLEGAL_DATA_ADDRESS)
            taken.append((a, found))
        return taken

    def _writable(self, row: Callable[[int], Row | None], address: int, count: int) -> list[Row]:
        """The rows a write takes, if it may take them all."""
        _check_block(address, count)
        rows = [row(a) for a in range(address, address + count)]
        found = [r for r in rows if r is not None]
        if len(found) < count:
            raise SimException(SimException.ILLEGAL_DATA_ADDRESS)
        if self._readonly_code is not None and any("w" not in r.access for r in found):
            raise SimException(self._readonly_code)
        return found

    def _check_word(self, address: int, row: Row, value: int) -> None:
        self._refuse(address, value)
        word = value - 0x10000 if row.signed and value & 0x8000 else value
        if not row.low <= word <= row.high:
            raise SimException(SimException.ILLEGAL_DATA_VALUE)
        if row.access == "rw-stopped" and self._turning():
            raise SimException(self._turning_code)

    def _row(self, address: int) -> Row | None:
        """The row at ``address`` (None: none)."""
        return self._rows.get(address)

    def _arrive(self, write: bool) -> None:
        """A request reaches the unit, before any check: pacing, the model up to now."""
        self._update()

    def _update(self) -> None:
        """Bring the model up to now."""

    def _live(self, address: int) -> int:
        """The word of a row without a default."""
        raise NotImplementedError

    def _refuse(self, address: int, value: int) -> None:
        """Raise :class:`SimException` to refuse ``value`` before its range is checked."""

    def _turning(self) -> bool:
        """Whether ``"rw-stopped"`` rows refuse writes now."""
        return False

    def _store(self, address: int, value: int) -> None:
        """Take a checked word: keep it, or act on it (a command); may refuse it by raising
        :class:`SimException` before it changes anything."""
        self._words[address] = value

    def _save(self) -> object:
        """What :meth:`_restore` puts back if a write is refused after a :meth:`_store`
        (a write in turn, or a :meth:`_store` that refuses after an earlier one of the
        same write took its word): a family whose ``_store`` can refuse keeps here what it
        changes. None by default: every check but ``_store``'s comes before any store."""
        return None

    def _restore(self, saved: object) -> None:
        """Put back what :meth:`_save` kept."""


class RegisterDevice(TableDevice):
    """A plain Modbus unit: 65536 each of holding registers, input registers, coils and
    discrete inputs, all 0 (False) unless given, and every public function of
    :data:`STANDARD_FUNCTIONS`.

    The tables are lists a test reads and sets directly: :attr:`registers` (holding,
    ``dev.registers[0x2000] = 5``), :attr:`input_registers`, :attr:`coils`
    (``dev.coils[20] = True``) and :attr:`discrete_inputs`; ``Simulator.peek`` reads them
    through the device. Requests for more than ``max_read`` (0x03, 0x04, the read of 0x17)
    or ``max_write`` (0x06 / 0x10, the write of 0x17) registers, or more than
    ``max_read_bits`` (0x01, 0x02) or ``max_write_bits`` (0x0F) bits, answer exception 3
    (illegal data value, see :attr:`SimDevice.max_read`), requests past address 0xFFFF
    exception 2 (illegal data address), and a write (0x06, 0x10, 0x16, 0x17) touching a
    holding register in ``readonly`` answers :attr:`readonly_code` (2, illegal data
    address, unless a subclass changes it) and writes nothing. Read Exception Status (0x07)
    answers :attr:`SimDevice.exception_status` and Report Server ID (0x11)
    :attr:`SimDevice.server_id`, :attr:`SimDevice.run_indicator` and
    :attr:`SimDevice.additional_data`, which may be set at any time.
    """

    #: The function codes a register device answers: every standard one.
    functions = STANDARD_FUNCTIONS

    #: Exception code answered to a write that touches a read-only register.
    readonly_code: int = SimException.ILLEGAL_DATA_ADDRESS

    @property
    def _readonly_code(self) -> int:  # type: ignore[override]
        return self.readonly_code

    def __init__(
        self,
        registers: Mapping[int, int] | None = None,
        *,
        input_registers: Mapping[int, int] | None = None,
        coils: Mapping[int, bool] | Iterable[int] | None = None,
        discrete_inputs: Mapping[int, bool] | Iterable[int] | None = None,
        identity: Mapping[int, str] | None = None,
        max_read: int | None = None,
        max_write: int | None = None,
        max_read_bits: int | None = None,
        max_write_bits: int | None = None,
        readonly: Iterable[int] = (),
    ) -> None:
        """Holding and input registers from ``{address: value}``, coils and discrete inputs
        from ``{address: bool}`` (or the addresses that are on); the others are 0 (False).

        ``max_read`` is at most 125, ``max_write`` at most 123, ``max_read_bits`` at most
        2000 and ``max_write_bits`` at most 1968 (the protocol's limits); None keeps the
        class's (:attr:`SimDevice.max_read`, which a subclass may declare).
        """
        for name, value, top in (
            ("max_read", max_read, 125),
            ("max_write", max_write, 123),
            ("max_read_bits", max_read_bits, 2000),
            ("max_write_bits", max_write_bits, 1968),
        ):
            if value is not None:
                if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
                    raise ValueError(f"{name} must be 1..{top}, not {value!r}")
                setattr(self, name, value)
        #: The holding registers (0x03, 0x06, 0x10, 0x16, 0x17): 65536 ints 0..0xFFFF.
        self.registers: list[int] = _words(registers)
        #: The input registers (0x04): 65536 ints 0..0xFFFF.
        self.input_registers: list[int] = _words(input_registers)
        #: The coils (0x01, 0x05, 0x0F): 65536 bools.
        self.coils: list[bool] = _bits(coils)
        #: The discrete inputs (0x02): 65536 bools.
        self.discrete_inputs: list[bool] = _bits(discrete_inputs)
        #: The identification objects (0x2B / 0x0E) by object id, or None: not answered.
        self.identity = dict(identity) if identity is not None else None
        #: The files of Read / Write File Record (0x14, 0x15) by file number: 10000
        #: registers each (records 0..9999), all 0 until written; a file is made when first
        #: read or written (``dev.files[4][1] = 0x0DFE``).
        self.files: collections.defaultdict[int, list[int]] = collections.defaultdict(
            lambda: [0] * FILE_RECORDS
        )
        #: The holding registers a write to answers :attr:`readonly_code`.
        self.readonly: set[int] = set(readonly)
        for address in self.readonly:
            _check_address(address)
        super().__init__({})

    def _row(self, address: int) -> Row | None:
        """Every register is a row: read-only if in :attr:`readonly`, the words in
        :attr:`registers`."""
        return _READ_ONLY if address in self.readonly else _READ_WRITE

    def _rows_of(self, table: str) -> Callable[[int], Row | None]:
        """The rows of ``table`` ("holding", "input", "coil" or "discrete")."""
        return self._row if table == "holding" else _any_address

    def _live(self, address: int) -> int:
        return self.registers[address]

    def _store(self, address: int, value: int) -> None:
        self.registers[address] = value

    def read_input_registers(self, address: int, count: int) -> list[int]:
        """The input registers ``address .. address + count - 1`` from
        :attr:`input_registers`."""
        self._readable(self._rows_of("input"), address, count)
        return _block(self.input_registers, address, count)

    def read_coils(self, address: int, count: int) -> list[bool]:
        """The coils ``address .. address + count - 1`` from :attr:`coils`."""
        self._readable(self._rows_of("coil"), address, count)
        return _block(self.coils, address, count)

    def write_coils(self, address: int, values: list[bool]) -> None:
        """Set the coils from ``address`` to ``values``, all or nothing."""
        self._writable(self._rows_of("coil"), address, len(values))
        self.coils[address : address + len(values)] = [bool(v) for v in values]

    def read_discrete_inputs(self, address: int, count: int) -> list[bool]:
        """The discrete inputs ``address .. address + count - 1`` from
        :attr:`discrete_inputs`."""
        self._readable(self._rows_of("discrete"), address, count)
        return _block(self.discrete_inputs, address, count)

    def read_file_record(self, file: int, record: int, length: int) -> list[int]:
        """The records ``record .. record + length - 1`` of :attr:`files` ``[file]``."""
        return _block(self.files[file], record, length)

    def write_file_record(self, file: int, record: int, values: list[int]) -> None:
        """Store ``values`` from record ``record`` of :attr:`files` ``[file]``."""
        _block(self.files[file], record, len(values))
        for value in values:
            _check_value(value)
        self.files[file][record : record + len(values)] = values

    def read_fifo_queue(self, address: int) -> list[int]:
        """The FIFO kept in the holding registers: its count in register ``address``, the
        values queued in the registers after it (read, not cleared, as the specification
        has it)."""
        (count,) = _block(self.registers, address, 1)
        return _block(self.registers, address + 1, count)

    def __repr__(self) -> str:
        """Class name and the registers that are not 0."""
        nonzero = {a: v for a, v in enumerate(self.registers) if v}
        shown = ", ".join(f"{a:#06x}: {v}" for a, v in list(nonzero.items())[:8])
        more = ", ..." if len(nonzero) > 8 else ""
        return f"{type(self).__name__}({{{shown}{more}}})"


#: :class:`RegisterDevice`'s rows: its words are in its lists, not kept by the table.
_READ_WRITE = Row(default=None)
_READ_ONLY = Row("r", default=None)


def _any_address(address: int) -> Row:
    return _READ_WRITE


_T = TypeVar("_T")


def _block(table: list[_T], address: int, count: int) -> list[_T]:
    """``table[address : address + count]``; exception 2 if it runs past the table."""
    _check_block(address, count, len(table))
    return table[address : address + count]


def _check_block(address: int, count: int, size: int = _REGISTER_SPACE) -> None:
    """Exception 2 if ``count`` entries from ``address`` run past a table of ``size``."""
    if not 0 <= address <= size - count:
        raise SimException(SimException.ILLEGAL_DATA_ADDRESS)


def _words(given: Mapping[int, int] | None) -> list[int]:
    table = [0] * _REGISTER_SPACE
    for address, value in (given or {}).items():
        _check_address(address)
        _check_value(value)
        table[address] = value
    return table


def _bits(given: Mapping[int, bool] | Iterable[int] | None) -> list[bool]:
    table = [False] * _REGISTER_SPACE
    items = given.items() if isinstance(given, Mapping) else ((a, True) for a in given or ())
    for address, value in items:
        _check_address(address)
        if not isinstance(value, bool):
            raise TypeError(f"a coil or input is True or False, not {value!r}")
        table[address] = value
    return table


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
