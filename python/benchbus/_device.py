"""What the device classes share: printable enums and properties backed by a register table.

Each device class has its compiled class as its base (``DriveCore`` under ``Drive``,
``PblCore`` under ``PblDrive``...), which knows the register table, scaling and limits, and
reads or writes a register by name with ``get`` / ``set``. A :class:`RegisterProperty` turns
one such register into a Python property, converting the raw value (an enum, an int, a
float) on the way out.
"""

from __future__ import annotations

import contextlib
import enum
import functools
import logging
import os
import time
from collections.abc import Callable, Iterable
from typing import (
    TYPE_CHECKING,
    Any,
    ClassVar,
    Generic,
    NamedTuple,
    NoReturn,
    Protocol,
    TypeVar,
    cast,
    overload,
)

from benchbus._core import Bus, _did_you_mean
from benchbus._record import Recording, record
from benchbus._scope import Scoped
from benchbus.exceptions import PortError

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = [
    "NOTED",
    "BusDevice",
    "LineDefaults",
    "MeasuredProperty",
    "MotorDevice",
    "PrintableIntEnum",
    "RegisterProperty",
    "add_note",
    "as_enum",
    "check_baudrate",
    "did_you_mean",
    "forked",
    "is_unknown",
    "member_name",
    "on_line",
    "to_enum",
    "to_float",
    "to_int",
]


#: Set on a log record whose text is also a note on the exception being raised (a reader
#: that reports the exception with its notes need not show the record too).
NOTED = "benchbus_noted"


def forked(bus: Bus) -> bool:
    """Whether this process is not the one that opened ``bus``: a child made by fork, which
    may neither use it nor close anything of it for its parent (``bus._owned()`` raises
    the PortError that says so)."""
    try:
        bus._owned()
    except PortError:
        return True
    return False


def add_note(exc: BaseException, text: str) -> None:
    """Add ``text`` to ``exc.__notes__`` (``BaseException.add_note`` from Python 3.11)."""
    notes = getattr(exc, "__notes__", None)
    if not isinstance(notes, list):
        notes = []
    notes.append(text)
    with contextlib.suppress(AttributeError):  # a type without attributes: the log says it
        setattr(exc, "__notes__", notes)  # noqa: B010 (BaseException lacks it before 3.11)


#: The name of a value read from a device that its enum does not list (see :func:`as_enum`).
UNKNOWN = "UNKNOWN"


class PrintableIntEnum(enum.IntEnum):
    """An IntEnum that prints as ``DriveState.FORWARD`` on every Python version, and a value
    its members do not list as ``DriveState.UNKNOWN(9)`` (see :func:`as_enum`)."""

    def __str__(self) -> str:
        """``ClassName.MEMBER``, or ``ClassName.UNKNOWN(value)`` for a value not listed."""
        return f"{type(self).__name__}.{member_name(self)}"

    def __reduce_ex__(self, protocol: Any) -> tuple[Any, ...]:
        """Pickled and copied as :func:`as_enum` of the class and the number, so that a
        value not listed survives too."""
        return as_enum, (type(self), int(self))


def is_unknown(value: object) -> bool:
    """Whether ``value``, read from a device, is a number its enum does not list: an
    ``UNKNOWN`` value :func:`as_enum` made (``DriveState.UNKNOWN(9)``), not a member."""
    if not isinstance(value, enum.Enum):
        return False
    return type(value)._member_map_.get(value.name) is not value


def member_name(value: enum.Enum) -> str:
    """The name of an enum value read from a device: its member's, or ``UNKNOWN(9)`` for a
    number its enum does not list (see :func:`as_enum`): what ``str()``, the command line
    and the ophyd-async signals show."""
    return f"{UNKNOWN}({value.value})" if is_unknown(value) else value.name


log = logging.getLogger("benchbus.device")


class Registers(Protocol):
    """A device that reads and writes its registers by name (its compiled base does)."""

    def get(self, name: str) -> int | float:
        """The register called ``name``, in engineering units."""
        ...

    def set(self, name: str, value: float) -> None:
        """Write the register called ``name``, checked before anything is sent."""
        ...


E = TypeVar("E", bound=enum.IntEnum)
T = TypeVar("T")
D = TypeVar("D", bound=Registers)


