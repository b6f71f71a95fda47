"""A small Modbus TCP server that owns one Bus and serialises many clients onto its line.

::

    client process --tcp://--+
    client process --tcp://--+--> Gateway --> Bus --> /dev/ttyUSB0 (RS485)
    notebook ------ tcp:// --+

Each client connection gets a thread; every request goes through the one :class:`Bus`, which
runs one transaction at a time, so requests from several processes never interleave on the
line. Every function goes through as the client sent it and comes back as the unit
answered (:meth:`Gateway.handle`), checked first by the core's rules for requests
(``_request_rules``). The Bus keeps its own t3.5, timeout and retries on the serial side,
and the per-unit write pacing the clients cannot keep for each other (``write_intervals``:
the gateway gives every write it forwards its unit's interval, and a broadcast the widest,
and the Bus waits them out, retries included).
"""

from __future__ import annotations

import contextlib
import dataclasses
import ipaddress
import logging
import math
import re
import select
import socket
import threading
import time
from collections.abc import Callable, Iterable, Mapping

from benchbus import _mbap
from benchbus._core import Bus, _request_rules
from benchbus._device import forked
from benchbus._scope import Scoped
from benchbus.exceptions import (
    BenchbusError,
    FrameError,
    ModbusException,
    PortError,
    ResponseTimeout,
)

__all__ = ["Gateway", "GatewayStats", "parse_allow", "parse_listen"]

log = logging.getLogger("benchbus.gateway")

#: Exception codes the gateway answers with itself (Modbus application protocol, 7); a
#: request the core's rules refuse is answered the code they give (0x01 or 0x03).
ILLEGAL_DATA_VALUE = 0x03
SERVER_DEVICE_FAILURE = 0x04
#: Server device busy: the answer to a client that came when every client slot was taken.
SERVER_DEVICE_BUSY = 0x06
PATH_UNAVAILABLE = 0x0A
TARGET_FAILED = 0x0B

