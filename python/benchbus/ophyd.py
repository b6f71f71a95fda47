"""benchbus devices as ophyd-async devices, for Bluesky: one signal per register of the
device's profile, and a drive as a motor on its speed.

::

    import bluesky.plan_stubs as bps
    from bluesky import RunEngine
    from bluesky.plans import count

    import benchbus as bb
    from benchbus.ophyd import device

    RE = RunEngine()
    sensor = device(bb.Device.from_profile("xy_md02.toml", "/dev/ttyUSB0"), "sensor")
    RE(count([sensor], num=3))          # events hold temperature, humidity... in degC, %RH
    RE(bps.mv(sensor.temperature_correction, -0.5))    # checked, then written
    spindle = device(bb.Drive("/dev/ttyUSB1"), "spindle", tolerance=20)
    RE(bps.mv(spindle, 1500))           # done once the measured speed is within 20 rpm

Needs ophyd-async and Bluesky (``pip install 'benchbus[bluesky]'``, Python 3.11 or later).
Without them the module still imports, and :func:`device` raises an ImportError that says
what to install.

A device whose ``get`` / ``set`` (and ``stop``, ``forward``) are coroutine functions is
awaited as it is; a blocking one has each call run in a worker thread, under a
:class:`benchbus.CancelToken` that a cancelled await cancels, so that the event loop never
waits on the line.
"""

from __future__ import annotations

import asyncio
import enum
import functools
import inspect
import logging
import math
import re
import time
from collections.abc import AsyncIterator, Callable
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

from benchbus._core import CancelToken
from benchbus._device import member_name
from benchbus._extras import need_framework
from benchbus.exceptions import BenchbusError

if TYPE_CHECKING:
    from benchbus._core import Profile
    from benchbus._profile import ProfileRegister

__all__ = [
    "SPEED_CONTROLS",
    "AsyncRegisterDevice",
    "DriveDevice",
    "RegisterBackend",
    "RegisterDevice",
    "RegisterSource",
    "SpeedControl",
    "asynchronous",
    "datatype",
    "device",
    "speed_control",
]

log = logging.getLogger("benchbus.ophyd")

#: Why ophyd-async or Bluesky could not be imported (None: they are there).
_MISSING: ImportError | None = None
try:
    import numpy as np
    from bluesky.protocols import Reading, Stoppable
    from event_model import DataKey, Limits
    from ophyd_async.core import (
        CALCULATE_TIMEOUT,
        CalculatableTimeout,
        Callback,
        SignalBackend,
        SignalMetadata,
        SignalR,
        SignalRW,
        SignalW,
        StandardReadable,
        StandardReadableFormat,
        SubsetEnum,
        WatchableAsyncStatus,
        WatcherUpdate,
        make_datakey,
    )
    from ophyd_async.core._device import DEVICE_RESERVED_ATTRS
except ImportError as exc:  # the module imports without the extra; device() says so
    _MISSING = exc


class SpeedControl(NamedTuple):
    """How a drive family runs at a speed: the registers and the command that
    :class:`DriveDevice` uses."""

    #: The register the speed (rpm) is written to.
    setpoint: str
    #: The register of the measured speed (rpm).
    readback: str
    #: The device's method that starts the motor.
    start: str
    #: The register that says whether the motor is running...
    state: str
    #: ...as this function of its value says.
    running: Callable[[int], bool]
    #: The registers of the ramp up and the ramp down.
    ramps: tuple[str, str]
    #: The seconds a ramp takes: a function of the change of speed (rpm) and the ramp
    #: register's value.
    ramp_seconds: Callable[[float, float], float]


#: The built-in drives: a BLD / C20 drive (runs forward, a ramp is its time for 3000 rpm)
#: and a PBL drive (starts in the direction it is set to, a ramp is in rpm/s).
SPEED_CONTROLS = (
    SpeedControl(
        "speed_setpoint",
        "speed",
        "forward",
        "state",
        lambda state: state in (1, 2),  # forward or reverse
        ("accel_time", "decel_time"),
        lambda change, seconds: change / 3000 * seconds,
    ),
    SpeedControl(
        "internal_speed",
        "speed",
        "start",
        "status",
        lambda status: bool(status & 1),
        ("acceleration", "deceleration"),
        lambda change, rate: change / rate if rate > 0 else 0.0,
    ),
)