def as_enum(enum_type: type[E], raw: int) -> E:
    """The member of ``enum_type`` whose value is ``raw``, read from a device; for a value
    the enum does not list (a device may report a code its manual does not), an ``UNKNOWN``
    value of the enum carrying the number: an instance of ``enum_type`` equal to ``raw``,
    named ``"UNKNOWN"``, printed ``DriveState.UNKNOWN(9)``, which no member equals and
    :func:`is_unknown` tells apart. Every family and every profile's enum reads so."""
    try:
        return enum_type(raw)
    except ValueError:
        unknown: E = int.__new__(enum_type, raw)
        unknown._name_ = UNKNOWN
        unknown._value_ = raw
        return unknown


class _Backed(Generic[D, T]):
    """A device attribute read from the register ``register`` of the device."""

    def __init__(self, register: str, convert: Callable[[D, Any], T], doc: str) -> None:
        """Read through ``convert(device, raw value)``; ``doc`` is the property's docstring."""
        self.register = register
        self.convert = convert
        self.__doc__ = doc

    @overload
    def __get__(self, device: None, owner: type[D]) -> Self: ...
    @overload
    def __get__(self, device: D, owner: type[D]) -> T: ...
    def __get__(self, device: D | None, owner: type[D]) -> T | Self:
        """The converted register value (the descriptor itself on the class)."""
        if device is None:
            return self
        return self.convert(device, device.get(self.register))


class RegisterProperty(_Backed[D, T]):
    """A read/write device property backed by one register of the device."""

    def __set__(self, device: D, value: float) -> None:
        """Write ``value`` (an enum member is an int) to the register."""
        device.set(self.register, value)


class MeasuredProperty(_Backed[D, T]):
    """A read-only device property backed by a measurement register."""

    def __set__(self, device: D, value: NoReturn) -> None:
        """Refuse: a measurement cannot be written."""
        raise AttributeError(f"{self.register} is a measurement: it cannot be set")


def to_int(_device: Any, raw: Any) -> int:
    """The raw value as an int."""
    return int(raw)


def to_float(_device: Any, raw: Any) -> float:
    """The raw value as a float."""
    return float(raw)


def to_enum(enum_type: type[E]) -> Callable[[Any, Any], E]:
    """A converter to ``enum_type`` (an ``UNKNOWN`` value for a number it does not list:
    see :func:`as_enum`)."""
    return lambda _device, raw: as_enum(enum_type, int(raw))


class LineDefaults(NamedTuple):
    """A device family's line format and reply timeout, used when a device opens its own
    Bus (and by the command line, the pytest plugin and the demo)."""

    #: Bits per second.
    baudrate: int
    #: "N", "E" or "O".
    parity: str
    #: Seconds from the start of a request by which a device of the family starts answering.
    timeout: float
    #: 1 or 2.
    stopbits: int = 1
    #: "rtu" or "ascii".
    framing: str = "rtu"
    #: Bits per character: 8, or 7 (Modbus ASCII only); None: the framing's own.
    bytesize: int | None = None


def check_baudrate(baudrate: object, allowed: tuple[int, ...]) -> None:
    """Refuse a ``baudrate`` that is not an int (TypeError) or not one of ``allowed``."""
    if isinstance(baudrate, bool) or not isinstance(baudrate, int):
        raise TypeError(f"baudrate must be an int, got {type(baudrate).__name__}")
    if baudrate not in allowed:
        *most, last = (str(b) for b in allowed)
        listed = f"{', '.join(most)} or {last}" if most else last
        raise ValueError(f"baudrate must be {listed}, got {baudrate}")


M = TypeVar("M")


def on_line(
    port_or_bus: str | os.PathLike[str] | Bus,
    make: Callable[[Bus, float | None, int | None], M],
    *,
    line: LineDefaults,
    timeout: float | None,
    retries: int | None,
) -> tuple[M, bool]:
    """``make(bus, timeout, retries)`` on a shared Bus, or ``make(bus, None, None)`` on a Bus
    opened here at ``line``; returns what was made and whether the Bus was opened here.

    ``timeout`` / ``retries`` set the Bus opened here, or on a shared Bus are given to
    ``make`` for this device's requests only. A Bus opened here is closed again if ``make``
    fails.
    """
    if isinstance(port_or_bus, Bus):
        return make(port_or_bus, timeout, retries), False
    bus = Bus(
        port_or_bus,
        baudrate=line.baudrate,
        parity=line.parity,
        stopbits=line.stopbits,
        timeout=line.timeout if timeout is None else timeout,
        retries=2 if retries is None else retries,
        framing=line.framing,
        bytesize=line.bytesize,
    )
    try:
        return make(bus, None, None), True
    except BaseException:
        bus.close()
        raise


