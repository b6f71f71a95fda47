"""A small Modbus TCP server that owns one Bus and serialises many clients onto its line.

::

    client process --tcp://--+
    client process --tcp://--+--> Gateway --> Bus --> /dev/ttyUSB0 (RS485)
    notebook ------ tcp:// --+

Each client connection gets a thread; every request goes through the one :class:`Bus`, which
runs one transaction at a time, so requests from several processes never interleave on the
line. The Bus keeps its own t3.5, timeout and retries on the serial side; the gateway adds
the per-unit write pacing the clients cannot keep for each other (``write_intervals``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from types import TracebackType

from benchbus._core import Bus
from benchbus.exceptions import (
    BenchbusError,
    FrameError,
    ModbusException,
    PortError,
    ResponseTimeout,
)

__all__ = ["Gateway", "GatewayStats", "parse_listen"]

log = logging.getLogger("benchbus.gateway")

#: Exception codes the gateway answers with itself (Modbus application protocol, 7).
ILLEGAL_FUNCTION = 0x01
ILLEGAL_DATA_VALUE = 0x03
SERVER_DEVICE_FAILURE = 0x04
PATH_UNAVAILABLE = 0x0A
TARGET_FAILED = 0x0B

#: The longest PDU (Modbus application protocol, 4.1).
MAX_PDU = 253
#: How long a client may stay silent mid-frame before its connection is dropped.
FRAME_TIMEOUT = 5.0
_MEI_DEVICE_ID = 0x0E


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (IPv6 in brackets: ``[::1]:5020``) as ``(host, port)``.

    Raises ValueError for anything else; port 0 asks for any free port.
    """
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise ValueError(f"listen address must be HOST:PORT, e.g. 127.0.0.1:5020, not {text!r}")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"listen port must be 0..65535, not {port!r}")
    return host, int(port)


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