def speed_control(source: Any) -> SpeedControl | None:
    """The :data:`SPEED_CONTROLS` entry whose registers ``source``'s profile has and whose
    start command and ``stop`` it has (None: not a drive)."""
    try:
        names = {r.name for r in source.profile.registers}
    except (AttributeError, RuntimeError):
        return None
    for control in SPEED_CONTROLS:
        wanted = {control.setpoint, control.readback, control.state, *control.ramps}
        if (
            wanted <= names
            and callable(getattr(source, control.start, None))
            and callable(getattr(source, "stop", None))
        ):
            return control
    return None


class RegisterSource(Protocol):
    """What :func:`device` wraps: any benchbus device, with its register table as
    ``profile`` and a register read and written by name with ``get`` / ``set``, blocking
    (``bb.Device``, ``bb.Drive``...) or coroutine functions (an async device)."""

    @property
    def profile(self) -> Profile:
        """The device's registers (a :class:`benchbus.Profile`)."""
        ...

    def get(self, name: str) -> Any:
        """The register ``name``, in engineering units (or a coroutine giving it)."""
        ...

    def set(self, name: str, value: Any) -> Any:
        """Write ``value`` to the register ``name`` (or a coroutine that does)."""
        ...


class AsyncRegisterDevice(Protocol):
    """A benchbus device whose register reads and writes are awaited: what the signals
    use (:func:`asynchronous` makes one of any device)."""

    @property
    def profile(self) -> Profile:
        """The device's registers (a :class:`benchbus.Profile`)."""
        ...

    async def get(self, name: str) -> Any:
        """The register ``name``, in engineering units."""
        ...

    async def set(self, name: str, value: Any) -> None:
        """Write ``value`` to the register ``name``, checked before anything is sent."""
        ...


async def _in_thread(call: Callable[..., Any], *args: Any) -> Any:
    """``call(*args)`` in a worker thread under a :class:`~benchbus.CancelToken`: when the
    await is cancelled, the token is, so that the call sends nothing further."""
    token = CancelToken()

    def run() -> Any:
        with token:
            return call(*args)

    try:
        return await asyncio.to_thread(run)
    except asyncio.CancelledError:
        token.cancel()
        raise


class _InThread:
    """A blocking benchbus device, its methods as coroutine functions run in a thread."""

    def __init__(self, device: RegisterSource) -> None:
        """Wrap ``device``."""
        self._device = device

    @property
    def profile(self) -> Profile:
        """The device's registers."""
        return self._device.profile

    async def get(self, name: str) -> Any:
        """``device.get(name)`` in a worker thread."""
        return await _in_thread(self._device.get, name)

    async def set(self, name: str, value: Any) -> None:
        """``device.set(name, value)`` in a worker thread."""
        await _in_thread(self._device.set, name, value)

    def __getattr__(self, name: str) -> Any:
        """Any other method of the device (``stop``, ``forward``...), awaited the same way;
        other attributes as they are."""
        member = getattr(self._device, name)
        if not callable(member):
            return member
        return functools.partial(_in_thread, member)


def asynchronous(device: RegisterSource) -> AsyncRegisterDevice:
    """``device`` itself when its ``get`` is a coroutine function, else the device with its
    methods run in a worker thread each (never blocking the event loop)."""
    if inspect.iscoroutinefunction(device.get):
        return device
    return _InThread(device)


def _needs_ophyd() -> None:
    """ImportError saying what to install, when ophyd-async or Bluesky is missing."""
    need_framework("benchbus.ophyd", "ophyd-async and Bluesky", "bluesky", "ophyd_async", _MISSING)


def _whole(register: ProfileRegister) -> bool:
    """Whether a register's engineering value is an integer (unscaled, not an enum)."""
    return register.integer_range() is not None and not register.enum


def _member_key(name: str, taken: set[str]) -> str:
    """An upper-case Python name for the enum member called ``name``, not in ``taken``."""
    key = re.sub(r"\W", "_", name).upper()
    if not key[:1].isalpha() or not key.isupper():
        key = f"V_{key}"
    while key in taken:
        key += "_"
    taken.add(key)
    return key


