"""The simulated RS485 line: two pseudo-terminal pairs and a forwarder thread between them.

::

    library <-> /dev/pts/A | master A <-> Forwarder <-> master B | /dev/pts/B <-> server

The forwarder cuts both byte streams into frames, logs them, applies the faults and routes
each request: to the server (one at a time, as on a real half-duplex line), to several units
(a broadcast), or to nobody. The random faults of a noisy line (``benchbus.sim._faults``)
are applied to the replies here. The network gateway (``benchbus.sim._network``) uses the
:class:`Framer` and :class:`LineState` too; what both ask the units is in
``benchbus.sim._units``. Pure Python, no pymodbus.
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
from collections.abc import Callable

from benchbus.sim._faults import FaultInjector, Faults, Injection
from benchbus.sim._rtu import (
    crc_ok,
    exception_frame,
    frame_gap,
    reply_length,
    request_length,
    with_crc,
)
from benchbus.sim._units import Job, UnitHooks, refusal

__all__ = ["LOG_SIZE", "Forwarder", "Framer", "LineState", "PtyPair"]

log = logging.getLogger("benchbus.sim")

#: How long the forwarder waits for the server's reply before giving the request up.
SERVER_REPLY_TIMEOUT = 1.0
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


class LineState:
    """Faults and frame logs, shared by the Simulator (any thread) and the forwarder thread."""

    def __init__(self, log_size: int = LOG_SIZE) -> None:
        """No fault; empty logs, each keeping the last ``log_size`` frames."""
        self.lock = threading.Lock()
        self.reply_delay = 0.0
        self.silent_all = False
        self.silent_units: set[int] = set()
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

    def take_fault(self, reply: bytes) -> Injection:
        """What goes on the line for the RTU frame ``reply``, with the fault due on it, which
        this consumes (call with the lock held)."""
        if self.corrupt > 0:
            self.corrupt -= 1
            return Injection([reply[:-2] + bytes([reply[-2] ^ 0xFF, reply[-1] ^ 0xFF])])
        if self.injector is not None:
            return self.injector.apply(reply)
        return Injection([reply])


class Framer:
    """Cuts a byte stream into frames by length, or by a silent gap when it is unknown.

    ``length(buf)`` is the length of the frame at the start of ``buf``: 0 when more bytes
    are needed to tell, None when it cannot be told (the gap ends the frame), below 0 when
    ``buf`` holds no frame at all (then :attr:`invalid` is set and nothing more is cut).
    With ``cut_partial`` the gap also ends a frame whose rest has not come (a serial line:
    the talker stopped); without, the rest is awaited (a TCP stream).
    """

    def __init__(
        self, length: Callable[[bytes], int | None], gap: float, *, cut_partial: bool
    ) -> None:
        self.buf = b""
        self.last = 0.0
        self.invalid = False  # the stream holds something that is not a frame
        self._length = length
        self._gap = gap
        self._cut_partial = cut_partial

    def feed(self, data: bytes, now: float) -> None:
        self.buf += data
        self.last = now

    def frames(self, now: float) -> list[bytes]:
        out = []
        while self.buf and not self.invalid:
            n = self._length(self.buf)
            if n is not None and n < 0:
                self.invalid = True
            elif n and len(self.buf) >= n:
                out.append(self.buf[:n])
                self.buf = self.buf[n:]
            elif (n is None or self._cut_partial) and now - self.last >= self._gap:
                out.append(self.buf)
                self.buf = b""
            else:
                break
        return out

    def deadline(self) -> float | None:
        """When the gap would end the frame now buffered; None if no gap can (nothing
        buffered, or a TCP stream whose frame length is known or still to be told)."""
        if not self.buf or self.invalid:
            return None
        if not self._cut_partial and self._length(self.buf) is not None:
            return None
        return self.last + self._gap


class Forwarder:
    """The thread between master A (library side) and master B (server side)."""

    def __init__(
        self,
        state: LineState,
        library: PtyPair,
        server: PtyPair,
        *,
        units: frozenset[int],
        broadcast: bool,
        hooks: UnitHooks,
        baudrate: int,
    ) -> None:
        """Forward between ``library`` and ``server`` for the simulated ``units``.

        ``hooks`` are the units' callbacks: whether a unit answers writes and its reply
        delay are asked once per request, when it is handed to the server; its own form of a
        reply that is delivered, before the faults apply.
        """
        self._state = state
        self._a = library.master
        self._b = server.master
        self._units = units
        self._broadcast = broadcast
        self._hooks = hooks
        gap = frame_gap(baudrate)
        self._rx_a = Framer(request_length, gap, cut_partial=True)
        self._rx_b = Framer(reply_length, gap, cut_partial=True)
        self._jobs: collections.deque[Job] = collections.deque()
        self._inflight: Job | None = None
        self._inflight_deadline = 0.0
        self._held: collections.deque[tuple[float, bytes]] = collections.deque()
        self._last_release = 0.0
        self._out_a = bytearray()
        self._out_b = bytearray()
        self._inject: collections.deque[tuple[bytes, threading.Event]] = collections.deque()
        self._lock = threading.Lock()  # guards _jobs (from probe) and _inject
        self._stopping = False
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._thread = threading.Thread(target=self._run, name="benchbus-sim-line", daemon=True)

    # ---- called from other threads -------------------------------------------------------

    def start(self) -> None:
        """Start the forwarder thread."""
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread and close the wake-up pipe (the pty pairs are the caller's)."""
        self._stopping = True
        self._wake()
        if self._thread.is_alive():
            self._thread.join(timeout)
        if self._thread.is_alive():  # pragma: no cover - the loop always ends within a select
            log.error("simulator line thread did not stop")
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
        with self._lock:
            self._jobs.append(job)
        self._wake()
        assert job.done is not None
        job.done.wait(timeout)
        return job.reply

    def _wake(self) -> None:
        if self._wake_w >= 0:
            with contextlib.suppress(BlockingIOError):  # already full of wake-ups
                os.write(self._wake_w, b"x")

    # ---- the forwarder thread ----------------------------------------------------------------

    def _run(self) -> None:
        try:
            while not self._stopping:
                self._step()
        except Exception:  # pragma: no cover - a bug here must not pass silently
            log.exception("simulator line thread failed")
        finally:
            self._fail_pending()

    def _fail_pending(self) -> None:
        with self._lock:
            pending = [*self._jobs, *([self._inflight] if self._inflight else [])]
            injects = list(self._inject)
        for job in pending:
            if job.done is not None:
                job.done.set()
        for _, event in injects:
            event.set()

    def _step(self) -> None:
        timeout = self._timeout(time.monotonic())
        readers = [self._a, self._b, self._wake_r]
        writers = [fd for fd, buf in ((self._a, self._out_a), (self._b, self._out_b)) if buf]
        readable, writable, _ = select.select(readers, writers, [], timeout)
        now = time.monotonic()
        if self._wake_r in readable:
            _drain(self._wake_r)
        if self._a in readable:
            data = _read(self._a)
            if data:
                self._rx_a.feed(data, now)
        if self._b in readable:
            data = _read(self._b)
            if data:
                self._rx_b.feed(data, now)
        for frame in self._rx_a.frames(now):
            # The last chunk read holds the frame's last byte (a frame cut by length is cut
            # in the step that completes it; one cut by a gap has had nothing since).
            self._on_request(frame, self._rx_a.last)
        for frame in self._rx_b.frames(now):
            self._on_server_reply(frame)
        if self._inflight is not None and now >= self._inflight_deadline:
            log.warning("simulator: no reply from the server to %s", self._inflight.frame.hex(" "))
            self._finish(None)
        self._dispatch(now)
        self._release(now)
        self._take_injects()
        if self._b in writable or self._out_b:
            _write(self._b, self._out_b)
        if self._a in writable or self._out_a:
            _write(self._a, self._out_a)
        if len(self._out_a) > _MAX_OUTPUT:  # nobody reads the library's end
            del self._out_a[:]

    def _timeout(self, now: float) -> float | None:
        deadlines = [self._rx_a.deadline(), self._rx_b.deadline()]
        if self._inflight is not None:
            deadlines.append(self._inflight_deadline)
        if self._held:
            deadlines.append(self._held[0][0])
        due = [d for d in deadlines if d is not None]
        return max(0.0, min(due) - now) if due else None

    def _take_injects(self) -> None:
        with self._lock:
            injects = list(self._inject)
            self._inject.clear()
        for data, written in injects:
            self._out_a += data
            _write(self._a, self._out_a)
            written.set()

    # requests from the library

    def _on_request(self, frame: bytes, complete: float) -> None:
        state = self._state
        with state.lock:
            echo = state.echo
            frame = state.take_collision(frame)
            state.log_request(frame, complete)
        if echo:
            self._out_a += frame
        if not crc_ok(frame):
            log.debug("simulator: request with a bad CRC ignored: %s", frame.hex(" "))
            return
        unit, pdu = frame[0], frame[1:-2]
        if unit == 0:
            if self._broadcast:
                self._on_broadcast(pdu)
            return
        if unit not in self._units:
            return
        with state.lock:
            if state.is_silent(unit):
                return
            forced = state.take_exception(unit)
        if forced is not None:
            self._queue(Job(frame, True, made_reply=exception_frame(unit, pdu[0], forced)))
        else:
            self._queue(self._unit_job(frame, deliver=True))

    def _on_broadcast(self, pdu: bytes) -> None:
        with self._state.lock:
            units = [u for u in sorted(self._units) if not self._state.is_silent(u)]
        for unit in units:
            frame = with_crc(bytes([unit]) + pdu)
            self._queue(self._unit_job(frame, deliver=self._hooks.answers_broadcast(unit)))

    def _unit_job(self, frame: bytes, deliver: bool) -> Job:
        code = refusal(frame[1:-2])
        made = None if code is None else exception_frame(frame[0], frame[1], code)
        return Job(frame, deliver, made_reply=made)

    def _queue(self, job: Job) -> None:
        with self._lock:
            self._jobs.append(job)

    def _dispatch(self, now: float) -> None:
        while self._inflight is None:
            with self._lock:
                if not self._jobs:
                    return
                job = self._jobs.popleft()
            self._inflight = job
            if job.done is None:  # a unit's request, not the internal probe
                self._hooks.settle(job, job.frame[0], job.frame[1:-2])
            if job.made_reply is not None:
                self._finish(job.made_reply)
                continue
            self._rx_b.buf = b""
            self._out_b += job.frame
            self._inflight_deadline = now + SERVER_REPLY_TIMEOUT

    # replies from the server

    def _on_server_reply(self, frame: bytes) -> None:
        if self._inflight is None:
            log.debug("simulator: unexpected bytes from the server: %s", frame.hex(" "))
            return
        job = self._inflight
        if job.done is None and job.deliver:
            frame = self._hooks.shape(job.frame[0], job.frame, frame)
        self._finish(frame)

    def _finish(self, reply: bytes | None) -> None:
        job, self._inflight = self._inflight, None
        if job is None:
            return
        job.reply = reply
        if job.done is not None:
            job.done.set()
        elif job.deliver and reply is not None:
            self._hold(reply, job.delay)

    def _hold(self, reply: bytes, unit_delay: float) -> None:
        now = time.monotonic()
        state = self._state
        with state.lock:
            delay = max(state.reply_delay, unit_delay)
            out = state.take_fault(reply)
        if out.kind is not None:
            log.debug("simulator: fault %s on %s", out.kind, reply.hex(" "))
        # Replies keep their order: one held longer holds back those after it.
        release = max(now + delay + out.delay, self._last_release)
        self._last_release = release
        for frame in out.frames:
            self._held.append((release, frame))

    def _release(self, now: float) -> None:
        while self._held and self._held[0][0] <= now:
            _, reply = self._held.popleft()
            with self._state.lock:
                self._state.replies.append(reply)
            self._out_a += reply


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