class Gateway:
    """A Modbus TCP server for the units on one :class:`Bus` (``benchbus gateway``).

    ::

        with bb.Bus("/dev/ttyUSB0") as bus, bb.Gateway(bus, "127.0.0.1:5020") as gw:
            ...  # other processes open bb.Bus(gw.url) and use their devices as usual

    Forwards functions 0x03, 0x06, 0x10 and 0x2B / 0x0E (what the benchbus devices speak);
    any other function is answered exception 0x01. Unit 0 with 0x06 is a broadcast: sent,
    not answered. A failure on the line comes back as the gateway exceptions: 0x0B when the
    unit gave no valid reply (after the Bus's retries), 0x0A when the serial port is lost
    or closed. An exception reply from the unit is passed on as it is.

    ``write_intervals`` (``{unit: seconds}``) keeps that least time between two writes to a
    unit on the line, whichever client sends them (a J2 controller needs 0.15 s; the
    clients' own pacing cannot see each other's writes).
    """

    def __init__(
        self,
        bus: Bus,
        listen: str = "127.0.0.1:5020",
        *,
        write_intervals: Mapping[int, float] | None = None,
    ) -> None:
        """Serve ``bus``'s units on ``listen`` (``HOST:PORT``; port 0: any free port).

        Nothing listens until :meth:`start` (or ``with``). Raises ValueError for a bad
        address or interval, TypeError for a ``bus`` that is not a :class:`Bus`.
        """
        if not isinstance(bus, Bus):
            raise TypeError(f"bus must be a benchbus.Bus, not {type(bus).__name__}")
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
        self._last_write: dict[int, float] = {}
        self._unit_locks: dict[int, threading.Lock] = {}
        self._locks_lock = threading.Lock()
        self._stats = GatewayStats()
        self._stats_lock = threading.Lock()
        self._server: socket.socket | None = None
        self._address: tuple[str, int] | None = None
        self._clients: set[socket.socket] = set()
        self._threads: list[threading.Thread] = []
        self._stopping = threading.Event()

    # ---- lifecycle -----------------------------------------------------------------------

    def start(self) -> Gateway:
        """Listen and serve in background threads; returns at once. Idempotent.

        Raises OSError if the address cannot be bound (in use, not this machine's).
        """
        if self._server is not None:
            return self
        host, port = self._listen
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
        self._spawn(self._accept_loop, "benchbus-gateway")
        log.info("gateway for %s listening on %s", self.bus.port, self.url)
        return self

    def stop(self) -> None:
        """Stop listening, close every client connection and end the threads (idempotent).

        The Bus stays open: it is the caller's.
        """
        server, self._server = self._server, None
        if server is None:
            return
        self._stopping.set()
        server.close()
        with self._stats_lock:
            clients = list(self._clients)
        for client in clients:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
        for thread in self._threads:
            thread.join(FRAME_TIMEOUT)
        self._threads = []

    def serve_forever(self, poll: float = 0.2) -> None:
        """Start, then block until :meth:`stop` is called (from another thread or a signal)."""
        self.start()
        while not self._stopping.wait(poll):
            pass

    def __enter__(self) -> Gateway:
        """Start serving."""
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Stop serving (the Bus stays open)."""
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

    def _spawn(self, target: Callable[..., None], name: str, *args: object) -> None:
        thread = threading.Thread(target=target, args=args, name=name, daemon=True)
        self._threads = [t for t in self._threads if t.is_alive()]
        self._threads.append(thread)
        thread.start()

    def _accept_loop(self) -> None:
        server = self._server
        while server is not None and not self._stopping.is_set():
            try:
                client, peer = server.accept()
            except TimeoutError:
                continue
            except OSError:
                break  # closed by stop()
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._stats_lock:
                self._stats.connections += 1
                self._clients.add(client)
            log.debug("gateway: client %s connected", peer)
            self._spawn(self._serve_client, f"benchbus-gateway-{peer[1]}", client)

    def _serve_client(self, client: socket.socket) -> None:
        try:
            while not self._stopping.is_set():
                header = _recv_exactly(client, 7, first=True)
                if header is None:
                    return
                tid, pid, length, unit = struct.unpack(">HHHB", header)
                if not 2 <= length <= MAX_PDU + 1:
                    self._count(bad_frames=1)
                    log.warning("gateway: MBAP length %d out of range; connection dropped", length)
                    return
                pdu = _recv_exactly(client, length - 1)
                if pdu is None:
                    return
                if pid != 0:
                    self._count(bad_frames=1)
                    continue
                reply = self.handle(unit, pdu)
                if reply is not None:
                    client.sendall(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)
        except OSError as exc:
            log.debug("gateway: client connection ended: %s", exc)
        finally:
            with self._stats_lock:
                self._clients.discard(client)
            client.close()

    def _count(self, **counts: int) -> None:
        with self._stats_lock:
            for name, n in counts.items():
                setattr(self._stats, name, getattr(self._stats, name) + n)

    # ---- requests ------------------------------------------------------------------------

    def handle(self, unit: int, pdu: bytes) -> bytes | None:
        """The reply PDU to request ``pdu`` for ``unit``, after it went over the Bus.

        None for a broadcast (no reply). Never raises for what a client sends or what
        happens on the line: those are exception replies.
        """
        function = pdu[0] if pdu else 0
        try:
            reply = self._forward(unit, function, pdu[1:])
        except ModbusException as exc:  # the unit's own answer (a gateway's, passed on)
            reply = bytes([function | 0x80, exc.code])
        except (ResponseTimeout, FrameError) as exc:
            log.debug("gateway: unit %d did not answer: %s", unit, exc)
            reply = self._refusal(function, TARGET_FAILED)
        except PortError as exc:
            log.warning("gateway: the line is unavailable: %s", exc)
            reply = self._refusal(function, PATH_UNAVAILABLE)
        except (ValueError, TypeError, struct.error, IndexError) as exc:
            log.debug("gateway: request refused: %s", exc)
            reply = self._refusal(function, ILLEGAL_DATA_VALUE)
        except _Unsupported:
            reply = self._refusal(function, ILLEGAL_FUNCTION)
        except BenchbusError as exc:
            log.warning("gateway: request failed: %s", exc)
            reply = self._refusal(function, SERVER_DEVICE_FAILURE)
        self._count(requests=1)
        return reply

    def _refusal(self, function: int, code: int) -> bytes:
        self._count(gateway_exceptions=1)
        return bytes([(function | 0x80) & 0xFF, code])

    def _forward(self, unit: int, function: int, data: bytes) -> bytes | None:
        bus = self.bus
        if unit == 0:
            if function == 0x06 and len(data) == 4:
                address, value = struct.unpack(">HH", data)
                with self._paced(list(self._intervals)):
                    bus.broadcast_write_register(address, value)
                return None
            raise _Unsupported
        if function == 0x03 and len(data) == 4:
            address, count = struct.unpack(">HH", data)
            values = bus.read_holding_registers(unit, address, count)
            return struct.pack(f">BB{len(values)}H", 0x03, 2 * len(values), *values)
        if function == 0x06 and len(data) == 4:
            address, value = struct.unpack(">HH", data)
            with self._paced([unit]):
                bus.write_register(unit, address, value, accept_count_echo=True)
            return bytes([0x06]) + data
        if function == 0x10 and len(data) >= 5:
            address, count, size = struct.unpack(">HHB", data[:5])
            if size != 2 * count or len(data) != 5 + size:
                raise ValueError("byte count does not match the register count")
            values = list(struct.unpack(f">{count}H", data[5:]))
            with self._paced([unit]):
                bus.write_registers(unit, address, values)
            return struct.pack(">BHH", 0x10, address, count)
        if function == 0x2B and len(data) == 3 and data[0] == _MEI_DEVICE_ID:
            objects = bus.read_device_identification(unit, data[1], data[2])
            return _identification_reply(objects, data[1])
        raise _Unsupported

    @contextlib.contextmanager
    def _paced(self, units: list[int]) -> Iterator[None]:
        """Hold each of ``units``' write lock, wait out its interval, and note the write."""
        paced = sorted(u for u in units if self._intervals.get(u, 0.0) > 0.0)
        with contextlib.ExitStack() as held:
            for unit in paced:
                held.enter_context(self._unit_lock(unit))
            for unit in paced:
                ready = self._last_write.get(unit, -1e9) + self._intervals[unit]
                delay = ready - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            try:
                yield
            finally:
                now = time.monotonic()
                for unit in paced:
                    self._last_write[unit] = now

    def _unit_lock(self, unit: int) -> threading.Lock:
        with self._locks_lock:
            return self._unit_locks.setdefault(unit, threading.Lock())