if _MISSING is None:

    def datatype(register: ProfileRegister) -> type[Any]:
        """The signal datatype of a register: ``bool``, ``str``, ``int`` for an unscaled
        integer, ``float`` for a float or a scaled value, and for an enum register a
        ``SubsetEnum`` whose values are the members' names (a number the device holds that
        the profile does not list reads as ``UNKNOWN(7)``)."""
        if register.enum:
            taken: set[str] = set()
            members = {_member_key(n, taken): n for n in register.enum.values()}
            made: type[SubsetEnum] = SubsetEnum(
                "".join(p.capitalize() for p in register.name.split("_")), members
            )
            return made
        if register.type == "bool":
            return bool
        if register.type == "string":
            return str
        return int if _whole(register) else float

    #: A value of each kind, for a descriptor made without reading the device.
    _BLANK: dict[type[Any], Any] = {bool: False, int: 0, float: 0.0, str: ""}

    class RegisterBackend(SignalBackend[Any]):
        """One register of a benchbus device as an ophyd-async signal backend: reads with
        ``get``, writes with ``set`` after checking the value, the register's unit and range
        in the descriptor. While a signal is subscribed (a plan watching it), the register is
        read every ``poll_period`` seconds and each new value passed on."""

        def __init__(
            self,
            device: AsyncRegisterDevice,
            register: ProfileRegister,
            *,
            source: str,
            poll_period: float = 0.1,
        ) -> None:
            """The backend of ``register`` of ``device``; ``source`` names it in
            descriptors."""
            super().__init__(datatype(register))
            #: The async device whose register this backend reads and writes.
            self.device = device
            #: The profile's register.
            self.register = register
            self._source = source
            #: Seconds between reads while a callback is subscribed.
            self.poll_period = poll_period
            self._setpoint: Any = None
            self._callback: Callback[Reading[Any]] | None = None
            self._poller: asyncio.Task[None] | None = None
            metadata: SignalMetadata = {}
            if register.unit:
                metadata["units"] = register.unit
            kind = self.datatype
            if (
                kind in (int, float)
                and register.access != "r"
                and register.min is not None
                and register.max is not None
                and register.decimals is None  # its range is in digits whose places change
            ):
                metadata["limits"] = Limits(control={"low": register.min, "high": register.max})
            if kind is float and 0 < register.scale < 1:
                metadata["precision"] = round(-math.log10(register.scale))
            if isinstance(kind, type) and issubclass(kind, SubsetEnum):
                metadata["choices"] = [m.value for m in kind]
            #: The signal's metadata: units, limits, precision, choices.
            self.metadata = metadata

        def source(self, name: str, read: bool) -> str:
            """Where the register is: ``benchbus://PORT/UNIT/NAME`` (the profile's name in
            place of the port and unit for a device that has none)."""
            return self._source

        async def connect(self, timeout: float) -> None:
            """Nothing to do: the device is open (its Bus connects on the first request)."""

        def check(self, value: Any) -> Any:
            """``value`` as the device takes it, or TypeError / ValueError for a value of
            the wrong kind, out of the register's range or not a member (nothing is sent)."""
            register, kind = self.register, self.datatype
            where = register.name
            if register.access == "r":
                raise ValueError(f"{where} is read-only")
            if isinstance(value, np.generic):
                value = value.item()
            if isinstance(kind, type) and issubclass(kind, SubsetEnum):
                names = [m.value for m in kind]
                if not isinstance(value, str):
                    raise TypeError(f"{where} takes a member's name ({', '.join(names)})")
                if value not in names:
                    raise ValueError(f"{where}: {value!r} is not one of {', '.join(names)}")
                return str(value)
            if kind is bool:
                if not isinstance(value, bool):
                    raise TypeError(f"{where} takes a bool, got {type(value).__name__}")
                return value
            if kind is str:
                if not isinstance(value, str):
                    raise TypeError(f"{where} takes a str, got {type(value).__name__}")
                if register.length and len(value) > 2 * register.length:
                    raise ValueError(f"{where} holds at most {2 * register.length} characters")
                return value
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"{where} takes a number, got {type(value).__name__}")
            if not math.isfinite(value):
                raise ValueError(f"{where} takes a finite number, got {value}")
            if kind is int:
                if value != int(value):
                    raise ValueError(f"{where} takes a whole number, got {value}")
                value = int(value)
            low, high = register.min, register.max
            if register.decimals is not None:  # digits whose places change: the device's
                low = high = None
            if (low is not None and value < low) or (high is not None and value > high):
                raise ValueError(f"{where} must be {low:g} to {high:g}, got {value}")
            return value

        async def put(self, value: Any) -> None:
            """Check ``value`` (see :meth:`check`), then write it."""
            checked = self.check(value)
            await self.device.set(self.register.name, checked)
            self._setpoint = checked

        def _shown(self, raw: Any) -> Any:
            """A value as the device gives it, as the signal's datatype has it."""
            kind = self.datatype
            if isinstance(kind, type) and issubclass(kind, SubsetEnum):
                return kind(member_name(raw) if isinstance(raw, enum.Enum) else str(raw))
            return kind(raw) if kind is not None else raw

        async def get_value(self) -> Any:
            """The register, read now."""
            return self._shown(await self.device.get(self.register.name))

        async def get_reading(self) -> Reading[Any]:
            """The register, read now, with the time of the reading."""
            value = await self.get_value()
            return Reading(value=value, timestamp=time.time(), alarm_severity=0)

        async def get_datakey(self, source: str) -> DataKey:
            """dtype, shape, unit, limits (and an enum's choices), without reading."""
            kind: type[Any] = self.datatype or float
            if issubclass(kind, SubsetEnum):
                blank: Any = next(iter(kind))
            else:
                blank = _BLANK[kind]
            return make_datakey(kind, blank, source, self.metadata)

        async def get_setpoint(self) -> Any:
            """The last value written through the signal (the register read, before the
            first write)."""
            if self._setpoint is None:
                return await self.get_value()
            return self._shown(self._setpoint)

        def set_callback(self, callback: Callback[Reading[Any]] | None) -> None:
            """Start passing readings to ``callback`` (poll the register), or stop."""
            if callback is not None and self._callback is not None:
                raise RuntimeError("cannot set a callback when one is already set")
            if self._poller is not None:
                self._poller.cancel()
                self._poller = None
            self._callback = callback
            if callback is not None:
                self._poller = asyncio.get_running_loop().create_task(self._poll(callback))

        async def _poll(self, callback: Callback[Reading[Any]]) -> None:
            """Read the register every :attr:`poll_period` and pass on each new value; a
            failed read is logged (once until a read succeeds again) and tried again."""
            last: Any = object()
            failing = False
            while True:
                try:
                    reading = await self.get_reading()
                except BenchbusError as exc:
                    if not failing:
                        log.warning("%s: polling goes on after %s", self._source, exc)
                    failing = True
                else:
                    failing = False
                    if reading["value"] != last:
                        last = reading["value"]
                        callback(reading)
                await asyncio.sleep(self.poll_period)

    def _signal(backend: RegisterBackend) -> SignalR[Any] | SignalW[Any]:
        """The signal of a register: readable, writable or both, as its access says."""
        access = backend.register.access
        if access == "r":
            return SignalR(backend)
        if access == "w":
            return SignalW(backend)
        return SignalRW(backend)

    def _where(device: Any) -> str:
        """``PORT/UNIT`` of a device on a Bus, else its profile's name."""
        try:
            return f"{device.bus.port}/{device.unit}"
        except (AttributeError, RuntimeError):
            return str(device.profile.name)

    class RegisterDevice(StandardReadable):
        """A benchbus device as an ophyd-async device: a signal per register of its
        profile, named after the register (see :func:`device`)."""

        def __init__(
            self, source: RegisterSource, name: str = "", *, poll_period: float = 0.1
        ) -> None:
            """The device for ``source`` called ``name``; see :func:`device`."""
            if not all(hasattr(source, member) for member in ("profile", "get", "set")):
                raise TypeError(
                    "an ophyd-async device is made of a benchbus device (with .profile, "
                    f".get and .set), got {type(source).__name__}"
                )
            #: The benchbus device, its calls awaited.
            self.bus_device: Any = asynchronous(source)
            profile = source.profile
            where = _where(source)
            #: Each register's signal, by register name.
            self.registers: dict[str, SignalR[Any] | SignalW[Any]] = {}
            #: Each register's backend, by register name.
            self.backends: dict[str, RegisterBackend] = {}
            reads: list[SignalR[Any]] = []
            settings: list[SignalR[Any]] = []
            for register in profile.registers:
                backend = RegisterBackend(
                    self.bus_device,
                    register,
                    source=f"benchbus://{where}/{register.name}",
                    poll_period=poll_period,
                )
                signal = _signal(backend)
                attribute = register.name
                if attribute in DEVICE_RESERVED_ATTRS or hasattr(self, attribute):
                    attribute += "_"
                setattr(self, attribute, signal)
                self.registers[register.name] = signal
                self.backends[register.name] = backend
                if register.access == "r":
                    reads.append(signal)  # type: ignore[arg-type]
                elif register.access in ("rw", "rw-stopped"):
                    settings.append(signal)  # type: ignore[arg-type]
            self.add_readables(reads, StandardReadableFormat.UNCACHED_SIGNAL)
            self.add_readables(settings, StandardReadableFormat.CONFIG_SIGNAL)
            super().__init__(name=name)

    class DriveDevice(RegisterDevice, Stoppable):
        """A drive as an ophyd-async device: its registers' signals, and a motor on its
        speed (``bps.mv(drive, 1500)``; see :meth:`set` and :meth:`stop`)."""

        def __init__(
            self,
            source: RegisterSource,
            name: str = "",
            *,
            control: SpeedControl | None = None,
            tolerance: float = 10.0,
            timeout: float | None = None,
            poll_period: float = 0.1,
        ) -> None:
            """The drive ``source`` called ``name``, run as ``control`` says (None: the
            built-in family it is, see :func:`speed_control`): :meth:`set` is done once the
            measured speed is within ``tolerance`` rpm of the target; it fails after
            ``timeout`` seconds (None: twice the time its ramp takes, plus 5 s)."""
            control = control or speed_control(source)
            if control is None:
                raise TypeError(f"{type(source).__name__} is not a drive this module knows")
            for key, number in (("tolerance", tolerance), ("poll_period", poll_period)):
                if isinstance(number, bool) or not isinstance(number, (int, float)):
                    raise TypeError(f"{key} must be a number, got {type(number).__name__}")
                if not (math.isfinite(number) and number >= 0):
                    raise ValueError(f"{key} must be >= 0, got {number}")
            if timeout is not None and (
                isinstance(timeout, bool)
                or not isinstance(timeout, (int, float))
                or not timeout > 0
            ):
                raise ValueError(f"timeout must be > 0 seconds or None, got {timeout!r}")
            super().__init__(source, name, poll_period=poll_period)
            #: How close (rpm) the measured speed must come to the target.
            self.tolerance = float(tolerance)
            #: The registers and command the motor is run with.
            self.control = control
            #: Seconds a move may take (None: from the ramp).
            self.timeout = timeout
            #: Seconds between two reads of the speed while a move waits.
            self.poll_period = float(poll_period)
            self._stopped: bool | None = None

        async def _ramp_timeout(self, start: float, target: float) -> float:
            """Twice the time the drive's ramp takes from ``start`` to ``target``, + 5 s."""
            up, down = self.control.ramps
            ramp = float(await self.bus_device.get(up if target >= start else down))
            return 2 * self.control.ramp_seconds(abs(target - start), ramp) + 5.0

        @WatchableAsyncStatus.wrap
        async def set(
            self, value: float, timeout: CalculatableTimeout = "CALCULATE_TIMEOUT"
        ) -> AsyncIterator[WatcherUpdate[float]]:
            """Run at ``value`` rpm: write the speed setpoint (checked first), start the
            motor if it is not running (a BLD / C20 drive forward, a PBL drive in the
            direction it is set to), and finish once the measured speed is within
            :attr:`tolerance` of it. TimeoutError after ``timeout`` seconds (by default the
            device's :attr:`timeout`); RuntimeError if :meth:`stop` ends the move with
            ``success=False``. Watchers see the speed as it ramps."""
            control = self.control
            backend = self.backends[control.setpoint]
            target = backend.check(value)
            self._stopped = None
            initial = float(await self.bus_device.get(control.readback))
            if timeout == CALCULATE_TIMEOUT:
                timeout = self.timeout
                if timeout is None:
                    timeout = await self._ramp_timeout(initial, target)
            await backend.put(target)
            if not control.running(int(await self.bus_device.get(control.state))):
                await getattr(self.bus_device, control.start)()
            deadline = None if timeout is None else time.monotonic() + float(timeout)
            while True:
                if self._stopped is not None:
                    if self._stopped:
                        return
                    raise RuntimeError(f"{self.name} was stopped")
                speed = float(await self.bus_device.get(control.readback))
                yield WatcherUpdate(
                    current=speed,
                    initial=initial,
                    target=float(target),
                    name=self.name,
                    unit="rpm",
                    fraction=(1.0 if initial == target else (speed - initial) / (target - initial)),
                )
                if abs(speed - target) <= self.tolerance:
                    return
                if deadline is not None and time.monotonic() >= deadline:
                    raise TimeoutError(
                        f"{self.name}: speed {speed:g} rpm, not within {self.tolerance:g} "
                        f"rpm of {target} rpm after {timeout} s"
                    )
                await asyncio.sleep(self.poll_period)

        async def stop(self, success: bool = True) -> None:
            """Stop the motor (the drive's stop command); a move in progress ends, as a
            success or (``success=False``, what Bluesky sends on an abort) an error."""
            self._stopped = success
            await self.bus_device.stop()


