"""Everything that knows pymodbus (3.16.x): the servers behind the simulated line and gateway.

pymodbus changes its server and datastore API between minor versions, so this is the one
module to change when it does. What 3.16 offers and how it is used here:

- ``ModbusServerContext`` / ``ModbusDeviceContext`` / ``ModbusSequentialDataBlock`` are
  deprecated for 4.0 (they log a warning; the sequential block's address is now offset by
  one). The non-deprecated datastore is ``pymodbus.simulator.SimDevice`` with ``SimData``
  blocks and an ``action`` coroutine, which pymodbus awaits on every register access with
  ``(function code, block start, address, count, registers, values to write or None)``. Each
  simulated unit is one such SimDevice whose action calls into the benchbus ``SimDevice``.
- An action signals an exception reply by returning an ``ExcCodes`` member; pymodbus then
  builds the reply itself. ``ExcCodes`` has only 1..8, 0x0A and 0x0B: for any other code the
  action returns 4 and the server puts the code into the reply (see ``trace_pdu`` below).
- Read Device Identification (0x2B/0x0E) in pymodbus answers from one process-wide
  ``ModbusControlBlock`` identity and ignores ``SimDevice.identity``. A per-unit identity
  needs a custom request PDU, passed as ``custom_pdu=``. The server's decoder takes the
  custom class for function 0x2B, but would swap pymodbus's own class back in for any
  request whose sub-function code is >= 0, so the custom class reports none (-1).
- pymodbus's ``DeviceInformationFactory`` answers a stream (read codes 1..3) that starts
  at an object id the stream does not hold with no objects at all for the basic stream
  (and for the regular one started at a private id); the spec says to restart at object 0,
  so the request class does that before asking the factory.
- The server's decoder takes a custom request class for a function pymodbus has classes of
  its own for too (``DecodePDU.register`` replaces the entry of its table). The functions
  beyond 0x03, 0x06, 0x10 and 0x2B get one such class each (:func:`_raw_request`): it
  keeps the request's data as bytes, hands them to ``serve`` and sends back the bytes it
  gives (or an exception reply with the code it gives), so pymodbus only frames them and
  its own datastore, process-wide control block (0x07, 0x08, 0x11) and checks are not
  used. The RTU framer asks the class for the request's length
  (``calculateRtuFrameSize``, 0 while more bytes are needed): the simulator's own
  ``request_length``, or all there is for a function whose length it cannot tell (0x08:
  the line delivers one whole frame at a time).
- An exception reply pymodbus builds from an ``ExcCodes`` member can carry any code once
  built: ``ExceptionResponse.encode`` packs whatever ``exception_code`` holds. The server's
  ``trace_pdu`` hook sees every PDU it sends, so for a code ``ExcCodes`` lacks the action
  returns 4 and the hook puts the real code into the reply. The action and the send of its
  reply run in one event-loop step (nothing between them suspends), so the code cannot go
  to another connection's reply.
- ``ModbusSerialServer`` opens the port with pyserial (8N1 here: a pseudo-terminal has no
  parity bit and pyserial fails on 8E1), must be built inside a running event loop, and
  ``serve_forever(background=True)`` returns once it listens.
- ``ModbusTcpServer`` takes ``framer=FramerType.SOCKET`` (MBAP) or ``FramerType.RTU`` (RTU
  frames over TCP, CRC included) and ``address=(host, port)``; port 0 binds an ephemeral
  port, read back from the listening ``asyncio.Server`` in ``server.transport``. Each client
  connection gets its own request handler; a request for a unit it does not serve is ignored
  with ``ignore_missing_devices=True`` (with False it answers exception 0x0B). It handles one
  frame per received chunk, so the simulator's gateway sends one request at a time.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from benchbus._extras import sim_missing
from benchbus.sim._functions import FUNCTIONS
from benchbus.sim._rtu import request_length

try:
    # pymodbus imports pyserial only when it opens a port: ask for it here, so that a
    # missing pyserial is said at import like a missing pymodbus.
    import serial  # type: ignore[import-untyped]  # noqa: F401
    from pymodbus.constants import DeviceInformation, ExcCodes
    from pymodbus.framer import FramerType
    from pymodbus.pdu import ExceptionResponse, ModbusPDU
    from pymodbus.pdu.device import DeviceInformationFactory, ModbusDeviceIdentification
    from pymodbus.pdu.mei_message import ReadDeviceInformationResponse
    from pymodbus.server import ModbusBaseServer, ModbusSerialServer, ModbusTcpServer
    from pymodbus.simulator import DataType, SimData
    from pymodbus.simulator import SimDevice as PymodbusSimDevice
except ImportError as exc:
    missing = sim_missing(exc)
    if missing is None:
        raise
    raise missing from exc

__all__ = ["Dispatch", "IdentityOf", "PymodbusServer", "SerialServer", "Serve", "TcpServer"]

log = logging.getLogger("benchbus.sim")

#: ``(unit, function, address, count, values or None)`` -> registers read, None (written),
#: or an int exception code.
Dispatch = Callable[[int, int, int, int, "list[int] | None"], "list[int] | int | None"]
#: unit -> its Read Device Identification objects, or None when it has none.
IdentityOf = Callable[[int], "Mapping[int, str] | None"]
#: ``(unit, function, request data)`` -> the reply's data (after the function code), or an
#: int exception code.
Serve = Callable[[int, int, bytes], "bytes | int"]

_EXC_CODES = {int(c) for c in ExcCodes}

#: The object ids each stream access (read codes 1 basic, 2 regular, 3 extended) may send.
_STREAM_OBJECTS: dict[int, frozenset[int]] = {
    DeviceInformation.BASIC: frozenset(range(0x00, 0x03)),
    DeviceInformation.REGULAR: frozenset(range(0x00, 0x07)),
    DeviceInformation.EXTENDED: frozenset([*range(0x00, 0x07), *range(0x80, 0x100)]),
}


class _Control:
    """What DeviceInformationFactory reads from a control block: only ``Identity``."""

    def __init__(self, identity: ModbusDeviceIdentification) -> None:
        self.Identity = identity  # pymodbus's attribute name


def _identification_request(identity_of: IdentityOf) -> type[ModbusPDU]:
    """A 0x2B request class answering each unit's own identity (see the module doc)."""

    class ReadDeviceIdentification(ModbusPDU):
        function_code = 0x2B
        sub_function_code = -1  # keep the decoder from swapping in pymodbus's own class
        rtu_frame_size = 7

        def __init__(self) -> None:
            super().__init__()
            self.mei_type = 0
            self.read_code = 0
            self.object_id = 0

        @classmethod
        def decode_sub_function_code(cls, data: bytes) -> int:
            return -1

        @classmethod
        def calculateRtuFrameSize(cls, data: bytes) -> int:  # noqa: N802 - pymodbus's name
            if len(data) < 3:
                return 0
            # The line delivers one whole frame at a time, so another MEI type's length is
            # simply all there is.
            return 7 if data[2] == 0x0E else len(data)

        def decode(self, data: bytes) -> None:
            self.mei_type = data[0]
            if len(data) >= 3:
                self.read_code, self.object_id = data[1], data[2]

        async def datastore_update(self, context: Any, device_id: int) -> ModbusPDU:
            identity = identity_of(device_id) if self.mei_type == 0x0E else None
            if identity is None:
                return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_FUNCTION)
            if not DeviceInformation.BASIC <= self.read_code <= DeviceInformation.SPECIFIC:
                return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_VALUE)
            object_id = self.object_id
            stream = _STREAM_OBJECTS.get(self.read_code)
            if stream is not None and not (object_id in stream and identity.get(object_id)):
                object_id = 0  # an object the stream does not hold: restart at the beginning
            control = _Control(ModbusDeviceIdentification(info=dict(identity)))  # type: ignore[no-untyped-call]
            information = DeviceInformationFactory.get(control, self.read_code, object_id)  # type: ignore[no-untyped-call]
            if self.read_code == DeviceInformation.SPECIFIC and (
                0x07 <= self.object_id < 0x80 or not information.get(self.object_id)
            ):
                return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_ADDRESS)
            return ReadDeviceInformationResponse(
                read_code=self.read_code,
                information=information,
                dev_id=device_id,
                transaction_id=self.transaction_id,
            )

    return ReadDeviceIdentification