class _Unsupported(Exception):
    """A function (or form of it) the gateway does not forward."""


def _recv_exactly(sock: socket.socket, n: int, *, first: bool = False) -> bytes | None:
    """``n`` bytes from ``sock``; None when the client closed (or stalled mid-frame)."""
    buf = b""
    while len(buf) < n:
        # Between frames a client may stay quiet for as long as it likes; within one, not.
        sock.settimeout(None if first and not buf else FRAME_TIMEOUT)
        try:
            chunk = sock.recv(n - len(buf))
        except TimeoutError:
            return None
        if not chunk:
            return None
        buf += chunk
    return buf


def _identification_reply(objects: Mapping[int, str], read_code: int) -> bytes:
    """A 0x2B / 0x0E reply PDU carrying as many of ``objects`` as fit; "more follows" and
    the next object's id when some do not (the client asks again from there)."""
    body = b""
    count = 0
    next_object = 0
    more = 0x00
    for object_id, text in sorted(objects.items()):
        value = text.encode("latin-1", "replace")[:245]
        item = bytes([object_id, len(value)]) + value
        if 7 + len(body) + len(item) > MAX_PDU:
            more, next_object = 0xFF, object_id
            break
        body += item
        count += 1
    conformity = read_code if 1 <= read_code <= 3 else 0x01
    return bytes([0x2B, _MEI_DEVICE_ID, read_code, conformity, more, next_object, count]) + body
