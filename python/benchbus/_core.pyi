"""Type stubs for the compiled core (``benchbus._core``)."""

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from types import TracebackType
from typing import Any, Literal

from typing_extensions import Self, disjoint_base, final

from benchbus._drive import DriveRegister, DriveStatus, DriveTelemetry, Model
from benchbus._instrument import Identification
from benchbus._j2 import J2Parameter, J2Status, Limits, Pid
from benchbus._pbl import Direction, PblParameter, PblStatus, PblTelemetry
from benchbus._profile import ProfileLimits, ProfileLine, ProfileRegister
from benchbus._results import CommEventCounter, CommEventLog

#: Which register (word order) or which byte of a register (byte order) of a multi-register
#: value comes first: "big" the most significant (the Modbus convention), "little" the least;
#: the aliases of an ``order`` (``_Layout``) the Instrument's value methods accept.
_Order = Literal["big", "little"]
#: The function a register read uses: 3 (holding registers) or 4 (input registers).
_Read = Literal[3, 4]

__all__ = [
    "Bus",
    "CancelToken",
    "DriveCore",
    "InstrumentCore",
    "J2Core",
    "PblCore",
    "Poll",
    "Profile",
    "ProfileCore",
    "Stats",
    "_Station",
    "_Ticks",
    "__version__",
    "_did_you_mean",
    "_endpoint_kind",
    "_panic_on_wire",
    "_request_rules",
    "crc16",
    "diagnose",
    "from_registers",
    "list_ports",
    "refresh_logging",
    "to_registers",
]

__version__: str

def crc16(data: bytes) -> int:
    """CRC-16/MODBUS of ``data`` (sent low byte first on the wire)."""

#: What one value over registers is: its width and kind.
_Type = Literal["u16", "i16", "u32", "i32", "u64", "i64", "f32", "f64"]
#: How a value lies over registers: where its bytes A (most significant) to D land.
_Layout = Literal["ABCD", "CDAB", "BADC", "DCBA"]

def from_registers(
    registers: Iterable[int], type: _Type = "u16", order: _Layout = "ABCD"
) -> list[int | float]:
    """The values ``registers`` hold, each of ``type`` ("u16" unless given: "i16", "u32",
    "i32", "u64", "i64", "f32", "f64") over as many registers as it takes, laid out as
    ``order`` ("ABCD" unless given: "CDAB", "BADC", "DCBA"; see ``Instrument.read_long``)."""

def to_registers(
    values: float | Iterable[float], type: _Type = "u16", order: _Layout = "ABCD"
) -> list[int]:
    """The registers that hold ``values`` (one number, or a sequence of them), each of
    ``type`` laid out as ``order`` (as :func:`from_registers` reads them); a value that does
    not fit its type raises ValueError."""

def list_ports(
    sysfs_root: str | os.PathLike[str] | None = None,
) -> list[dict[str, str | int | None]]:
    """The serial ports of this system, sorted by path: a dict for each with ``path``,
    ``driver``, and for a USB adapter ``vid``, ``pid``, ``manufacturer``, ``product``,
    ``serial_number`` and ``chip`` (FTDI, CH340, CP210x, PL2303...; None where the system
    does not say). ``sysfs_root`` reads another sysfs tree than ``/sys`` (Linux only)."""

def diagnose(
    port: str | os.PathLike[str],
    baudrate: int = 19200,
    parity: str = "N",
    stopbits: int = 1,
    unit: int = 1,
    timeout: float = 0.1,
    sysfs_root: str | os.PathLike[str] | None = None,
    proc_root: str | os.PathLike[str] | None = None,
) -> list[tuple[str, str, str, str | None]]:
    """The check-up of the serial port ``port``: ``(name, verdict, message, fix)`` for each
    finding (see :func:`benchbus.doctor`, which returns them as :class:`benchbus.Finding`).
    The port is opened at the line format given, and ``unit`` is sent one read of holding
    register 0 to see whether it comes back within ``timeout`` seconds. ``sysfs_root`` and
    ``proc_root`` read other trees than ``/sys`` and ``/proc`` (Linux). ValueError for a
    network port."""

def refresh_logging() -> None:
    """Re-read the Python logging levels (cached for speed; a Bus reads them when it opens)."""

def _did_you_mean(name: str, known: list[str]) -> str:
    """``; did you mean 'a' or 'b'?`` naming the closest of ``known`` to ``name``, or ""."""

def _endpoint_kind(port: str) -> str:
    """What ``port`` reaches, read as a Bus reads it: "serial", "tcp" (Modbus TCP) or
    "rtu+tcp"; ValueError for a port string a Bus refuses."""

def _request_rules(function: int, data: bytes) -> tuple[tuple[int, str] | None, int | None, bool]:
    """What a server needs to forward the request PDU ``function`` / ``data``, by the core's
    rules (the gateway's): ``(refusal, reply_length, write)``. ``refusal`` is None for a
    well-formed request, else ``(exception code, why)``: 0x01 for a function code no
    request has (0, 0x80 and up), 0x03 for a wrong length or byte count, or a count past
    the specification's limits; ``reply_length`` is the reply's bytes after its function
    code where the request tells them, None where the reply carries its own length or ends
    when the line falls quiet; ``write`` whether it is paced as a write (all but the
    reads)."""

def _panic_on_wire() -> None:
    """Panic on the path every wire call takes; raises BenchbusError (a test hook)."""

@final
class Stats:
    """Counters of what happened on a Bus since it was opened."""

    @property
    def transactions(self) -> int:
        """Requests completed with a reply (normal or exception) or sent as a broadcast."""
    @property
    def retries(self) -> int:
        """Attempts repeated after a timeout or a corrupt frame."""
    @property
    def timeouts(self) -> int:
        """Attempts that got no complete reply in time."""
    @property
    def crc_errors(self) -> int:
        """Replies with a bad CRC (in Modbus ASCII, a bad LRC)."""
    @property
    def frame_errors(self) -> int:
        """Other malformed replies (wrong unit, function, length or echo)."""
    @property
    def exceptions(self) -> int:
        """Exception replies."""
    @property
    def stale_bytes(self) -> int:
        """Stale bytes dropped from the input before a request."""
    @property
    def broadcasts(self) -> int:
        """Broadcast requests sent."""
    @property
    def reopens(self) -> int:
        """Times the port was opened again (:meth:`Bus.reopen`, or a reconnect)."""
    @property
    def resyncs(self) -> int:
        """Times the line was found out of step and brought back: a frame that came too
        soon after a request to answer it (a copy of an earlier reply, an earlier request's
        answer) was dropped, or bytes nobody expected were waiting before a request."""
    def as_dict(self) -> dict[str, int]:
        """The counters as a dict."""

