"""The request router of the simulated line and of each simulated network connection.

::

    library bytes -> Router.rx_req -> route -> Router.to_server -> server
    library <- Router.to_library <- faults, delay <- shape <- Router.rx_rep <- server bytes

A :class:`Router` cuts the library's requests and the server's replies into frames (in the
line's RTU framing, or a network's MBAP or RTU framing: :func:`framing`), logs the requests,
and routes each: to the server, one at a time, as on a half-duplex line; to every unit in
turn (a broadcast); or to nobody. It answers itself what the server cannot take and the
exceptions a test forces, asks the units how their replies go out (:class:`UnitHooks`), and
holds each reply for its delay with the faults due on it. It does no I/O: the line's
forwarder (pseudo-terminals, ``benchbus.sim._line``) and the network's gateway (sockets,
``benchbus.sim._network``) feed it bytes and write out what it gives. Pure Python, no
pymodbus.
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from benchbus import _mbap
from benchbus.sim._faults import Injection
from benchbus.sim._functions import DIAGNOSTICS, FORCE_LISTEN_ONLY, RESTART_COMMUNICATIONS
from benchbus.sim._rtu import crc_ok, reply_length, request_length, with_crc
from benchbus.sim._units import Job, UnitHooks, refusal

if TYPE_CHECKING:
    from benchbus.sim._line import SimState

__all__ = ["NETWORKS", "SERVER_REPLY_TIMEOUT", "Framer", "Framing", "Router", "framing"]

log = logging.getLogger("benchbus.sim")

#: The network kinds a Simulator serves: Modbus TCP (MBAP) and RTU frames over TCP.
NETWORKS = ("tcp", "rtu+tcp")
#: How long the server may take to answer a request before it is given up.
SERVER_REPLY_TIMEOUT = 1.0
#: Exception code of a Modbus TCP gateway whose target unit does not answer.
GATEWAY_TARGET_FAILED = 0x0B
#: How long a connection cut by ``reset_next`` lingers after its half reply, so that the
#: half is on its way before the reset.
RESET_GRACE = 0.02


class Framer:
    """Cuts a byte stream into frames by length, or by the end-of-frame silence when it is unknown.

    ``length(buf)`` is the length of the frame at the start of ``buf``: 0 when more bytes
    are needed to tell, None when it cannot be told (the silence ends the frame), below 0 when
    ``buf`` holds no frame at all (then :attr:`invalid` is set and nothing more is cut).
    With ``cut_partial`` the silence also ends a frame whose rest has not come (a serial line:
    the talker stopped); without, the rest is awaited (a TCP stream).
    """

    def __init__(
        self,
        length: Callable[[bytes], int | None],
        end_of_frame_silence: float,
        *,
        cut_partial: bool,
    ) -> None:
        self.buf = b""
        self.last = 0.0
        self.invalid = False  # the stream holds something that is not a frame
        self._length = length
        self._end_of_frame_silence = end_of_frame_silence
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
            elif (n is None or self._cut_partial) and now - self.last >= self._end_of_frame_silence:
                out.append(self.buf)
                self.buf = b""
            else:
                break
        return out

    def deadline(self) -> float | None:
        """When the silence would end the frame now buffered; None if none can (nothing
        buffered, or a TCP stream whose frame length is known or still to be told)."""
        if not self.buf or self.invalid:
            return None
        if not self._cut_partial and self._length(self.buf) is not None:
            return None
        return self.last + self._end_of_frame_silence


# ---- framings ------------------------------------------------------------------------------


class Framing:
    """How frames look on the line or a network: RTU (unit, PDU, CRC), or MBAP."""

    #: RTU frames: a CRC to check, and a serial line (collisions, noise) behind them.
    rtu = True

    def request_length(self, buf: bytes) -> int | None:
        """Length of the frame at the start of ``buf``: 0 more bytes needed, None unknown
        (wait for the silence), -1 not a frame at all."""
        return request_length(buf)

    def reply_length(self, buf: bytes) -> int | None:
        """As :meth:`request_length`, for replies."""
        return reply_length(buf)

    def unit(self, frame: bytes) -> int:
        """The unit ``frame`` is for (or from)."""
        return frame[0]

    def pdu(self, frame: bytes) -> bytes:
        """The PDU ``frame`` carries."""
        return frame[1:-2]

    def make(self, unit: int, pdu: bytes, request: bytes) -> bytes:
        """A frame carrying ``pdu`` for ``unit``, in answer to (or in place of) ``request``."""
        return with_crc(bytes([unit]) + pdu)

    def to_rtu(self, frame: bytes) -> bytes:
        """``frame`` as an RTU frame (unit, PDU, CRC)."""
        return frame

    def from_rtu(self, rtu: bytes, request: bytes) -> bytes:
        """The RTU frame ``rtu`` in this framing, in answer to ``request``."""
        return rtu

    def exception(self, request: bytes, code: int) -> bytes:
        """The exception reply ``code`` to ``request``."""
        pdu = self.pdu(request)
        function = pdu[0] if pdu else 0
        return self.make(self.unit(request), bytes([(function | 0x80) & 0xFF, code]), request)

    def target_failed(self, request: bytes) -> bytes | None:
        """What answers a request whose unit is not there or did not answer: nothing on a
        serial line (or behind a transparent converter)."""
        return None


class _Mbap(Framing):
    """Modbus TCP (``benchbus._mbap``): ``transaction id, protocol id 0, length, unit``,
    then the PDU."""

    rtu = False

    def request_length(self, buf: bytes) -> int | None:
        return _mbap.frame_length(buf)

    reply_length = request_length

    def unit(self, frame: bytes) -> int:
        return _mbap.Header.parse(frame).unit

    def pdu(self, frame: bytes) -> bytes:
        return frame[_mbap.HEADER_SIZE :]

    def make(self, unit: int, pdu: bytes, request: bytes) -> bytes:
        return _mbap.frame(_mbap.Header.parse(request).transaction, unit, pdu)

    def to_rtu(self, frame: bytes) -> bytes:
        return with_crc(bytes([self.unit(frame)]) + self.pdu(frame))

    def from_rtu(self, rtu: bytes, request: bytes) -> bytes:
        return self.make(rtu[0], rtu[1:-2], request)

    def target_failed(self, request: bytes) -> bytes | None:
        """A Modbus TCP gateway answers exception 0x0B (gateway target failed to respond)."""
        return self.exception(request, GATEWAY_TARGET_FAILED)


def framing(network: str | None) -> Framing:
    """The framing of ``network`` (None: the serial line)."""
    if network is None or network == "rtu+tcp":
        return Framing()
    if network == "tcp":
        return _Mbap()
    raise ValueError(f"network must be one of {NETWORKS}, not {network!r}")


# ---- the router ----------------------------------------------------------------------------


@dataclasses.dataclass
class _Held:
    release: float
    frame: bytes
    reset: bool = False  # cut the connection (RST) once this is sent


class Router:
    """Routes one stream's requests to the units and holds their replies (see the module)."""

    def __init__(
        self,
        state: SimState,
        f: Framing,
        *,
        units: frozenset[int],
        broadcast: bool,
        hooks: UnitHooks,
        end_of_frame_silence: float,
        cut_partial: bool,
    ) -> None:
        """Route for the simulated ``units`` (``broadcast``: they take unit 0 too).

        ``hooks`` are the units' callbacks: whether a unit answers writes and its reply
        delay are asked once per request, when it is handed to the server; its own form of a
        reply that is delivered (on RTU frames, whatever the framing), before the faults.
        ``end_of_frame_silence`` is the silence that ends a frame of unknown length, and with
        ``cut_partial`` also one whose rest has not come (see :class:`Framer`).
        """
        self._state = state
        self._f = f
        self._units = units
        self._broadcast = broadcast
        self._hooks = hooks
        self._who = hooks.who
        #: The library's bytes and the server's, to be cut into frames.
        self.rx_req = Framer(f.request_length, end_of_frame_silence, cut_partial=cut_partial)
        self.rx_rep = Framer(f.reply_length, end_of_frame_silence, cut_partial=cut_partial)
        #: What goes to the library and to the server: the caller writes it out.
        self.to_library = bytearray()
        self.to_server = bytearray()
        #: When a connection cut by ``reset_next`` is to be reset (None: not dying).
        self.reset_at: float | None = None
        self._lock = threading.Lock()  # guards _jobs (queued from other threads too)
        self._jobs: collections.deque[Job] = collections.deque()
        self._inflight: Job | None = None
        self._inflight_deadline = 0.0
        self._held: collections.deque[_Held] = collections.deque()
        self._last_release = 0.0

    def queue(self, job: Job) -> None:
        """Queue ``job`` behind the others (from any thread)."""
        with self._lock:
            self._jobs.append(job)

    def pending(self) -> list[Job]:
        """The jobs queued or in flight."""
        with self._lock:
            return [*self._jobs, *([self._inflight] if self._inflight else [])]

    def deadline(self) -> float | None:
        """When :meth:`step` has something to do next without new bytes (None: nothing)."""
        deadlines = [self.rx_req.deadline(), self.rx_rep.deadline(), self.reset_at]
        if self._inflight is not None:
            deadlines.append(self._inflight_deadline)
        if self._held:
            deadlines.append(self._held[0].release)
        due = [d for d in deadlines if d is not None]
        return min(due) if due else None

    def step(self, now: float) -> bool:
        """Route what came, hand the next request to the server, release what is due.

        False when the library sent something that is not a frame (the stream is lost:
        the caller closes it), after logging it as a request.
        """
        for frame in self.rx_req.frames(now):
            # The last chunk read holds the frame's last byte (a frame cut by length is cut
            # in the step that completes it; one cut by the silence has had nothing since).
            self._on_request(frame, self.rx_req.last)
        if self.rx_req.invalid:
            with self._state.lock:
                self._state.log_request(self.rx_req.buf, self.rx_req.last)
            return False
        for frame in self.rx_rep.frames(now):
            self._on_server_reply(frame)
        if self.rx_rep.invalid:
            log.warning("%s: not a frame from the server: %s", self._who, self.rx_rep.buf.hex())
            self.rx_rep.buf, self.rx_rep.invalid = b"", False
        if self._inflight is not None and now >= self._inflight_deadline:
            job = self._inflight
            log.warning("%s: no reply from the server to %s", self._who, job.frame.hex(" "))
            self._finish(self._f.target_failed(job.frame))
        self._dispatch(now)
        self._release(now)
        return True

    # requests from the library

    def _on_request(self, frame: bytes, complete: float) -> None:
        state, f = self._state, self._f
        with state.lock:
            echo = state.echo
            if f.rtu:  # another talker on the serial line garbles the frame
                frame = state.take_collision(frame)
            state.log_request(frame, complete)
        if echo:
            self.to_library += frame
        if f.rtu and not crc_ok(frame):
            log.debug("%s: request with a bad CRC ignored: %s", self._who, frame.hex(" "))
            return
        unit = f.unit(frame)
        if unit == 0:
            if self._broadcast:
                self._on_broadcast(frame)
            return
        if unit not in self._units:
            made = f.target_failed(frame)
            if made is not None:
                self.queue(Job(frame, True, made_reply=made))
            return
        sub_function = self._diagnostic(unit, f.pdu(frame))
        with state.lock:
            if state.is_silent(unit):
                return
            listening = self._listens_only(unit, sub_function)
            forced = None if listening else state.take_exception(unit)
        if listening:
            self._hooks.took(unit, f.pdu(frame), None, broadcast=False, listen_only=True)
            return
        if forced is not None:
            self.queue(Job(frame, True, made_reply=f.exception(frame, forced)))
        else:
            self.queue(self._unit_job(frame, deliver=True))

    def _on_broadcast(self, frame: bytes) -> None:
        pdu = self._f.pdu(frame)
        subs = {unit: self._diagnostic(unit, pdu) for unit in self._units}
        with self._state.lock:
            awake = [u for u in sorted(self._units) if not self._state.is_silent(u)]
            listening = {u for u in awake if self._listens_only(u, subs[u])}
        for unit in awake:
            if unit in listening:
                self._hooks.took(unit, pdu, None, broadcast=True, listen_only=True)
                continue
            request = self._f.make(unit, pdu, frame)
            job = self._unit_job(request, deliver=self._hooks.answers_broadcast(unit))
            job.broadcast = True
            self.queue(job)

    def _diagnostic(self, unit: int, pdu: bytes) -> int | None:
        """The Diagnostics (0x08) sub-function of ``pdu``, if ``unit`` serves 0x08."""
        if len(pdu) < 3 or pdu[0] != DIAGNOSTICS:
            return None
        if DIAGNOSTICS not in self._hooks.functions(unit):
            return None
        return int.from_bytes(pdu[1:3], "big")

    def _listens_only(self, unit: int, sub_function: int | None) -> bool:
        """Whether a request to ``unit`` (with this Diagnostics sub-function, if any) goes no
        further, as the spec's listen only mode says (call with the state's lock held).

        0x08 / 0x0004 puts the unit in the mode, unanswered; there it takes no request
        and answers none, until 0x08 / 0x0001 (restart communications) ends the mode,
        unanswered too.
        """
        listening = self._state.listen_only
        if unit in listening:
            if sub_function == RESTART_COMMUNICATIONS:
                listening.discard(unit)
            return True
        if sub_function == FORCE_LISTEN_ONLY:
            listening.add(unit)
            return True
        return False

    def _unit_job(self, frame: bytes, deliver: bool) -> Job:
        code = refusal(self._f.pdu(frame), self._hooks.functions(self._f.unit(frame)))
        made = None if code is None else self._f.exception(frame, code)
        return Job(frame, deliver, made_reply=made)

    def _dispatch(self, now: float) -> None:
        while self._inflight is None:
            with self._lock:
                if not self._jobs:
                    return
                job = self._jobs.popleft()
            self._inflight = job
            unit = self._f.unit(job.frame)
            # Not the line's internal probe, nor a network's answer for a unit it lacks.
            if job.done is None and unit in self._units:
                self._hooks.settle(job, unit, self._f.pdu(job.frame))
            if job.made_reply is not None:
                self._finish(job.made_reply)
                continue
            self.rx_rep.buf = b""
            self.to_server += job.frame
            self._inflight_deadline = now + SERVER_REPLY_TIMEOUT

    # replies from the server

    def _on_server_reply(self, frame: bytes) -> None:
        job = self._inflight
        if job is None:
            log.debug("%s: unexpected bytes from the server: %s", self._who, frame.hex(" "))
            return
        if job.deliver:
            frame = self._shaped(job.frame, frame)
        self._finish(frame)

    def _shaped(self, request: bytes, reply: bytes) -> bytes:
        """The unit's own form of the server's ``reply`` to ``request`` (shaped as RTU)."""
        f = self._f
        rtu = f.to_rtu(reply)
        shaped = self._hooks.shape(f.unit(request), f.to_rtu(request), rtu)
        return reply if shaped == rtu else f.from_rtu(shaped, request)

    def _finish(self, reply: bytes | None) -> None:
        job, self._inflight = self._inflight, None
        if job is None:
            return
        job.reply = reply
        unit = self._f.unit(job.frame)
        if job.done is None and unit in self._units:
            self._hooks.took(
                unit,
                self._f.pdu(job.frame),
                None if reply is None else self._f.pdu(reply),
                broadcast=job.broadcast,
                listen_only=False,
            )
        if job.done is not None:
            job.done.set()
        elif job.deliver and reply is not None:
            self._hold(reply, job.delay)

    def _hold(self, reply: bytes, unit_delay: float) -> None:
        now = time.monotonic()
        state = self._state
        reset = False
        with state.lock:
            delay = max(state.reply_delay, unit_delay)
            if state.take_reset():
                reset = True
                out = Injection([reply[: len(reply) // 2]])
            elif self._f.rtu:  # the faults of a serial line spoil RTU frames only
                out = state.take_fault(reply)
            else:
                out = Injection([reply])
        if out.kind is not None:
            log.debug("%s: fault %s on %s", self._who, out.kind, reply.hex(" "))
        # Replies keep their order: one held longer holds back those after it.
        release = max(now + delay + out.delay, self._last_release)
        self._last_release = release
        for frame in out.frames:
            self._held.append(_Held(release, frame, reset))

    def _release(self, now: float) -> None:
        while self._held and self._held[0].release <= now:
            held = self._held.popleft()
            with self._state.lock:
                self._state.replies.append(held.frame)
            self.to_library += held.frame
            if held.reset:
                # A gateway dying mid-reply: the half goes out, then the connection resets.
                self._held.clear()
                with self._lock:
                    self._jobs.clear()
                self._inflight = None
                self.reset_at = now + RESET_GRACE
                return
