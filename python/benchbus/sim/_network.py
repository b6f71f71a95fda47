"""The simulated gateway: a TCP proxy in front of the pymodbus TCP server (no pymodbus here).

::

    library --TCP--> Gateway (127.0.0.1:P) --TCP, one connection per client--> pymodbus server

The library connects to the gateway's port, as it would to a Modbus TCP gateway (``tcp``:
MBAP frames) or to a transparent serial-to-Ethernet converter (``rtu+tcp``: RTU frames, CRC
included, over TCP). For each client connection the gateway opens its own connection to the
pymodbus server, cuts both byte streams into frames (MBAP by its length field, RTU by the
lengths ``benchbus.sim._rtu`` knows or a silent gap), logs them, applies the faults and
routes each request: to the server (one at a time per connection, as a gateway in front of
a serial line does), to several units (a broadcast), or to nobody. Everything runs in one
thread on a ``selectors`` loop; other threads talk to it through a command queue.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import logging
import selectors
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import Any

from benchbus import _mbap
from benchbus.sim._faults import Injection
from benchbus.sim._line import LOG_SIZE, SERVER_REPLY_TIMEOUT, Framer, LineState
from benchbus.sim._rtu import crc_ok, frame_gap, reply_length, request_length, with_crc
from benchbus.sim._units import Job, UnitHooks, refusal

__all__ = ["NETWORKS", "Gateway", "NetworkState", "probe"]

log = logging.getLogger("benchbus.sim")

#: The network kinds a Simulator serves: Modbus TCP (MBAP) and RTU frames over TCP.
NETWORKS = ("tcp", "rtu+tcp")
#: Exception code of a Modbus TCP gateway whose target unit does not answer.
GATEWAY_TARGET_FAILED = 0x0B
#: How long a connection cut by ``reset_next`` lingers after its half reply, so that the
#: half is on its way before the reset.
RESET_GRACE = 0.02
_CONNECT_TIMEOUT = 2.0
_RECV_SIZE = 65536
_MAX_OUTPUT = 1 << 20  # drop bytes toward a client that does not read past this


class NetworkState(LineState):
    """The line's faults and logs, plus those only a network has."""

    def __init__(self, log_size: int = LOG_SIZE) -> None:
        """No fault; empty logs, each keeping the last ``log_size`` frames."""
        super().__init__(log_size)
        #: How many of the next delivered replies are cut halfway, with the connection reset.
        self.resets = 0


# ---- framing ---------------------------------------------------------------------------------


class _Framing:
    """How frames look on one kind of network (MBAP or RTU)."""

    rtu = False

    def request_length(self, buf: bytes) -> int | None:
        """Length of the frame at the start of ``buf``: 0 more bytes needed, None unknown
        (wait for a gap), -1 not a frame at all."""
        raise NotImplementedError

    def reply_length(self, buf: bytes) -> int | None:
        """As :meth:`request_length`, for replies."""
        raise NotImplementedError

    def unit(self, frame: bytes) -> int:
        raise NotImplementedError

    def pdu(self, frame: bytes) -> bytes:
        raise NotImplementedError

    def make(self, unit: int, pdu: bytes, request: bytes) -> bytes:
        """A frame carrying ``pdu`` for ``unit``, in answer to (or in place of) ``request``."""
        raise NotImplementedError

    def to_rtu(self, frame: bytes) -> bytes:
        """``frame`` as an RTU frame (unit, PDU, CRC)."""
        return with_crc(bytes([self.unit(frame)]) + self.pdu(frame))

    def from_rtu(self, rtu: bytes, request: bytes) -> bytes:
        """The RTU frame ``rtu`` in this framing, in answer to ``request``."""
        return self.make(rtu[0], rtu[1:-2], request)