def device(
    source: RegisterSource,
    name: str,
    *,
    tolerance: float = 10.0,
    timeout: float | None = None,
    poll_period: float = 0.1,
) -> RegisterDevice:
    """An ophyd-async device called ``name`` for a benchbus device: a signal per register of
    ``source.profile``, named after the register (``dev.temperature``; a name that Bluesky's
    protocols or the device itself use, such as ``stage`` or ``log``, gets a trailing
    underscore, ``dev.stage_``; every signal by register name in ``dev.registers``).

    A read-only register is a readable signal that :meth:`~RegisterDevice.read` gives (in
    each event of a plan); a read-and-write one a readable and settable signal that
    ``read_configuration`` gives (in the descriptor's configuration); a write-only one a
    settable signal. Each descriptor has the register's ``units``, its ``limits``
    (``control``: the profile's min and max) and dtype: ``integer`` for an unscaled
    integer, ``number`` for a float or a scaled value (with ``precision`` from the scale),
    ``boolean``, ``string``, and for an enum ``string`` with its members' names as
    ``choices``. A write is checked against the register's type and range (an enum by a
    member's name) and raises TypeError or ValueError before anything is sent; the device
    checks it again.

    A drive (``bb.Drive``, ``bb.PblDrive``, or an async drive with their registers and
    commands: :func:`speed_control`) gives a :class:`DriveDevice`, which is also a motor
    on its speed: ``set(rpm)`` completes once the measured speed is within
    ``tolerance`` rpm (``timeout`` seconds at most), ``stop()`` stops the motor. While a
    plan watches a signal, the register is read every ``poll_period`` seconds.

    The device belongs to the caller and stays open; ``source`` may be blocking (each call
    runs in a worker thread) or have coroutine methods (awaited as they are).
    """
    _needs_ophyd()
    control = speed_control(source)
    if control is not None:
        return DriveDevice(
            source,
            name,
            control=control,
            tolerance=tolerance,
            timeout=timeout,
            poll_period=poll_period,
        )
    return RegisterDevice(source, name, poll_period=poll_period)


if not TYPE_CHECKING:

    def __getattr__(name: str) -> Any:
        """The ophyd-async classes and functions, or the ImportError saying what to
        install."""
        if name in ("DriveDevice", "RegisterBackend", "RegisterDevice", "datatype"):
            _needs_ophyd()
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
