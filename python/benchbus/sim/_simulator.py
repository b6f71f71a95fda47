"""The Simulator: simulated Modbus units on a pseudo-terminal or loopback TCP, with faults."""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Mapping
from typing import Generic, Literal, TypeVar, overload

from benchbus import _mbap
from benchbus._scope import Scoped
from benchbus.sim._device import SimDevice, SimException
from benchbus.sim._faults import FAULT_KINDS, Faults
from benchbus.sim._functions import serve, took
from benchbus.sim._line import LOG_SIZE, Forwarder, PtyPair, SimState
from benchbus.sim._network import NETWORKS, NetworkProxy, NetworkState, probe
from benchbus.sim._pymodbus import PymodbusServer, SerialServer, TcpServer
from benchbus.sim._rtu import with_crc
from benchbus.sim._units import UnitHooks

__all__ = ["FRAMINGS", "Simulator"]

log = logging.getLogger("benchbus.sim")

D = TypeVar("D", bound=SimDevice)
_R = TypeVar("_R")

#: The framings a Simulator's line speaks.
FRAMINGS = ("rtu", "ascii")

_START_TIMEOUT = 5.0
_STOP_TIMEOUT = 5.0


class Simulator(Scoped, Generic[D]):
    """Simulated Modbus units served on a pseudo-terminal (or loopback TCP) the library opens.

    ::

        with Simulator({1: RegisterDevice({0x3006: 1450})}) as sim:
            bus = benchbus.Bus(sim.port)

    The library opens :attr:`port` (``/dev/pts/N``) as if it were a serial port; a pymodbus
    RTU server answers for :attr:`devices`, and a forwarder thread between the two sees every
    byte: it logs the frames (:attr:`requests`, :attr:`replies`) and applies the faults
    (:attr:`reply_delay`, :meth:`set_silent`, :meth:`corrupt_next`, :meth:`answer_exception`,
    :meth:`inject_raw`, :meth:`collide_next`, and the random faults of a noisy line,
    :attr:`faults`), all of which are thread-safe and may be set before or while running.
    The library's adapter may echo what it sends (:attr:`echo`). What the units hold, the truth
    a test checks the library's results against, is in :attr:`devices` (:meth:`peek`).
    The frame logs keep the most recent ``log_size`` frames each (10,000 by default), so a
    simulator served for days does not grow; :attr:`request_count` counts every request.

    The line serves one request at a time, as a half-duplex RS485 line does. Requests to a
    unit not in :attr:`devices`, or with a bad CRC, get no reply. A broadcast (unit 0) is
    given to every unit in turn and answered by none, except units whose
    :attr:`SimDevice.answers_broadcast` is set. A unit whose :attr:`SimDevice.answers_writes`
    is False acts on writes without answering them, and a unit's own
    :attr:`SimDevice.reply_delay` holds its replies (the larger of it and :attr:`reply_delay`
    applies). A unit may give its replies a form of its own (:meth:`SimDevice.shape_reply`,
    applied before the faults). A unit answers the functions of its
    :attr:`SimDevice.functions` (a :class:`RegisterDevice` every public function of the
    Modbus Application Protocol a master needs: coils, discrete inputs, input and holding
    registers, 0x16, 0x17, 0x07, 0x08 and 0x11; the device families the functions of
    their manuals), and exception 1 (illegal function) to any other. The set of units is
    fixed at :meth:`start`; a device object may be replaced in :attr:`devices` for a unit
    that exists.

    **Network.** ``Simulator(devices, network="tcp")`` serves the units as a Modbus TCP gateway
    does (MBAP frames), and ``network="rtu+tcp"`` as a transparent serial-to-Ethernet converter
    (RTU frames, CRC included, over TCP); :attr:`port` is then ``tcp://127.0.0.1:N`` or
    ``rtu+tcp://127.0.0.1:N``. A pymodbus TCP server answers for the units behind a proxy thread
    listening on that port, which accepts several client connections at once (each with its own
    connection to the server; the requests of one connection are served one at a time, in
    order), logs every frame as it crossed the socket (:attr:`requests`, :attr:`replies`; the
    MBAP header included) and applies the faults. The units answer the same functions as on a
    line, the serial line's 0x07, 0x08 and 0x11 too (as serial devices behind a gateway would).
    The line's rules above hold, except on ``tcp``: a request to a unit not in :attr:`devices`,
    or one the server leaves unanswered for 1 s, is answered with exception 0x0B (gateway target
    failed to respond), while a request to a silent unit (:meth:`set_silent`) or to one in the
    Diagnostics' listen only mode (see :class:`SimDevice`), a write to a unit that does not
    answer writes and a broadcast get NO reply at all, as behind a gateway whose own timeout is
    longer than the client's. Replies the simulator makes (:meth:`answer_exception`, illegal
    function, 0x0B) and a broadcast answered by a unit carry the request's transaction id; the
    latter the unit's own unit id. :meth:`SimDevice.shape_reply` sees and gives RTU frames on
    both networks. An MBAP header whose protocol id is not 0, or whose length is not 2..254,
    closes the connection. Network only: :meth:`reset_next`, :meth:`refuse_connections`,
    :meth:`drop_connections`, :attr:`connections`, :attr:`accepted`. Refused on ``tcp``
    (ValueError): :meth:`corrupt_next`, :meth:`collide_next`, :attr:`faults`. Refused on any
    network (ValueError): ``echo=True``.
    """

    def __init__(
        self,
        devices: Mapping[int, D] | D,
        *,
        baudrate: int = 19200,
        broadcast: bool = True,
        faults: Faults | None = None,
        echo: bool = False,
        network: str | None = None,
        log_size: int = LOG_SIZE,
        framing: str = "rtu",
    ) -> None:
        """Simulate ``devices`` (``{unit: device}``; a single device is unit 1).

        Units are 1..255: Modbus reserves 248..255, but some instruments (the J2
        controllers) take station numbers up to 255. Unit 0 is the broadcast.

        ``baudrate`` only sets the end-of-frame silence (the pseudo-terminal carries bytes
        instantly). ``broadcast=False`` makes the units ignore unit 0 entirely. ``faults``
        makes the line noisy from the first reply on (see :attr:`faults`). ``echo=True``
        makes the library's adapter echo what it sends (see :attr:`echo`). ``network``
        (``"tcp"`` or ``"rtu+tcp"``) serves the units over loopback TCP instead of a
        pseudo-terminal (see the class doc); ``baudrate`` then only sets the silent gap that
        ends an RTU frame of unknown length. ``log_size`` is how many frames each log
        (:attr:`requests`, :attr:`request_times`, :attr:`replies`) keeps, the most recent:
        an int >= 1, 10,000 by default. ``framing="ascii"`` serves the line in Modbus ASCII
        (see :attr:`framing`; the pseudo-terminal line only: ValueError with ``network``).
        """
        if isinstance(devices, SimDevice):
            devices = {1: devices}
        #: The simulated devices by unit address; a device may be replaced for a unit
        #: while the simulator runs (the set of units is fixed at :meth:`start`).
        self.devices: dict[int, D] = dict(devices)
        for unit, device in self.devices.items():
            if isinstance(unit, bool) or not isinstance(unit, int) or not 1 <= unit <= 255:
                raise ValueError(f"a unit address is 1..255, not {unit!r}")
            if not isinstance(device, SimDevice):
                raise TypeError(f"unit {unit}: {type(device).__name__} is not a SimDevice")
        if isinstance(baudrate, bool) or not isinstance(baudrate, int) or baudrate <= 0:
            raise ValueError(f"baudrate must be a positive int, not {baudrate!r}")
        if network is not None and network not in NETWORKS:
            raise ValueError(f"network must be None or one of {NETWORKS}, not {network!r}")
        if framing not in FRAMINGS:
            raise ValueError(f"framing must be one of {FRAMINGS}, not {framing!r}")
        if framing == "ascii" and network is not None:
            raise ValueError(
                "framing='ascii' is served on the pseudo-terminal line only, not a network"
            )
        self._framing: str = framing
        if isinstance(log_size, bool) or not isinstance(log_size, int):
            raise TypeError(f"log_size must be an int, not {type(log_size).__name__}")
        if log_size < 1:
            raise ValueError(f"log_size must be >= 1, not {log_size}")
        self._network: str | None = network
        #: The line's baud rate, which sets its character and t3.5 timing.
        self.baudrate: int = baudrate
        #: Whether the devices act on broadcasts (unit 0).
        self.broadcast: bool = broadcast
        #: Exceptions other than SimException raised by device handlers (each answered with
        #: exception 4), and failures of :meth:`SimDevice.shape_reply` (the reply then goes
        #: unchanged); a test can assert this stays empty.
        self.errors: list[BaseException] = []
        self._state: SimState = SimState(log_size) if network is None else NetworkState(log_size)
        self._refusing = False
        self.echo = echo
        self._faults: Faults | None = None
        self.faults = faults
        self._lifecycle = threading.Lock()
        self._pairs: list[PtyPair] = []
        self._forwarder: Forwarder | None = None
        self._proxy: NetworkProxy | None = None
        self._server: PymodbusServer | None = None
        self._port: str | None = None

    # ---- lifecycle -------------------------------------------------------------------------

    @property
    def network(self) -> str | None:
        """``"tcp"``, ``"rtu+tcp"``, or None for a pseudo-terminal line."""
        return self._network

    @property
    def framing(self) -> str:
        """``"rtu"``, or ``"ascii"``: the line speaks Modbus ASCII to the library (``:``,
        hex, LRC, CR LF, from the serial line spec; a frame with a bad LRC gets no reply, a
        frame begun and left for over 1 s is dropped). The units behind it speak RTU: the
        logs (:attr:`requests`, :attr:`replies`) hold each frame as the RTU frame of its unit
        and PDU, and the faults spoil those, a spoiled reply going out with a bad LRC.
        :meth:`inject_raw` puts its bytes on the line as they are."""
        return self._framing

    @property
    def port(self) -> str:
        """What the library opens; new at each start.

        The pseudo-terminal path (``/dev/pts/N``), or on a network the URL
        ``tcp://127.0.0.1:N`` / ``rtu+tcp://127.0.0.1:N``.
        """
        if self._port is None:
            raise RuntimeError("the simulator is not running: call start() first")
        return self._port

    @property
    def running(self) -> bool:
        """Whether the simulator is started and not stopped."""
        return self._port is not None

    def start(self) -> Simulator[D]:
        """Open the line and serve; returns once a request has been answered through it.

        Does nothing if already running. Raises RuntimeError if the server does not come up.
        """
        with self._lifecycle:
            if self._port is not None:
                return self
            try:
                self._start()
            except BaseException:
                self._stop()
                raise
        return self

    def _start(self) -> None:
        if self._network is not None:
            self._start_network(self._network)
            return
        library, server = PtyPair(), PtyPair()
        self._pairs = [library, server]
        units = frozenset(self.devices)
        self._forwarder = Forwarder(
            self._state,
            library,
            server,
            units=units,
            broadcast=self.broadcast,
            hooks=self._unit_hooks("simulator"),
            baudrate=self.baudrate,
            ascii=self._framing == "ascii",
        )
        self._server = SerialServer(
            server.path,
            sorted(units),
            baudrate=self.baudrate,
            dispatch=self._dispatch,
            identity_of=self._identity_of,
            serve=self._serve,
        )
        self._server.start(_START_TIMEOUT)
        self._forwarder.start()
        # Prove the server answers: Diagnostics 0x08 / 0x00 "return query data" is echoed
        # without touching any device (the probe passes by the units' own functions).
        probe = with_crc(bytes([min(units, default=1), 0x08, 0x00, 0x00]) + os.urandom(2))
        for _ in range(3):
            if self._forwarder.probe(probe, timeout=_START_TIMEOUT / 3) == probe:
                break
        else:
            raise RuntimeError("the simulator's server does not answer")
        self._port = library.path

    def _unit_hooks(self, who: str) -> UnitHooks:
        """The units' callbacks, for the line or the network (``who`` names it in the log)."""
        return UnitHooks(
            who,
            answers_broadcast=lambda unit: bool(self.devices[unit].answers_broadcast),
            answers_writes=lambda unit: bool(self.devices[unit].answers_writes),
            reply_delay=lambda unit: float(self.devices[unit].reply_delay),
            shape_reply=self._shape_reply,
            functions=lambda unit: self.devices[unit].functions,
            took=lambda unit, pdu, reply, broadcast, listen_only: took(
                self.devices[unit], pdu, reply, broadcast=broadcast, listen_only=listen_only
            ),
        )

    def _start_network(self, network: str) -> None:
        units = frozenset(self.devices)
        rtu = network == "rtu+tcp"
        server = TcpServer(
            sorted(units),
            rtu=rtu,
            dispatch=self._dispatch,
            identity_of=self._identity_of,
            serve=self._serve,
        )
        self._server = server
        server.start(_START_TIMEOUT)
        # Prove the server answers (see _start), straight to it, past the gateway.
        pdu = bytes([0x08, 0x00, 0x00]) + os.urandom(2)
        unit = min(units, default=1)
        if rtu:
            probe_frame = with_crc(bytes([unit]) + pdu)
        else:
            probe_frame = _mbap.frame(int.from_bytes(os.urandom(2), "big"), unit, pdu)
        for _ in range(3):
            if probe(server.address, probe_frame, timeout=_START_TIMEOUT / 3) == probe_frame:
                break
        else:
            raise RuntimeError("the simulator's server does not answer")
        assert isinstance(self._state, NetworkState)
        self._proxy = NetworkProxy(
            self._state,
            server.address,
            network=network,
            units=units,
            broadcast=self.broadcast,
            hooks=self._unit_hooks("simulator gateway"),
            baudrate=self.baudrate,
            refuse=self._refusing,
        )
        self._proxy.start()
        host, port = self._proxy.address
        self._port = f"{network}://{host}:{port}"

    def stop(self) -> None:
        """Stop serving and release every thread and file descriptor (idempotent).

        On a network this closes every client connection and the port.
        """
        with self._lifecycle:
            self._stop()

    def _stop(self) -> None:
        self._port = None
        if self._proxy is not None:
            self._proxy.stop(_STOP_TIMEOUT)
            self._proxy = None
        if self._server is not None:
            self._server.stop(_STOP_TIMEOUT)
            self._server = None
        if self._forwarder is not None:
            self._forwarder.stop(_STOP_TIMEOUT)
            self._forwarder = None
        for pair in self._pairs:
            pair.close()
        self._pairs = []

    def __enter__(self) -> Simulator[D]:
        """Start (see :meth:`start`)."""
        return self.start()

    def _leave(self, exc: BaseException | None) -> None:
        """Stop (see :meth:`stop`)."""
        self.stop()

    def __repr__(self) -> str:
        """Units, port and state."""
        where = f"port={self._port!r}" if self._port else "stopped"
        return f"<Simulator units={sorted(self.devices)} {where}>"

    # ---- faults ----------------------------------------------------------------------------

    @property
    def reply_delay(self) -> float:
        """Seconds each reply is held before it is released toward the library (0 = none).

        A unit with a longer :attr:`SimDevice.reply_delay` of its own holds its replies for
        that long instead.
        """
        with self._state.lock:
            return self._state.reply_delay

    @reply_delay.setter
    def reply_delay(self, seconds: float) -> None:
        seconds = float(seconds)
        if not seconds >= 0.0:
            raise ValueError(f"reply_delay must be >= 0, not {seconds}")
        with self._state.lock:
            self._state.reply_delay = seconds

    def set_silent(self, unit: int | None, silent: bool = True) -> None:
        """Swallow every request to ``unit`` (None: to all units): no reply, no action.

        ``set_silent(unit, False)`` undoes it; ``set_silent(None, False)`` undoes all of it.
        A silent unit does not take part in broadcasts either. Requests are still logged.
        """
        with self._state.lock:
            if unit is None:
                self._state.silent_all = silent
                if not silent:
                    self._state.silent_units.clear()
            elif silent:
                self._state.silent_units.add(unit)
            else:
                self._state.silent_units.discard(unit)

    def corrupt_next(self, n: int = 1) -> None:
        """Corrupt the CRC of the next ``n`` replies (adds to any still pending).

        ValueError on a ``tcp`` network: an MBAP frame has no CRC (TCP's own checks keep
        bytes intact); :meth:`reset_next` spoils a reply there.
        """
        self._refuse_on("tcp", "corrupt_next: a Modbus TCP (MBAP) reply has no CRC to corrupt")
        if n < 0:
            raise ValueError(f"n must be >= 0, not {n}")
        with self._state.lock:
            self._state.corrupt += n

    @property
    def echo(self) -> bool:
        """Whether the library's adapter echoes what it sends, as an RS485 adapter whose
        receiver stays on while it transmits does: every request comes back to the library,
        ahead of its reply (open the Bus with ``echo=True``). May be set while running.
        """
        return self._state.echo

    @echo.setter
    def echo(self, echo: bool) -> None:
        if not isinstance(echo, bool):
            raise TypeError(f"echo must be True or False, not {echo!r}")
        if echo and self._network is not None:
            raise ValueError("echo: a TCP connection does not echo what the library sends")
        with self._state.lock:
            self._state.echo = echo

    def collide_next(self, n: int = 1) -> None:
        """Garble the next ``n`` requests as a collision with another talker would.

        The units get the garbled frame (a bad CRC: ignored, no reply) and, with
        :attr:`echo`, the library's echo carries the same garbled frame. Adds to any still
        pending; :meth:`clear_faults` cancels them. On ``rtu+tcp`` the request reaches the
        units garbled (a collision on the serial line behind the converter); ValueError on
        ``tcp``.
        """
        self._refuse_on("tcp", "collide_next: a Modbus TCP request cannot collide")
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"n must be an int >= 0, not {n!r}")
        with self._state.lock:
            self._state.collisions += n

    def answer_exception(self, code: int, n: int = 1, unit: int | None = None) -> None:
        """Answer the next ``n`` requests (to ``unit``; None = any unit) with exception ``code``.

        The reply is ``unit, function | 0x80, code, CRC`` and the device does not see the
        request (a write is not applied). Broadcasts, silent units and units that do not
        exist do not use up the count.
        """
        SimException(code)  # validates the code
        if n < 1:
            raise ValueError(f"n must be >= 1, not {n}")
        self._state.add_exception_rule(code, n, unit)

    def inject_raw(self, data: bytes) -> None:
        """Put ``data`` on the line toward the library now; returns once it is written.

        The bytes are not logged as a reply. On a network they go to every client
        connection open now (none: they are lost).
        """
        if self._proxy is not None:
            self._proxy.inject(bytes(data))
            return
        if self._forwarder is None:
            raise RuntimeError("the simulator is not running: call start() first")
        self._forwarder.inject(bytes(data))

    @property
    def faults(self) -> Faults | None:
        """The random faults spoiling replies on the line (a :class:`Faults`), or None.

        Setting a :class:`Faults` (also while running, from any thread) starts its random
        sequence afresh from the next reply on, and restarts :attr:`fault_counts`; setting
        None makes the line clean again and keeps the counts. On ``rtu+tcp`` they spoil the
        RTU replies the converter passes on; a ``tcp`` network refuses them (ValueError).
        """
        return self._faults

    @faults.setter
    def faults(self, faults: Faults | None) -> None:
        if faults is not None and not isinstance(faults, Faults):
            raise TypeError(f"faults must be a Faults or None, not {type(faults).__name__}")
        if faults is not None:
            self._refuse_on("tcp", "faults: the random faults of a noisy line spoil RTU frames")
        self._state.set_faults(faults)
        self._faults = faults

    @property
    def fault_counts(self) -> dict[str, int]:
        """How many faults of each kind were injected since :attr:`faults` was last set.

        A new dict with every kind of :data:`FAULT_KINDS` (0 when none); faults from
        :meth:`corrupt_next` and the other deterministic methods are not counted.
        """
        with self._state.lock:
            counts = dict(self._state.fault_counts)
        return {kind: counts.get(kind, 0) for kind in FAULT_KINDS}

    def clear_faults(self) -> None:
        """Remove every fault: no delay, nobody silent, no pending corruption or exception.

        Also stops the random faults (:attr:`faults` becomes None; the counts stay), and on a
        network cancels pending :meth:`reset_next` and accepts connections again.
        """
        self.faults = None
        with self._state.lock:
            self._state.reply_delay = 0.0
            self._state.silent_all = False
            self._state.silent_units.clear()
            self._state.collisions = 0
            self._state.corrupt = 0
            self._state.exception_rules.clear()
            if isinstance(self._state, NetworkState):
                self._state.resets = 0
        if self._network is not None and self._refusing:
            self.refuse_connections(False)

    # ---- network only ----------------------------------------------------------------------

    def _refuse_on(self, network: str, message: str) -> None:
        if self._network == network:
            raise ValueError(f"{message} (network={network!r})")

    def _network_state(self, what: str) -> NetworkState:
        if not isinstance(self._state, NetworkState):
            raise ValueError(f"{what}: only a network simulator (network='tcp' or 'rtu+tcp')")
        return self._state

    def reset_next(self, n: int = 1) -> None:
        """Cut the next ``n`` replies halfway and reset their connection (network only).

        As a gateway dying mid-reply: the first half of the reply (``len // 2`` bytes,
        logged in :attr:`replies`) goes to the client, then the connection is closed with
        SO_LINGER 0 (a TCP reset), and the requests still queued on it are lost. Adds to any
        still pending; :meth:`clear_faults` cancels them. Replies that are not sent (silent
        units) do not use up the count.
        """
        state = self._network_state("reset_next")
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"n must be an int >= 0, not {n!r}")
        with state.lock:
            state.resets += n

    def refuse_connections(self, refuse: bool = True) -> None:
        """Refuse new connections (True) or accept them again (False); network only.

        Refusing closes the listening socket, so a connect gets ECONNREFUSED
        (``ConnectionRefusedError``); connections already open stay (see
        :meth:`drop_connections`). Accepting again listens on the same port. Returns once
        done; may be called before :meth:`start` (then nothing listens from the start, and
        :attr:`port` still names the port) and holds across restarts.
        """
        self._network_state("refuse_connections")
        with self._lifecycle:
            self._refusing = bool(refuse)
            if self._proxy is not None:
                self._proxy.refuse(self._refusing)

    def drop_connections(self, reset: bool = False) -> None:
        """Close every client connection open now (network only); returns once done.

        The client sees an end of stream (with ``reset``: a TCP reset, ECONNRESET). Its
        pending requests and held replies are lost; the port keeps accepting connections.
        """
        self._network_state("drop_connections")
        with self._lifecycle:
            if self._proxy is not None:
                self._proxy.drop(reset=reset)

    @property
    def connections(self) -> int:
        """How many client connections are open now (network only; 0 when stopped)."""
        self._network_state("connections")
        proxy = self._proxy
        return 0 if proxy is None else proxy.connections

    @property
    def accepted(self) -> int:
        """How many client connections were accepted since :meth:`start` (network only)."""
        self._network_state("accepted")
        proxy = self._proxy
        return 0 if proxy is None else proxy.accepted

    # ---- observation -----------------------------------------------------------------------

    @property
    def log_size(self) -> int:
        """How many frames each log keeps (the most recent ones); see :attr:`requests`."""
        return int(self._state.requests.maxlen or 0)

    @property
    def requests(self) -> list[bytes]:
        """The request frames received from the library, oldest first (as received, CRC
        too): the most recent :attr:`log_size` of them (older ones are dropped, so the log
        does not grow without bound; :attr:`request_count` counts them all).

        On a network: from every connection, the frames as they crossed the socket (the
        MBAP header included for ``tcp``). A new list at each access: a snapshot.
        """
        with self._state.lock:
            return list(self._state.requests)

    @property
    def request_times(self) -> list[float]:
        """When each frame in :attr:`requests` was complete at the line, ``time.monotonic()``.

        Same order and length as :attr:`requests`: the time the forwarder read the frame's
        last byte from the library's end of the line (for a frame cut by a silent gap, not
        the end of the gap). For checking the spacing of a master's requests. Read with
        :attr:`requests` while the line is idle to pair them up.
        """
        with self._state.lock:
            return list(self._state.request_times)

    @property
    def replies(self) -> list[bytes]:
        """The reply frames sent toward the library, oldest first (as sent, after the
        faults): the most recent :attr:`log_size` of them. A new list at each access."""
        with self._state.lock:
            return list(self._state.replies)

    @property
    def request_count(self) -> int:
        """How many requests came since the start (or :meth:`clear_log`), also those the
        bounded :attr:`requests` log no longer holds."""
        with self._state.lock:
            return self._state.request_count

    @overload
    def peek(
        self,
        unit: int,
        address: int,
        count: int = 1,
        *,
        table: Literal["holding", "input"] = "holding",
    ) -> list[int]: ...

    @overload
    def peek(
        self, unit: int, address: int, count: int = 1, *, table: Literal["coils", "discrete"]
    ) -> list[bool]: ...

    def peek(
        self, unit: int, address: int, count: int = 1, *, table: str = "holding"
    ) -> list[int] | list[bool]:
        """What unit ``unit`` holds in ``count`` entries of ``table`` from ``address``: the
        truth.

        ``table`` is ``"holding"`` (registers, the default), ``"input"`` (input registers),
        ``"coils"`` or ``"discrete"`` (discrete inputs; both as bools). Asks the device
        directly (:meth:`SimDevice.read_holding`, :meth:`SimDevice.read_input_registers`,
        :meth:`SimDevice.read_coils`, :meth:`SimDevice.read_discrete_inputs`), past the line
        and its faults, and logs nothing; a :class:`SimException` the device raises
        propagates. For checking what the library returned, between its calls (the server
        thread may be handling a request meanwhile otherwise).
        """
        if unit not in self.devices:
            raise ValueError(f"no simulated unit {unit!r}")
        device = self.devices[unit]
        if table == "holding":
            return list(device.read_holding(address, count))
        if table == "input":
            return list(device.read_input_registers(address, count))
        if table == "coils":
            return [bool(b) for b in device.read_coils(address, count)]
        if table == "discrete":
            return [bool(b) for b in device.read_discrete_inputs(address, count)]
        raise ValueError(f"table must be 'holding', 'input', 'coils' or 'discrete', not {table!r}")

    def clear_log(self) -> None:
        """Empty :attr:`requests`, :attr:`request_times` and :attr:`replies`, and set
        :attr:`request_count` to 0."""
        with self._state.lock:
            self._state.clear_log()

    # ---- called by the server thread -------------------------------------------------------

    def _dispatch(
        self, unit: int, function: int, address: int, count: int, values: list[int] | None
    ) -> list[int] | int | None:
        device = self.devices[unit]
        wanted, limit = (
            (count, device.max_read) if values is None else (len(values), device.max_write)
        )
        if not 1 <= wanted <= limit:  # the device's own limit (its manual's), as data
            return int(device.too_many_code)
        return self._answer(unit, function, lambda: _holding(device, address, count, values))

    def _serve(self, unit: int, function: int, data: bytes) -> bytes | int:
        """The reply data of ``unit`` to ``function`` with ``data`` (see
        ``benchbus.sim._functions``), or its exception code."""
        return self._answer(unit, function, lambda: serve(self.devices[unit], function, data))

    def _answer(self, unit: int, function: int, call: Callable[[], _R]) -> _R | int:
        """``call()``, or the exception code ``unit`` answers instead: a
        :class:`SimException`'s, or 4 for any other error (kept in :attr:`errors`)."""
        try:
            return call()
        except SimException as exc:
            return exc.code
        except Exception as exc:
            log.exception("simulated unit %d failed on function %#04x", unit, function)
            self.errors.append(exc)
            return SimException.SERVER_DEVICE_FAILURE

    def _shape_reply(self, unit: int, request: bytes, reply: bytes) -> bytes:
        """The unit's :meth:`SimDevice.shape_reply`; on failure the reply as it is."""
        device = self.devices[unit]
        try:
            shaped = device.shape_reply(request, reply)
            if not isinstance(shaped, (bytes, bytearray)) or len(shaped) < 4:
                raise TypeError(
                    f"{type(device).__name__}.shape_reply returned {shaped!r}: expected a"
                    " frame of at least 4 bytes"
                )
        except Exception as exc:
            log.exception("simulated unit %d: shape_reply failed; reply sent unchanged", unit)
            self.errors.append(exc)
            return reply
        return bytes(shaped)

    def _identity_of(self, unit: int) -> Mapping[int, str] | None:
        device = self.devices.get(unit)
        return None if device is None else device.identity


def _holding(
    device: SimDevice, address: int, count: int, values: list[int] | None
) -> list[int] | None:
    """``device``'s read of ``count`` holding registers, checked, or its write of ``values``."""
    if values is not None:
        device.write_holding(address, values)
        return None
    result = device.read_holding(address, count)
    if len(result) != count or not all(isinstance(v, int) and 0 <= v <= 0xFFFF for v in result):
        raise ValueError(
            f"{type(device).__name__}.read_holding({address}, {count}) returned"
            f" {result!r}: expected {count} ints 0..0xFFFF"
        )
    return [int(v) for v in result]