class _Attachable(Protocol):
    """A device whose compiled base is attached to a Bus by ``_attach`` (see
    ``src/python/mod.rs``, ``Attached``)."""

    def _attach(self, bus: Bus, *args: Any) -> None:
        """Attach to ``bus`` with the family's arguments, then ``timeout`` and ``retries``."""
        ...


class _DeviceType(type):
    """The type of device classes: an instance takes new attributes only while it is made."""

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        """Make the device, then refuse attributes it does not know (see BusDevice)."""
        device = super().__call__(*args, **kwargs)
        object.__setattr__(device, "_made", True)
        return device


def _declared(cls: type, name: str) -> bool:
    """Whether ``name`` is defined or annotated on ``cls`` or one of its bases."""
    return any(name in vars(klass) or name in _annotations(klass) for klass in cls.__mro__)


def _annotations(klass: type) -> dict[str, Any]:
    """The annotations of ``klass`` itself ({} if they cannot be evaluated)."""
    annotations = vars(klass).get("__annotations__")
    if annotations is None:  # Python 3.14 evaluates them on first access
        try:
            annotations = getattr(klass, "__annotations__", None)
        except Exception:
            annotations = None
    return annotations if isinstance(annotations, dict) else {}


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``; did you mean 'a' or 'b'?`` naming up to three of ``known`` closest to ``name``
    (letter case aside), or "" when none is close: what a typo's error message ends with.

    The core's rule (``src/device/suggest.rs``), which also ends its errors for an unknown
    register or parameter name: one rule for every name a user can mistype."""
    return _did_you_mean(name, list(known))


def _unknown_attribute(device: object, name: str, to: str = " to set") -> AttributeError:
    """An AttributeError for setting (or with ``to=""``, reading) ``name``, naming the
    closest known names."""
    known = {n for n in dir(type(device)) if not n.startswith("__")}
    known |= set(vars(device))
    known = {n for n in known if n.startswith("_") == name.startswith("_")} - {"_made"}
    hint = did_you_mean(name, known)
    return _no_such(device, name, f"{to}{hint}")


def _no_such(device: object, name: str, tail: str = "") -> AttributeError:
    """Python's AttributeError for ``name`` on ``device``, its message ending in ``tail``."""
    error = AttributeError(f"{type(device).__name__!r} object has no attribute {name!r}{tail}")
    error.name, error.obj = name, device
    return error


@functools.cache
def _converters(cls: type) -> dict[str, Callable[[Any, Any], Any]]:
    """The converters of ``cls``'s register properties, by register name."""
    found: dict[str, Callable[[Any, Any], Any]] = {}
    for klass in reversed(cls.__mro__):
        for attribute in vars(klass).values():
            if isinstance(attribute, _Backed):
                found[attribute.register] = attribute.convert
    return found