class _RawResponse(ModbusPDU):
    """A reply PDU sent as the bytes it was given."""

    def __init__(self, function: int, data: bytes) -> None:
        super().__init__()
        self.function_code = function
        self.data = data

    def encode(self) -> bytes:
        return self.data


def _raw_request(function: int, serve: Serve) -> type[ModbusPDU]:
    """A request class for ``function`` that ``serve`` answers (see the module doc)."""

    class RawRequest(ModbusPDU):
        function_code = function

        def __init__(self) -> None:
            super().__init__()
            self.data = b""

        @classmethod
        def calculateRtuFrameSize(cls, data: bytes) -> int:  # noqa: N802 - pymodbus's name
            length = request_length(bytes(data))
            return len(data) if length is None else length

        def decode(self, data: bytes) -> None:
            self.data = bytes(data)

        async def datastore_update(self, context: Any, device_id: int) -> ModbusPDU:
            answer = serve(device_id, self.function_code, self.data)
            if isinstance(answer, int):
                # encode() packs any code, also one ExcCodes has no member for.
                return ExceptionResponse(self.function_code, answer)
            return _RawResponse(self.function_code, answer)

    return RawRequest


async def _cancel_other_tasks() -> None:
    """Cancel and await whatever pymodbus left running in this loop."""
    current = asyncio.current_task()
    tasks = [t for t in asyncio.all_tasks() if t is not current]
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)