@final
class CancelToken:
    """Cancels the calls made inside its ``with`` block, from any thread.

    ``with token: bus.read_holding_registers(...)``: the calls this thread makes inside the
    block (on a Bus, or on a device, which calls its Bus) honour the token. ``token.cancel()``
    (from any thread) then stops them: a call waiting for its turn on the line leaves the
    queue without sending anything; an attempt in flight finishes (its reply is read or its
    timeout runs out, so the line stays in step) and the call starts no further attempt or
    request. Either way it raises :class:`benchbus.Cancelled`; an attempt that ends the call
    (a reply, an exception reply) stands, and its result is returned. A cancelled token
    stays cancelled: every call in its block raises at once.
    """

    def __init__(self) -> None: ...
    def cancel(self) -> None:
        """Cancels the calls made under this token, now and later; any thread may call it."""

    @property
    def cancelled(self) -> bool:
        """Whether :meth:`cancel` was called."""

    @property
    def queued(self) -> bool:
        """Whether a call made under this token has taken its place in a Bus's queue for the
        line (its first turn asked for; a write waiting for the earlier writes to its unit,
        its place among them)."""
    def __enter__(self) -> Self: ...
    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool: ...

@final
class Bus:
    """A Modbus RTU (or ASCII: ``framing="ascii"``) master on one serial line, or through a
    TCP gateway to one.

    The port string picks the transport:

    - a serial port path (``/dev/ttyUSB0``): Modbus RTU on the line;
    - ``tcp://HOST[:PORT]`` (port 502 by default): Modbus TCP to a gateway (mbusd, an
      industrial RS485 converter), which does the serial timing itself;
    - ``rtu+tcp://HOST:PORT``: RTU frames, CRC included, over a TCP socket to a serial device
      server (ser2net); give the baudrate and format of its serial side.

    HOST is a DNS name, an IPv4 address or a bracketed IPv6 address (``[::1]``). The same
    calls, devices, retries and errors work on all three; a connection the peer closes is a
    lost port, brought back by :meth:`reopen` or ``reconnect=True`` (which connect again).

    One transaction at a time: threads sharing a Bus wait their turn, and the GIL is released
    while a call waits for the wire. Before each request the line is kept silent for t3.5
    (serial and ``rtu+tcp`` only); replies are read by their expected length; a timeout or a
    corrupt reply is retried up to ``retries`` times, an exception reply never is.

    A serial port is opened exclusively (``TIOCEXCL`` and an exclusive ``flock``): a port
    another Bus holds, in this process or another, raises PortError ("in use by another Bus
    or program"), as does one held by any program that locks it too (pyserial with
    ``exclusive=True``). While a Bus holds a port, other programs cannot open it unless they
    run as root. (Network ports are not held: a gateway may serve several masters.)

    A port that vanishes (a USB adapter unplugged, a pseudo-terminal whose other end closed)
    raises PortError at once, from the call that finds it gone, never after a timeout. The
    Bus then drops the port (releasing it, so a replugged adapter can get its old name back)
    and later calls raise PortError at once, until :meth:`reopen` succeeds; with
    ``reconnect=True`` each call tries that itself first. Device objects on the Bus carry on
    after a reopen without being rebuilt. Open a port by a name that comes back when the
    adapter does (``/dev/serial/by-id/...``) for that to work.

    A Bus belongs to the process that opened it. In a child made by ``fork()``
    (``multiprocessing``'s fork start method, a forking server) every call, :attr:`stats`
    and :meth:`reopen` raise PortError at once, naming fork and what to do, and send
    nothing; :meth:`close` and garbage collection there send nothing, raise nothing and
    leave the parent's port as it was. Open a new Bus in the child once the parent has
    closed its own, start children with the ``spawn`` or ``forkserver`` method, or serve
    the line through a :class:`benchbus.Gateway`.
    """

    def __new__(
        cls,
        port: str | os.PathLike[str],
        baudrate: int = 19200,
        parity: str = "N",
        stopbits: int = 1,
        timeout: float = 0.1,
        retries: int = 2,
        *,
        turnaround: float = 0.1,
        reconnect: bool = False,
        echo: bool = False,
        rs485: bool = False,
        rts_delay: Sequence[float] | None = None,
        silence: float = 0.0,
        framing: str = "rtu",
        bytesize: int | None = None,
    ) -> Self:
        """Open ``port`` (``/dev/ttyUSB0``, ``tcp://HOST[:PORT]`` or ``rtu+tcp://HOST:PORT``)
        at the given line format (the serial line's; unused by ``tcp://``).

        ``timeout`` is per attempt, in seconds, counted from the start of the request as in
        other Modbus masters (a request longer than half of it on the wire still leaves the
        device half of it after the request's end); a reply's own time on the wire comes on
        top. Over TCP it counts from the request's sending and covers the network's delay.
        ``turnaround`` is the quiet time after a broadcast. Raises PortError if the port
        cannot be opened (absent, or in use by another Bus or program) or the connection
        made (refused, or no answer within 3 s),
        ValueError for a malformed ``scheme://`` port or other bad arguments, TypeError for
        arguments of the wrong type.

        ``reconnect=True``: a call that finds the port lost first reopens the path (as
        :meth:`reopen` does) and goes on, once per call, with no waiting and no loop. If the
        path is still absent the call raises PortError saying it tried. The call during
        which the port vanishes raises PortError (whether its request reached the device is
        unknown), unless nothing of it had been sent yet: then it reopens and goes on. A
        closed Bus is never reopened by this.

        ``echo=True`` is for an adapter that echoes what it sends (its receiver stays on
        while it transmits): each request's echo is read back (within ``timeout`` after the
        request's end) and checked before the reply is awaited. An echo that differs or
        breaks off (a collision on the line) raises FrameError and is retried like a
        corrupt reply (a broadcast is not repeated). Until a first echo has come back, no
        echo at all, or the device's reply in its place, raises PortError: the adapter does
        not echo (a single-register write then times out instead, its reply being the
        request's own bytes). Without ``echo``, a reply that begins with the request itself
        raises FrameError saying to open the Bus with ``echo=True``. Refused (ValueError)
        on ``tcp://``, where the gateway keeps the line.

        ``rs485=True`` is for a board UART wired to an RS485 transceiver (a Raspberry Pi
        HAT, an industrial PC's port): the port is opened in the Linux kernel's RS485 mode
        (``TIOCSRS485``: RTS drives the transceiver, high while sending), with
        ``rts_delay=(before, after)`` seconds between RTS and the first bit and after the
        last (each 0 to 0.1, whole milliseconds; default no delay). The mode is set at every
        open and stays on after the port closes, as the kernel keeps it. A port without the
        mode (a USB adapter, which switches direction by itself; a pseudo-terminal) raises
        PortError and is left closed. ValueError before anything is opened: ``rts_delay``
        without ``rs485=True``, a negative or too long delay, ``rs485`` on a network port or
        on a system other than Linux.

        On Linux every serial port is also asked for its driver's low-latency mode (an FTDI
        adapter then uses a 1 ms latency timer); a port without it opens as before
        (:func:`benchbus.doctor` reports which).

        ``silence`` (seconds, default 0: t3.5) is the quiet gap that ends the reply of a raw
        :meth:`request` without ``reply_length``, when longer than t3.5: raise it for an
        adapter that delivers replies in bursts (an FTDI chip's 16 ms latency timer splits a
        reply into chunks). Every other reply is read by its length and never waits for it.

        ``framing="ascii"`` speaks Modbus ASCII on the line (``:``, the hex digits of unit,
        PDU and LRC, CR LF), for serial lines and ``rtu+tcp://`` (ValueError on ``tcp://``,
        which is Modbus TCP). Its line format is the serial line spec's 7E1 unless given:
        ``bytesize`` 7 (8 if asked), ``parity`` "E", and with ``parity="N"`` 2 stop bits
        (7N2; ``stopbits=1`` with 7 data bits and no parity, 7N1, is not allowed: ValueError).
        A reply ends at its CR LF, with up to 1 s between two of its characters; characters
        before its ``:`` are dropped (``stale_bytes``), a bad LRC is a CrcError. Every method
        works the same. ``bytesize`` is 8 for RTU (7: ValueError). On a pseudo-terminal,
        which carries 8 data bits and no parity, the port opens at 8N1 as for parity.
        """
    def read_holding_registers(self, unit: int, address: int, count: int) -> list[int]:
        """Read ``count`` (1..125) holding registers from ``address`` (function 0x03)."""
    def read_coils(self, unit: int, address: int, count: int) -> list[bool]:
        """Read ``count`` (1..2000) coils from ``address`` (function 0x01)."""
    def read_discrete_inputs(self, unit: int, address: int, count: int) -> list[bool]:
        """Read ``count`` (1..2000) discrete inputs from ``address`` (function 0x02)."""
    def read_input_registers(self, unit: int, address: int, count: int) -> list[int]:
        """Read ``count`` (1..125) input registers from ``address`` (function 0x04)."""
    def write_coil(self, unit: int, address: int, value: bool) -> None:
        """Set one coil on (True) or off (False) (function 0x05). The reply must echo the
        request (0xFF00 / 0x0000), else FrameError. ``value`` must be a bool (TypeError)."""
    def write_coils(self, unit: int, address: int, values: Iterable[bool]) -> None:
        """Set 1..1968 consecutive coils from ``address`` (function 0x0F), each a bool."""
    def mask_write_register(self, unit: int, address: int, and_mask: int, or_mask: int) -> None:
        """Change bits of one register (function 0x16): it becomes ``(value & and_mask) |
        (or_mask & ~and_mask)``. The reply must echo the request, else FrameError."""
    def read_write_registers(
        self,
        unit: int,
        read_address: int,
        read_count: int,
        write_address: int,
        values: Iterable[int],
    ) -> list[int]:
        """Write ``values`` (1..121) from ``write_address``, then read ``read_count``
        (1..125) registers from ``read_address``, in one transaction (function 0x17; the
        device writes first)."""
    def read_exception_status(self, unit: int) -> int:
        """The unit's eight exception status outputs (function 0x07), as an int 0..255.

        A serial line function in the specification: over ``tcp://`` it goes to the unit
        behind the gateway like any other; a gateway that does not forward it answers
        exception 1 (ModbusException). The same holds for :meth:`diagnostics` and
        :meth:`report_server_id`."""
    def diagnostics(
        self, unit: int, sub_function: int, data: bytes | bytearray = b"\x00\x00"
    ) -> bytes:
        """Run diagnostics sub-function ``sub_function`` with ``data`` (function 0x08) and
        return the reply's data after its sub-function.

        The reply must carry the same sub-function and, like every sub-function's, as many
        data bytes as the request; sub-function 0x00 (return query data) is a line test:
        the reply must echo the data exactly (else FrameError). Sub-function 0x04 (force
        listen only) gets no reply: it is sent once, not awaited, not retried, and returns
        ``b""``; the unit then answers nothing until restarted (sub-function 0x01)."""
    def report_server_id(self, unit: int) -> bytes:
        """The data field of the unit's Report Server ID reply (function 0x11), after its
        byte count, as the device sent it (its layout is the device's: typically an id, a
        run indicator 0x00 / 0xFF, then free text)."""
    def get_comm_event_counter(self, unit: int) -> CommEventCounter:
        """The unit's status word (0xFFFF busy with a program command, 0x0000 not) and
        event counter (function 0x0B), as ``CommEventCounter(status, event_count)``.

        A serial line function, sent over ``tcp://`` as :meth:`read_exception_status` is."""
    def get_comm_event_log(self, unit: int) -> CommEventLog:
        """The unit's status word, event counter, message counter and events (0 to 64
        bytes, the newest first) (function 0x0C), as ``CommEventLog(status, event_count,
        message_count, events)``.

        A serial line function, sent over ``tcp://`` as :meth:`read_exception_status` is."""
    def read_file_record(
        self, unit: int, groups: Iterable[tuple[int, int, int]]
    ) -> list[list[int]]:
        """Read file records (function 0x14): for each group ``(file, record, length)``,
        ``length`` registers (1 or more) from record ``record`` (0..0x270F) of file
        ``file`` (1..0xFFFF); one list of registers per group, in the groups' order.

        At least one group; the request (7 bytes a group) and the reply (2 bytes and the
        registers a group) must each fit the 253-byte PDU, and no group may run past record
        0x270F: else ValueError, and nothing is sent."""
    def write_file_record(
        self, unit: int, groups: Iterable[tuple[int, int, Iterable[int]]]
    ) -> None:
        """Write file records (function 0x15): for each group ``(file, record, values)``,
        ``values`` (1 or more) from record ``record`` (0..0x270F) of file ``file``
        (1..0xFFFF). The reply must echo the request (else FrameError).

        At least one group; the request (7 bytes and the values a group) must fit the
        253-byte PDU, and no group may run past record 0x270F: else ValueError, and nothing
        is sent."""
    def read_fifo_queue(self, unit: int, address: int) -> list[int]:
        """The values queued in the FIFO whose count register is at ``address``
        (0..0xFFFF) (function 0x18), oldest first: at most 31, as the specification
        bounds a FIFO (a reply that counts more is a FrameError)."""
    def request(
        self,
        unit: int,
        function: int,
        data: bytes | bytearray,
        *,
        reply_length: int | None = None,
        write_interval: float = 0.0,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> bytes:
        """Send a raw PDU: function ``function`` (1..127) and ``data`` (at most 252 bytes),
        and return the reply's bytes after its function code.

        With ``reply_length`` (the reply's bytes after the function code) the reply is read
        by that length, as every other function's is. Without it the reply ends when the
        line has been quiet for t3.5, or the Bus's ``silence`` if longer: the one slower
        path, for replies whose length is not known in advance. An exception reply
        (function | 0x80) is known at 5 bytes and raises ModbusException. Retries, stats,
        the wire log and errors are as for any function. ValueError for function 0 or 0x80
        and up (exception replies), or data too long, before anything is sent. A raw
        request may write, so it counts as a write to the unit: ``write_interval``,
        ``timeout`` and ``retries`` as for :meth:`write_register`."""
    def write_register(
        self,
        unit: int,
        address: int,
        value: int,
        *,
        accept_count_echo: bool = False,
        write_interval: float = 0.0,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """Write one register (function 0x06).

        With ``accept_count_echo``, a reply carrying a register count of 1 in place of the
        value (as PBL drives send) is accepted. ``write_interval`` (seconds, 0..60) is the
        least time the unit needs between two writes (a J2 controller: 0.15): the Bus waits
        it out since its last write to the unit, before a retry too, while other units' calls
        go on; a later broadcast waits for it as well. ``timeout`` and ``retries``, if given,
        replace the Bus's for this call only (a long flash write), checked as the
        constructor checks them.
        """
    def write_registers(
        self,
        unit: int,
        address: int,
        values: Iterable[int],
        *,
        write_interval: float = 0.0,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """Write 1..123 consecutive registers from ``address`` (function 0x10);
        ``write_interval``, ``timeout`` and ``retries`` as for :meth:`write_register`."""
    def read_device_identification(
        self, unit: int, read_code: int = 1, object_id: int = 0
    ) -> dict[int, str]:
        """Read device identification objects (0x2B / MEI 0x0E) as ``{object_id: text}``,
        one character per byte (Latin-1)."""
    def _device_identification(
        self, unit: int, read_code: int, object_id: int
    ) -> tuple[int, dict[int, bytes]]:
        """Internal (the gateway's): ``(conformity, {object_id: raw bytes})``, the
        conformity level the device sent and its objects undecoded. Use
        :meth:`read_device_identification`."""
    def _broadcast(
        self, function: int, data: bytes | bytearray, *, write_interval: float = 0.0
    ) -> None:
        """Internal (the gateway's): send the request PDU ``function`` / ``data`` to every
        unit (unit 0), if it is a write that can be broadcast (0x05, 0x06, 0x0F, 0x10,
        0x16), as a write to units that want ``write_interval`` (seconds) between writes:
        it waits that long after the last broadcast too. ValueError for any other request,
        or a malformed one, before anything is sent."""
    def broadcast_write_register(self, address: int, value: int) -> None:
        """Write one register on every unit (unit 0); waits no reply."""
    def broadcast_write_coil(self, address: int, value: bool) -> None:
        """Set one coil on every unit (unit 0, function 0x05); waits no reply."""
    def broadcast_write_coils(self, address: int, values: Iterable[bool]) -> None:
        """Set 1..1968 consecutive coils from ``address`` on every unit (unit 0, function
        0x0F); waits no reply."""
    def broadcast_write_registers(self, address: int, values: Iterable[int]) -> None:
        """Write 1..123 consecutive registers from ``address`` on every unit (unit 0,
        function 0x10); waits no reply."""
    def scan(
        self, units: Iterable[int] | None = None, timeout: float = 0.05, address: int = 0
    ) -> list[int]:
        """The units (default the standard 1..247) that answer a read of ``address`` within
        ``timeout``.

        ``timeout`` is each unit's whole window, counted from the start of its request (the
        request's own time on the wire included), so n absent units take about n x
        ``timeout``; a device always gets at least t3.5 after the request to answer.
        """
    def poll(
        self,
        unit: int,
        address: int,
        count: int = 1,
        *,
        interval: float,
        duration: float | None = None,
    ) -> Poll:
        """Read ``count`` (1..125) holding registers from ``address`` every ``interval``
        seconds (0 < interval <= 3600), for ``duration`` seconds or, with None, for ever::

            for t, (speed,) in bus.poll(1, 0x3006, interval=0.05, duration=10):
                print(f"{t:6.2f} s  {speed} rpm")
            # t is 0.0, 0.05, 0.1, ... on the poll's own clock

        The iterator yields ``(t, values)``: ``t`` is the sample's deadline in seconds from
        the start (``n * interval``), ``values`` what :meth:`read_holding_registers` returns.
        Deadlines are absolute (``start + n * interval`` on the monotonic clock), so time
        spent in the loop body does not accumulate as drift; a deadline already past when
        the next sample is asked for is skipped (counted in :attr:`Poll.missed`), not fired
        late in a burst. The poll starts at the first ``next()``, whose sample is due at
        once; with ``duration`` it stops before the first deadline at or after
        ``start + duration`` (``duration=0.3, interval=0.05`` gives 6 samples).

        Arguments are checked here, before anything is sent (ValueError / TypeError), and a
        closed bus raises PortError here. Each ``next()`` releases the GIL while it waits
        and reads; Ctrl-C interrupts a long wait within 100 ms. A failed read raises the
        usual exception (ResponseTimeout, ModbusException, ...) from ``next()``; the poll can
        be resumed with the following deadline.
        """
    @property
    def stats(self) -> Stats:
        """Counters of what happened on this bus."""
    def _owned(self) -> None:
        """Internal: PortError in a process other than the one that opened the bus (a
        child made by fork), saying what to do."""
    def close(self) -> None:
        """Close the port; further calls raise PortError. Closing twice is harmless.

        In a process other than the one that opened the bus (a child made by fork) it sends
        nothing, raises nothing and leaves the port to the parent."""
    @property
    def closed(self) -> bool:
        """True once the bus is closed (and not reopened since), and always in a process
        other than the one that opened it (a child made by fork)."""
    def reopen(self) -> None:
        """Close the port and open the same path again with the same line format.

        For a port that was lost and has come back (an adapter plugged in again), or to
        start afresh. :attr:`stats` carry on (``stats.reopens`` counts the reopens), and so
        do device objects holding this Bus. It also opens a closed Bus again. The GIL is
        released meanwhile; a call in progress on another thread finishes first.

        Raises PortError if the path cannot be opened (absent, or in use); the Bus is then
        left without a port (calls raise PortError at once) until a reopen succeeds.
        """
    @property
    def reconnect(self) -> bool:
        """Whether a call that finds the port lost reopens it first (see ``reconnect=``)."""
    @property
    def echo(self) -> bool:
        """Whether the adapter's local echo of each request is read back (see ``echo=``)."""
    @property
    def rs485(self) -> bool:
        """Whether the port was opened in the kernel's RS485 mode (see ``rs485=``)."""
    def __enter__(self) -> Self:
        """Return the bus itself."""
    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool:
        """Close the bus."""
    @property
    def port(self) -> str:
        """The port path."""
    @property
    def baudrate(self) -> int:
        """Bits per second."""
    @property
    def parity(self) -> str:
        """Parity letter: "N", "E" or "O"."""
    @property
    def stopbits(self) -> int:
        """Stop bits: 1 or 2."""
    @property
    def bytesize(self) -> int:
        """Data bits: 8, or 7 (Modbus ASCII's usual line format)."""
    @property
    def framing(self) -> str:
        """The framing on the line: "rtu", or "ascii" (Modbus ASCII)."""
    @property
    def timeout(self) -> float:
        """Reply timeout per attempt, in seconds. Settable (``bus.timeout = 5`` for a slow
        command): the calls that start from then on use it, a call in flight keeps its own; a
        bad value raises TypeError or ValueError, as in the constructor, and changes nothing."""
    @timeout.setter
    def timeout(self, value: float) -> None: ...
    @property
    def retries(self) -> int:
        """Further attempts after a timeout or a corrupt frame. Settable, like :attr:`timeout`."""
    @retries.setter
    def retries(self, value: int) -> None: ...
    @property
    def turnaround(self) -> float:
        """Quiet time after a broadcast, in seconds."""
    @property
    def silence(self) -> float:
        """The quiet gap, in seconds, that ends a raw :meth:`request`'s reply read without
        ``reply_length`` (see ``silence=``; t3.5 when that is longer)."""
    @property
    def char_time(self) -> float:
        """Time one character takes on the wire, in seconds."""
    @property
    def t3_5(self) -> float:
        """The silence between frames (t3.5), in seconds."""

@final
class Poll:
    """Reads of holding registers on absolute deadlines; made by :meth:`Bus.poll`.

    An iterator of ``(t, values)``: deadline ``n`` is ``start + n * interval`` on the
    monotonic clock, ``t`` is ``n * interval`` in seconds. The latency of a sample, as the
    caller sees it, is ``time.monotonic() - (poll.started + t)``.
    """

    def __iter__(self) -> Self:
        """Return the poll itself."""
    def __next__(self) -> tuple[float, list[int]]:
        """Sleep until the next deadline not yet past, read, and return ``(t, values)``.

        Raises StopIteration once the duration is over, and the usual benchbus exceptions
        if the read fails.
        """
    @property
    def missed(self) -> int:
        """Deadlines skipped because they had passed when the next sample was asked for."""
    @property
    def started(self) -> float | None:
        """``time.monotonic()`` at the poll's start (the first ``next()``); None before it.

        Python's ``time.monotonic()`` and the poll's deadlines read the same clock
        (CLOCK_MONOTONIC on Linux), so ``started + t`` is sample ``t``'s deadline on it.
        """

@final
class _Ticks:
    """Deadlines every ``interval`` seconds from the first ``next()`` (the Schedule of
    :meth:`Bus.poll`), for ``duration`` seconds or for ever; internal."""

    def __new__(
        cls,
        interval: float,
        duration: float | None = None,
        *,
        clock: Callable[[], float] | None = None,
        sleep: Callable[[float], object] | None = None,
    ) -> Self: ...
    def __iter__(self) -> Self: ...
    def __next__(self) -> tuple[int, float, int]:
        """Wait for the next deadline not yet past; ``(n, deadline, missed)``."""

@disjoint_base
class _Station:
    """The base of every compiled device class: the Bus the device talks through and its
    unit."""

    @property
    def bus(self) -> Bus:
        """The Bus the device talks through."""
    @property
    def unit(self) -> int:
        """The device's unit address."""
    def verify_identity(self) -> None:
        """Checks now, if not done yet, that the unit is of the device's family (what the
        device's first exchange does): ``WrongDevice`` if it answers as another family, a
        timeout if it does not answer (it is checked again on the next call). Nothing to
        check for a device made with ``check_identity=False`` or without an identity (an
        ``Instrument``, a profile's ``Device``)."""
    def _check_identity_with(self, check: Callable[[], object]) -> None: ...
    def __new__(cls, *args: Any, **kwargs: Any) -> Self:
        """An empty device of the subclass, attached to its Bus by ``__init__`` (so that a
        subclass's ``__init__`` may take its own arguments)."""

@disjoint_base
class DriveCore(_Station):
    """The compiled base of ``benchbus.Drive`` (use that): the register and command tables
    and every call to the drive.

    Every call that touches the wire releases the GIL. Values are in engineering units
    (scaled registers are floats); ranges are checked before anything is sent.
    """

    #: The names :meth:`sample` gives: the fields of :meth:`telemetry`.
    SAMPLE_FIELDS: tuple[str, ...] | None
    def _attach(
        self,
        bus: Bus,
        unit: int,
        family: str,
        write_ack: bool,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """Attaches the drive at ``unit`` (1..247) of ``family`` ("BLD" or "C20") to ``bus``
        (what ``Drive.__init__`` does); ``timeout`` / ``retries`` replace the Bus's."""
    @property
    def family(self) -> str:
        """ "BLD" (BLD2, BLD3H) or "C20"."""
    @property
    def write_ack(self) -> bool:
        """Whether writes are answered (False for a drive set to F08.06 = 1)."""
    @property
    def timeout(self) -> float:
        """Reply timeout of the drive's requests, in seconds (its own, or the Bus's)."""
    @property
    def retries(self) -> int:
        """Retries of the drive's requests (its own, or the Bus's)."""
    @property
    def block_reads(self) -> bool | None:
        """Whether the drive answers multi-register reads; None until one was tried."""
    def get(self, name: str) -> int | float:
        """Reads the register called ``name`` (see the table), in engineering units: an
        int, or a float for a scaled register; a member of its enum where the
        device's class names its values."""
    def set(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the register called ``name``, checked
        against its range, steps, access and the family's rules before anything is sent."""
    def get_many(self, names: Iterable[str]) -> dict[str, int | float]:
        """Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
        each as :meth:`get` gives it,
        in as few requests as the table's limits allow (neighbours share one)."""
    def set_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
        as :meth:`set` does. Every value is checked against its register (range, steps,
        access) before the first is sent; the family's rules are checked write by write,
        so a refusal there leaves the earlier writes done."""
    def forward(self) -> None:
        """Run forward at the speed setpoint (command 1)."""
    def reverse(self) -> None:
        """Run in reverse at the speed setpoint (command 2)."""
    def jog_forward(self) -> None:
        """Jog forward (command 3)."""
    def jog_reverse(self) -> None:
        """Jog in reverse (command 4)."""
    def stop(self) -> None:
        """Stop: decelerate, or as :attr:`stop_mode` says (command 5)."""
    def coast(self) -> None:
        """Free stop (emergency stop): cut the output and let the motor coast (command 6)."""
    def reset_fault(self) -> None:
        """Reset a fault (command 7)."""
    def jog_stop(self) -> None:
        """End a jog (command 8)."""
    def brake(self) -> None:
        """Brake stop, BLD only; ValueError on a C20 (command 9)."""
    @staticmethod
    def commands() -> list[tuple[str, int]]:
        """The command table: ``(name, code)`` of every value the command register 0x2000
        takes, in code order, the brake stop (BLD only) included; each is a method."""
    def status(self) -> DriveStatus:
        """Status words 1 and 2 and the fault code, read in one request where allowed."""
    def telemetry(self) -> DriveTelemetry:
        """All measurement registers in one snapshot (one request where the drive allows)."""
    def sample(self) -> dict[str, float]:
        """The numeric fields of :meth:`telemetry` as floats (one request where the drive
        allows); ``hall_count`` only where the drive has it."""
    @staticmethod
    def model_from_id(family: str, id: int) -> str | None:
        """The model an identification code (0x2103) names on a drive of ``family``: "BLD2",
        "BLD3H" or "C20", or None for a code the manuals do not list."""
    @staticmethod
    def models() -> list[tuple[str, int, str]]:
        """The model table: ``(name, identification code, family)`` of each model the manuals
        name."""
    @property
    def baud_rate(self) -> int:
        """The line speed the drive has stored (0x2009), in bits per second (the raw code if
        the manuals do not list it)."""
    def set_baud_rate(self, bps: int) -> None:
        """Store a new line speed (0x2009; stopped only): 1200..115200 (C20 up to 57600).

        The drive talks at the new speed from then on: open a new Bus at it.
        """
    def read_parameter(self, code: str) -> int:
        """The raw value of function-code parameter ``code``, e.g. ``"F00.10"``.

        Fgg.nn lives at ``gg << 8 | nn``; a parameter the drive lacks raises
        :class:`benchbus.ModbusException` (code 2).
        """
    def write_parameter(self, code: str, value: int) -> None:
        """Write the raw ``value`` (0..0xFFFF) to function-code parameter ``code``.

        Sets the write enable 0x200E to 1 first when it is not, and puts it back afterwards,
        also when the write fails; a refusal raises :class:`benchbus.ModbusException` naming
        the parameter (0x03 out of range, 0x08 not while running...).
        """
    def read_setting(self, name: str) -> float:
        """Reads the setting called ``name`` (a function-code parameter in engineering units,
        "comm_loss_timeout" for F08.04)."""
    def write_setting(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the setting called ``name``, enabling 0x200E
        around it; the value and the family are checked before anything is sent."""
    def registers(self) -> list[DriveRegister]:
        """The register table of this drive's family: a ``DriveRegister`` ``(name, address,
        scale, unit, access, low, high)`` for each register; access is "R", "W/R" or "W/R*"."""
    def units(self) -> dict[str, str]:
        """The unit of each register by name, from :meth:`registers` (``""`` for none)."""
    # The subclass turns this into a warning on another family's model; the command line
    # reads the table without a drive; leaving a ``with`` block ends a jog, then stops.
    def _model(self) -> Model | int: ...
    @staticmethod
    def _table(family: str) -> list[DriveRegister]: ...
    def _stop_on_exit(self, urgent: bool = False) -> None: ...

@disjoint_base
class PblCore(_Station):
    """The compiled base of ``benchbus.PblDrive`` (use that): the parameter table and every
    call to the drive.

    Parameters are given by number (0..222) or by name from :meth:`table`; values are the
    raw words, checked against the table before anything is sent. Every call that touches
    the wire releases the GIL. A 0x06 reply carrying a count of 1 instead of the echo is
    accepted, as these drives send it.
    """

    #: The names :meth:`sample` gives: parameters 50..54.
    SAMPLE_FIELDS: tuple[str, ...] | None
    def _attach(
        self, bus: Bus, unit: int, timeout: float | None = None, retries: int | None = None
    ) -> None:
        """Attaches the drive at ``unit`` to ``bus`` (what ``PblDrive.__init__`` does);
        ``timeout`` / ``retries`` replace the Bus's."""
    def get(self, name: str) -> int:
        """Reads the register called ``name`` (see the table), in engineering units: an
        int, or a float for a scaled register; a member of its enum where the
        device's class names its values."""
    def set(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the register called ``name``, checked
        against its range, steps, access and the family's rules before anything is sent."""
    def get_many(self, names: Iterable[str]) -> dict[str, int]:
        """Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
        each as :meth:`get` gives it,
        in as few requests as the table's limits allow (neighbours share one)."""
    def set_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
        as :meth:`set` does. Every value is checked against its register (range, steps,
        access) before the first is sent; the family's rules are checked write by write,
        so a refusal there leaves the earlier writes done."""
    def read_parameter(self, key: int | str) -> int:
        """Reads one parameter, by number or name."""
    def write_parameter(self, key: int | str, value: int) -> None:
        """Writes one parameter, by number or name, checked against the table first."""
    def read_parameters(self, start: int | str, count: int) -> list[int]:
        """Reads ``count`` parameters from ``start`` (in as few requests as allowed)."""
    def parameters(self) -> dict[str, int]:
        """Every documented parameter, ``{name: value}``, in four requests (61 a reply)."""
    def telemetry(self) -> PblTelemetry:
        """Parameters 0..99 (status and measurements) by name, in two requests: a dict, shown
        as a table in notebooks."""
    def sample(self) -> dict[str, float]:
        """Speed (rpm), bus voltage (V), analog speed input (mV), current (A) and power (W):
        parameters 50..54, in one request."""
    def start(self) -> None:
        """Start: set bit 0 of the control word, keeping its other bits."""
    def stop(self) -> None:
        """Stop: clear bit 0 of the control word, keeping its other bits."""
    def _stop_on_exit(self, urgent: bool = False) -> None: ...
    @property
    def running(self) -> bool:
        """Whether the motor is moving (status word bit 0)."""
    @property
    def alarm_word(self) -> int:
        """The 32-bit alarm word (parameter 5 high, 4 low)."""
    @property
    def alarms(self) -> frozenset[str]:
        """The active alarm bits by name ("alarm bit N": the manual names none)."""
    def units(self) -> dict[str, str]:
        """The unit of each parameter by name, from :meth:`table` (``""`` for none)."""
    @staticmethod
    def table() -> list[PblParameter]:
        """The parameter table: a :class:`~benchbus.PblParameter` (number, name, unit, access,
        low, high) for each parameter; access "R" or "W/R"."""
    @property
    def direction(self) -> Direction:
        """The direction asked for: bit 1 of the control word (see :meth:`status` for the
        direction the motor turns). Setting it keeps the control word's other bits."""
    @direction.setter
    def direction(self, direction: Direction) -> None: ...
    # The subclass adds the warning.
    def status(self) -> PblStatus:
        """The status word: running, and the direction the motor turns."""
    def _restore_defaults(self) -> None: ...

@disjoint_base
class J2Core(_Station):
    """The compiled base of ``benchbus.J2Controller`` (use that): the parameter table, the
    manual's rules and every call to the controller.

    Parameters are named as in the manual ("SV", "AL1", "RAPNF"; any case). Signed-table
    values are floats in engineering units (tenths on the wire), unsigned-table values ints.
    Writes follow the manual's rules: paced 150 ms apart, ranges checked first (SV also
    against the limits read from the controller), MV only in manual mode,
    RAPNF written 0 before RAP or RTM. Every call that touches the wire releases the GIL.
    """

    #: The names :meth:`sample` gives: ``pv``, ``sv``, ``mv``.
    SAMPLE_FIELDS: tuple[str, ...] | None
    def _attach(
        self, bus: Bus, unit: int, timeout: float | None = None, retries: int | None = None
    ) -> None:
        """Attaches the controller at ``unit`` (1..255) to ``bus`` (what
        ``J2Controller.__init__`` does); ``timeout`` / ``retries`` replace the Bus's."""
    def get(self, name: str) -> int | float:
        """Reads the register called ``name`` (see the table), in engineering units: an
        int, or a float for a scaled register; a member of its enum where the
        device's class names its values."""
    def set(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the register called ``name``, checked
        against its range, steps, access and the family's rules before anything is sent."""
    def get_many(self, names: Iterable[str]) -> dict[str, int | float]:
        """Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
        each as :meth:`get` gives it,
        in as few requests as the table's limits allow (neighbours share one)."""
    def set_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
        as :meth:`set` does. Every value is checked against its register (range, steps,
        access) before the first is sent; the family's rules are checked write by write,
        so a refusal there leaves the earlier writes done."""
    def read(self, name: str) -> int | float:
        """One parameter by its manual name ("SV", "AL1", "INP"; any case): a float for the
        signed table, an int for the unsigned one (a member of its enum, as :meth:`get`)."""
    def write(self, name: str, value: float, *, function: int = 0x06) -> None:
        """Write one parameter by name, with the manual's rules; ``function`` is 0x06 or
        0x10 (the manual shows both for SV)."""
    def read_many(self, names: Iterable[str]) -> list[int | float]:
        """Several parameters by name, in as few requests as the 16-register limit allows (each
        as :meth:`read` gives it)."""
    def write_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Write several parameters in order, each as :meth:`write` does; every value is
        checked against its fixed range before the first is sent."""
    def parameters(self) -> dict[str, int | float]:
        """Every parameter, ``{name: value}``, in blocks of at most 16 registers."""
    def set_output(self, percent: float, switch_to_manual: bool = False) -> None:
        """Set the output MV to ``percent`` (0..100); in automatic mode refused with
        StateError, unless ``switch_to_manual`` (AM written 0 first)."""
    def start_ramp(self) -> None:
        """Start the setpoint ramp (RAPNF = 1)."""
    def stop_ramp(self) -> None:
        """End the setpoint ramp (RAPNF = 0)."""
    def sample(self) -> dict[str, float]:
        """PV, SV and MV (``{"pv": .., "sv": .., "mv": ..}``), in one request."""
    @staticmethod
    def table() -> list[J2Parameter]:
        """The parameter table: a :class:`~benchbus.J2Parameter` (name, address, signed,
        writable, low, high, within_limits) for each parameter."""
    @staticmethod
    def units() -> dict[str, str]:
        """The unit of each parameter by its manual name (``""`` for none)."""
    def status(self) -> J2Status:
        """PV, SV, MV, mode, autotune, ramp and alarm values, in two requests."""
    @property
    def pid(self) -> Pid:
        """The first PID set (P, I, D), read in one request; set it with a 3-tuple."""
    @pid.setter
    def pid(self, value: Iterable[float]) -> None: ...
    @property
    def pid2(self) -> Pid:
        """The second PID set (P1, I1, D1), read in one request; set it with a 3-tuple."""
    @pid2.setter
    def pid2(self, value: Iterable[float]) -> None: ...
    @property
    def limits(self) -> Limits:
        """The setpoint limits (LSP, USP), read in one request. Set them with a
        ``(low, high)`` pair: they are written in the order that keeps LSP <= USP."""
    @limits.setter
    def limits(self, value: Iterable[float]) -> None: ...

@disjoint_base
class InstrumentCore(_Station):
    """The compiled base of ``benchbus.Instrument`` (use that): the request limits, the
    value conversions and every call to the instrument.

    Reads and writes of any length are split into requests of at most ``max_read`` /
    ``max_write`` registers; writes are paced ``min_write_interval`` seconds apart. Every
    argument is checked before anything is sent, and every call that touches the wire
    releases the GIL.
    """

    def _attach(
        self,
        bus: Bus,
        unit: int,
        max_read: int,
        max_write: int,
        min_write_interval: float,
        max_read_bits: int,
        max_write_bits: int,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """Attaches the instrument at ``unit`` to ``bus`` with its request limits (what
        ``Instrument.__init__`` does); ``timeout`` / ``retries`` replace the Bus's."""
    @property
    def max_read(self) -> int:
        """Most registers one read asks for."""
    @property
    def max_write(self) -> int:
        """Most registers one write carries."""
    @property
    def max_read_bits(self) -> int:
        """Most coils or discrete inputs one read asks for."""
    @property
    def max_write_bits(self) -> int:
        """Most coils one write carries."""
    @property
    def min_write_interval(self) -> float:
        """Least time between two writes, seconds."""
    def read_register(
        self, address: int, decimals: int = 0, signed: bool = False, *, function: _Read = 3
    ) -> int | float:
        """One register as a value: ``raw / 10**decimals`` (an int when ``decimals`` is 0),
        two's complement if ``signed``; ``function=4`` reads an input register instead of a
        holding register (3)."""
    def write_register(
        self,
        address: int,
        value: float,
        decimals: int = 0,
        signed: bool = False,
        *,
        function: int = 6,
    ) -> None:
        """Write ``value * 10**decimals`` to one register with 0x06 (or 0x10 if ``function``
        is 16). A value that does not fit or has more decimals raises ValueError before
        anything is sent."""
    def read_registers(self, address: int, count: int, *, function: _Read = 3) -> list[int]:
        """``count`` raw registers from ``address``, in requests of at most ``max_read``
        (``function=4``: input registers)."""
    def read_coil(self, address: int) -> bool:
        """One coil (0x01)."""
    def read_coils(self, address: int, count: int) -> list[bool]:
        """``count`` coils from ``address`` (0x01), in requests of at most ``max_read_bits``."""
    def read_discrete_input(self, address: int) -> bool:
        """One discrete input (0x02)."""
    def read_discrete_inputs(self, address: int, count: int) -> list[bool]:
        """``count`` discrete inputs from ``address`` (0x02), in requests of at most
        ``max_read_bits``."""
    def write_coil(self, address: int, value: bool) -> None:
        """Set one coil on (True) or off (False) with 0x05; the reply must echo it."""
    def write_coils(self, address: int, values: Iterable[bool]) -> None:
        """Set the coils from ``address`` to ``values`` (True or False each) with 0x0F, in
        requests of at most ``max_write_bits``."""
    def write_registers(self, address: int, values: Iterable[int]) -> None:
        """Write raw ``values`` from ``address`` with 0x10, in requests of at most
        ``max_write``."""
    def read_long(
        self,
        address: int,
        signed: bool = False,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        function: _Read = 3,
        order: _Layout = "ABCD",
    ) -> int:
        """An integer of ``bits`` (32 or 64) over the 2 or 4 registers from ``address``,
        signed or not, laid out by ``order``, as profiles and :func:`benchbus.from_registers`
        name it: ``"ABCD"`` (most significant register and byte first), ``"CDAB"`` (words
        swapped), ``"BADC"`` (bytes swapped in each register) or ``"DCBA"``.

        For 0x01020304: ABCD ``[0x0102, 0x0304]``, CDAB ``[0x0304, 0x0102]``, BADC
        ``[0x0201, 0x0403]``, DCBA ``[0x0403, 0x0201]``; a 64-bit value lies the same way
        over four registers.

        ``word_order`` (which register first) and ``byte_order`` (which byte of each
        register first), each ``"big"`` or ``"little"``, are accepted aliases:
        ``word_order="little"`` is ``order="CDAB"``, ``byte_order="little"`` ``"BADC"``.
        Giving ``order`` with either is a TypeError."""
    def write_long(
        self,
        address: int,
        value: int,
        signed: bool = False,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        order: _Layout = "ABCD",
    ) -> None:
        """Write an integer of ``bits`` (32 or 64) over 2 or 4 registers, laid out as
        :meth:`read_long` reads it (``order``, or its aliases ``word_order`` /
        ``byte_order``), in one request (more if ``max_write`` is smaller)."""
    def read_float(
        self,
        address: int,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        function: _Read = 3,
        order: _Layout = "ABCD",
    ) -> float:
        """An IEEE 754 float of ``bits`` (32: single, 64: double) over 2 or 4 registers,
        laid out as :meth:`read_long` reads an integer (``order``, or its aliases
        ``word_order`` / ``byte_order``)."""
    def write_float(
        self,
        address: int,
        value: float,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        order: _Layout = "ABCD",
    ) -> None:
        """Write an IEEE 754 float of ``bits`` (32 or 64) over 2 or 4 registers (NaN,
        infinities and, in 32 bits, numbers beyond a single's range are refused), laid out
        as :meth:`read_long` reads an integer (``order``, or its aliases ``word_order`` /
        ``byte_order``)."""
    def read_string(self, address: int, count: int, *, function: _Read = 3) -> str:
        """``count`` registers as text, two Latin-1 characters a register (high byte first),
        without the NULs that pad it (``function=4``: input registers)."""
    def write_string(self, address: int, text: str, count: int) -> None:
        """Write ``text`` into ``count`` registers, two characters a register, padded with
        NULs (longer text or characters outside Latin-1 raise ValueError)."""
    def identify(self, level: Literal["basic", "regular", "extended"] = "basic") -> Identification:
        """Read Device Identification (0x2B / MEI 0x0E) from object 0, following "more
        follows" until the device has sent them all.

        A device without the function raises :class:`~benchbus.ModbusException` with code 1
        (its ``meaning`` says so).
        """
    def get_comm_event_counter(self) -> CommEventCounter:
        """The status word (0xFFFF busy with a program command, 0x0000 not) and event
        counter (function 0x0B), as :meth:`Bus.get_comm_event_counter` reads them."""
    def get_comm_event_log(self) -> CommEventLog:
        """The status word, event counter, message counter and events (function 0x0C), as
        :meth:`Bus.get_comm_event_log` reads them."""
    def read_file_record(self, groups: Iterable[tuple[int, int, int]]) -> list[list[int]]:
        """File records (function 0x14): for each group ``(file, record, length)``,
        ``length`` registers from record ``record`` (0..0x270F) of file ``file``
        (1..0xFFFF); one list per group. The limits of :meth:`Bus.read_file_record`
        (ValueError, nothing sent)."""
    def write_file_record(self, groups: Iterable[tuple[int, int, Iterable[int]]]) -> None:
        """Write file records (function 0x15): for each group ``(file, record, values)``,
        ``values`` from record ``record`` of file ``file``, paced as the instrument's other
        writes; the reply must echo the request. The limits of
        :meth:`Bus.write_file_record` (ValueError, nothing sent)."""
    def read_fifo_queue(self, address: int) -> list[int]:
        """The values queued in the FIFO whose count register is at ``address`` (function
        0x18), oldest first: at most 31 (a reply that counts more is a FrameError)."""

@final
class Profile:
    """A device profile: a device described in a TOML file, read and checked by the core.

    ::

        profile = bb.Profile("xy_md02.toml")
        profile.name, len(profile), profile["temperature"].unit
        profile.plan(["temperature", "humidity"])   # the requests that read them
        bb.Profile("sdm630").source                 # a shipped profile, by name

    Every mistake (unknown keys, duplicate names, overlapping addresses, a name that shadows
    a device member, a type that does not fit its table, a bad enum or range, a value one
    request cannot carry) raises ``ProfileError`` (a ``ValueError``) naming the file, the
    line and the key.
    """

    def __new__(cls, path: str | os.PathLike[str]) -> Self:
        """Reads and checks the device profile (TOML) at ``path``; ``ProfileError`` (a
        ``ValueError``) names the file, the line and the key of its first mistake.
        ``path`` may also be a profile's name (``"sdm630"``): ``BENCHBUS_PROFILES``'
        folders, then the profiles the package ships; a file that exists wins."""
    @staticmethod
    def parse(text: str, path: str = "<string>") -> Profile:
        """Checks the profile ``text``; ``path`` names it in errors."""
    @staticmethod
    def families() -> list[str]:
        """The keys :meth:`family` takes: the built-in families whose register map is a file
        ("drive", "drive-c20", "pbl", "j2")."""
    @staticmethod
    def family(key: str) -> Profile:
        """The built-in family ``key`` ("drive", "pbl" or "j2") as a profile: the family's file
        as the package ships it (``families/``); "drive-c20" is its C20 model
        (``for_model("C20")``; the file's rows are the BLD's). ValueError for another key."""
    def to_toml(self) -> str:
        """The profile as a TOML file that reads back as the same profile (a built-in family's
        file as it is; each starts with comments on what its class does in code and the
        file cannot say)."""
    @property
    def name(self) -> str:
        """The device's name (``[device] name``)."""
    @property
    def description(self) -> str:
        """The device's description ("" if the file has none)."""
    @property
    def maker(self) -> str:
        """Who makes the device (``[device] maker``; "" if the file does not say)."""
    @property
    def model(self) -> str:
        """The model or series the file covers (``[device] model``; "")."""
    @property
    def kind(self) -> str:
        """What sort of device it is (``[device] kind``: "energy-meter", "sensor",
        "temperature-controller"...; "")."""
    @property
    def source(self) -> str:
        """The document its registers were written from (``[device] source``: title,
        version, sections; "")."""
    @property
    def models(self) -> tuple[str, ...]:
        """The models the file describes (``[device] models``; the first is the one its rows
        are written for), ``()`` for a file of one model."""
    def for_model(self, model: str) -> Profile:
        """The profile of ``model``, one of :attr:`models`: the registers that model has, each
        with its range there (a register's ``ranges``); ValueError for another name."""
    @property
    def path(self) -> str:
        """The file it was read from (what ``parse`` was given for text)."""
    @property
    def line(self) -> ProfileLine:
        """The ``[line]`` section as a ``ProfileLine`` (None where the file is silent)."""
    @property
    def limits(self) -> ProfileLimits:
        """The ``[limits]`` section as a ``ProfileLimits`` (None where the file is silent)."""
    @property
    def registers(self) -> tuple[ProfileRegister, ...]:
        """Every register as a ``ProfileRegister``, in the file's order."""
    def __getitem__(self, key: str, /) -> ProfileRegister:
        """The register called ``key`` (KeyError if there is none)."""
    def __contains__(self, key: str, /) -> bool:
        """Whether a register is called ``key``."""
    def __len__(self) -> int:
        """How many registers."""
    def check(self, name: str, value: object) -> None:
        """Checks ``value`` for the register ``name`` as writing it would, and sends nothing:
        ValueError for no such register, a read-only one, a value out of range, off the
        scale's steps, not a member or more than the type holds; TypeError for a value of
        the wrong kind. A family's rules that ask the device (a drive's registers that take
        writes only while stopped, the J2's SV within LSP..USP) are checked when writing;
        a register with ``decimals`` is checked against the widest range its places allow,
        and at its places (range, steps) when writing."""
    def plan(self, names: Sequence[str]) -> list[tuple[str, int, int, list[str]]]:
        """The requests that read the registers ``names`` (repeats once): ``(table, start,
        count, names)`` each, tables apart, neighbours together where the limits allow;
        with the registers giving any of them their decimal places (``decimals``), read
        with them."""

@disjoint_base
class ProfileCore(_Station):
    """The compiled base of ``benchbus.Device`` (use that): the request plan, the value
    conversions and every check of a device described by a profile. Every call that
    touches the wire releases the GIL."""

    def _attach(
        self,
        bus: Bus,
        unit: int,
        profile: Profile,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """Attaches the device ``profile`` describes at ``unit`` to ``bus`` (what
        ``Device.__init__`` does); ``timeout`` / ``retries`` replace the Bus's."""
    @property
    def profile(self) -> Profile:
        """The profile the device follows."""
    def _read(self, names: Sequence[str]) -> list[Any]:
        """The values of the registers ``names``, in that order, read in the fewest requests
        the profile's limits allow; enum registers as their numbers."""
    def _write_many(self, values: Mapping[str, Any] | Iterable[tuple[str, Any]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order; every
        value is checked before the first is sent."""
    def _write(self, name: str, value: Any) -> None:
        """Writes ``value`` to the register ``name``, every check made before anything is
        sent."""