class BusDevice(Scoped, metaclass=_DeviceType):
    """A device on a Bus: its identity, and a context manager that closes what it opened.

    A subclass has a compiled device class as its first base (``class Drive(DriveCore,
    MotorDevice)``), which holds the Bus and the unit; its ``__init__`` attaches it with
    :meth:`_on_line`, which also records whether :meth:`close` closes the Bus.

    Once made, a device takes no new attribute: setting a name that is not one of its
    properties, nor defined or annotated on its class, nor set while ``__init__`` ran,
    raises AttributeError with the closest names (``j2.SV = 150``: did you mean 'sv'?),
    so that a typo cannot pass for a setting. Reading a name the device lacks says the
    same (``drive.sped``: did you mean 'speed'?); a private or special name (``_x``,
    ``__getstate__``) gets Python's plain AttributeError, found without a search, so that
    ``hasattr``, ``copy`` and ``pickle`` ask as cheaply as ever. A subclass may set any
    attribute of its own in its ``__init__``, or declare it on the class (``log:
    list[str]`` is enough) to set it later.
    """

    _owns_bus: bool
    #: The family's line defaults (a subclass sets its own).
    LINE_DEFAULTS = LineDefaults(19200, "N", 0.1)
    #: The family whose identity the device checks before its first exchange (a key of
    #: ``benchbus._families``); None: no check (a device of any kind).
    IDENTITY: ClassVar[str | None] = None

    if not TYPE_CHECKING:  # a __setattr__ would make type checkers accept any name

        def __setattr__(self, name: str, value: Any) -> None:
            """Set ``name``; AttributeError if the device is made and does not know it."""
            if (
                "_made" in self.__dict__
                and name not in self.__dict__
                and not _declared(type(self), name)
            ):
                raise _unknown_attribute(self, name)
            super().__setattr__(name, value)

        def __getattr__(self, name: str) -> Any:
            """Called only for a name the device lacks: AttributeError with the closest
            public names (none for a private name, nor for one the class declares, whose
            own reading failed)."""
            if name.startswith("_") or _declared(type(self), name):
                raise _no_such(self, name)
            raise _unknown_attribute(self, name, "")

    def _named(self, name: str, value: Any) -> Any:
        """``value`` of the register ``name`` as the class's property of that register reads
        it, where that is an enum's (a member, or the enum's ``UNKNOWN`` value): so that
        ``get``, ``get_many`` and the attribute agree; otherwise ``value`` as it is."""
        convert = _converters(type(self)).get(name)
        if convert is None:
            return value
        named = convert(self, value)
        return named if isinstance(named, enum.Enum) else value

    def _on_line(
        self,
        port_or_bus: str | os.PathLike[str] | Bus,
        *args: Any,
        timeout: float | None,
        retries: int | None,
        line: LineDefaults | None = None,
        check_identity: bool = False,
    ) -> None:
        """Attach the compiled base to a shared Bus, with ``(bus, *args, timeout, retries)``,
        or to a Bus opened at ``line`` (the class's ``LINE_DEFAULTS`` by default; see
        :func:`on_line`): what the ``__init__`` of a class whose base is compiled calls.

        With ``check_identity``, the device's first exchange is preceded by the check that
        its unit is of the family :attr:`IDENTITY` (see ``verify_identity``)."""
        if not isinstance(check_identity, bool):
            kind = type(check_identity).__name__
            raise TypeError(f"check_identity must be True or False, got {kind}")
        attachable = cast("_Attachable", self)

        def attach(bus: Bus, t: float | None, r: int | None) -> Bus:
            attachable._attach(bus, *args, t, r)
            return bus

        bus, self._owns_bus = on_line(
            port_or_bus,
            attach,
            line=self.LINE_DEFAULTS if line is None else line,
            timeout=timeout,
            retries=retries,
        )
        if check_identity and self.IDENTITY is not None:
            from benchbus._families import check_identity as check  # imports the families

            self._check_identity_with(
                functools.partial(check, self.IDENTITY, bus, self.unit, timeout, retries)
            )

    if TYPE_CHECKING:  # the compiled base (``_core._Station``) has them

        @property
        def bus(self) -> Bus:
            """The Bus the device talks through."""
            ...

        @property
        def unit(self) -> int:
            """The device's unit address."""
            ...

        def verify_identity(self) -> None:
            """Check now that the unit is of the device's family (``WrongDevice``)."""
            ...

        def _check_identity_with(self, check: Callable[[], object]) -> None: ...

    #: The names :meth:`sample` gives (None: not known in advance), so that a bad
    #: ``record(columns=...)`` is refused before anything is sent.
    SAMPLE_FIELDS: tuple[str, ...] | None = None

    def units(self) -> dict[str, str]:
        """The unit of each register or parameter by name, from the family's table (``""``
        for none; empty for a device without a fixed table)."""
        return {}

    def sample_units(self) -> dict[str, str]:
        """The unit of each field :meth:`sample` gives, from the family's table (``""`` for
        none): ``{"speed": "rpm", ...}``, what ``benchbus monitor`` and recordings show."""
        units = self.units()
        return {f: units.get(f, "") for f in self.SAMPLE_FIELDS or ()}

    def sample(self) -> dict[str, float]:
        """One snapshot of the device's main measurements, ``{name: value}`` as numbers, in
        as few requests as the device allows: what :meth:`record`, ``benchbus monitor`` and
        the demo sample. Devices without fixed measurements raise ``TypeError``."""
        raise TypeError(f"{type(self).__name__} has no fixed measurements to sample")

    def record(
        self,
        duration: float,
        interval: float,
        *,
        columns: Iterable[str] | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> Recording:
        """Take :meth:`sample` every ``interval`` seconds for ``duration`` seconds.

        ::

            rec = drive.record(5.0, 0.05)     # 100 samples, 50 ms apart
            rec.to_pandas().describe()        # or rec.to_csv(path), rec.plot(["speed"])

        Samples are taken on absolute deadlines ``n * interval`` after the start, the
        last one before ``duration``: time spent on the wire never adds up to drift. A
        sample that overruns its period skips the deadlines already past (the recording
        counts them in ``missed``) rather than taking late ones in a burst; when samples
        take longer than ``interval`` itself, a UserWarning at the end says so, with the
        period achieved and the count missed. Each sample
        keeps the time it was actually taken, read from ``clock`` just before its
        request; ``clock`` and ``sleep`` are injectable for tests.

        ``columns`` keeps only those measurements, in that order (a name the device does
        not give raises ValueError at the first sample); by default every one. A
        ``duration`` or ``interval`` that is not a positive, finite number raises
        TypeError or ValueError before anything is sent; an ``interval`` longer than
        ``duration`` gives one sample.

        A bus error ends the recording and is raised; the samples taken before it are in
        the exception's ``recording`` attribute. Ctrl-C ends it and returns the samples
        taken so far, with the recording's ``interrupted`` set.
        """
        return record(
            self.sample,
            duration,
            interval,
            device=f"{self._kind()} unit {self.unit}",
            columns=columns,
            known=self.SAMPLE_FIELDS,
            units=self.sample_units(),
            clock=clock,
            sleep=sleep,
        )

    def _kind(self) -> str:
        """What the device is, as recordings name it: its class."""
        return type(self).__name__

    def close(self) -> None:
        """Close the Bus if the device opened it (a shared Bus stays open)."""
        if self._owns_bus:
            self.bus.close()

    def _leave(self, exc: BaseException | None) -> None:
        """Leaving a ``with`` block: :meth:`close`."""
        self.close()

    def __repr__(self) -> str:
        """Class, unit and bus."""
        return f"<{type(self).__name__} unit={self.unit} on {self.bus!r}>"


class MotorDevice(BusDevice):
    """A motor drive on a Bus: a context manager that stops the motor, then closes.

    Subclasses define :meth:`stop`.
    """

    def stop(self) -> None:
        """Stop the motor."""
        raise NotImplementedError

    def _stop_on_exit(self, urgent: bool = False) -> None:
        """What leaving a ``with`` block sends (the stop; a subclass may add to it).

        ``urgent`` when the block is left by an exception (Ctrl-C among them): the stop is
        then sent once and at once (no retry, no wait for answers the drive still owes).
        """
        self.stop()

    def _leave(self, exc: BaseException | None) -> None:
        """Leaving a ``with`` block: stop the motor (also after an exception or Ctrl-C),
        then :meth:`close`.

        Leaving on an exception, the stop is sent once and at once: no retry, no wait for
        answers the drive still owes (a write's reply must echo it, so such an answer is
        never taken for the stop's), so the block is left within one timeout (a jog this
        object started adds its jog stop). A second Ctrl-C raises once the request in
        flight is over (after a jog stop the drive did not answer, the stop is not sent).

        If stopping fails while another exception is on its way out, that exception goes
        on, carrying the failure as a note (``__notes__``, shown in its traceback), and the
        failure is logged as an error; otherwise the failure is raised.
        """
        try:
            self._stop_on_exit(exc is not None)
        except Exception as failure:
            if exc is None:
                raise
            text = (
                f"unit {self.unit}: could not stop the motor on leaving the block "
                f"({type(failure).__name__}: {failure})"
            )
            add_note(exc, text)
            log.error(text, extra={NOTED: True})
            log.debug("the stop's failure", exc_info=failure)
        finally:
            self.close()