class PymodbusServer:
    """A pymodbus server for ``units`` in a daemon thread with its own event loop.

    The base of :class:`SerialServer` and :class:`TcpServer`, which say where it listens:
    every register access goes to ``dispatch``, Read Device Identification to
    ``identity_of``, the other functions (``FUNCTIONS``) to ``serve``, and exception
    codes pymodbus lacks are put into the replies here.
    """

    def __init__(
        self,
        units: Sequence[int],
        *,
        dispatch: Dispatch,
        identity_of: IdentityOf,
        serve: Serve,
        where: str,
    ) -> None:
        """Serve ``units``; ``where`` names the place in error messages."""
        self._units = list(units)
        self._dispatch = dispatch
        self._identity_of = identity_of
        self._serve_raw = serve
        self._where = where
        self._pending_code: int | None = None  # only touched in the server's event loop
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop_event: asyncio.Event | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="benchbus-sim-server", daemon=True)

    def start(self, timeout: float) -> None:
        """Start the thread; return once the server listens."""
        self._thread.start()
        if not self._ready.wait(timeout):
            self.stop(timeout)
            raise RuntimeError(f"the pymodbus server did not start on {self._where}")
        if self._error is not None:
            self.stop(timeout)
            raise RuntimeError(f"the pymodbus server failed on {self._where}") from self._error

    def stop(self, timeout: float) -> None:
        """Shut the server down, close its port and end the thread (idempotent)."""
        loop, event = self._loop, self._stop_event
        if loop is not None and event is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                loop.call_soon_threadsafe(event.set)
        if self._thread.is_alive():
            self._thread.join(timeout)
        if self._thread.is_alive():  # pragma: no cover
            log.error("simulator server thread did not stop")

    def _create(self, devices: list[PymodbusSimDevice], **common: Any) -> ModbusBaseServer:
        """The pymodbus server for ``devices`` (built in the running loop)."""
        raise NotImplementedError

    def _listening(self, server: ModbusBaseServer) -> None:
        """Called in the loop once ``server`` listens."""

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:
            self._error = exc
        finally:
            self._ready.set()
            try:
                loop.run_until_complete(_cancel_other_tasks())
                loop.run_until_complete(loop.shutdown_asyncgens())
            finally:
                loop.close()

    async def _serve(self) -> None:
        self._stop_event = asyncio.Event()
        devices = [
            PymodbusSimDevice(
                id=unit,
                simdata=[SimData(address=0, count=0x10000, datatype=DataType.REGISTERS)],
                action=self._action_for(unit),
            )
            for unit in self._units
        ]
        server = self._create(
            devices,
            ignore_missing_devices=True,
            broadcast_enable=False,  # the line or gateway fans broadcasts out itself
            trace_pdu=self._trace_pdu,
            custom_pdu=[
                _identification_request(self._identity_of),
                *(_raw_request(f, self._serve_raw) for f in sorted(FUNCTIONS)),
            ],
        )
        try:
            await server.serve_forever(background=True)
            self._listening(server)
            self._ready.set()
            await self._stop_event.wait()
        finally:
            await server.shutdown()  # type: ignore[no-untyped-call]
            if ModbusBaseServer.active_server is server:
                ModbusBaseServer.active_server = None

    def _trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        """Give the exception reply now being sent the code its action asked for."""
        if sending:
            code, self._pending_code = self._pending_code, None
            if code is not None and isinstance(pdu, ExceptionResponse):
                pdu.exception_code = code
        return pdu

    def _action_for(self, unit: int) -> Callable[[int, int, int, int, list[int], Any], Any]:
        dispatch = self._dispatch

        async def action(
            function: int,
            start: int,
            address: int,
            count: int,
            registers: list[int],
            values: list[int] | list[bool] | None,
        ) -> ExcCodes | None:
            self._pending_code = None
            if values is None and function == 0x06:
                return None  # the echo of a write: pymodbus reads back what it just stored
            if values is None and function == 0x03:
                result = dispatch(unit, function, address, count, None)
            elif values is not None and function in (0x06, 0x10):
                result = dispatch(unit, function, address, count, [int(v) for v in values])
            else:
                return ExcCodes.ILLEGAL_FUNCTION
            if isinstance(result, int):
                return self._exception(result)
            if result is not None:
                registers[address - start : address - start + count] = result
            return None

        return action

    def _exception(self, code: int) -> ExcCodes:
        if code in _EXC_CODES:
            return ExcCodes(code)
        self._pending_code = code
        return ExcCodes.DEVICE_FAILURE


