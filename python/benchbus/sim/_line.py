"""The simulated RS485 line: two pseudo-terminal pairs and a forwarder thread between them.

::

    library <-> /dev/pts/A | master A <-> Forwarder <-> master B | /dev/pts/B <-> server

The forwarder moves the bytes; its router (``benchbus.sim._router``, the network gateway's
too) cuts both byte streams into frames, logs them, applies the faults and routes each
request: to the server (one at a time, as on a real half-duplex line), to several units (a
broadcast), or to nobody. :class:`SimState` holds the faults and logs a test sets and reads,
whether the simulator serves a line or a network (the network's extends it). Pure Python, no
pymodbus.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import logging
import os
import select
import threading
import time

from benchbus.sim import _ascii
from benchbus.sim._faults import FaultInjector, Faults, Injection
from benchbus.sim._loop import StepLoop
from benchbus.sim._router import Router, framing
from benchbus.sim._rtu import crc_ok, end_of_frame_silence, with_crc
from benchbus.sim._units import Job, UnitHooks

__all__ = ["LOG_SIZE", "Forwarder", "PtyPair", "SimState"]

log = logging.getLogger("benchbus.sim")

_MAX_OUTPUT = 1 << 20  # drop bytes toward a port nobody reads past this


class PtyPair:
    """A pseudo-terminal pair in raw mode; the slave end stays open so it never hangs up."""

    def __init__(self) -> None:
        """Open the pair; ``path`` is the slave's /dev/pts/N."""
        # Imported here: tty needs termios, which Windows lacks, and a TCP simulator needs no pty.
        import tty

        self.master, self.slave = os.openpty()
        try:
            tty.setraw(self.slave)
            self.path = os.ttyname(self.slave)
            os.set_blocking(self.master, False)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Close both ends (idempotent)."""
        for fd in (self.master, self.slave):
            if fd >= 0:
                os.close(fd)
        self.master = self.slave = -1


@dataclasses.dataclass
class _ExceptionRule:
    code: int
    remaining: int
    unit: int | None


#: How many frames each log of a simulator keeps by default: the most recent ones.
LOG_SIZE = 10_000


class SimState:
    """Faults and frame logs, shared by the Simulator (any thread) and the thread that
    serves its port (the forwarder of a line, the proxy of a network)."""

    def __init__(self, log_size: int = LOG_SIZE) -> None:
        """No fault; empty logs, each keeping the last ``log_size`` frames."""
        self.lock = threading.Lock()
        self.reply_delay = 0.0
        self.silent_all = False
        self.silent_units: set[int] = set()
        #: Units in the Diagnostics' listen only mode (0x08 / 0x0004) until 0x08 / 0x0001.
        self.listen_only: set[int] = set()
        self.corrupt = 0
        #: Whether the library's adapter hears its own requests (they come back to it).
        self.echo = False
        #: How many of the next requests a collision garbles (echo and units alike).
        self.collisions = 0
        self.exception_rules: list[_ExceptionRule] = []
        self.requests: collections.deque[bytes] = collections.deque(maxlen=log_size)
        #: ``time.monotonic()`` when each frame in ``requests`` was complete (its last byte read).
        self.request_times: collections.deque[float] = collections.deque(maxlen=log_size)
        self.replies: collections.deque[bytes] = collections.deque(maxlen=log_size)
        #: Every request logged since the logs were last cleared, also those the logs dropped.
        self.request_count = 0
        #: The random faults now applied to replies (None: none), and how many of each kind
        #: were injected since they were last set.
        self.injector: FaultInjector | None = None
        self.fault_counts: dict[str, int] = {}

    def log_request(self, frame: bytes, complete: float) -> None:
        """Log a request that was complete at ``complete`` (call with the lock held)."""
        self.requests.append(frame)
        self.request_times.append(complete)
        self.request_count += 1

    def clear_log(self) -> None:
        """Empty the logs and the request count (call with the lock held)."""
        self.requests.clear()
        self.request_times.clear()
        self.replies.clear()
        self.request_count = 0

    def set_faults(self, faults: Faults | None) -> None:
        """Apply ``faults`` from the next reply on (None: stop); a new run restarts the counts."""
        with self.lock:
            if faults is None:
                self.injector = None
            else:
                self.fault_counts = {}
                self.injector = FaultInjector(faults, self.fault_counts)

    def add_exception_rule(self, code: int, n: int, unit: int | None) -> None:
        """The next ``n`` requests (to ``unit``; None = any) get exception ``code``."""
        with self.lock:
            self.exception_rules.append(_ExceptionRule(code, n, unit))

    def is_silent(self, unit: int) -> bool:
        """Whether requests to ``unit`` are swallowed (call with the lock held)."""
        return self.silent_all or unit in self.silent_units

    def take_exception(self, unit: int) -> int | None:
        """Consume one forced exception for ``unit`` (call with the lock held)."""
        for rule in self.exception_rules:
            if rule.unit is None or rule.unit == unit:
                rule.remaining -= 1
                if rule.remaining <= 0:
                    self.exception_rules.remove(rule)
                return rule.code
        return None

    def take_collision(self, frame: bytes) -> bytes:
        """``frame`` as the line carries it: garbled if a collision is due, which this
        consumes (call with the lock held)."""
        if self.collisions <= 0:
            return frame
        self.collisions -= 1
        # Another talker at once: the line carries neither frame intact.
        return frame[:2] + bytes([frame[2] ^ 0x5A]) + frame[3:] if len(frame) > 2 else b"\0"

    def take_reset(self) -> bool:
        """Whether the reply now going out is cut, with its connection reset, which this
        consumes (call with the lock held); never on a serial line."""
        return False

    def take_fault(self, reply: bytes) -> Injection:
        """What goes on the line for the RTU frame ``reply``, with the fault due on it, which
        this consumes (call with the lock held)."""
        if self.corrupt > 0:
            self.corrupt -= 1
            return Injection([reply[:-2] + bytes([reply[-2] ^ 0xFF, reply[-1] ^ 0xFF])])
        if self.injector is not None:
            return self.injector.apply(reply)
        return Injection([reply])


class _AsciiLine(bytearray):
    """The bytes toward the library on a Modbus ASCII line. The router adds each frame it
    puts on the line (``+=``: a reply or an echo, as an RTU frame): it goes out as the ASCII
    frame of its unit and PDU, with a bad LRC if its CRC is bad (a fault, a collision).
    ``extend`` adds bytes as they are (injected bytes)."""

    def __iadd__(self, frame: bytes | bytearray) -> _AsciiLine:  # type: ignore[override,misc]
        rtu = bytes(frame)
        self.extend(_ascii.encode(rtu[:-2], bad_lrc=not crc_ok(rtu)))
        return self


class Forwarder(StepLoop):
    """The thread between master A (library side) and master B (server side): the I/O of a
    :class:`~benchbus.sim._router.Router`."""

    def __init__(
        self,
        state: SimState,
        library: PtyPair,
        server: PtyPair,
        *,
        units: frozenset[int],
        broadcast: bool,
        hooks: UnitHooks,
        baudrate: int,
        ascii: bool = False,
    ) -> None:
        """Forward between ``library`` and ``server`` for the simulated ``units``.

        ``hooks`` are the units' callbacks (see :class:`~benchbus.sim._router.Router`).
        With ``ascii`` the library's side of the line speaks Modbus ASCII: each of its
        frames goes to the router as the RTU frame of its unit and PDU (so the logs and the
        faults see RTU frames), and each frame for the library goes out in ASCII; the server
        speaks RTU either way.
        """
        super().__init__("simulator line thread", "benchbus-sim-line")
        self._a = library.master
        self._b = server.master
        self._router = Router(
            state,
            framing(None),
            units=units,
            broadcast=broadcast,
            hooks=hooks,
            end_of_frame_silence=end_of_frame_silence(baudrate),
            cut_partial=True,  # a serial line: a talker that stops has ended its frame
        )
        self._ascii = _ascii.Receiver() if ascii else None
        if ascii:
            self._router.to_library = _AsciiLine()
        self._inject: collections.deque[tuple[bytes, threading.Event]] = collections.deque()
        self._lock = threading.Lock()  # guards _inject
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)

    # ---- called from other threads -------------------------------------------------------

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread and close the wake-up pipe (the pty pairs are the caller's)."""
        if not self._end(timeout):
            return
        for fd in (self._wake_r, self._wake_w):
            os.close(fd)
        self._wake_r = self._wake_w = -1

    def inject(self, data: bytes, timeout: float = 2.0) -> None:
        """Put ``data`` on the line toward the library; returns once it is written."""
        written = threading.Event()
        with self._lock:
            self._inject.append((bytes(data), written))
        self._wake()
        if not written.wait(timeout):
            raise TimeoutError("the simulator did not get the bytes onto the line")

    def probe(self, frame: bytes, timeout: float) -> bytes | None:
        """Send ``frame`` to the server outside the logs and faults; its reply, or None."""
        job = Job(frame=frame, deliver=False, done=threading.Event())
        self._router.queue(job)
        self._wake()
        assert job.done is not None
        job.done.wait(timeout)
        return job.reply

    def _wake(self) -> None:
        if self._wake_w >= 0:
            with contextlib.suppress(BlockingIOError):  # already full of wake-ups
                os.write(self._wake_w, b"x")

    # ---- the forwarder thread ----------------------------------------------------------------

    def _ended(self) -> None:
        pending = self._router.pending()
        with self._lock:
            injects = list(self._inject)
        for job in pending:
            if job.done is not None:
                job.done.set()
        for _, event in injects:
            event.set()

    def _step(self) -> None:
        router = self._router
        deadline = router.deadline()
        timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
        readers = [self._a, self._b, self._wake_r]
        outputs = ((self._a, router.to_library), (self._b, router.to_server))
        writers = [fd for fd, buf in outputs if buf]
        readable, writable, _ = select.select(readers, writers, [], timeout)
        now = time.monotonic()
        if self._wake_r in readable:
            _drain(self._wake_r)
        if self._a in readable:
            data = _read(self._a)
            if data and self._ascii is not None:
                for unit_pdu in self._ascii.feed(data, now):
                    router.rx_req.feed(with_crc(unit_pdu), now)
            elif data:
                router.rx_req.feed(data, now)
        if self._b in readable:
            data = _read(self._b)
            if data:
                router.rx_rep.feed(data, now)
        router.step(now)  # RTU frames: always a frame, whatever the bytes
        self._take_injects()
        if self._b in writable or router.to_server:
            _write(self._b, router.to_server)
        if self._a in writable or router.to_library:
            _write(self._a, router.to_library)
        if len(router.to_library) > _MAX_OUTPUT:  # nobody reads the library's end
            del router.to_library[:]

    def _take_injects(self) -> None:
        with self._lock:
            injects = list(self._inject)
            self._inject.clear()
        for data, written in injects:
            self._router.to_library.extend(data)
            _write(self._a, self._router.to_library)
            written.set()


def _read(fd: int) -> bytes:
    try:
        return os.read(fd, 4096)
    except (BlockingIOError, InterruptedError):
        return b""
    except OSError:  # EIO: no slave end open (cannot happen while we hold one)
        return b""


def _write(fd: int, buf: bytearray) -> None:
    while buf:
        try:
            n = os.write(fd, buf)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            log.debug("simulator: write failed: %s", exc)
            del buf[:]
            return
        del buf[:n]


def _drain(fd: int) -> None:
    with contextlib.suppress(BlockingIOError, InterruptedError):
        while os.read(fd, 4096):
            pass
