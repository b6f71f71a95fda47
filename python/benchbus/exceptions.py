"""The benchbus exception tree, defined once here and raised from the Rust core.

::

    BenchbusError(Exception)                       base of everything below
    ├── PortError(BenchbusError, OSError)          port cannot be opened, vanished, I/O failed
    ├── ResponseTimeout(BenchbusError, TimeoutError)   no (complete) reply in time
    ├── FrameError(BenchbusError)                  reply malformed: wrong unit, function,
    │   └── CrcError(FrameError)                   length or echo, a garbled local echo;
    │                                              bad CRC
    ├── ModbusException(BenchbusError)             the device answered with an exception
    │   └── GatewayError(ModbusException)          a gateway answered 0x0A (no path to the
    │                                              unit) or 0x0B (the unit did not answer it)
    ├── StateError(BenchbusError)                  the device's state forbids the request
    ├── Cancelled(BenchbusError)                   the call's CancelToken was cancelled
    ├── WrongDevice(BenchbusError)                 the unit answers as another device
    │                                              family than the device object's
    └── ProfileError(BenchbusError, ValueError)    a device profile file is wrong: its
                                                   path, line and key

Bad arguments raise ``ValueError`` / ``TypeError`` before anything is sent. A bug inside
benchbus (a panic in its core) raises ``BenchbusError`` itself, saying so, and the Bus goes on.

Every exception carries ``unit`` and ``function`` (``None`` where they do not apply) and
``frame``, the raw bytes involved as uppercase hex (``"01 83 02 C0 F1"``) or ``None``.
"""

from __future__ import annotations

__all__ = [
    "BenchbusError",
    "Cancelled",
    "CrcError",
    "FrameError",
    "GatewayError",
    "ModbusException",
    "PortError",
    "ProfileError",
    "ResponseTimeout",
    "StateError",
    "WrongDevice",
]


class BenchbusError(Exception):
    """Base class of every error benchbus raises about the bus or a device.

    Raised itself only for an internal error (a bug in benchbus's core, caught there).
    """

    unit: int | None
    """The unit addressed, if any."""
    function: int | None
    """The Modbus function code of the request, if any."""
    frame: str | None
    """The raw frame involved, as uppercase hex bytes, if any."""

    def __init__(
        self,
        message: str,
        *,
        unit: int | None = None,
        function: int | None = None,
        frame: str | None = None,
    ) -> None:
        super().__init__(message)
        self.unit = unit
        self.function = function
        self.frame = frame


class PortError(BenchbusError, OSError):
    """The port cannot be opened, has vanished, or an I/O call on it failed."""


class ResponseTimeout(BenchbusError, TimeoutError):
    """No complete reply arrived within the timeout, on every attempt.

    ``frame`` holds the bytes of an incomplete reply, if some arrived.
    """


class FrameError(BenchbusError):
    """A reply arrived but is malformed: wrong unit, function, length or echo."""


class CrcError(FrameError):
    """A reply arrived with a CRC (in Modbus ASCII, an LRC) that does not match its contents."""


class ModbusException(BenchbusError):
    """The device answered with a Modbus exception response.

    ``code`` is the exception code and ``meaning`` its text, in the device family's words
    where its manual gives them (e.g. 0x08 "not changeable while running" on a Drive).
    """

    code: int
    """The exception code (1 illegal function, 2 illegal data address, ...)."""
    meaning: str
    """What the code means for this device."""

    def __init__(
        self,
        message: str,
        *,
        code: int,
        meaning: str,
        unit: int | None = None,
        function: int | None = None,
        frame: str | None = None,
    ) -> None:
        super().__init__(message, unit=unit, function=function, frame=frame)
        self.code = code
        self.meaning = meaning


class GatewayError(ModbusException):
    """A Modbus gateway (a TCP to RS485 converter, ``benchbus gateway``) answered for the unit.

    ``code`` 0x0A: the gateway has no path to the unit (not configured, or its serial port
    is gone). ``code`` 0x0B: the gateway asked the unit and got no valid reply in time (the
    unit is off, or on another address); the gateway's own timeout and retries applied, not
    the Bus's.
    """


class StateError(BenchbusError):
    """The device is in a state that forbids the request, so nothing was written.

    For example MV written to a J2 controller in automatic mode (its manual allows MV only
    in manual mode). The message says how to get past it.
    """


class Cancelled(BenchbusError):
    """The call's :class:`benchbus.CancelToken` was cancelled, so the call stopped short.

    It left the queue for the line without sending anything, or its attempt in flight
    finished (the line stays in step) and it started no further attempt or request. It is a
    :class:`BenchbusError`, not an ``asyncio.CancelledError``: a plain thread catches it as
    any benchbus error, and an event loop that cancelled a call running in a worker thread
    raises its own task's ``CancelledError``. ``frame`` is None.
    """


class WrongDevice(BenchbusError):
    """The unit answers, but as a device of another family than the object talking to it.

    A :class:`benchbus.Drive`, :class:`benchbus.PblDrive` or :class:`benchbus.J2Controller`
    checks, before its first exchange, that its unit is of its family, with the reads
    ``benchbus scan`` names a unit by; a unit another family's reads recognise raises this
    (``unit 1 answers but is not a BLD drive: it looks like a J2 controller``), before
    anything is written. Every later call of that object raises it again and sends nothing,
    and leaving its ``with`` block writes nothing. A unit no family recognises is given the
    benefit of the doubt. Make the device with ``check_identity=False`` for a unit whose
    identity registers differ from its manual's.
    """

    expected: str
    """The family the object was made for: ``"drive"``, ``"pbl"`` or ``"j2"``."""
    looks_like: str
    """The family the unit looks like (one of the same keys)."""

    def __init__(self, message: str, *, unit: int, expected: str, looks_like: str) -> None:
        super().__init__(message, unit=unit)
        self.expected = expected
        self.looks_like = looks_like


class ProfileError(BenchbusError, ValueError):
    """A device profile file is wrong; raised before any port is opened.

    The message reads ``FILE:LINE: key: what is wrong``, or ``FILE: cannot read the
    file: ...`` for a file that cannot be read (it has no line).
    """

    path: str
    """The file, as it was given or as a profile's name found it (a name found nowhere:
    the name)."""
    line: int
    """The line (from 1) of the offending key or value; 0 if the file cannot be read."""
    key: str
    """The key, dotted from the top of the file (``line.parity``, ``register[2].type``);
    empty for a file that is not valid TOML."""

    def __init__(self, message: str, *, path: str = "", line: int = 0, key: str = "") -> None:
        super().__init__(message)
        self.path = path
        self.line = line
        self.key = key