MAX_PDU = _mbap.MAX_PDU
#: How long a request may take to arrive whole, counted from its first byte, by default,
#: before the connection is dropped.
FRAME_TIMEOUT = 5.0
#: How long a client may stay silent between requests, by default, before it is dropped.
IDLE_TIMEOUT = 60.0
#: When every client slot is taken, a client whose request has been arriving for longer
#: than this (seconds) is dropped to make room for a new client.
SLOW_REQUEST = 1.0
#: How long a refused client's connection stays open after its 0x06 answer, for the client
#: to read it (and close first) before the gateway closes it.
_REFUSAL_LINGER = 1.0
#: The most refused clients answered at once (a thread each, for a moment); past them a
#: newcomer is closed at once.
_MOST_REFUSING = 32
_MEI_DEVICE_ID = 0x0E


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (an IPv6 address in brackets: ``[::1]:5020``) as ``(host, port)``.

    HOST is an IP address or a host name; port 0 asks for any free port. Raises ValueError
    for anything else.
    """
    form = f"listen address must be HOST:PORT, e.g. 127.0.0.1:5020, not {text!r}"
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise ValueError(form)
    bracketed = host.startswith("[") or host.endswith("]")
    if bracketed:
        if not (host.startswith("[") and host.endswith("]")):
            raise ValueError(form)
        host = host[1:-1]
    if not port.isascii() or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"listen port must be 0..65535, not {port!r}")
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        if bracketed or not _HOST_NAME.fullmatch(host):
            raise ValueError(form) from None
    else:
        if bracketed != (address.version == 6):
            raise ValueError(form)
    return host, int(port)


def parse_allow(text: str) -> ipaddress.IPv4Network | ipaddress.IPv6Network:
    """``ADDR`` or ``ADDR/BITS`` (IPv4 or IPv6: ``192.168.1.0/24``, ``::1``) as a network.

    Raises ValueError, saying what is wrong, for anything else (host bits set included:
    ``192.168.1.5/24`` is refused, naming ``192.168.1.0/24``); TypeError for a non-str.
    """
    if not isinstance(text, str):
        raise TypeError(f"allow: an address is a str, not {type(text).__name__}")
    try:
        return ipaddress.ip_network(text.strip(), strict=True)
    except ValueError as exc:
        try:
            network = ipaddress.ip_network(text.strip(), strict=False)
        except ValueError:
            raise ValueError(
                f"allow: {text!r} is not ADDR or ADDR/BITS (e.g. 192.168.1.0/24, ::1): {exc}"
            ) from None
        raise ValueError(f"allow: {text!r} has host bits set: the network is {network}") from None


def _on_this_machine(host: str) -> bool:
    """Whether a listen address ``host`` is reachable from this machine only (loopback)."""
    if host.lower().rstrip(".") == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name: assume the network


_HOST_NAME = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)(\.(?!-)[A-Za-z0-9-]{1,63}(?<!-))*\.?")


@dataclasses.dataclass
class GatewayStats:
    """What the gateway has done since it started (a snapshot)."""

    #: Client connections accepted.
    connections: int = 0
    #: Requests answered (normal or exception reply), broadcasts included.
    requests: int = 0
    #: Requests answered with an exception the gateway made: 0x0A, 0x0B, or a refusal.
    gateway_exceptions: int = 0
    #: Frames dropped: a protocol id other than 0, a length out of range.
    bad_frames: int = 0
    #: Connections turned away: from an address ``allow`` leaves out (closed at once), or
    #: that came while ``max_clients`` were connected, none idle or slow to send its
    #: request (their first request answered 0x06, server device busy, then closed).
    refused: int = 0
    #: Connections closed for being idle: silent for ``idle_timeout``, or the longest idle
    #: one when a new client came and ``max_clients`` were connected.
    idle_closed: int = 0
    #: Connections closed for a request that came too slowly: not whole within
    #: ``frame_timeout`` of its first byte, or, when a new client came and ``max_clients``
    #: were connected, none of them idle, still arriving after ``SLOW_REQUEST`` (1 s).
    slow_closed: int = 0


@dataclasses.dataclass
class _Client:
    """A connection's state, kept under the gateway's lock."""

    #: ``time.monotonic()`` when it connected or its last request was answered.
    idle_since: float
    #: Whether a request of it is being read or served (it is then not idle).
    busy: bool = False
    #: ``time.monotonic()`` when the first byte of the request being read came; None when
    #: no request is arriving (idle, or its request is whole and being served: never dropped).
    arriving_since: float | None = None


class Gateway(Scoped):
    """A Modbus TCP server for the units on one :class:`Bus` (``benchbus gateway``).

    ::

        with bb.Bus("/dev/ttyUSB0") as bus, bb.Gateway(bus, "127.0.0.1:5020") as gw:
            ...  # other processes open bb.Bus(gw.url) and use their devices as usual

    Forwards every function code (1..127): the client's PDU goes on the line as it came
    (:meth:`Bus.request`), and the unit's reply goes back as it came, under the client's
    transaction id. The reply is read by its length where the request tells it (0x01 to
    0x08, 0x0B, 0x0F, 0x10, 0x14, 0x15, 0x16, 0x17), or by the byte count it carries (0x0C,
    0x11, 0x18; 0x2B / 0x0E, the identification, whose pages the gateway follows and sends
    with the conformity level and object bytes the unit sent); any other function's reply (a
    vendor's function, another MEI type) ends when the line falls quiet (the Bus's
    ``silence``, at least t3.5). The serial line functions (0x07, 0x08, 0x0B, 0x0C, 0x11)
    are forwarded as any other. A request of one of the specification's functions with a
    wrong length or byte count, or a count past the specification's limits, is answered
    exception 0x03 (illegal data value) and not sent; a function code 0 or 0x80 and up,
    0x01: the rules benchbus's own requests are held to. Diagnostics sub-function 0x04
    (force listen only) is sent once and not answered, as no device answers it. Unit 0
    with 0x05, 0x06, 0x0F, 0x10 or 0x16 (the writes the Bus can broadcast) is a
    broadcast: sent, not answered (nor is any other request to unit 0, which is not
    sent). A failure on the line comes back as the gateway exceptions: 0x0B when the unit
    gave no valid reply (after the Bus's retries), 0x0A when the serial port is lost or
    closed. An exception reply from the unit is passed on as it is.

    ``write_intervals`` (``{unit: seconds}``) keeps that least time between two writes to a
    unit on the line (every function but the reads: 0x01 to 0x04, 0x07, 0x08, 0x0B, 0x0C,
    0x11, 0x14, 0x18 and 0x2B / 0x0E), whichever client sends them (a J2 controller needs
    0.15 s; the clients' own pacing cannot see each other's writes). The Bus keeps it, the
    Bus's retries of every write too, and a broadcast counts as a write to every unit.

    A client's timeout must cover the gateway's work: up to the Bus's ``timeout x (retries
    + 1)``, the unit's write interval, and the requests of other clients queued ahead of it.
    Give clients ``timeout=1.0`` (or more) and ``retries=0``: over TCP nothing is lost on the
    way, and a repeated request only queues behind the first.

    Connections: a client silent for ``idle_timeout`` seconds between requests is dropped,
    and so is one whose request does not arrive whole within ``frame_timeout`` seconds of
    its first byte. When ``max_clients`` are connected, a new client takes the place of the
    one idle the longest, or, if none is idle, of the one whose request has been arriving
    the longest, if for over ``SLOW_REQUEST`` (1 s); a request that has arrived whole is
    always served. Failing both, the new client is refused: its first request (if whole
    within ``frame_timeout`` of connecting) is answered exception 0x06, server device busy,
    and the connection closed; benchbus's own client raises :class:`ModbusException` 0x06,
    whose meaning says so. A client opened with ``reconnect=True`` does not notice being
    dropped while idle.

    Modbus TCP has no authentication: whoever reaches the port drives the devices on the
    line. Listening on an address other than loopback logs a warning (``benchbus.gateway``
    logger; ``benchbus gateway`` prints it), and ``allow`` (``["192.168.1.0/24", "::1"]``)
    limits who may connect: a connection from elsewhere is closed at once and counted
    (:attr:`GatewayStats.refused`).

    The gateway is how several processes share one line: each opens ``Bus(gw.url)``, a
    child made by fork included. The gateway itself, like its Bus, belongs to the process
    that opened the Bus: in a child made by fork, making one, :meth:`start`,
    :meth:`serve_forever` and :meth:`handle` raise the Bus's PortError at once, and
    :meth:`stop` only closes that process's copies of the sockets (the parent's listening
    socket and connections go on).
    """

    def __init__(
        self,
        bus: Bus,
        listen: str = "127.0.0.1:5020",
        *,
        write_intervals: Mapping[int, float] | None = None,
        max_clients: int = 32,
        idle_timeout: float | None = IDLE_TIMEOUT,
        allow: str | Iterable[str] | None = None,
        frame_timeout: float = FRAME_TIMEOUT,
    ) -> None:
        """Serve ``bus``'s units on ``listen`` (``HOST:PORT``; port 0: any free port).

        Nothing listens until :meth:`start` (or ``with``). At most ``max_clients``
        connections are served at once (a new one replaces the longest idle, else the
        slowest to send its request; failing both it is answered 0x06 and closed); one
        silent for ``idle_timeout`` seconds between requests is closed (None: never), and
        one whose request has not arrived whole ``frame_timeout`` seconds after its first
        byte. ``allow``: the addresses (``ADDR`` or ``ADDR/BITS``, IPv4 or IPv6) that may
        connect; None: any. Raises ValueError for a bad address, network, interval, limit
        or timeout, TypeError for a ``bus`` that is not a :class:`Bus`.
        """
        if not isinstance(bus, Bus):
            raise TypeError(f"bus must be a benchbus.Bus, not {type(bus).__name__}")
        bus._owned()
        #: The Bus the gateway forwards requests to.
        self.bus = bus
        self._listen = parse_listen(listen)
        self._intervals: dict[int, float] = {}
        for unit, seconds in (write_intervals or {}).items():
            if isinstance(unit, bool) or not isinstance(unit, int) or not 1 <= unit <= 255:
                raise ValueError(f"write_intervals: a unit is 1..255, not {unit!r}")
            if isinstance(seconds, bool) or not isinstance(seconds, (int, float)):
                raise TypeError(f"write_intervals: unit {unit}: seconds must be a number")
            if not 0.0 <= seconds <= 60.0:
                raise ValueError(f"write_intervals: unit {unit}: 0..60 seconds, not {seconds}")
            self._intervals[unit] = float(seconds)
        if isinstance(max_clients, bool) or not isinstance(max_clients, int) or max_clients < 1:
            raise ValueError(f"max_clients must be an int >= 1, not {max_clients!r}")
        self._max_clients = max_clients
        if idle_timeout is not None and (
            isinstance(idle_timeout, bool) or not isinstance(idle_timeout, (int, float))
        ):
            raise TypeError(f"idle_timeout must be seconds or None, not {idle_timeout!r}")
        if idle_timeout is not None and not (idle_timeout > 0 and math.isfinite(idle_timeout)):
            raise ValueError(f"idle_timeout must be > 0 seconds (or None), not {idle_timeout}")
        self._idle_timeout = None if idle_timeout is None else float(idle_timeout)
        if isinstance(frame_timeout, bool) or not isinstance(frame_timeout, (int, float)):
            raise TypeError(f"frame_timeout must be seconds, not {frame_timeout!r}")
        if not (frame_timeout > 0 and math.isfinite(frame_timeout)):
            raise ValueError(f"frame_timeout must be > 0 seconds, not {frame_timeout}")
        self._frame_timeout = float(frame_timeout)
        if isinstance(allow, str):
            allow = [allow]
        self._allow = None if allow is None else [parse_allow(a) for a in allow]
        if self._allow == []:
            raise ValueError("allow is empty: no client could connect (None allows any)")
        self._stats = GatewayStats()
        self._stats_lock = threading.Lock()
        self._server: socket.socket | None = None
        self._address: tuple[str, int] | None = None
        self._clients: dict[socket.socket, _Client] = {}
        #: Connections being refused (their first request answered 0x06), under the lock.
        self._refusing: set[socket.socket] = set()
        self._threads: list[threading.Thread] = []
        self._acceptor: threading.Thread | None = None
        self._stopping = threading.Event()

    # ---- lifecycle -----------------------------------------------------------------------

    def start(self) -> Gateway:
        """Listen and serve in background threads; returns at once. Idempotent.

        Raises OSError if the address cannot be bound (in use, not this machine's), and the
        Bus's PortError in a child made by fork.
        """
        self.bus._owned()
        if self._server is not None:
            return self
        host, port = self._listen
        if not _on_this_machine(host):
            log.warning(
                "gateway: listening on %s, beyond this machine: Modbus TCP has no "
                "authentication, whoever reaches the port drives the devices on the line; %s",
                host,
                "limit who may connect with allow (--allow ADDR[/BITS])"
                if self._allow is None
                else "only " + ", ".join(map(str, self._allow)) + " may connect",
            )
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        server = socket.socket(family, socket.SOCK_STREAM)
        try:
            server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            server.bind((host, port))
            server.listen()
            server.settimeout(0.2)  # so that stop() is seen
        except BaseException:
            server.close()
            raise
        self._stopping.clear()
        self._server = server
        self._address = server.getsockname()[:2]
        self._acceptor = self._spawn(self._accept_loop, "benchbus-gateway")
        log.info("gateway for %s listening on %s", self.bus.port, self.url)
        return self

    def stop(self) -> None:
        """Stop listening, close every client connection and end the threads (idempotent).

        A request already on its way finishes first (bounded by the Bus's timeout, retries
        and the unit's write interval), so nothing reaches the line after this returns. The
        Bus stays open: it is the caller's.

        In a child made by fork, it closes that process's copies of the sockets, without
        shutting the connections down, and waits for nothing: the threads and their locks
        are the parent's, whose gateway goes on serving.
        """
        server, self._server = self._server, None
        if server is None:
            return
        if forked(self.bus):
            clients, self._clients = list(self._clients), {}
            for sock in (server, *clients):
                with contextlib.suppress(OSError):
                    sock.close()
            return
        self._stopping.set()
        server.close()
        bus = self.bus
        longest_call = bus.timeout * (bus.retries + 1) + max(self._intervals.values(), default=0)
        deadline = time.monotonic() + longest_call + self._frame_timeout
        # Once the acceptor has ended, no client joins the lists below behind our back.
        if self._acceptor is not None:
            self._acceptor.join(max(0.0, deadline - time.monotonic()))
        with self._stats_lock:
            clients = [*self._clients, *self._refusing]
        for client in clients:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
        for thread in list(self._threads):
            thread.join(max(0.0, deadline - time.monotonic()))
        left = [t.name for t in self._threads if t.is_alive()]
        if left:  # pragma: no cover - a Bus call outlived its own bound
            log.error("gateway: threads still running after stop: %s", ", ".join(left))
        self._threads = []

    def serve_forever(self, poll: float = 0.2) -> None:
        """Start, then block until :meth:`stop` is called (from another thread or a signal)."""
        self.start()
        while not self._stopping.wait(poll):
            pass

    def __enter__(self) -> Gateway:
        """Start serving."""
        return self.start()

    def _leave(self, exc: BaseException | None) -> None:
        """Leaving a ``with`` block: stop serving (the Bus stays open)."""
        self.stop()

    @property
    def address(self) -> tuple[str, int]:
        """The ``(host, port)`` listened on (the real port when 0 was asked for)."""
        if self._address is None:
            raise RuntimeError("the gateway is not running: call start() first")
        return self._address

    @property
    def url(self) -> str:
        """What a client gives :class:`Bus` to reach the gateway: ``tcp://host:port``."""
        host, port = self.address
        return f"tcp://[{host}]:{port}" if ":" in host else f"tcp://{host}:{port}"

    @property
    def stats(self) -> GatewayStats:
        """A snapshot of the counters."""
        with self._stats_lock:
            return dataclasses.replace(self._stats)

    def __repr__(self) -> str:
        """``Gateway('/dev/ttyUSB0' on tcp://127.0.0.1:5020)``."""
        where = self.url if self._address is not None and self._server else "stopped"
        return f"Gateway({self.bus.port!r} on {where})"

    # ---- threads -------------------------------------------------------------------------

    def _spawn(self, target: Callable[..., None], name: str, *args: object) -> threading.Thread:
        thread = threading.Thread(target=target, args=args, name=name, daemon=True)
        self._threads = [t for t in self._threads if t.is_alive()]
        self._threads.append(thread)
        thread.start()
        return thread

    def _accept_loop(self) -> None:
        server = self._server
        while server is not None and not self._stopping.is_set():
            try:
                client, peer = server.accept()
            except TimeoutError:
                continue
            except OSError as exc:
                if self._stopping.is_set():
                    break  # closed by stop()
                # Out of file descriptors, a connection reset before it was accepted...:
                # the listening socket is still good, so keep serving.
                log.warning("gateway: accept failed: %s", exc)
                self._stopping.wait(0.1)
                continue
            if not self._allowed(peer[0]):
                self._count(refused=1)
                log.warning("gateway: %s may not connect (allow); connection closed", peer[0])
                client.close()
                continue
            with self._stats_lock:
                dropped = self._make_room()
                full = len(self._clients) >= self._max_clients
                answered = full and len(self._refusing) < _MOST_REFUSING
                if full:
                    self._stats.refused += 1
                    if answered:
                        self._refusing.add(client)
                else:
                    self._stats.connections += 1
                    self._clients[client] = _Client(time.monotonic())
            if dropped is not None:
                log.info(
                    "gateway: %d clients: the %s closed for %s", self._max_clients, dropped, peer
                )
            if full:
                log.warning(
                    "gateway: %d clients, none idle or slow: %s refused (0x06, server device busy)",
                    self._max_clients,
                    peer,
                )
                if answered:
                    self._spawn(self._refuse, f"benchbus-gateway-refuse-{peer[1]}", client)
                else:
                    client.close()
                continue
            log.debug("gateway: client %s connected", peer)
            self._spawn(self._serve_client, f"benchbus-gateway-{peer[1]}", client)

    def _allowed(self, host: str) -> bool:
        if self._allow is None:
            return True
        address = ipaddress.ip_address(host.partition("%")[0])
        if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
            address = address.ipv4_mapped  # an IPv4 client of a dual-stack socket
        return any(address in network for network in self._allow)

    def _make_room(self) -> str | None:
        """When ``max_clients`` are connected, close the one idle the longest, else the one
        whose request has been arriving the longest, if for over ``SLOW_REQUEST``; say which
        it was ("longest idle client", ...). None if there is room, or no client may
        be dropped: each is serving a request, or receiving one that began less than
        ``SLOW_REQUEST`` ago (call with the lock held)."""
        if len(self._clients) < self._max_clients:
            return None
        # A request whose first bytes wait unread is a request under way: not idle.
        idle = [(c.idle_since, s) for s, c in self._clients.items() if not c.busy]
        idle = [(since, s) for since, s in idle if not _readable(s)]
        slow_since = time.monotonic() - SLOW_REQUEST
        slow = [
            (c.arriving_since, s)
            for s, c in self._clients.items()
            if c.arriving_since is not None and c.arriving_since < slow_since
        ]
        if idle:
            _, sock = min(idle, key=lambda pair: pair[0])
            self._stats.idle_closed += 1
            which = "longest idle client"
        elif slow:
            _, sock = min(slow, key=lambda pair: pair[0])
            self._stats.slow_closed += 1
            which = "client slowest to send its request"
        else:
            return None
        del self._clients[sock]
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)  # its thread sees the end and closes it
        return which

    def _serve_client(self, client: socket.socket) -> None:
        try:
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            while not self._stopping.is_set():
                deadline = self._next_request(client)
                if deadline is None:
                    return
                try:
                    request = _recv_request(client, deadline)
                except TimeoutError:
                    self._too_slow(client)
                    return
                if request is None:
                    return
                header, pdu = request
                if not self._arrived(client):
                    return  # dropped while it arrived, to make room
                if pdu is None:
                    self._count(bad_frames=1)
                    log.warning(
                        "gateway: MBAP length %d out of range; connection dropped", header.length
                    )
                    return
                if header.protocol != 0:
                    self._count(bad_frames=1)
                    continue
                if self._stopping.is_set():
                    return
                reply = self.handle(header.unit, pdu)
                if reply is not None:
                    client.settimeout(self._frame_timeout)  # for a client that stops reading
                    client.sendall(_mbap.frame(header.transaction, header.unit, reply))
        except OSError as exc:
            log.debug("gateway: client connection ended: %s", exc)
        finally:
            with self._stats_lock:
                self._clients.pop(client, None)
            client.close()

    def _next_request(self, client: socket.socket) -> float | None:
        """Wait, idle, for the first byte of the client's next request; then mark it busy
        and arriving, and return the ``time.monotonic()`` by which it must have arrived
        whole. None when the client closed, was silent for ``idle_timeout`` or was dropped."""
        with self._stats_lock:
            state = self._clients.get(client)
            if state is None:
                return None
            if state.busy:  # its request was answered: idle from now
                state.busy, state.idle_since = False, time.monotonic()
        client.settimeout(self._idle_timeout)
        try:
            # Peeked, not read: while the byte waits, the client is not taken for idle.
            if not client.recv(1, socket.MSG_PEEK):
                return None
        except TimeoutError:
            with self._stats_lock:
                if self._clients.pop(client, None) is not None:
                    self._stats.idle_closed += 1
            log.debug("gateway: a client idle for %g s closed", self._idle_timeout)
            return None
        with self._stats_lock:
            state = self._clients.get(client)
            if state is None:
                return None
            state.busy = True
            state.arriving_since = time.monotonic()
            return state.arriving_since + self._frame_timeout

    def _too_slow(self, client: socket.socket) -> None:
        """Drop a client whose request did not arrive whole within ``frame_timeout`` of its
        first byte (its thread then closes it)."""
        with self._stats_lock:
            if self._clients.pop(client, None) is not None:
                self._stats.slow_closed += 1
        log.info(
            "gateway: a request not whole %g s after its first byte: connection dropped",
            self._frame_timeout,
        )

    def _arrived(self, client: socket.socket) -> bool:
        """Mark the client's request as arrived whole (from now on it is served, never
        dropped); False if the client was dropped meanwhile."""
        with self._stats_lock:
            state = self._clients.get(client)
            if state is None:
                return False
            state.arriving_since = None
            return True

    def _refuse(self, client: socket.socket) -> None:
        """Answer a client that came when every slot was taken: its first request, if it
        arrives whole within ``frame_timeout``, gets exception 0x06 (server device busy;
        none for a broadcast), then the connection is closed, after a short wait for the
        client to read the answer and close first."""
        try:
            request = _recv_request(client, time.monotonic() + self._frame_timeout)
            header, pdu = request or (None, None)
            if header is not None and pdu and header.protocol == 0 and header.unit != 0:
                busy = bytes([(pdu[0] | 0x80) & 0xFF, SERVER_DEVICE_BUSY])
                client.sendall(_mbap.frame(header.transaction, header.unit, busy))
            client.shutdown(socket.SHUT_WR)
            # Read what else it sent until it closes: a socket closed with bytes unread
            # resets the connection, which can cost the client the answer.
            linger = time.monotonic() + _REFUSAL_LINGER
            while (left := linger - time.monotonic()) > 0:
                client.settimeout(left)
                if not client.recv(4096):
                    break
        except OSError as exc:  # TimeoutError included: it was slow, or did not close
            log.debug("gateway: refused client: %s", exc)
        finally:
            with self._stats_lock:
                self._refusing.discard(client)
            client.close()

    def _count(self, **counts: int) -> None:
        with self._stats_lock:
            for name, n in counts.items():
                setattr(self._stats, name, getattr(self._stats, name) + n)

    # ---- requests ------------------------------------------------------------------------

    def handle(self, unit: int, pdu: bytes) -> bytes | None:
        """The reply PDU to request ``pdu`` for ``unit``, after it went over the Bus.

        None for a broadcast and for force listen only (0x08 / 0x04): no reply is due.
        Never raises for what a client sends or what happens on the line: those are
        exception replies. In a child made by fork, raises the Bus's PortError at once.
        """
        self.bus._owned()
        function = pdu[0] if pdu else 0
        reply: bytes | None = None
        refusal = None
        try:
            reply = self._forward(unit, function, pdu[1:])
        except ModbusException as exc:  # the unit's own answer (a gateway's, passed on)
            reply = bytes([function | 0x80, exc.code])
        except (ResponseTimeout, FrameError) as exc:
            log.debug("gateway: unit %d did not answer: %s", unit, exc)
            refusal = TARGET_FAILED
        except PortError as exc:
            log.warning("gateway: the line is unavailable: %s", exc)
            refusal = PATH_UNAVAILABLE
        except _Refused as exc:
            log.debug("gateway: request refused: %s", exc)
            refusal = exc.code
        except (ValueError, TypeError, IndexError) as exc:
            log.debug("gateway: request refused: %s", exc)
            refusal = ILLEGAL_DATA_VALUE
        except BenchbusError as exc:
            log.warning("gateway: request failed: %s", exc)
            refusal = SERVER_DEVICE_FAILURE
        self._count(requests=1)
        if unit == 0:  # a broadcast is never answered, whatever it asks and however it went
            return None
        if refusal is None:
            return reply  # None for force listen only: the unit answers nothing
        self._count(gateway_exceptions=1)
        return bytes([(function | 0x80) & 0xFF, refusal])

    def _forward(self, unit: int, function: int, data: bytes) -> bytes | None:
        """The reply PDU the line gave for request ``function`` / ``data``; None when none
        is due (a broadcast, force listen only). Raises what the Bus raises, ValueError for
        a broadcast the Bus refuses, _Refused for a request the core's rules refuse."""
        if unit == 0:  # a write to every unit: it keeps each one's interval
            interval = max(self._intervals.values(), default=0.0)
            self.bus._broadcast(function, data, write_interval=interval)
            return None
        refusal, reply_length, write = _request_rules(function, data)
        if refusal is not None:
            raise _Refused(*refusal)
        interval = self._intervals.get(unit, 0.0) if write else 0.0
        return self._ask(unit, function, data, reply_length, interval)

    def _ask(
        self,
        unit: int,
        function: int,
        data: bytes,
        reply_length: int | None,
        write_interval: float,
    ) -> bytes | None:
        """One request on the line, its reply PDU as the unit sent it (None: no reply due).

        Every function goes out as the client's PDU through :meth:`Bus.request`, its reply
        read by its length where the request tells it (``reply_length``), else by silence on
        the line, and paced by the Bus as a write by ``write_interval`` (retries too). Four
        read the Bus's own way, by the byte count their reply carries: the identification
        (0x2B / 0x0E, its pages followed), the server id (0x11), the comm event log (0x0C)
        and the FIFO queue (0x18, at most 31 values). Force listen only (0x08 / 0x04) is
        sent once, not awaited.
        """
        bus = self.bus
        if function == 0x2B and data[0] == _MEI_DEVICE_ID:
            conformity, objects = bus._device_identification(unit, data[1], data[2])
            return _identification_reply(data[1], conformity, objects)
        if function == 0x11:
            server_id = bus.report_server_id(unit)
            return bytes([0x11, len(server_id)]) + server_id
        if function == 0x0C:
            status, events, messages, log = bus.get_comm_event_log(unit)
            field = b"".join(w.to_bytes(2, "big") for w in (status, events, messages)) + log
            return bytes([0x0C, len(field)]) + field
        if function == 0x18:
            values = bus.read_fifo_queue(unit, int.from_bytes(data, "big"))
            field = b"".join(w.to_bytes(2, "big") for w in (len(values), *values))
            return bytes([0x18]) + len(field).to_bytes(2, "big") + field
        if function == 0x08 and data[:2] == _FORCE_LISTEN_ONLY:
            bus.diagnostics(unit, 0x04, data[2:])
            return None
        reply = bus.request(
            unit, function, data, reply_length=reply_length, write_interval=write_interval
        )
        return bytes([function]) + reply


#: Diagnostics (0x08) sub-function 0x04, force listen only: no device answers it.
_FORCE_LISTEN_ONLY = b"\x00\x04"


class _Refused(Exception):
    """A request the core's rules refuse, with the exception code it is answered with:
    0x01 for a function code no request has (0, 0x80 and up), 0x03 for a malformed one."""

    def __init__(self, code: int, why: str) -> None:
        super().__init__(why)
        self.code = code


def _recv_request(sock: socket.socket, deadline: float) -> tuple[_mbap.Header, bytes | None] | None:
    """The next request from ``sock``, whole by ``deadline`` (``time.monotonic()``): its
    header and PDU, or its header and None when its length is out of range (the rest is
    not read: the stream is out of step). None when the client closed first. Raises
    TimeoutError once ``deadline`` passes, however the bytes trickle in, and OSError."""
    data = _recv_exactly(sock, _mbap.HEADER_SIZE, deadline)
    if data is None:
        return None
    header = _mbap.Header.parse(data)
    if not header.length_ok:
        return header, None
    pdu = _recv_exactly(sock, header.length - 1, deadline)
    return None if pdu is None else (header, pdu)


def _recv_exactly(sock: socket.socket, n: int, deadline: float) -> bytes | None:
    """``n`` bytes from ``sock`` by ``deadline`` (``time.monotonic()``); None when the client
    closed first. Raises TimeoutError once the deadline passes: one deadline for them all,
    not one per ``recv``."""
    buf = b""
    while len(buf) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"{len(buf)} of {n} bytes by the deadline")
        sock.settimeout(left)
        chunk = sock.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf


def _readable(sock: socket.socket) -> bool:
    """Whether bytes (or the peer's close) wait to be read on ``sock``; does not wait."""
    if hasattr(select, "poll"):
        poller = select.poll()
        poller.register(sock, select.POLLIN)
        return bool(poller.poll(0))
    return bool(select.select([sock], [], [], 0)[0])  # pragma: no cover - Windows


def _identification_reply(read_code: int, conformity: int, objects: Mapping[int, bytes]) -> bytes:
    """A 0x2B / 0x0E reply PDU carrying as many of ``objects`` as fit, with the device's own
    conformity level; "more follows" and the next object's id when some do not (the client
    asks again from there). The objects' bytes go as the unit sent them."""
    body = b""
    count = 0
    next_object = 0
    more = 0x00
    for object_id, value in sorted(objects.items()):
        item = bytes([object_id, len(value[:245])]) + value[:245]
        if 7 + len(body) + len(item) > MAX_PDU:
            more, next_object = 0xFF, object_id
            break
        body += item
        count += 1
    return bytes([0x2B, _MEI_DEVICE_ID, read_code, conformity, more, next_object, count]) + body