class _Mbap(_Framing):
    """Modbus TCP (``benchbus._mbap``): ``transaction id, protocol id 0, length, unit``,
    then the PDU."""

    def request_length(self, buf: bytes) -> int | None:
        return _mbap.frame_length(buf)

    reply_length = request_length

    def unit(self, frame: bytes) -> int:
        return _mbap.Header.parse(frame).unit

    def pdu(self, frame: bytes) -> bytes:
        return frame[_mbap.HEADER_SIZE :]

    def make(self, unit: int, pdu: bytes, request: bytes) -> bytes:
        return _mbap.frame(_mbap.Header.parse(request).transaction, unit, pdu)


class _Rtu(_Framing):
    """RTU over TCP: ``unit``, the PDU, CRC (low byte first)."""

    rtu = True

    def request_length(self, buf: bytes) -> int | None:
        return request_length(buf)

    def reply_length(self, buf: bytes) -> int | None:
        return reply_length(buf)

    def unit(self, frame: bytes) -> int:
        return frame[0]

    def pdu(self, frame: bytes) -> bytes:
        return frame[1:-2]

    def make(self, unit: int, pdu: bytes, request: bytes) -> bytes:
        return with_crc(bytes([unit]) + pdu)

    def to_rtu(self, frame: bytes) -> bytes:
        return frame

    def from_rtu(self, rtu: bytes, request: bytes) -> bytes:
        return rtu


def _framing(network: str) -> _Framing:
    if network == "tcp":
        return _Mbap()
    if network == "rtu+tcp":
        return _Rtu()
    raise ValueError(f"network must be one of {NETWORKS}, not {network!r}")


# ---- the connections -------------------------------------------------------------------------


@dataclasses.dataclass
class _Held:
    release: float
    frame: bytes
    reset: bool = False  # cut the connection (RST) once this is sent


class _Conn:
    """One client connection and its own connection to the server."""

    def __init__(
        self, number: int, client: socket.socket, up: socket.socket, gap: float, f: _Framing
    ) -> None:
        self.number = number
        self.client = client
        self.up = up
        # Over TCP the rest of a frame is on its way: only an unknown length waits for a gap.
        self.rx_req = Framer(f.request_length, gap, cut_partial=False)
        self.rx_rep = Framer(f.reply_length, gap, cut_partial=False)
        self.jobs: collections.deque[Job] = collections.deque()
        self.inflight: Job | None = None
        self.inflight_deadline = 0.0
        self.held: collections.deque[_Held] = collections.deque()
        self.last_release = 0.0
        self.out_client = bytearray()
        self.out_up = bytearray()
        self.reset_at: float | None = None  # dying: reset the connection then
        self.masks = {client.fileno(): 0, up.fileno(): 0}


@dataclasses.dataclass
class _Command:
    run: Callable[[], Any]
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    error: BaseException | None = None


_LISTENER = "listener"
_WAKE = "wake"