class SerialServer(PymodbusServer):
    """A pymodbus RTU server on the serial port (pseudo-terminal) ``port``."""

    def __init__(
        self,
        port: str,
        units: Sequence[int],
        *,
        baudrate: int,
        dispatch: Dispatch,
        identity_of: IdentityOf,
        serve: Serve,
    ) -> None:
        """Serve ``units`` on ``port``; register accesses go to ``dispatch``."""
        super().__init__(units, dispatch=dispatch, identity_of=identity_of, serve=serve, where=port)
        self._port = port
        self._baudrate = baudrate

    def _create(self, devices: list[PymodbusSimDevice], **common: Any) -> ModbusBaseServer:
        return ModbusSerialServer(
            devices,
            framer=FramerType.RTU,
            port=self._port,
            baudrate=self._baudrate,
            bytesize=8,
            parity="N",
            stopbits=1,
            **common,
        )


class TcpServer(PymodbusServer):
    """A pymodbus TCP server on 127.0.0.1 (an ephemeral port): MBAP or RTU frames."""

    def __init__(
        self,
        units: Sequence[int],
        *,
        rtu: bool,
        dispatch: Dispatch,
        identity_of: IdentityOf,
        serve: Serve,
        host: str = "127.0.0.1",
    ) -> None:
        """Serve ``units`` with RTU framing (``rtu``) or MBAP framing (Modbus TCP)."""
        super().__init__(units, dispatch=dispatch, identity_of=identity_of, serve=serve, where=host)
        self._host = host
        self._framer = FramerType.RTU if rtu else FramerType.SOCKET
        self._address: tuple[str, int] | None = None

    @property
    def address(self) -> tuple[str, int]:
        """The ``(host, port)`` the server listens on (once started)."""
        if self._address is None:
            raise RuntimeError("the pymodbus TCP server is not listening")
        return self._address

    def _create(self, devices: list[PymodbusSimDevice], **common: Any) -> ModbusBaseServer:
        return ModbusTcpServer(devices, framer=self._framer, address=(self._host, 0), **common)

    def _listening(self, server: ModbusBaseServer) -> None:
        listener: Any = server.transport  # an asyncio.Server once it listens
        host, port = listener.sockets[0].getsockname()[:2]
        self._address = (str(host), int(port))
