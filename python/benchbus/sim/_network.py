"""The simulated gateway: :class:`NetworkProxy`, a TCP proxy in front of the pymodbus TCP server
(no pymodbus here).

Not to be mixed up with :class:`benchbus.Gateway`, the library's own gateway that serves a
Bus over Modbus TCP: this one plays the part of a gateway for the library to talk to.

::

    library --TCP--> NetworkProxy (127.0.0.1:P) --TCP, one connection per client--> pymodbus server

The library connects to the gateway's port, as it would to a Modbus TCP gateway (``tcp``:
MBAP frames) or to a transparent serial-to-Ethernet converter (``rtu+tcp``: RTU frames, CRC
included, over TCP). For each client connection the gateway opens its own connection to the
pymodbus server, and a router (``benchbus.sim._router``, the serial line's too) that cuts
both byte streams into frames (MBAP by its length field, RTU by the lengths
``benchbus.sim._rtu`` knows or a silent gap), logs them, applies the faults and routes each
request: to the server (one at a time per connection, as a gateway in front of a serial line
does), to several units (a broadcast), or to nobody. Everything runs in one thread on a
``selectors`` loop; other threads talk to it through a command queue.
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

from benchbus.sim._line import LOG_SIZE, SimState
from benchbus.sim._loop import StepLoop
from benchbus.sim._router import NETWORKS, Router, framing
from benchbus.sim._rtu import end_of_frame_silence
from benchbus.sim._units import UnitHooks

__all__ = ["NETWORKS", "NetworkProxy", "NetworkState", "probe"]

log = logging.getLogger("benchbus.sim")

_CONNECT_TIMEOUT = 2.0
_RECV_SIZE = 65536
_MAX_OUTPUT = 1 << 20  # drop bytes toward a client that does not read past this


class NetworkState(SimState):
    """The simulator's faults and logs, plus those only a network has."""

    def __init__(self, log_size: int = LOG_SIZE) -> None:
        """No fault; empty logs, each keeping the last ``log_size`` frames."""
        super().__init__(log_size)
        #: How many of the next delivered replies are cut halfway, with the connection reset.
        self.resets = 0

    def take_reset(self) -> bool:
        """Whether the reply now going out is cut, with its connection reset, which this
        consumes (call with the lock held)."""
        if self.resets <= 0:
            return False
        self.resets -= 1
        return True


# ---- the connections -------------------------------------------------------------------------


class _Conn:
    """One client connection, its own connection to the server, and its router."""

    def __init__(
        self, number: int, client: socket.socket, up: socket.socket, router: Router
    ) -> None:
        self.number = number
        self.client = client
        self.up = up
        self.router = router
        self.masks = {client.fileno(): 0, up.fileno(): 0}


@dataclasses.dataclass
class _Command:
    run: Callable[[], Any]
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    error: BaseException | None = None


_LISTENER = "listener"
_WAKE = "wake"


class NetworkProxy(StepLoop):
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
        super().__init__("simulator gateway thread", "benchbus-sim-gateway")
        self._state = state
        self._upstream = upstream
        self.network = network
        self._f = framing(network)
        self._units = units
        self._broadcast = broadcast
        self._hooks = hooks
        self._end_of_frame_silence = end_of_frame_silence(baudrate)
        self._host = host
        self._conns: dict[int, _Conn] = {}
        self._numbers = 0
        self._lock = threading.Lock()  # guards _commands and the counts
        self._commands: collections.deque[_Command] = collections.deque()
        self._open = 0
        self._accepted = 0
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

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread; close every socket (clients, server side, the port)."""
        if self._end(timeout):
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
                conn.router.to_library += data
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
            router = Router(
                self._state,
                self._f,
                units=self._units,
                broadcast=self._broadcast,
                hooks=self._hooks,
                end_of_frame_silence=self._end_of_frame_silence,
                cut_partial=False,  # over TCP the rest of a frame is on its way
            )
            conn = _Conn(self._numbers, client, up, router)
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

    def _ended(self) -> None:
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
        deadlines = [conn.router.deadline() for conn in self._conns.values()]
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
        elif conn.router.reset_at is not None:
            return  # dying: whatever comes now is lost
        elif is_client:
            conn.router.rx_req.feed(data, now)
        else:
            conn.router.rx_rep.feed(data, now)

    def _service(self, conn: _Conn, now: float) -> None:
        router = conn.router
        if router.reset_at is not None:  # dying: the half reply goes out, then the reset
            self._flush_client(conn)
            if now >= router.reset_at and conn.number in self._conns:
                self._close(conn, reset=True)
            return
        if not router.step(now):
            log.warning(
                "simulator gateway: connection %d: not an MBAP frame, closed: %s",
                conn.number,
                router.rx_req.buf[:16].hex(" "),
            )
            self._close(conn)
            return
        if conn.number in self._conns:
            self._flush_up(conn)
        if conn.number in self._conns:
            self._flush_client(conn)

    # writing

    def _flush_client(self, conn: _Conn) -> None:
        out = conn.router.to_library
        if not self._flush(conn, conn.client, out):
            return
        if len(out) > _MAX_OUTPUT:  # nobody reads this client's end
            del out[:]
        self._want(conn, conn.client, bool(out))

    def _flush_up(self, conn: _Conn) -> None:
        out = conn.router.to_server
        if self._flush(conn, conn.up, out):
            self._want(conn, conn.up, bool(out))

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