class Gateway:
    """The proxy thread between the library's TCP clients and the pymodbus TCP server."""

    def __init__(
        self,
        state: NetworkState,
        upstream: tuple[str, int],
        *,
        network: str,
        units: frozenset[int],
        broadcast: bool,
        hooks: UnitHooks,
        baudrate: int = 19200,
        host: str = "127.0.0.1",
        refuse: bool = False,
    ) -> None:
        """Serve ``units`` of the server at ``upstream`` on a new port of ``host``.

        ``hooks`` are the units' callbacks, as for ``benchbus.sim._line.Forwarder``; their
        ``shape`` is given and gives RTU frames whatever the network. The port is bound here
        (see :attr:`address`); with ``refuse`` nothing listens on it until :meth:`refuse`
        False.
        """
        self._state = state
        self._upstream = upstream
        self.network = network
        self._f = _framing(network)
        self._units = units
        self._broadcast = broadcast
        self._hooks = hooks
        self._gap = frame_gap(baudrate)
        self._host = host
        self._conns: dict[int, _Conn] = {}
        self._numbers = 0
        self._lock = threading.Lock()  # guards _commands and the counts
        self._commands: collections.deque[_Command] = collections.deque()
        self._open = 0
        self._accepted = 0
        self._stopping = False
        self._sel = selectors.DefaultSelector()
        self._wake_r, self._wake_w = socket.socketpair()
        self._listener: socket.socket | None = None
        try:
            self._wake_r.setblocking(False)
            self._wake_w.setblocking(False)
            self._sel.register(self._wake_r, selectors.EVENT_READ, _WAKE)
            self._listener = self._listen(0)
            self.address: tuple[str, int] = self._listener.getsockname()[:2]
            if refuse:
                self._unlisten()
        except BaseException:
            self._close_all()
            raise
        self._thread = threading.Thread(target=self._run, name="benchbus-sim-gateway", daemon=True)

    # ---- called from other threads -------------------------------------------------------

    @property
    def connections(self) -> int:
        """How many client connections are open now."""
        with self._lock:
            return self._open

    @property
    def accepted(self) -> int:
        """How many client connections were accepted since the start."""
        with self._lock:
            return self._accepted

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread; close every socket (clients, server side, the port)."""
        self._stopping = True
        self._wake()
        if self._thread.is_alive():
            self._thread.join(timeout)
        if self._thread.is_alive():  # pragma: no cover - the loop ends within a select
            log.error("simulator gateway thread did not stop")
            return
        self._close_all()

    def refuse(self, refuse: bool, timeout: float = 2.0) -> None:
        """Stop (True) or start again (False) listening on the port; returns once done."""
        self._call(lambda: self._unlisten() if refuse else self._relisten(), timeout)

    def drop(self, reset: bool = False, timeout: float = 2.0) -> None:
        """Close every client connection (with a reset when ``reset``); returns once done."""

        def drop_all() -> None:
            for conn in list(self._conns.values()):
                self._close(conn, reset=reset)

        self._call(drop_all, timeout)

    def inject(self, data: bytes, timeout: float = 2.0) -> None:
        """Send ``data`` to every client connection now (not logged)."""

        def send_all() -> None:
            for conn in list(self._conns.values()):
                conn.out_client += data
                self._flush_client(conn)

        self._call(send_all, timeout)

    def _call(self, run: Callable[[], Any], timeout: float) -> None:
        if not self._thread.is_alive():
            run()  # not started yet (or stopped): nothing else touches the sockets
            return
        command = _Command(run)
        with self._lock:
            self._commands.append(command)
        self._wake()
        if not command.done.wait(timeout):
            raise TimeoutError("the simulator's gateway did not answer")
        if command.error is not None:
            raise command.error

    def _wake(self) -> None:
        with contextlib.suppress(OSError):  # full of wake-ups already, or closed
            self._wake_w.send(b"x")

    # ---- listening -------------------------------------------------------------------------

    def _listen(self, port: int) -> socket.socket:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            listener.bind((self._host, port))
            listener.listen(16)
            listener.setblocking(False)
            self._sel.register(listener, selectors.EVENT_READ, _LISTENER)
        except BaseException:
            listener.close()
            raise
        return listener

    def _unlisten(self) -> None:
        if self._listener is not None:
            self._sel.unregister(self._listener)
            self._listener.close()
            self._listener = None

    def _relisten(self) -> None:
        if self._listener is None:
            try:
                self._listener = self._listen(self.address[1])
            except OSError as exc:
                raise RuntimeError(f"cannot listen on port {self.address[1]} again: {exc}") from exc

    def _accept(self, now: float) -> None:
        assert self._listener is not None
        while True:
            try:
                client, _ = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                log.debug("simulator gateway: accept failed: %s", exc)
                return
            try:
                up = socket.create_connection(self._upstream, timeout=_CONNECT_TIMEOUT)
            except OSError as exc:
                log.error("simulator gateway: cannot reach the server: %s", exc)
                client.close()
                continue
            for sock in (client, up):
                sock.setblocking(False)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._numbers += 1
            conn = _Conn(self._numbers, client, up, self._gap, self._f)
            self._conns[conn.number] = conn
            self._sel.register(client, selectors.EVENT_READ, (conn, True))
            self._sel.register(up, selectors.EVENT_READ, (conn, False))
            conn.masks = {client.fileno(): selectors.EVENT_READ, up.fileno(): selectors.EVENT_READ}
            with self._lock:
                self._open += 1
                self._accepted += 1
            log.debug("simulator gateway: connection %d accepted", conn.number)

    def _close(self, conn: _Conn, reset: bool = False) -> None:
        if self._conns.pop(conn.number, None) is None:
            return
        for sock in (conn.client, conn.up):
            with contextlib.suppress(KeyError, ValueError):
                self._sel.unregister(sock)
        if reset:
            with contextlib.suppress(OSError):
                conn.client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        conn.client.close()
        conn.up.close()
        with self._lock:
            self._open -= 1
        log.debug("simulator gateway: connection %d closed%s", conn.number, " (reset)" * reset)

    def _close_all(self) -> None:
        for conn in list(self._conns.values()):
            self._close(conn)
        self._unlisten()
        with contextlib.suppress(KeyError, ValueError):
            self._sel.unregister(self._wake_r)
        self._sel.close()
        self._wake_r.close()
        self._wake_w.close()

    # ---- the gateway thread ----------------------------------------------------------------

    def _run(self) -> None:
        try:
            while not self._stopping:
                self._step()
        except Exception:  # pragma: no cover - a bug here must not pass silently
            log.exception("simulator gateway thread failed")
        finally:
            with self._lock:
                commands = list(self._commands)
                self._commands.clear()
            for command in commands:
                command.error = RuntimeError("the simulator's gateway stopped")
                command.done.set()

    def _step(self) -> None:
        events = self._sel.select(self._timeout(time.monotonic()))
        now = time.monotonic()
        for key, mask in events:
            if key.data == _WAKE:
                with contextlib.suppress(OSError):
                    while self._wake_r.recv(4096):
                        pass
            elif key.data == _LISTENER:
                self._accept(now)
            else:
                conn, is_client = key.data
                if conn.number not in self._conns:
                    continue  # closed earlier in this step
                if mask & selectors.EVENT_WRITE:
                    if is_client:
                        self._flush_client(conn)
                    else:
                        self._flush_up(conn)
                if mask & selectors.EVENT_READ and conn.number in self._conns:
                    self._receive(conn, is_client, now)
        self._run_commands()
        for conn in list(self._conns.values()):
            self._service(conn, now)

    def _run_commands(self) -> None:
        with self._lock:
            commands = list(self._commands)
            self._commands.clear()
        for command in commands:
            try:
                command.run()
            except BaseException as exc:
                command.error = exc
            command.done.set()

    def _timeout(self, now: float) -> float | None:
        deadlines: list[float | None] = []
        for conn in self._conns.values():
            deadlines += [conn.rx_req.deadline(), conn.rx_rep.deadline(), conn.reset_at]
            if conn.inflight is not None:
                deadlines.append(conn.inflight_deadline)
            if conn.held:
                deadlines.append(conn.held[0].release)
        due = [d for d in deadlines if d is not None]
        return max(0.0, min(due) - now) if due else None

    def _receive(self, conn: _Conn, is_client: bool, now: float) -> None:
        sock = conn.client if is_client else conn.up
        try:
            data = sock.recv(_RECV_SIZE)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            log.debug("simulator gateway: connection %d: %s", conn.number, exc)
            data = b""
        if not data:
            if not is_client:
                log.warning("simulator gateway: the server closed connection %d", conn.number)
            self._close(conn)
        elif conn.reset_at is not None:
            return  # dying: whatever comes now is lost
        elif is_client:
            conn.rx_req.feed(data, now)
        else:
            conn.rx_rep.feed(data, now)

    def _service(self, conn: _Conn, now: float) -> None:
        if conn.reset_at is not None:  # dying: the half reply goes out, then the reset
            self._flush_client(conn)
            if now >= conn.reset_at and conn.number in self._conns:
                self._close(conn, reset=True)
            return
        for frame in conn.rx_req.frames(now):
            self._on_request(conn, frame, conn.rx_req.last)
        if conn.rx_req.invalid:
            with self._state.lock:
                self._state.log_request(conn.rx_req.buf, conn.rx_req.last)
            log.warning(
                "simulator gateway: connection %d: not an MBAP frame, closed: %s",
                conn.number,
                conn.rx_req.buf[:16].hex(" "),
            )
            self._close(conn)
            return
        for frame in conn.rx_rep.frames(now):
            self._on_server_reply(conn, frame)
        if conn.rx_rep.invalid:
            log.warning("simulator gateway: not a frame from the server: %s", conn.rx_rep.buf.hex())
            conn.rx_rep.buf, conn.rx_rep.invalid = b"", False
        if conn.inflight is not None and now >= conn.inflight_deadline:
            log.warning(
                "simulator gateway: no reply from the server to %s", conn.inflight.frame.hex(" ")
            )
            job = conn.inflight
            made = None if self._f.rtu else self._exception(job.frame, GATEWAY_TARGET_FAILED)
            self._finish(conn, made)
        self._dispatch(conn, now)
        self._release(conn, now)
        if conn.number in self._conns:
            self._flush_up(conn)
        if conn.number in self._conns:
            self._flush_client(conn)

    # requests from the library

    def _exception(self, request: bytes, code: int) -> bytes:
        pdu = self._f.pdu(request)
        function = pdu[0] if pdu else 0
        return self._f.make(self._f.unit(request), bytes([(function | 0x80) & 0xFF, code]), request)

    def _on_request(self, conn: _Conn, frame: bytes, complete: float) -> None:
        state = self._state
        with state.lock:
            if self._f.rtu:  # another talker on the serial line behind garbles the frame
                frame = state.take_collision(frame)
            state.log_request(frame, complete)
        if self._f.rtu and not crc_ok(frame):
            log.debug("simulator gateway: request with a bad CRC ignored: %s", frame.hex(" "))
            return
        unit = self._f.unit(frame)
        if unit == 0:
            if self._broadcast:
                self._on_broadcast(conn, frame)
            return
        if unit not in self._units:
            if not self._f.rtu:  # a Modbus TCP gateway says its target is not there
                conn.jobs.append(
                    Job(frame, True, made_reply=self._exception(frame, GATEWAY_TARGET_FAILED))
                )
            return
        with state.lock:
            if state.is_silent(unit):
                return
            forced = state.take_exception(unit)
        if forced is not None:
            conn.jobs.append(Job(frame, True, made_reply=self._exception(frame, forced)))
        else:
            conn.jobs.append(self._unit_job(frame, deliver=True))

    def _on_broadcast(self, conn: _Conn, frame: bytes) -> None:
        pdu = self._f.pdu(frame)
        with self._state.lock:
            units = [u for u in sorted(self._units) if not self._state.is_silent(u)]
        for unit in units:
            request = self._f.make(unit, pdu, frame)
            conn.jobs.append(self._unit_job(request, deliver=self._hooks.answers_broadcast(unit)))

    def _unit_job(self, frame: bytes, deliver: bool) -> Job:
        code = refusal(self._f.pdu(frame))
        made = None if code is None else self._exception(frame, code)
        return Job(frame, deliver, made_reply=made)

    def _dispatch(self, conn: _Conn, now: float) -> None:
        while conn.inflight is None and conn.jobs:
            job = conn.jobs.popleft()
            conn.inflight = job
            unit = self._f.unit(job.frame)
            if unit in self._units:  # not the gateway's own answer for a unit it lacks
                self._hooks.settle(job, unit, self._f.pdu(job.frame))
            if job.made_reply is not None:
                self._finish(conn, job.made_reply)
                continue
            conn.rx_rep.buf = b""
            conn.out_up += job.frame
            conn.inflight_deadline = now + SERVER_REPLY_TIMEOUT

    # replies from the server

    def _on_server_reply(self, conn: _Conn, frame: bytes) -> None:
        job = conn.inflight
        if job is None:
            log.debug("simulator gateway: unexpected bytes from the server: %s", frame.hex(" "))
            return
        if job.deliver:
            frame = self._shaped(job.frame, frame)
        self._finish(conn, frame)

    def _shaped(self, request: bytes, reply: bytes) -> bytes:
        """The unit's own form of the server's ``reply`` to ``request`` (shaped as RTU)."""
        rtu = self._f.to_rtu(reply)
        shaped = self._hooks.shape(self._f.unit(request), self._f.to_rtu(request), rtu)
        return reply if shaped == rtu else self._f.from_rtu(shaped, request)

    def _finish(self, conn: _Conn, reply: bytes | None) -> None:
        job, conn.inflight = conn.inflight, None
        if job is not None and job.deliver and reply is not None:
            self._hold(conn, reply, job.delay)

    def _hold(self, conn: _Conn, reply: bytes, unit_delay: float) -> None:
        now = time.monotonic()
        state = self._state
        reset = False
        with state.lock:
            delay = max(state.reply_delay, unit_delay)
            if state.resets > 0:
                state.resets -= 1
                reset = True
                out = Injection([reply[: len(reply) // 2]])
            elif self._f.rtu:  # the faults of a serial line apply to RTU frames only
                out = state.take_fault(reply)
            else:
                out = Injection([reply])
        if out.kind is not None:
            log.debug("simulator gateway: fault %s on %s", out.kind, reply.hex(" "))
        # Replies keep their order: one held longer holds back those after it.
        release = max(now + delay + out.delay, conn.last_release)
        conn.last_release = release
        for frame in out.frames:
            conn.held.append(_Held(release, frame, reset))

    def _release(self, conn: _Conn, now: float) -> None:
        while conn.held and conn.held[0].release <= now:
            held = conn.held.popleft()
            with self._state.lock:
                self._state.replies.append(held.frame)
            conn.out_client += held.frame
            if held.reset:
                # A gateway dying mid-reply: the half goes out, then the connection resets.
                conn.held.clear()
                conn.jobs.clear()
                conn.inflight = None
                conn.reset_at = now + RESET_GRACE
                return

    # writing

    def _flush_client(self, conn: _Conn) -> None:
        if not self._flush(conn, conn.client, conn.out_client):
            return
        if len(conn.out_client) > _MAX_OUTPUT:  # nobody reads this client's end
            del conn.out_client[:]
        self._want(conn, conn.client, bool(conn.out_client))

    def _flush_up(self, conn: _Conn) -> None:
        if self._flush(conn, conn.up, conn.out_up):
            self._want(conn, conn.up, bool(conn.out_up))

    def _flush(self, conn: _Conn, sock: socket.socket, buf: bytearray) -> bool:
        """Write what ``buf`` holds to ``sock``; False if that closed the connection."""
        while buf:
            try:
                n = sock.send(buf)
            except (BlockingIOError, InterruptedError):
                return True
            except OSError as exc:
                log.debug("simulator gateway: connection %d: write failed: %s", conn.number, exc)
                self._close(conn)
                return False
            del buf[:n]
        return True

    def _want(self, conn: _Conn, sock: socket.socket, write: bool) -> None:
        mask = selectors.EVENT_READ | (selectors.EVENT_WRITE if write else 0)
        if conn.masks.get(sock.fileno()) != mask:
            self._sel.modify(sock, mask, (conn, sock is conn.client))
            conn.masks[sock.fileno()] = mask


def probe(address: tuple[str, int], frame: bytes, timeout: float) -> bytes | None:
    """Send ``frame`` to a server at ``address`` on a new connection; what came back.

    Reads until as many bytes as ``frame`` has came (a Diagnostics echo) or ``timeout``.
    """
    deadline = time.monotonic() + timeout
    try:
        with socket.create_connection(address, timeout=timeout) as sock:
            sock.sendall(frame)
            reply = b""
            while len(reply) < len(frame):
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                sock.settimeout(left)
                chunk = sock.recv(_RECV_SIZE)
                if not chunk:
                    break
                reply += chunk
            return reply
    except OSError as exc:
        log.debug("simulator: probe of %s failed: %s", address, exc)
        return None
